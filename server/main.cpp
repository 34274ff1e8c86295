// fulcrum-server: the Physics gRPC service on one address. Prints "listening on HOST:PORT" once
// it accepts calls, and stops cleanly on SIGTERM or SIGINT (health NOT_SERVING, streams end,
// calls in progress get a grace period) with exit code 0.
//
// The flags are Abseil flags. Abseil names a flag like an identifier (max_worlds) while
// Fulcrum's command line, scripts and docs spell it with hyphens (--max-worlds), so
// normalize_command_line() first rewrites each flag to Abseil's `--max_worlds=VALUE` form and
// turns the mistakes it can see (an unknown flag, a missing or malformed value) into usage
// errors naming the flag as it was typed; absl::ParseCommandLine then sets the flags (and
// handles --helpfull, --flagfile, --fromenv), and the range checks below run on the result.
#include <pthread.h>
#include <signal.h>

#include <chrono>
#include <cstdint>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/marshalling.h"
#include "absl/flags/parse.h"
#include "absl/flags/reflection.h"
#include "absl/flags/usage.h"
#include "absl/flags/usage_config.h"
#include "absl/strings/match.h"
#include "agones.h"
#include "server.h"
#include "stats.h"

ABSL_FLAG(std::string, listen, "127.0.0.1:50051",
          "HOST:PORT to listen on; port 0 picks a free port, printed as \"listening on "
          "HOST:PORT\"");
ABSL_FLAG(int64_t, max_worlds, 64, "worlds alive at once, 1 or more");
ABSL_FLAG(int64_t, max_bodies, 100000, "live bodies per world, 1 or more");
ABSL_FLAG(int64_t, max_step_ticks, 1000000, "ticks per Step call, 1 to 4294967295");
ABSL_FLAG(int64_t, max_shapes, 400000,
          "live shapes per world (chain segments included), 1 or more; about 0.5 KB each");
ABSL_FLAG(int64_t, max_shapes_per_body, 1024,
          "shapes on one dynamic or kinematic body, 1 or more (static bodies: only --max-shapes)");
ABSL_FLAG(int64_t, max_edits, 100000, "edits per ApplyEdits batch, 1 or more");
ABSL_FLAG(int64_t, max_batch_work, 10000000,
          "work one edit batch or one CreateWorld scene may do, 1 or more: about one unit per "
          "shape created and per shape its box overlaps (10 million is about half a second)");
ABSL_FLAG(int64_t, max_contacts, 500000,
          "live contacts per world, 1 or more; a tick that would pass it does not run (about 1 KB "
          "each; 100 000 resting bodies make about 260 000)");
ABSL_FLAG(int64_t, max_message_bytes, 64 << 20,
          "largest request or reply in bytes, 131072 or more; larger requests are refused with "
          "RESOURCE_EXHAUSTED (snapshots and replays also travel in 64 KiB chunks)");
ABSL_FLAG(int64_t, max_snapshot_bytes, int64_t{1} << 30,
          "largest snapshot RestoreSnapshotStream takes in chunks, 1024 or more bytes (held "
          "whole while it is checked)");
ABSL_FLAG(std::string, token_file, "",
          "FILE whose first line is a token: every call but health checks must then carry "
          "`authorization: Bearer <token>` (default: no token)");
ABSL_FLAG(int64_t, grace_ms, 5000,
          "on SIGTERM/SIGINT, the time in ms calls in progress get, 0 to 3600000");
ABSL_FLAG(int64_t, worker_threads, 0,
          "threads stepping the worlds that run in real time, 0 to 1024; 0: the number of "
          "hardware threads");
ABSL_FLAG(int64_t, world_threads, 1,
          "threads each world's step may use, 1 to 64: more than 1 for a few large worlds; 1 "
          "when many worlds share the cores (same results at any count)");
ABSL_FLAG(std::string, replay_dir, "",
          "DIR where StartRecording writes replays, created if missing (default: none, "
          "recording is refused)");
ABSL_FLAG(std::string, metrics_listen, "",
          "HOST:PORT for Prometheus metrics over HTTP at GET /metrics (port 0 picks one, "
          "printed as \"metrics on HOST:PORT\"); default: none");
ABSL_FLAG(std::string, tls_cert, "",
          "FILE: serve TLS only, with this PEM certificate chain (needs --tls-key)");
ABSL_FLAG(std::string, tls_key, "", "FILE: the PEM private key of --tls-cert");
ABSL_FLAG(int64_t, max_reader_stall_ms, 10000,
          "end a StreamFrames reader with RESOURCE_EXHAUSTED when its frame has been in flight "
          "this many ms, 1 to 86400000");
