// Shared by the subcommands that talk to a fulcrum-server (create, worlds, step, edit,
// snapshot, watch, stats): the --server, --token-file, --deadline-ms and TLS flags, connecting, and
// reading a world id.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "args.h"
#include "command.h"
#include "fulcrum/client.h"

namespace fulcrum::cli {

inline constexpr FlagSpec kServerFlag = {"server", "HOST:PORT",
                                         "the fulcrum-server (default 127.0.0.1:50051)"};
inline constexpr FlagSpec kTokenFileFlag = {"token-file", "FILE",
                                            "bearer token for the server (first line of FILE)"};
inline constexpr FlagSpec kDeadlineFlag = {"deadline-ms", "MS",
                                           "deadline of each call (default 30000)"};
inline constexpr FlagSpec kTlsCaFlag = {
    "tls-ca", "FILE", "connect with TLS, trusting the PEM root certificate(s) in FILE"};
inline constexpr FlagSpec kTlsNameFlag = {
    "tls-name", "NAME", "with --tls-ca: the name the server's certificate must carry"};

// Connects per --server/--token-file/--deadline-ms/--tls-ca/--tls-name. On error prints why, sets
// *exit_code and returns null.
std::unique_ptr<client::Client> connect_from_args(const Invocation& inv, int* exit_code);

// Positional argument `index` as a world id (>= 1). On error prints a usage error, sets
// *exit_code and returns nullopt.
std::optional<uint64_t> world_arg(const Invocation& inv, size_t index, int* exit_code);

// Reads a whole file; nullopt (and *error) when it cannot.
std::optional<std::string> read_file(const std::string& path, std::string* error);

}  // namespace fulcrum::cli
