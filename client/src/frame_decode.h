// Frames as the server sends them (frames.proto) into the client's Frame: exact body states and
// quantized ones decoded from fixed point, in one index order. Kept apart from the gRPC code so
// that the fuzz target for frames (tests/fuzz/) decodes exactly what a subscription does.
#pragma once

#include "fulcrum/client.h"
#include "fulcrum/v1/frames.pb.h"

namespace fulcrum::client {

Frame frame_from(const v1::Frame& f);
BodyFrame body_frame_from(const v1::BodyFrame& b);

}  // namespace fulcrum::client