ABSL_FLAG(int64_t, keepalive_ms, 20000,
          "ping each client connection this often, 1 to 3600000 ms; with --keepalive-timeout-ms "
          "it bounds how long the streams of a client that vanished stay open");
ABSL_FLAG(int64_t, keepalive_timeout_ms, 10000,
          "drop a connection whose ping is not answered within this many ms, 1 to 3600000");
ABSL_FLAG(int64_t, max_streams_per_connection, 100,
          "concurrent calls on one client connection, 1 to 100000");
ABSL_FLAG(bool, agones, false,
          "run as an Agones GameServer: Ready once listening, Health pings, the label worlds, "
          "Shutdown on SIGTERM (the SDK sidecar at localhost:$AGONES_SDK_GRPC_PORT, default "
          "9357; docs/scaling.md)");
ABSL_FLAG(int64_t, agones_health_ms, 2000,
          "with --agones: the Health ping period in ms, 100 to 60000 (below the GameServer's "
          "health periodSeconds)");
ABSL_FLAG(int64_t, agones_ready_ms, 30000,
          "with --agones: how long Ready is retried while the SDK sidecar is not answering, in "
          "ms, 1000 to 600000; the server then exits 1");
ABSL_FLAG(std::string, log, "on",
          "on|off: one key=value line per world event and refused request on stderr");

