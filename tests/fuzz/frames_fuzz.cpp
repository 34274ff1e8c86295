// Fuzz target: the client library's decoding of frames (StreamFrames), exact and quantized.
// Checks: every body of the message is decoded once; quantized states are finite and within
// the fixed-point range frames.proto gives; when both lists are present the result is in index
// order.
#include <cmath>

#include "frame_decode.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace fulcrum;
  v1::Frame message;
  if (!message.ParseFromArray(data, static_cast<int>(size))) return 0;
  fuzz::print(message);
  const client::Frame f = client::frame_from(message);
  fuzz::check(f.bodies.size() ==
                  static_cast<size_t>(message.bodies_size() + message.quantized_bodies_size()),
              "a body was lost or added");
  fuzz::check(f.destroyed.size() == static_cast<size_t>(message.destroyed_size()),
              "a destroyed handle was lost");
  for (size_t i = 0; i < f.bodies.size(); ++i) {
    const client::BodyFrame& b = f.bodies[i];
    if (b.quantized) {
      // sint32 steps of 1/4096 m, 2 pi / 65536 rad and 1/1024 m/s: at most 2^31 steps.
      fuzz::check(std::fabs(b.position.x()) <= 524288.0 && std::fabs(b.position.y()) <= 524288.0,
                  "a quantized position out of range");
      fuzz::check(std::isfinite(b.angle) && std::isfinite(b.angular_velocity) &&
                      std::isfinite(b.linear_velocity.x()) && std::isfinite(b.linear_velocity.y()),
                  "a quantized state is not finite");
    }
    if (i > 0 && message.bodies_size() > 0 && message.quantized_bodies_size() > 0) {
      fuzz::check(f.bodies[i - 1].id.index <= b.id.index, "bodies out of index order");
    }
  }
  return 0;
}
