// Command-line parsing for the fulcrum CLI: each subcommand declares its flags in a table, and
// one parser checks every invocation against it, so all subcommands report bad input the same
// way (and exit with kExitUsage).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fulcrum/types.h"

namespace fulcrum::cli {

// Exit codes shared by every subcommand.
inline constexpr int kExitOk = 0;
inline constexpr int kExitError = 1;  // the request was well formed but failed (bad scene, ...)
inline constexpr int kExitUsage = 2;  // the command line itself is wrong

struct FlagSpec {
  std::string_view name;        // without the leading "--"
  std::string_view value_name;  // e.g. "FILE"; empty for a switch that takes no value
  std::string_view help;
  bool repeatable = false;  // may be given more than once (Args::values lists them in order)
  // The value may be left out (last word, or followed by another flag): it is then "".
  bool value_optional = false;
};

// The flags and positional arguments of one invocation, already checked against the specs.
class Args {
 public:
  // Parses `argv` (the words after the subcommand name). Accepts "--name value",
  // "--name=value" and, for switches, "--name"; "--" ends the flags. On error returns false
  // and sets `*error` to a message naming the offending word.
  static bool parse(std::span<const std::string> argv, std::span<const FlagSpec> specs, Args* out,
                    std::string* error);

  bool has(std::string_view name) const { return values_.count(std::string(name)) != 0; }
  // The value of a flag that takes one, if given (the first, for a repeatable flag).
  std::optional<std::string> value(std::string_view name) const;
  // Every value of a flag, in command-line order; empty when not given.
  std::vector<std::string> values(std::string_view name) const;
  const std::vector<std::string>& positional() const { return positional_; }
  // Whether --help or -h was given (always accepted).
  bool help() const { return help_; }

 private:
  std::map<std::string, std::vector<std::string>> values_;  // switches map to {""}
  std::vector<std::string> positional_;
  bool help_ = false;
};

// Parses a whole decimal number in [min, max]; no sign tricks, no trailing junk. On error
// returns nullopt and sets `*error` ("expected a whole number, got 'abc'").
std::optional<int64_t> parse_int(std::string_view text, int64_t min, int64_t max,
                                 std::string* error);

// "3,7:2,12": body handles as INDEX or INDEX:GENERATION, generation 1 when left out (the
// handles of a new world's scene bodies: scene body i is {i, 1}). On error returns nullopt and
// sets `*error` naming the item.
std::optional<std::vector<BodyId>> parse_body_list(const std::string& text, std::string* error);

}  // namespace fulcrum::cli