namespace {

constexpr char kUsage[] =
    "the Fulcrum physics gRPC service on one address.\n"
    "usage: fulcrum-server [--flag VALUE | --flag=VALUE]...\n"
    "exit codes: 0 stopped by a signal, 1 could not start, 2 bad command line";

// Fulcrum's flags in the order --help lists them.
std::vector<const absl::CommandLineFlag*> fulcrum_flags() {
  return {&absl::GetFlagReflectionHandle(FLAGS_listen),
          &absl::GetFlagReflectionHandle(FLAGS_max_worlds),
          &absl::GetFlagReflectionHandle(FLAGS_max_bodies),
          &absl::GetFlagReflectionHandle(FLAGS_max_step_ticks),
          &absl::GetFlagReflectionHandle(FLAGS_max_shapes),
          &absl::GetFlagReflectionHandle(FLAGS_max_shapes_per_body),
          &absl::GetFlagReflectionHandle(FLAGS_max_edits),
          &absl::GetFlagReflectionHandle(FLAGS_max_batch_work),
          &absl::GetFlagReflectionHandle(FLAGS_max_contacts),
          &absl::GetFlagReflectionHandle(FLAGS_max_message_bytes),
          &absl::GetFlagReflectionHandle(FLAGS_max_snapshot_bytes),
          &absl::GetFlagReflectionHandle(FLAGS_token_file),
          &absl::GetFlagReflectionHandle(FLAGS_grace_ms),
          &absl::GetFlagReflectionHandle(FLAGS_worker_threads),
          &absl::GetFlagReflectionHandle(FLAGS_world_threads),
          &absl::GetFlagReflectionHandle(FLAGS_replay_dir),
          &absl::GetFlagReflectionHandle(FLAGS_metrics_listen),
          &absl::GetFlagReflectionHandle(FLAGS_agones),
          &absl::GetFlagReflectionHandle(FLAGS_agones_health_ms),
          &absl::GetFlagReflectionHandle(FLAGS_agones_ready_ms),
          &absl::GetFlagReflectionHandle(FLAGS_tls_cert),
          &absl::GetFlagReflectionHandle(FLAGS_tls_key),
          &absl::GetFlagReflectionHandle(FLAGS_max_reader_stall_ms),
          &absl::GetFlagReflectionHandle(FLAGS_keepalive_ms),
          &absl::GetFlagReflectionHandle(FLAGS_keepalive_timeout_ms),
          &absl::GetFlagReflectionHandle(FLAGS_max_streams_per_connection),
          &absl::GetFlagReflectionHandle(FLAGS_log)};
}

// "max_worlds" -> "--max-worlds", the spelling users type.
std::string dashed(absl::string_view name) {
  std::string out = "--" + std::string(name);
  for (size_t i = 2; i < out.size(); ++i) {
    if (out[i] == '_') out[i] = '-';
  }
  return out;
}

void print_help(std::ostream& out) {
  out << "fulcrum-server: " << kUsage << "\n\n";
  for (const absl::CommandLineFlag* flag : fulcrum_flags()) {
    out << "  " << dashed(flag->Name());
    const std::string value = flag->DefaultValue();
    if (!value.empty()) out << " (default " << value << ")";
    // The help text, wrapped at spaces to lines of at most 90 characters.
    const std::string help = flag->Help();
    size_t line_start = 0;
    while (line_start < help.size()) {
      size_t end = help.size();
      if (end - line_start > 84) {
        end = help.rfind(' ', line_start + 84);
        if (end == std::string::npos || end <= line_start) end = help.find(' ', line_start + 84);
        if (end == std::string::npos) end = help.size();
      }
      out << "\n      " << help.substr(line_start, end - line_start);
      line_start = end + 1;
    }
    out << "\n";
  }
  out << "\nThese are Abseil flags: --helpfull lists Abseil's own flags too (--flagfile=FILE, "
         "--fromenv=NAMES),\nwhich spell names with underscores (--max_worlds=64).\n";
}

int usage_error(const std::string& message) {
  std::cerr << "fulcrum-server: " << message << "\nfulcrum-server --help lists the flags\n";
  return 2;
}

bool is_fulcrum_flag(const absl::CommandLineFlag* flag) {
  for (const absl::CommandLineFlag* own : fulcrum_flags()) {
    if (own == flag) return true;
  }
  return false;
}

// The flags absl::ParseCommandLine answers itself (they are not in Abseil's flag registry):
// --helpfull, --helpshort, --help=SUBSTRING, --version and the like.
bool is_abseil_usage_flag(std::string_view name) {
  for (std::string_view usage : {"help", "helpfull", "helpshort", "helppackage", "helpon",
                                 "helpmatch", "version", "only_check_args"}) {
    if (name == usage) return true;
  }
  return false;
}

// Rewrites argv into Abseil's spelling (program name, then one `--name=value` per flag) in
// *out, or returns the usage error for the first argument it cannot take. A non-boolean flag
// takes its value after `=` or from the next argument, unless that is a flag too.
std::string normalize_command_line(int argc, char** argv, std::vector<std::string>* out) {
  out->assign(1, argv[0]);
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) {
      return (!arg.empty() && arg[0] == '-' ? "unknown flag '" : "unexpected argument '") + arg +
             "'";
    }
    const size_t eq = arg.find('=');
    std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    for (char& c : name) {
      if (c == '-') c = '_';
    }
    const std::string typed = dashed(name);
    if (is_abseil_usage_flag(name)) {  // Abseil answers these and exits
      out->push_back("--" + name + (eq == std::string::npos ? "" : arg.substr(eq)));
      continue;
    }
    const absl::CommandLineFlag* flag = absl::FindCommandLineFlag(name);
    if (flag == nullptr) return "unknown flag '" + typed + "'";
    if (eq == std::string::npos && flag->IsOfType<bool>()) {
      out->push_back("--" + name);
      continue;
    }
    std::string value;
    if (eq != std::string::npos) {
      value = arg.substr(eq + 1);
    } else if (i + 1 < argc && std::string_view(argv[i + 1]).rfind("--", 0) != 0) {
      value = argv[++i];
    } else {
      return typed + " needs a value";
    }
    int64_t number = 0;
    std::string why;
    if (flag->IsOfType<int64_t>() && !absl::ParseFlag(value, &number, &why)) {
      return typed + ": expected a whole number, got '" + value + "'";
    }
    if (value.empty() && is_fulcrum_flag(flag)) return typed + ": expected a value, got ''";
    out->push_back("--" + name + "=" + value);
  }
  return "";
}

// The value of an integer flag, or a usage error naming the flag when outside [min, max].
bool in_range(const absl::Flag<int64_t>& flag, int64_t min, int64_t max, int64_t* value,
              std::string* error) {
  *value = absl::GetFlag(flag);
  if (*value >= min && *value <= max) return true;
  *error = dashed(absl::GetFlagReflectionHandle(flag).Name()) + ": expected " +
           std::to_string(min) + " to " + std::to_string(max) + " (got " + std::to_string(*value) +
           ")";
  return false;
}

