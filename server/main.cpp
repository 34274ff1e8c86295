// fulcrum-server: the Physics gRPC service on one address. Prints "listening on HOST:PORT" once
// it accepts calls, and stops cleanly on SIGTERM or SIGINT (health NOT_SERVING, streams end,
// calls in progress get a grace period) with exit code 0.
#include <pthread.h>
#include <signal.h>

#include <charconv>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <string_view>

#include "server.h"
#include "stats.h"

namespace {

constexpr char kUsage[] =
    "usage: fulcrum-server [FLAGS]\n"
    "\n"
    "  --listen HOST:PORT       address to listen on (default 127.0.0.1:50051; port 0 picks a\n"
    "                           free port, printed as \"listening on HOST:PORT\")\n"
    "  --max-worlds N           worlds alive at once (default 64)\n"
    "  --max-bodies N           live bodies per world (default 100000)\n"
    "  --max-step-ticks N       ticks per Step call (default 1000000)\n"
    "  --max-message-bytes N    largest request or reply (default 67108864)\n"
    "  --token-file FILE        require `authorization: Bearer <token>` on every call but\n"
    "                           health checks; the token is the file's first line\n"
    "  --grace-ms N             on SIGTERM/SIGINT, time calls in progress get (default 5000)\n"
    "  --worker-threads N       threads stepping worlds that run in real time (default: the\n"
    "                           number of hardware threads)\n"
    "  --replay-dir DIR         where StartRecording writes replays (created if missing;\n"
    "                           default: none, recording is refused)\n"
    "  --tls-cert FILE          serve TLS only, with this PEM certificate chain (needs --tls-key)\n"
    "  --tls-key FILE           the PEM private key of --tls-cert\n"
    "  --max-reader-stall-ms N  end a StreamFrames reader with RESOURCE_EXHAUSTED when its\n"
    "                           frame has been in flight this long (default 10000)\n"
    "  --log on|off             one key=value line per world event and refused request on\n"
    "                           stderr (default on)\n"
    "\n"
    "exit codes: 0 stopped by a signal, 1 could not start, 2 bad command line\n";

bool parse_number(std::string_view text, int64_t min, int64_t max, int64_t* out) {
  int64_t value = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < min || value > max) {
    return false;
  }
  *out = value;
  return true;
}

bool read_token(const std::string& path, std::string* token, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = path + ": cannot open the token file";
    return false;
  }
  std::getline(in, *token);
  while (!token->empty() && (token->back() == '\r' || token->back() == ' ')) token->pop_back();
  if (token->empty()) {
    *error = path + ": the first line (the token) is empty";
    return false;
  }
  return true;
}

// A whole PEM file; false (and *error naming the flag and file) when it cannot be read or is
// not PEM.
bool read_pem(const std::string& flag, const std::string& path, std::string* pem,
              std::string* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = flag + ": cannot read " + path;
    return false;
  }
  std::ostringstream text;
  text << in.rdbuf();
  *pem = text.str();
  if (pem->find("-----BEGIN ") == std::string::npos) {
    *error = flag + ": " + path + " is not a PEM file (no -----BEGIN line)";
    return false;
  }
  return true;
}

int usage_error(const std::string& message) {
  std::cerr << "fulcrum-server: " << message << "\n\n" << kUsage;
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  fulcrum::server::ServerOptions options;
  int64_t grace_ms = 5000;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::cout << kUsage;
      return 0;
    }
    std::string value;
    const size_t eq = arg.find('=');
    if (arg.rfind("--", 0) == 0 && eq != std::string::npos) {
      value = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
    } else if (i + 1 < argc) {
      value = argv[++i];
    } else {
      return usage_error(arg + " needs a value");
    }
    int64_t n = 0;
    const int64_t kMaxInt = 0x7fffffff;
    if (arg == "--listen") {
      options.listen = value;
    } else if (arg == "--max-worlds") {
      if (!parse_number(value, 1, kMaxInt, &n)) return usage_error(arg + ": expected 1 or more");
      options.limits.max_worlds = static_cast<int>(n);
    } else if (arg == "--max-bodies") {
      if (!parse_number(value, 1, kMaxInt, &n)) return usage_error(arg + ": expected 1 or more");
      options.limits.max_bodies = static_cast<int>(n);
    } else if (arg == "--max-step-ticks") {
      if (!parse_number(value, 1, 0xffffffff, &n)) return usage_error(arg + ": expected 1 or more");
      options.limits.max_step_ticks = static_cast<uint32_t>(n);
    } else if (arg == "--max-message-bytes") {
      if (!parse_number(value, 1024, kMaxInt, &n)) return usage_error(arg + ": expected >= 1024");
      options.max_message_bytes = static_cast<int>(n);
    } else if (arg == "--grace-ms") {
      if (!parse_number(value, 0, 3600000, &grace_ms)) return usage_error(arg + ": expected >= 0");
    } else if (arg == "--token-file") {
      std::string error;
      if (!read_token(value, &options.token, &error)) {
        std::cerr << "fulcrum-server: " << error << "\n";
        return 1;
      }
    } else if (arg == "--worker-threads") {
      if (!parse_number(value, 1, 1024, &n)) return usage_error(arg + ": expected 1 to 1024");
      options.worker_threads = static_cast<int>(n);
    } else if (arg == "--replay-dir") {
      if (value.empty()) return usage_error(arg + ": expected a directory");
      options.replay_dir = value;
    } else if (arg == "--tls-cert" || arg == "--tls-key") {
      std::string error;
      if (!read_pem(arg, value, arg == "--tls-cert" ? &options.tls_cert_pem : &options.tls_key_pem,
                    &error)) {
        std::cerr << "fulcrum-server: " << error << "\n";
        return 1;
      }
    } else if (arg == "--max-reader-stall-ms") {
      if (!parse_number(value, 1, 86400000, &n)) return usage_error(arg + ": expected >= 1");
      options.limits.max_reader_stall_ms = n;
    } else if (arg == "--log") {
      if (value != "on" && value != "off") return usage_error(arg + ": expected on or off");
      fulcrum::server::set_logging(value == "on");
    } else {
      return usage_error("unknown flag '" + arg + "'");
    }
  }

  if (options.tls_cert_pem.empty() != options.tls_key_pem.empty()) {
    return usage_error(options.tls_cert_pem.empty() ? "--tls-key needs --tls-cert"
                                                    : "--tls-cert needs --tls-key");
  }

  // Signals are taken by sigwait on this thread only: block them before gRPC starts threads,
  // which inherit the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  auto server = fulcrum::server::Server::start(options);
  if (!server.ok()) {
    std::cerr << "fulcrum-server: " << server.status().message() << "\n";
    return 1;
  }
  std::cout << "listening on " << (*server)->address() << std::endl;
  fulcrum::server::log_event("listening", {{"address", (*server)->address()},
                                           {"tls", options.tls_cert_pem.empty() ? "off" : "on"},
                                           {"token", options.token.empty() ? "off" : "on"}});

  int signal_number = 0;
  sigwait(&signals, &signal_number);
  std::cerr << "fulcrum-server: " << (signal_number == SIGTERM ? "SIGTERM" : "SIGINT")
            << ", stopping\n";
  (*server)->shutdown(std::chrono::milliseconds(grace_ms));
  std::cerr << "fulcrum-server: stopped\n";
  return 0;
}
