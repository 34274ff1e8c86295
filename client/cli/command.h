// The subcommand table of the fulcrum CLI. A subcommand is a Command entry plus one run
// function in its own file; main.cpp parses the flags against the entry's specs, handles
// --help, and calls run. Adding a subcommand means adding a file and a row in commands().
#pragma once

#include <cstdint>
#include <iosfwd>
#include <span>
#include <string>
#include <string_view>

#include "args.h"
#include "fulcrum/scene.h"
#include "fulcrum/status.h"

namespace fulcrum::cli {

struct Invocation;

struct Command {
  std::string_view name;
  std::string_view summary;  // one line, for `fulcrum --help`
  std::string_view usage;    // synopsis after "fulcrum NAME", e.g. "--scene FILE --ticks N"
  std::string_view details;  // optional paragraph for `fulcrum NAME --help`
  std::span<const FlagSpec> flags;
  int max_positional = 0;  // positional arguments accepted
  int (*run)(const Invocation& inv) = nullptr;
};

// What a run function gets: its parsed arguments and where to write.
struct Invocation {
  const Command& command;
  Args args;
  std::ostream& out;
  std::ostream& err;

  // Prints "fulcrum NAME: message" and the usage line to err; returns kExitUsage.
  int usage_error(const std::string& message) const;
  // Prints "fulcrum NAME: error: message" to err; returns kExitError.
  int fail(const std::string& message) const;
};

// Every subcommand, in the order `fulcrum --help` lists them.
std::span<const Command> commands();
// Full help for one subcommand (usage, details, flags).
void print_command_help(const Command& command, std::ostream& out);

// --- Shared by subcommands -------------------------------------------------------------------

// The two ways of naming a scene: "--scene FILE" or "--builtin NAME".
inline constexpr FlagSpec kSceneFlag = {"scene", "FILE",
                                        "scene file (Protobuf JSON, see "
                                        "proto/fulcrum/v1/scene.proto)"};
inline constexpr FlagSpec kBuiltinFlag = {"builtin", "NAME",
                                          "built-in scene (list them with `fulcrum scenes`)"};

struct LoadedScene {
  SceneDef scene;
  std::string label;  // "scenes/stack.json" or "builtin:pyramid"
  std::string name;   // file stem or builtin name
};

// Loads the scene named by exactly one of --scene/--builtin. Sets *exit_code to kExitUsage
// (neither or both given) or kExitError (the scene is bad), having printed why, and returns
// false; returns true on success.
bool load_scene_from_args(const Invocation& inv, LoadedScene* loaded, int* exit_code);

// An error from building the loaded scene's world, named after the scene file as load errors
// are ("scenes/x.json: joints[1].body_b: ...").
std::string scene_error(const LoadedScene& loaded, const Status& status);

// A state hash as 16 hex digits, the way every subcommand prints it.
std::string hex64(uint64_t value);

// The subcommands.
int run_sim(const Invocation& inv);
int run_scenes(const Invocation& inv);
int run_export(const Invocation& inv);
int run_replay(const Invocation& inv);
// Against a fulcrum-server (remote.h).
int run_create(const Invocation& inv);
int run_worlds(const Invocation& inv);
int run_step(const Invocation& inv);
int run_edit(const Invocation& inv);
int run_snapshot(const Invocation& inv);
int run_watch(const Invocation& inv);
int run_run(const Invocation& inv);
int run_pause(const Invocation& inv);
int run_query(const Invocation& inv);
int run_stats(const Invocation& inv);
int run_health(const Invocation& inv);
int run_view(const Invocation& inv);
int run_session(const Invocation& inv);

}  // namespace fulcrum::cli
