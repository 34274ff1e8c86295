// fulcrum scenes: list the built-in scene names, one a line.
#include <ostream>
#include <string>

#include "command.h"
#include "fulcrum/scenes.h"

namespace fulcrum::cli {

int run_scenes(const Invocation& inv) {
  for (const std::string& name : scenes::builtin_names()) inv.out << name << "\n";
  return kExitOk;
}

}  // namespace fulcrum::cli
