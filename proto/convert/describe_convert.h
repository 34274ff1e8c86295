// A world's bodies, shapes and joints as fulcrum.v1.DescribeWorldReply (describe.proto): what
// a viewer needs to draw it, in the scene's own messages.
#pragma once

#include "fulcrum/v1/describe.pb.h"
#include "fulcrum/world.h"

namespace fulcrum {

// Every live body (with its shapes in the body frame) and every live joint, in index order,
// with the world's tick and state hash. world_id is left for the caller.
void describe_world_to_proto(const World& world, v1::DescribeWorldReply* out);

}  // namespace fulcrum
