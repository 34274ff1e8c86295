// What must hold of any world the engine accepted, whatever it was given: shared by the random
// worlds (random_worlds_test.cpp) and the fuzz targets (tests/fuzz/).
#pragma once

#include <cmath>
#include <string>

#include "fulcrum/world.h"
#include "world_impl.h"

namespace fulcrum::checks {

// Empty when every body state is finite, the broad-phase tree is valid and the world's snapshot
// restores into a fresh world with the same hash (the restore re-checks every record, link and
// list: shapes, contacts and their edges, joints, islands, free lists); else what is wrong.
// `restore_check` off skips the snapshot, the most expensive part.
inline std::string world_problem(const World& w, bool restore_check = true) {
  for (BodyId id : w.bodies()) {
    Result<BodyState> b = w.body_state(id);
    if (!b.ok()) return "body " + std::to_string(id.index) + ": " + b.status().message();
    const bool finite = std::isfinite(b->center.x()) && std::isfinite(b->center.y()) &&
                        std::isfinite(b->linear_velocity.x()) &&
                        std::isfinite(b->linear_velocity.y()) &&
                        std::isfinite(b->angular_velocity) && std::isfinite(b->transform.q.c) &&
                        std::isfinite(b->transform.q.s) && std::isfinite(b->transform.p.x()) &&
                        std::isfinite(b->transform.p.y());
    if (!finite) return "body " + std::to_string(id.index) + " is not finite";
  }
  if (!w.impl().tree.validate()) return "the broad-phase tree is invalid";
  if (!w.impl().static_tree.validate()) return "the broad-phase static tree is invalid";
  if (restore_check) {
    World copy{WorldSettings{}};
    Status s = copy.restore(w.snapshot());
    if (!s.ok()) return "its snapshot does not restore: " + s.message();
    if (copy.state_hash() != w.state_hash()) return "its restored snapshot has another hash";
  }
  return {};
}

}  // namespace fulcrum::checks
