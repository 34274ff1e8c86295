#include "command.h"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <ostream>

#include "fulcrum/scenes.h"
#include "scene_convert.h"

namespace fulcrum::cli {

std::string hex64(uint64_t value) {
  return World::hash_text(value);
}

std::string scene_error(const LoadedScene& loaded, const Status& status) {
  const std::string& m = status.message();
  return m.rfind(loaded.label, 0) == 0 ? m : loaded.label + ": " + m;
}

int Invocation::usage_error(const std::string& message) const {
  err << "fulcrum " << command.name << ": " << message << "\n"
      << "usage: fulcrum " << command.name << (command.usage.empty() ? "" : " ") << command.usage
      << "\n"
      << "(see fulcrum " << command.name << " --help)\n";
  return kExitUsage;
}

int Invocation::fail(const std::string& message) const {
  err << "fulcrum " << command.name << ": error: " << message << "\n";
  return kExitError;
}

void print_command_help(const Command& command, std::ostream& out) {
  out << "usage: fulcrum " << command.name << (command.usage.empty() ? "" : " ") << command.usage
      << "\n\n"
      << command.summary << "\n";
  if (!command.details.empty()) out << "\n" << command.details << "\n";
  if (!command.flags.empty()) {
    out << "\nflags:\n";
    for (const FlagSpec& flag : command.flags) {
      std::string left = "--" + std::string(flag.name);
      if (!flag.value_name.empty()) left += " " + std::string(flag.value_name);
      left.resize(std::max<size_t>(left.size() + 2, 18), ' ');
      out << "  " << left << flag.help << "\n";
    }
  }
}

bool load_scene_from_args(const Invocation& inv, LoadedScene* loaded, int* exit_code) {
  const std::optional<std::string> file = inv.args.value("scene");
  const std::optional<std::string> builtin = inv.args.value("builtin");
  if (file.has_value() == builtin.has_value()) {
    *exit_code = inv.usage_error(file ? "give either --scene or --builtin, not both"
                                      : "missing --scene FILE or --builtin NAME");
    return false;
  }
  if (file) {
    Result<SceneDef> scene = load_scene_json(*file);
    if (!scene.ok()) {
      *exit_code = inv.fail(scene.status().message());
      return false;
    }
    loaded->scene = std::move(scene).value();
    loaded->label = *file;
    loaded->name = std::filesystem::path(*file).stem().string();
    return true;
  }
  // Checked here rather than left to scenes::builtin so that the message lists the choices.
  const std::vector<std::string> names = scenes::builtin_names();
  if (std::find(names.begin(), names.end(), *builtin) == names.end()) {
    std::string known;
    for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
    *exit_code = inv.fail("unknown builtin scene '" + *builtin + "' (known: " + known + ")");
    return false;
  }
  Result<SceneDef> scene = scenes::builtin(*builtin);
  if (!scene.ok()) {
    *exit_code = inv.fail(scene.status().message());
    return false;
  }
  loaded->scene = std::move(scene).value();
  loaded->label = "builtin:" + *builtin;
  loaded->name = *builtin;
  return true;
}

}  // namespace fulcrum::cli