// The first line of a token file, trailing spaces and CR removed; false (and *error naming the
// flag and file) when it cannot be read or that line is empty.
bool read_token(const std::string& path, std::string* token, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = "--token-file: cannot open " + path;
    return false;
  }
  std::getline(in, *token);
  while (!token->empty() && (token->back() == '\r' || token->back() == ' ')) token->pop_back();
  if (token->empty()) {
    *error = "--token-file: the first line of " + path + " (the token) is empty";
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

// The server's options from the parsed flags: 0, or 2 after printing a usage error.
int options_from_flags(fulcrum::server::ServerOptions* options, int64_t* grace_ms) {
  const int64_t kMaxInt = 0x7fffffff;
  int64_t n = 0;
  std::string error;
  options->listen = absl::GetFlag(FLAGS_listen);
  if (!in_range(FLAGS_max_worlds, 1, kMaxInt, &n, &error)) return usage_error(error);
  options->limits.max_worlds = static_cast<int>(n);
  if (!in_range(FLAGS_max_bodies, 1, kMaxInt, &n, &error)) return usage_error(error);
  options->limits.max_bodies = static_cast<int>(n);
  if (!in_range(FLAGS_max_step_ticks, 1, 0xffffffff, &n, &error)) return usage_error(error);
  options->limits.max_step_ticks = static_cast<uint32_t>(n);
  if (!in_range(FLAGS_max_shapes, 1, kMaxInt, &n, &error)) return usage_error(error);
  options->limits.max_shapes = static_cast<int>(n);
  if (!in_range(FLAGS_max_shapes_per_body, 1, kMaxInt, &n, &error)) return usage_error(error);
  options->limits.max_shapes_per_body = static_cast<int>(n);
  if (!in_range(FLAGS_max_edits, 1, kMaxInt, &n, &error)) return usage_error(error);
  options->limits.max_edits = static_cast<size_t>(n);
  if (!in_range(FLAGS_max_batch_work, 1, std::numeric_limits<int64_t>::max(), &n, &error)) {
    return usage_error(error);
  }
  options->limits.max_batch_work = static_cast<uint64_t>(n);
  if (!in_range(FLAGS_max_contacts, 1, std::numeric_limits<int64_t>::max(), &n, &error)) {
    return usage_error(error);
  }
  options->limits.max_contacts = n;
  if (!in_range(FLAGS_max_message_bytes, fulcrum::server::ServerOptions::kMinMessageBytes, kMaxInt,
                &n, &error)) {
    return usage_error(error);
  }
  options->max_message_bytes = static_cast<int>(n);
  if (!in_range(FLAGS_max_snapshot_bytes, 1024, std::numeric_limits<int64_t>::max(), &n, &error)) {
    return usage_error(error);
  }
  options->limits.max_snapshot_bytes = n;
  if (!in_range(FLAGS_grace_ms, 0, 3600000, grace_ms, &error)) return usage_error(error);
  if (!in_range(FLAGS_worker_threads, 0, 1024, &n, &error)) return usage_error(error);
  options->worker_threads = static_cast<int>(n);
  if (!in_range(FLAGS_world_threads, 1, fulcrum::World::kMaxThreads, &n, &error)) {
    return usage_error(error);
  }
  options->limits.world_threads = static_cast<int>(n);
  if (!in_range(FLAGS_max_reader_stall_ms, 1, 86400000, &n, &error)) return usage_error(error);
  options->limits.max_reader_stall_ms = n;
  if (!in_range(FLAGS_keepalive_ms, 1, 3600000, &n, &error)) return usage_error(error);
  options->keepalive_ms = static_cast<int>(n);
  if (!in_range(FLAGS_keepalive_timeout_ms, 1, 3600000, &n, &error)) return usage_error(error);
  options->keepalive_timeout_ms = static_cast<int>(n);
  if (!in_range(FLAGS_max_streams_per_connection, 1, 100000, &n, &error)) {
    return usage_error(error);
  }
  options->max_streams_per_connection = static_cast<int>(n);
  options->replay_dir = absl::GetFlag(FLAGS_replay_dir);
  options->metrics_listen = absl::GetFlag(FLAGS_metrics_listen);
  if (!in_range(FLAGS_agones_health_ms, 100, 60000, &n, &error)) return usage_error(error);
  if (!in_range(FLAGS_agones_ready_ms, 1000, 600000, &n, &error)) return usage_error(error);
  const std::string log = absl::GetFlag(FLAGS_log);
  if (log != "on" && log != "off")
    return usage_error("--log: expected on or off, got '" + log + "'");
  fulcrum::server::set_logging(log == "on");
  if (absl::GetFlag(FLAGS_tls_cert).empty() != absl::GetFlag(FLAGS_tls_key).empty()) {
    return usage_error(absl::GetFlag(FLAGS_tls_cert).empty() ? "--tls-key needs --tls-cert"
                                                             : "--tls-cert needs --tls-key");
  }
  return 0;
}

// Reads the files the flags name (token, TLS certificate and key): 0, or 1 after printing why
// one could not be read.
int read_flag_files(fulcrum::server::ServerOptions* options) {
  std::string error;
  const std::string token_file = absl::GetFlag(FLAGS_token_file);
  const std::string tls_cert = absl::GetFlag(FLAGS_tls_cert);
  const std::string tls_key = absl::GetFlag(FLAGS_tls_key);
  if ((!token_file.empty() && !read_token(token_file, &options->token, &error)) ||
      (!tls_cert.empty() && !read_pem("--tls-cert", tls_cert, &options->tls_cert_pem, &error)) ||
      (!tls_key.empty() && !read_pem("--tls-key", tls_key, &options->tls_key_pem, &error))) {
    std::cerr << "fulcrum-server: " << error << "\n";
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(kUsage);
  absl::FlagsUsageConfig usage_config;
  // --helpshort and --help=SUBSTRING (handled by Abseil) list the flags of this file.
  usage_config.contains_help_flags = [](absl::string_view file) {
    return absl::EndsWith(file, "server/main.cpp");
  };
  usage_config.contains_helpshort_flags = usage_config.contains_help_flags;
  usage_config.version_string = [] { return std::string("fulcrum-server " FULCRUM_VERSION "\n"); };
  absl::SetFlagsUsageConfig(usage_config);

  // --help and -h are answered here, with the flags spelled as users type them, and exit 0
  // (Abseil's own --help exits 1).
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      print_help(std::cout);
      return 0;
    }
  }
  std::vector<std::string> normalized;
  if (std::string error = normalize_command_line(argc, argv, &normalized); !error.empty()) {
    return usage_error(error);
  }
  std::vector<char*> abseil_argv;
  for (std::string& arg : normalized) abseil_argv.push_back(arg.data());
  abseil_argv.push_back(nullptr);
  absl::ParseCommandLine(static_cast<int>(normalized.size()), abseil_argv.data());

  fulcrum::server::ServerOptions options;
  int64_t grace_ms = 0;
  if (int code = options_from_flags(&options, &grace_ms); code != 0) return code;
  if (int code = read_flag_files(&options); code != 0) return code;

  // Signals are taken by sigwait on this thread only: block them before gRPC starts threads,
  // which inherit the mask.
  // A replay write past a file size limit (ulimit -f) must fail with EFBIG and stop that
  // recording, not kill the server with SIGXFSZ.
  signal(SIGXFSZ, SIG_IGN);
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
  if (!(*server)->metrics_address().empty()) {
    std::cout << "metrics on " << (*server)->metrics_address() << std::endl;
    fulcrum::server::log_event("metrics_listening", {{"address", (*server)->metrics_address()}});
  }

  std::unique_ptr<fulcrum::server::AgonesSdk> agones;
  if (absl::GetFlag(FLAGS_agones)) {
    const int64_t health_ms = absl::GetFlag(FLAGS_agones_health_ms);  // checked with the rest
    const int64_t ready_ms = absl::GetFlag(FLAGS_agones_ready_ms);
    const std::string sdk_address = fulcrum::server::AgonesSdk::address_from_environment();
    agones = std::make_unique<fulcrum::server::AgonesSdk>(sdk_address);
    fulcrum::Status ready = agones->ready(std::chrono::milliseconds(ready_ms));
    if (!ready.ok()) {
      std::cerr << "fulcrum-server: " << ready.message() << " (the SDK sidecar at " << sdk_address
                << ")\n";
      return 1;
    }
    fulcrum::server::Registry* registry = &(*server)->registry();
    agones->start_health(std::chrono::milliseconds(health_ms),
                         [registry] { return static_cast<int>(registry->list().size()); });
    fulcrum::server::log_event("agones_ready", {{"sdk", sdk_address}});
  }

  int signal_number = 0;
  sigwait(&signals, &signal_number);
  std::cerr << "fulcrum-server: " << (signal_number == SIGTERM ? "SIGTERM" : "SIGINT")
            << ", stopping\n";
  if (agones) {
    // Agones stops allocating this server and replaces it; the grace period still applies.
    fulcrum::Status down = agones->shutdown();
    fulcrum::server::log_event("agones_shutdown", {{"error", down.ok() ? "" : down.message()}});
  }
  (*server)->shutdown(std::chrono::milliseconds(grace_ms));
  agones.reset();
  std::cerr << "fulcrum-server: stopped\n";
  return 0;
}
