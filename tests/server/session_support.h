// What the multiplayer tests share: handles of the example pyramid's bodies and the push each
// test's players give them.
#pragma once

#include <cstdint>

#include "fulcrum/v1/edit.pb.h"

namespace fulcrum::testing_support {

// The pyramid's top two boxes (scene bodies 210 and 209), one per player.
inline constexpr int kTop = 210;
inline constexpr int kBelow = 209;

inline fulcrum::v1::Handle handle(int index, uint32_t generation = 1) {
  fulcrum::v1::Handle h;
  h.set_index(index);
  h.set_generation(generation);
  return h;
}

// One impulse along x on scene body `body`.
inline fulcrum::v1::EditBatch impulse(int body, double x) {
  fulcrum::v1::EditBatch batch;
  fulcrum::v1::ApplyImpulse* push = batch.add_edits()->mutable_apply_impulse();
  *push->mutable_body() = handle(body);
  push->mutable_impulse()->set_x(x);
  return batch;
}

}  // namespace fulcrum::testing_support
