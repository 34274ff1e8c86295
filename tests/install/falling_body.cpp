// Built with nothing but `pkg-config --cflags --libs fulcrum-engine` (tests/install/
// check_install.sh): a ball dropped from 10 m, stepped for one second at the default 60 Hz.
// Prints "height: <m>".
#include <cstdio>

#include "fulcrum/world.h"

int main() {
  fulcrum::World world;  // gravity (0, -10) m/s^2, dt 1/60 s
  fulcrum::BodyDef body;
  body.type = fulcrum::BodyType::kDynamic;
  body.position = fulcrum::Vec2(0.0, 10.0);
  const fulcrum::Result<fulcrum::BodyId> ball = world.create_body(body);
  if (!ball.ok() || !world.create_shape(*ball, fulcrum::ShapeDef{}).ok()) return 1;
  for (int i = 0; i < 60; ++i) world.step();
  std::printf("height: %.9f\n", world.body_state(*ball)->transform.p.y());
  return 0;
}
