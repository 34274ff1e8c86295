// fulcrum export: print a scene as a scene file (explicit bodies, every setting written out).
#include <ostream>

#include "command.h"
#include "scene_convert.h"

namespace fulcrum::cli {

int run_export(const Invocation& inv) {
  LoadedScene loaded;
  int exit_code = kExitOk;
  if (!load_scene_from_args(inv, &loaded, &exit_code)) return exit_code;
  inv.out << scene_to_json(loaded.scene, loaded.name);
  return kExitOk;
}

}  // namespace fulcrum::cli
