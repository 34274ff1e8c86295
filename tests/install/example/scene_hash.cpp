// scene_hash SCENE.json TICKS: loads the scene, steps it TICKS times and prints
// "state hash: <16 hex digits>", as `fulcrum sim --scene SCENE.json --ticks TICKS` does.
#include <cstdio>
#include <cstdlib>

#include "fulcrum/convert/scene_convert.h"
#include "fulcrum/scene.h"
#include "fulcrum/world.h"

// Fulcrum::engine's public definitions reach this file along with its determinism options.
#ifndef EIGEN_DONT_PARALLELIZE
#error "Fulcrum::engine's public compile definitions did not reach this program"
#endif

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: scene_hash SCENE.json TICKS\n");
    return 2;
  }
  const fulcrum::Result<fulcrum::SceneDef> scene = fulcrum::load_scene_json(argv[1]);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().to_string().c_str());
    return 1;
  }
  fulcrum::Result<fulcrum::World> world = fulcrum::build_world(*scene);
  if (!world.ok()) {
    std::fprintf(stderr, "%s\n", world.status().to_string().c_str());
    return 1;
  }
  const long ticks = std::strtol(argv[2], nullptr, 10);
  for (long i = 0; i < ticks; ++i) world->step();
  std::printf("bodies: %d\n", world->body_count());
  std::printf("state hash: %s\n", fulcrum::World::hash_text(world->state_hash()).c_str());
  return 0;
}
