// fulcrum-server as a child process on 127.0.0.1 with an ephemeral port, for the tests that need
// a real process: signals, resource limits, memory and threads read from /proc/PID.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "fulcrum/client.h"
#include "test_support.h"

extern char** environ;

namespace fulcrum::testing_support {

using namespace std::chrono_literals;

inline pid_t spawn(const std::vector<std::string>& argv, const std::string& out,
                   const std::string& err) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

// Exit code of a finished child, or -1 when it was killed by a signal.
inline int reap(pid_t pid) {
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class ServerProcess {
 public:
  explicit ServerProcess(std::vector<std::string> flags) {
    static int count = 0;
    dir_ = ::testing::TempDir() + "fulcrum_fault_" + std::to_string(getpid()) + "_" +
           std::to_string(count++);
    std::filesystem::create_directories(dir_);
    // A short grace period by default (a test's own flags come later and win): only calls in
    // progress wait for it.
    std::vector<std::string> argv = {FULCRUM_SERVER_BIN, "--listen", "127.0.0.1:0", "--grace-ms",
                                     "500"};
    argv.insert(argv.end(), flags.begin(), flags.end());
    pid_ = spawn(argv, dir_ + "/out.txt", dir_ + "/log.txt");
    eventually(
        [&] {
          const std::string out = read_text(dir_ + "/out.txt");
          const size_t at = out.find("listening on ");
          if (at == std::string::npos || out.find('\n', at) == std::string::npos) return false;
          address_ = out.substr(at + 13, out.find('\n', at) - at - 13);
          return true;
        },
        10s);
  }
  ~ServerProcess() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      reap(pid_);
    }
    std::filesystem::remove_all(dir_);
  }

  const std::string& address() const { return address_; }
  pid_t pid() const { return pid_; }
  std::string log() const { return read_text(dir_ + "/log.txt"); }
  const std::string& dir() const { return dir_; }

  // VmRSS from /proc/PID/status, kB.
  long rss_kb() const {
    std::ifstream in("/proc/" + std::to_string(pid_) + "/status");
    std::string key;
    while (in >> key) {
      if (key == "VmRSS:") {
        long kb = 0;
        in >> kb;
        return kb;
      }
      in.ignore(1 << 20, '\n');
    }
    return -1;
  }
  int threads() const {
    int n = 0;
    for (const auto& entry :
         std::filesystem::directory_iterator("/proc/" + std::to_string(pid_) + "/task")) {
      (void)entry;
      ++n;
    }
    return n;
  }
  // SIGTERM, then the exit code.
  int terminate() {
    kill(pid_, SIGTERM);
    const int code = reap(pid_);
    pid_ = -1;
    return code;
  }

 private:
  std::string dir_;
  std::string address_;
  pid_t pid_ = -1;
};

inline std::unique_ptr<client::Client> connect(const ServerProcess& server) {
  client::ClientOptions options;
  options.address = server.address();
  return client::Client::connect(options);
}

// One edit: set body `index`'s (generation 1) velocity to (vx, 0).
inline v1::EditBatch push(int index, double vx) {
  v1::EditBatch batch;
  v1::SetVelocity* v = batch.add_edits()->mutable_set_velocity();
  v->mutable_body()->set_index(index);
  v->mutable_body()->set_generation(1);
  v->mutable_linear()->set_x(vx);
  return batch;
}

}  // namespace fulcrum::testing_support
