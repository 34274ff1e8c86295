// The golden scenarios. Each is small (tens to 150 bodies, 240-480 ticks) so that all of them
// run in a few seconds even in a -O0 build or under qemu, yet together they reach every stage
// of the step: contacts of every shape pair kind, every joint type (motors, limits, springs,
// breaking), particles, kinematic bodies, sleeping and waking, and edits of every kind between
// ticks (create, destroy, velocities, forces, impulses, teleports, materials, settings).
//
// Everything here is a fixed program: positions and velocities are literals or come from a
// fixed-seed LCG and det_sin/det_cos, never from libm or a clock.
#include "golden_scenes.h"

#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <utility>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/trig.h"

namespace fulcrum::golden {

namespace {

// --- Helpers -----------------------------------------------------------------------------------

[[noreturn]] void fail(const char* scenario, const std::string& what) {
  std::fprintf(stderr, "golden scenario %s: %s\n", scenario, what.c_str());
  std::abort();
}

void require(const Status& status, const char* scenario, const char* what) {
  if (!status.ok()) fail(scenario, std::string(what) + ": " + status.to_string());
}

template <typename T>
T require(Result<T> result, const char* scenario, const char* what) {
  if (!result.ok()) fail(scenario, std::string(what) + ": " + result.status().to_string());
  return std::move(result).value();
}

// Knuth's MMIX linear congruential generator: the only source of variety in the edits, always
// seeded from fixed integers (the tick), so the edits are a pure function of the tick.
//
// Draw at most one number per full expression, into a named local: the order in which a call's
// arguments are evaluated is unspecified, and it does differ (gcc evaluates f(rng(), rng())
// in one order on x86-64 and in the other on aarch64; tools/cross_aarch64.sh caught exactly
// that here).
class Lcg {
 public:
  explicit Lcg(uint64_t seed) : state_(seed * 0x9E3779B97F4A7C15ull + 0x2545F4914F6CDD1Dull) {
    next();
    next();
  }
  uint64_t next() {
    state_ = state_ * 6364136223846793005ull + 1442695040888963407ull;
    return state_;
  }
  // Uniform in [0, 1): the top 53 bits, converted exactly.
  double unit() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
  // Uniform in [0, n) for small n (the high bits of an LCG are its good ones).
  int below(int n) { return static_cast<int>((next() >> 33) % static_cast<uint64_t>(n)); }

 private:
  uint64_t state_;
};

SceneBody box_body(BodyType type, const Vec2& position, double hx, double hy, double density,
                   double angle = 0.0) {
  SceneBody body;
  body.def.type = type;
  body.def.position = position;
  body.def.angle = angle;
  ShapeDef shape;
  shape.geometry = make_box(hx, hy);
  shape.density = density;
  body.shapes.push_back(shape);
  return body;
}

SceneBody ball_body(const Vec2& position, double radius, double density) {
  SceneBody body;
  body.def.type = BodyType::kDynamic;
  body.def.position = position;
  ShapeDef shape;
  shape.geometry = Circle{Vec2::Zero(), radius};
  shape.density = density;
  body.shapes.push_back(shape);
  return body;
}

int push(SceneDef* scene, SceneBody body) {
  scene->bodies.push_back(std::move(body));
  return static_cast<int>(scene->bodies.size()) - 1;
}

// The live body whose user_data is `tag` (null if none): edits find their bodies this way
// rather than by holding handles, so that they need no state of their own.
BodyId find_tagged(const World& world, uint64_t tag) {
  for (BodyId id : world.bodies()) {
    if (world.body_state(id)->user_data == tag) return id;
  }
  return BodyId{};
}

// Dynamic bodies and particles, in index order.
std::vector<BodyId> moving_bodies(const World& world) {
  std::vector<BodyId> out;
  for (BodyId id : world.bodies()) {
    BodyType type = world.body_state(id)->type;
    if (type == BodyType::kDynamic || type == BodyType::kParticle) out.push_back(id);
  }
  return out;
}

// A joint made by build() in a fresh world: joints are numbered in creation order from 0, and
// a fresh world issues generation 1. Checks the type so that a changed numbering fails loudly.
JointId built_joint(const World& world, int32_t index, JointType type, const char* scenario) {
  JointId id{index, 1};
  Result<JointState> state = world.joint_state(id);
  if (!state.ok() || state->type != type) {
    fail(scenario, "joint " + std::to_string(index) + " is not the expected " +
                       joint_type_name(type) + " joint");
  }
  return id;
}

void no_edits(World&, int64_t) {}

// --- 1. pyramid: a base-10 pyramid (55 boxes) hit on its flank by a heavy ball --------------

World build_pyramid() {
  SceneDef s;
  scenes::add_ground(&s, 60.0);
  scenes::PyramidOptions p;
  p.base = 10;
  scenes::add_pyramid(&s, p);
  // Thrown from the left; it strikes the pyramid's upper rows at about tick 25 and knocks them
  // off.
  SceneBody ball = ball_body(Vec2(-12.0, 5.0), 0.5, 20.0);
  ball.def.linear_velocity = Vec2(18.0, 5.0);
  push(&s, std::move(ball));
  return require(build_world(s), "pyramid", "build_world");
}

// --- 2. ragdolls: eight ragdolls of three sizes tumbling down two ramps -----------------------

World build_ragdolls() {
  SceneDef s;
  scenes::add_ground(&s, 30.0);
  push(&s, box_body(BodyType::kStatic, Vec2(-4.0, 0.5), 3.0, 0.2, 1.0, 0.35));
  push(&s, box_body(BodyType::kStatic, Vec2(5.0, 0.8), 3.0, 0.2, 1.0, -0.3));
  for (int i = 0; i < 8; ++i) {
    scenes::RagdollOptions o;
    o.feet = Vec2(-7.0 + 1.9 * i, 3.0 + 1.5 * (i % 3));
    o.scale = 0.8 + 0.15 * (i % 3);
    o.group = -(i + 1);
    int first = scenes::add_ragdoll(&s, o);
    // One velocity for all eleven parts, so the joints start satisfied.
    for (int b = first; b < first + 11; ++b) {
      s.bodies[b].def.linear_velocity = Vec2(3.0 - 0.8 * i, 1.0 * (i % 2));
    }
  }
  // A few loose boxes for the ragdolls to land on.
  for (int i = 0; i < 4; ++i) {
    push(&s, box_body(BodyType::kDynamic, Vec2(-6.0 + 4.0 * i, 4.5), 0.3, 0.3, 2.0));
  }
  return require(build_world(s), "ragdolls", "build_world");
}

// --- 3. rope_cloth: a rope with a box on its end, and a cloth a ball falls into ---------------

World build_rope_cloth() {
  SceneDef s;
  scenes::add_ground(&s, 20.0, -2.0);
  scenes::RopeOptions r;
  r.start = Vec2(-9.0, 7.0);
  r.end = Vec2(-3.0, 7.0);
  r.count = 24;
  int last = scenes::add_rope(&s, r) + r.count - 1;
  int box = push(&s, box_body(BodyType::kDynamic, Vec2(-2.5, 7.0), 0.3, 0.3, 2.0));
  DistanceJointDef tie;  // slack below 0.5 m, taut at it
  tie.length = 0.5;
  tie.min_length = 0.0;
  tie.max_length = 0.5;
  s.joints.push_back(SceneJoint{last, box, tie});

  scenes::ClothOptions c;
  c.top_left = Vec2(1.0, 7.0);
  c.columns = 12;
  c.rows = 10;
  c.spacing = 0.3;
  c.pinned = {{0, 0}, {11, 0}};
  scenes::add_cloth(&s, c);
  push(&s, ball_body(Vec2(2.6, 10.0), 0.4, 3.0));
  return require(build_world(s), "rope_cloth", "build_world");
}

// --- 4. sleep_wake: a stack and a small pyramid fall asleep; a dropped ball wakes the stack at
// tick 180, an impulse wakes the pyramid at tick 360 -------------------------------------------

World build_sleep_wake() {
  SceneDef s;
  scenes::add_ground(&s, 20.0);
  int first = static_cast<int>(s.bodies.size());
  scenes::StackOptions st;
  st.count = kStackBoxes;
  st.offset = 0.0;
  scenes::add_stack(&s, st);
  for (int i = first; i < static_cast<int>(s.bodies.size()); ++i) {
    s.bodies[i].def.user_data = kTagStack + (i - first);
  }
  first = static_cast<int>(s.bodies.size());
  scenes::PyramidOptions p;
  p.base = 3;  // kPyramidBoxes = 3 + 2 + 1
  p.origin = Vec2(6.0, 0.0);
  scenes::add_pyramid(&s, p);
  for (int i = first; i < static_cast<int>(s.bodies.size()); ++i) {
    s.bodies[i].def.user_data = kTagPyramid + (i - first);
  }
  return require(build_world(s), "sleep_wake", "build_world");
}

void edit_sleep_wake(World& world, int64_t tick) {
  if (tick == kSleepWakeDropTick) {
    BodyDef def;
    def.type = BodyType::kDynamic;
    def.position = Vec2(0.3, 8.0);
    def.linear_velocity = Vec2(0.0, -4.0);
    def.user_data = kTagDroppedBall;
    BodyId ball = require(world.create_body(def), "sleep_wake", "create ball");
    ShapeDef shape;
    shape.geometry = Circle{Vec2::Zero(), 0.4};
    shape.density = 3.0;
    require(world.create_shape(ball, shape), "sleep_wake", "create ball shape");
  } else if (tick == kSleepWakeImpulseTick) {
    BodyId box = find_tagged(world, kTagPyramid);  // bottom-left box of the pyramid
    BodyState state = require(world.body_state(box), "sleep_wake", "pyramid box");
    require(world.apply_linear_impulse(box, Vec2(4.0, 1.0), state.center + Vec2(-0.5, 0.4)),
            "sleep_wake", "impulse");
  }
}

// --- 5. edits: a closed bin with a kinematic rotor, edited every 5 ticks ----------------------

constexpr uint64_t kTagEdited = 500;  // bodies created by the edits (and the initial ones)
constexpr int kEditEvery = 5;
constexpr int kSettingsEvery = 60;

// A shape of one of five kinds, about `size` across; kind 4 is a particle's circle.
ShapeDef edit_shape(int kind, double size) {
  ShapeDef shape;
  switch (kind) {
    case 0:
    case 4:
      shape.geometry = Circle{Vec2::Zero(), 0.5 * size};
      break;
    case 1:
      shape.geometry = make_box(0.5 * size, 0.35 * size);
      break;
    case 2:
      shape.geometry = Capsule{Vec2(-0.3 * size, 0.0), Vec2(0.3 * size, 0.0), 0.25 * size};
      break;
    default: {
      // A rounded pentagon.
      const Vec2 points[5] = {Vec2(0.5, 0.0), Vec2(0.15, 0.48), Vec2(-0.4, 0.3), Vec2(-0.4, -0.3),
                              Vec2(0.15, -0.48)};
      Vec2 scaled[5];
      for (int i = 0; i < 5; ++i) scaled[i] = size * points[i];
      Polygon polygon;
      require(make_polygon(scaled, 0.04, &polygon), "edits", "pentagon");
      shape.geometry = polygon;
      break;
    }
  }
  shape.density = 1.0 + 0.5 * kind;
  shape.friction = 0.4 + 0.1 * kind;
  shape.restitution = kind == 0 ? 0.3 : 0.0;
  return shape;
}

BodyDef edit_body_def(int kind, const Vec2& position, double angle, const Vec2& velocity) {
  BodyDef def;
  def.type = kind == 4 ? BodyType::kParticle : BodyType::kDynamic;
  def.position = position;
  def.angle = angle;
  def.linear_velocity = velocity;
  def.user_data = kTagEdited;
  return def;
}

void add_static(SceneDef* s, const Vec2& center, double hx, double hy) {
  push(s, box_body(BodyType::kStatic, center, hx, hy, 1.0));
}

World build_edits() {
  SceneDef s;
  // A closed bin 14 m wide and 12 m tall, so nothing leaves.
  scenes::add_ground(&s, 8.0);
  add_static(&s, Vec2(-7.5, 6.0), 0.5, 6.0);
  add_static(&s, Vec2(7.5, 6.0), 0.5, 6.0);
  add_static(&s, Vec2(0.0, 12.5), 8.0, 0.5);
  SceneBody rotor = box_body(BodyType::kKinematic, Vec2(0.0, 2.5), 2.0, 0.15, 1.0);
  rotor.def.angular_velocity = 1.0;
  push(&s, std::move(rotor));
  for (int i = 0; i < 16; ++i) {
    int kind = i % 5;
    SceneBody body;
    body.def = edit_body_def(kind, Vec2(-4.5 + 3.0 * (i % 4), 5.0 + 1.8 * (i / 4)), 0.1 * i,
                             Vec2(0.0, 0.0));
    body.shapes.push_back(edit_shape(kind, 0.6 + 0.1 * (i % 3)));
    push(&s, std::move(body));
  }
  return require(build_world(s), "edits", "build_world");
}

void edit_settings(World& world, int64_t tick) {
  WorldSettings settings = world.settings();
  switch ((tick / kSettingsEvery) % 4) {
    case 0:  // the defaults, but for gravity
      settings = WorldSettings{};
      settings.gravity = Vec2(0.0, -10.0);
      break;
    case 1:
      settings.gravity = Vec2(-3.0, -9.0);
      settings.substeps = 2;
      settings.velocity_iterations = 4;
      break;
    case 2:
      settings.gravity = Vec2(2.0, -12.0);
      settings.contact_hertz = 30.0;
      settings.restitution_threshold = 0.5;
      settings.warm_starting = false;
      break;
    default:
      settings.substeps = 1;
      settings.velocity_iterations = 8;
      settings.relax_iterations = 0;
      settings.contact_hertz = 0.0;  // rigid contacts with Baumgarte and slop
      settings.split_impulses = true;
      break;
  }
  require(world.set_settings(settings), "edits", "set_settings");
}

void edit_edits(World& world, int64_t tick) {
  if (tick > 0 && tick % kSettingsEvery == 0) edit_settings(world, tick);
  if (tick % kEditEvery != 0) return;
  Lcg rng(static_cast<uint64_t>(tick));
  std::vector<BodyId> bodies = moving_bodies(world);
  // Two edits per edit tick.
  for (int e = 0; e < 2; ++e) {
    int op = rng.below(9);
    if (op == 0 && bodies.size() >= 40) op = 1;  // keep the bin from filling up
    if (op == 1 && bodies.size() <= 8) op = 0;
    BodyId target = bodies.empty() ? BodyId{} : bodies[rng.below(static_cast<int>(bodies.size()))];
    switch (op) {
      case 0: {  // create
        const int kind = rng.below(5);
        const double x = rng.uniform(-6.0, 6.0);
        const double y = rng.uniform(9.0, 11.0);
        const double vx = rng.uniform(-3.0, 3.0);
        const double vy = rng.uniform(-3.0, 0.0);
        const double angle = rng.uniform(-kPi, kPi);
        const double size = rng.uniform(0.4, 0.9);
        BodyId id = require(world.create_body(edit_body_def(kind, Vec2(x, y), angle, Vec2(vx, vy))),
                            "edits", "create_body");
        require(world.create_shape(id, edit_shape(kind, size)), "edits", "create_shape");
        bodies.push_back(id);
        break;
      }
      case 1:  // destroy (its joints go with it)
        require(world.destroy_body(target), "edits", "destroy_body");
        std::erase(bodies, target);
        break;
      case 2: {
        const double vx = rng.uniform(-6.0, 6.0);
        const double vy = rng.uniform(-2.0, 8.0);
        const double w = rng.uniform(-10.0, 10.0);
        require(world.set_linear_velocity(target, Vec2(vx, vy)), "edits", "set_linear_velocity");
        require(world.set_angular_velocity(target, w), "edits", "set_angular_velocity");
        break;
      }
      case 3: {
        BodyState state = require(world.body_state(target), "edits", "body_state");
        const double ox = rng.uniform(-0.3, 0.3);
        const double oy = rng.uniform(-0.3, 0.3);
        const double ix = rng.uniform(-5.0, 5.0);
        const double iy = rng.uniform(0.0, 8.0);
        require(world.apply_linear_impulse(target, state.mass * Vec2(ix, iy),
                                           state.center + Vec2(ox, oy)),
                "edits", "apply_linear_impulse");
        require(world.apply_angular_impulse(target, state.rotational_inertia * 4.0), "edits",
                "apply_angular_impulse");
        break;
      }
      case 4: {  // forces act for the next tick only
        BodyState state = require(world.body_state(target), "edits", "body_state");
        require(world.apply_force(target, state.mass * Vec2(0.0, 400.0),
                                  state.transform.apply(Vec2(0.2, 0.0))),
                "edits", "apply_force");
        const double fx = rng.uniform(-200.0, 200.0);
        const double torque = rng.uniform(-5.0, 5.0);
        require(world.apply_force_to_center(target, state.mass * Vec2(fx, 0.0)), "edits",
                "apply_force_to_center");
        require(world.apply_torque(target, torque), "edits", "apply_torque");
        break;
      }
      case 5: {
        std::vector<ShapeId> shapes = require(world.body_shapes(target), "edits", "body_shapes");
        const double friction = rng.uniform(0.0, 1.0);
        const double restitution = rng.uniform(0.0, 0.8);
        require(world.set_shape_material(shapes.front(), friction, restitution), "edits",
                "set_shape_material");
        break;
      }
      case 6: {  // teleport to the top of the bin
        const double x = rng.uniform(-6.0, 6.0);
        const double angle = rng.uniform(-kPi, kPi);
        require(world.set_transform(target, Vec2(x, 10.5), angle), "edits", "set_transform");
        break;
      }
      case 7:
        require(world.set_awake(target, false), "edits", "set_awake");
        break;
      default: {  // a rope between two bodies, taut at their present distance
        BodyId other = bodies[rng.below(static_cast<int>(bodies.size()))];
        if (other == target) break;
        Vec2 a = require(world.body_state(target), "edits", "body_state").transform.p;
        Vec2 b = require(world.body_state(other), "edits", "body_state").transform.p;
        double length = distance(a, b);
        if (length < 0.1) break;
        DistanceJointDef def;
        def.body_a = target;
        def.body_b = other;
        def.length = length;
        def.min_length = 0.0;
        def.max_length = length;
        require(world.create_distance_joint(def), "edits", "create_distance_joint");
        break;
      }
    }
  }
}

// --- 6. joints: every joint type: a bridge that breaks, a motor cart, an elevator, welds, a
// dragged box and a spring pendulum ------------------------------------------------------------

constexpr int kBridgePlanks = 12;
constexpr int kBridgeJoints = kBridgePlanks + 1;  // joints 0..12, created by build_world
// Joints created afterwards, in this order.
constexpr int32_t kJointWheelRear = kBridgeJoints;
constexpr int32_t kJointWheelFront = kBridgeJoints + 1;
constexpr int32_t kJointTarget = kBridgeJoints + 5;
constexpr int kCartReverseTick = 150;

World build_joints() {
  SceneDef s;
  int ground = static_cast<int>(s.bodies.size());
  scenes::add_ground(&s, 30.0);
  // The bridge: planks pinned end to end between two points of the ground body, 4 m up.
  int first = static_cast<int>(s.bodies.size());
  for (int i = 0; i < kBridgePlanks; ++i) {
    push(&s, box_body(BodyType::kDynamic, Vec2(-13.5 + i, 4.0), 0.5, 0.1, 5.0));
  }
  auto pin = [&](int a, int b, const Vec2& anchor_a, const Vec2& anchor_b) {
    RevoluteJointDef def;
    def.local_anchor_a = anchor_a;
    def.local_anchor_b = anchor_b;
    s.joints.push_back(SceneJoint{a, b, def});
  };
  // The ground body's origin is 1 m below its top surface.
  pin(ground, first, Vec2(-14.0, 5.0), Vec2(-0.5, 0.0));
  for (int i = 1; i < kBridgePlanks; ++i) {
    pin(first + i - 1, first + i, Vec2(0.5, 0.0), Vec2(-0.5, 0.0));
  }
  pin(first + kBridgePlanks - 1, ground, Vec2(0.5, 0.0), Vec2(-2.0, 5.0));
  for (int i = 0; i < 3; ++i) {
    push(&s, box_body(BodyType::kDynamic, Vec2(-11.0 + 2.5 * i, 6.0 + i), 0.4, 0.4, 3.0));
  }
  int chassis = push(&s, box_body(BodyType::kDynamic, Vec2(2.0, 1.3), 1.0, 0.2, 2.0));
  int rear = push(&s, ball_body(Vec2(1.3, 0.4), 0.4, 1.0));
  int front = push(&s, ball_body(Vec2(2.7, 0.4), 0.4, 1.0));
  int platform = push(&s, box_body(BodyType::kDynamic, Vec2(9.0, 0.5), 1.0, 0.1, 2.0));
  push(&s, box_body(BodyType::kDynamic, Vec2(9.0, 0.95), 0.3, 0.3, 1.0));
  int l_foot = push(&s, box_body(BodyType::kDynamic, Vec2(5.0, 3.0), 0.6, 0.15, 1.0, 0.2));
  int l_arm = push(&s, box_body(BodyType::kDynamic, Vec2(5.45, 3.6), 0.15, 0.6, 1.0, 0.2));
  int l_tip = push(&s, box_body(BodyType::kDynamic, Vec2(5.45, 4.5), 0.2, 0.2, 1.0, 0.2));
  int dragged = push(&s, box_body(BodyType::kDynamic, Vec2(-6.0, 9.0), 0.4, 0.25, 1.0));
  int bob = push(&s, ball_body(Vec2(1.5, 8.0), 0.3, 2.0));
  push(&s, box_body(BodyType::kStatic, Vec2(15.0, 1.0), 0.5, 1.0, 1.0));  // a wall for the cart

  World world = require(build_world(s), "joints", "build_world");
  auto id = [&](int index) { return world.bodies()[index]; };
  const char* n = "joints";
  // The bridge's middle joint breaks under the boxes.
  require(world.set_joint_break_limits(JointId{kBridgeJoints / 2, 1}, 150.0,
                                       std::numeric_limits<double>::infinity()),
          n, "set_joint_break_limits");
  for (auto [wheel, anchor] :
       {std::pair{rear, Vec2(-0.7, -0.9)}, std::pair{front, Vec2(0.7, -0.9)}}) {
    RevoluteJointDef def;
    def.body_a = id(chassis);
    def.body_b = id(wheel);
    def.local_anchor_a = anchor;
    def.enable_motor = true;
    def.motor_speed = -6.0;  // clockwise: drives to the right
    def.max_motor_torque = 20.0;
    require(world.create_revolute_joint(def), n, "wheel joint");
  }
  PrismaticJointDef lift;
  lift.body_a = id(ground);
  lift.body_b = id(platform);
  lift.local_anchor_a = Vec2(9.0, 1.5);
  lift.local_axis_a = Vec2(0.0, 1.0);
  lift.enable_limit = true;
  lift.lower_translation = 0.0;
  lift.upper_translation = 3.0;
  lift.enable_motor = true;
  lift.motor_speed = 1.0;
  lift.max_motor_force = 200.0;
  require(world.create_prismatic_joint(lift), n, "prismatic joint");
  WeldJointDef weld;  // rigid
  weld.body_a = id(l_foot);
  weld.body_b = id(l_arm);
  weld.local_anchor_a = Vec2(0.45, 0.15);
  weld.local_anchor_b = Vec2(0.0, -0.45);
  require(world.create_weld_joint(weld), n, "weld joint");
  WeldJointDef soft;  // springy in both parts
  soft.body_a = id(l_arm);
  soft.body_b = id(l_tip);
  soft.local_anchor_a = Vec2(0.0, 0.6);
  soft.local_anchor_b = Vec2(0.0, -0.3);
  soft.linear_hertz = 5.0;
  soft.linear_damping_ratio = 0.5;
  soft.angular_hertz = 3.0;
  soft.angular_damping_ratio = 0.2;
  require(world.create_weld_joint(soft), n, "soft weld joint");
  TargetJointDef drag;
  drag.body_a = id(ground);
  drag.body_b = id(dragged);
  drag.local_anchor_b = Vec2(0.3, 0.0);
  drag.target = Vec2(-6.0, 9.0);
  drag.max_force = 200.0;
  require(world.create_target_joint(drag), n, "target joint");
  DistanceJointDef spring;
  spring.body_a = id(ground);
  spring.body_b = id(bob);
  spring.local_anchor_a = Vec2(0.0, 11.0);
  spring.length = 2.0;
  spring.min_length = 0.5;
  spring.max_length = 3.0;
  spring.hertz = 2.0;
  spring.damping_ratio = 0.1;
  require(world.create_distance_joint(spring), n, "spring joint");
  return world;
}

void edit_joints(World& world, int64_t tick) {
  // The dragged box's target circles at 0.25 turns per second.
  JointId target = built_joint(world, kJointTarget, JointType::kTarget, "joints");
  SinCos sc = det_sincos(0.5 * kPi * static_cast<double>(tick) / 60.0);
  require(world.set_joint_target(target, Vec2(-6.0 + 2.0 * sc.cos, 9.0 + 2.0 * sc.sin)), "joints",
          "set_joint_target");
  if (tick == kCartReverseTick) {
    for (int32_t j : {kJointWheelRear, kJointWheelFront}) {
      require(world.set_motor_speed(built_joint(world, j, JointType::kRevolute, "joints"), 6.0),
              "joints", "set_motor_speed");
    }
  }
}

// --- 7. lanes: what the coloured contact lanes must get right --------------------------------
// A plank carrying 40 balls touches more bodies than there are colours, so some of its
// contacts overflow and are solved one by one; a kinematic paddle sweeps through a pile of
// boxes (contacts of one colour may share it: the solver never writes it); bouncy balls give
// one-point manifolds with restitution; a base-20 pyramid gives colours of several chunks, so
// that the contact solver shares them out when the world has threads. Its hash is compared
// across the instruction paths and thread counts.

World build_lanes() {
  SceneDef s;
  scenes::add_ground(&s, 60.0);
  SceneBody plank = box_body(BodyType::kDynamic, Vec2(-10.0, 0.6), 12.0, 0.1, 2.0);
  push(&s, std::move(plank));
  for (int i = 0; i < 40; ++i) {
    double r = 0.2 + 0.05 * (i % 3);
    push(&s, ball_body(Vec2(-21.5 + 0.6 * i, 0.7 + r + 0.01 * (i % 5)), r, 1.0));
  }
  for (int row = 0; row < 5; ++row) {
    for (int col = 0; col < 8; ++col) {
      push(&s,
           box_body(BodyType::kDynamic, Vec2(8.0 + 0.55 * col + 0.1 * (row % 2), 0.25 + 0.5 * row),
                    0.25, 0.25, 1.0));
    }
  }
  SceneBody paddle = box_body(BodyType::kKinematic, Vec2(5.0, 1.0), 0.2, 1.0, 1.0);
  paddle.def.linear_velocity = Vec2(3.0, 0.0);
  paddle.def.angular_velocity = 0.5;
  push(&s, std::move(paddle));
  for (int i = 0; i < 12; ++i) {
    SceneBody ball = ball_body(Vec2(18.0 + 0.9 * i, 4.0 + 0.3 * (i % 4)), 0.3, 1.0);
    ball.shapes[0].restitution = 0.6;
    push(&s, std::move(ball));
  }
  scenes::PyramidOptions p;
  p.base = 20;
  p.origin = Vec2(-40.0, 0.0);
  scenes::add_pyramid(&s, p);
  return require(build_world(s), "lanes", "build_world");
}

// --- 8. recovery: deep overlaps that make their islands recover --------------------------------
// Overlaps deep enough that their push-out reaches the cap give their islands three relax
// passes and twice the cap (docs/solver.md, Budgets): a pyramid of boxes created overlapping
// by a quarter (case 6's), which recovers for its first ticks, and 100 circles jammed into a
// closed box they cannot fit (covering 123 % of it), which recover while they are slow, with
// contacts enough that threads share them.

World build_recovery() {
  SceneDef s;
  scenes::add_ground(&s, 40.0);
  for (int row = 0; row < 4; ++row) {
    const int n = 4 - row;
    for (int i = 0; i < n; ++i) {
      push(&s, box_body(BodyType::kDynamic,
                        Vec2(-12.0 + (i - 0.5 * (n - 1)) * 0.75, 0.5 + 0.75 * row), 0.5, 0.5, 1.0));
    }
  }
  // The box: inner faces 4 m either side of x = 10, from the ground to 8 m.
  push(&s, box_body(BodyType::kStatic, Vec2(5.5, 4.0), 0.5, 4.0, 1.0));
  push(&s, box_body(BodyType::kStatic, Vec2(14.5, 4.0), 0.5, 4.0, 1.0));
  push(&s, box_body(BodyType::kStatic, Vec2(10.0, 8.5), 5.0, 0.5, 1.0));
  for (int j = 0; j < 10; ++j) {
    for (int i = 0; i < 10; ++i) {
      push(&s, ball_body(Vec2(6.5 + 0.78 * i, 0.5 + 0.74 * j), 0.5, 1.0));
    }
  }
  return require(build_world(s), "recovery", "build_world");
}

// --- 9. pins: plain revolute joints in lanes --------------------------------------------------
// Pins with no limit, motor or spring are solved colour by colour in lanes (docs/performance.md):
// a 20 x 20 grid of circles pinned to their right and lower neighbours (760 pins, colours
// large enough that threads share them) hanging from its two top corners; a dense wheel whose
// hub holds 30 spokes (more pins than colours: an overflow), one of them by a limited joint (a
// row of its own); and a chain of 12 boxes created 0.4 m apart, whose feedback closes at the
// cap.

void pin(SceneDef* s, int a, int b, const Vec2& world_anchor) {
  RevoluteJointDef def;
  def.local_anchor_a = world_anchor - s->bodies[a].def.position;
  def.local_anchor_b = world_anchor - s->bodies[b].def.position;
  s->joints.push_back(SceneJoint{a, b, def});
}

World build_pins() {
  SceneDef s;
  scenes::add_ground(&s, 60.0, -30.0);
  constexpr int n = 20;
  const int first = static_cast<int>(s.bodies.size());
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      SceneBody b = ball_body(Vec2(-30.0 + col, 20.0 - row), 0.4, 1.0);
      if (row == 0 && (col == 0 || col == n - 1)) b.def.type = BodyType::kStatic;
      push(&s, std::move(b));
    }
  }
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      const int i = first + row * n + col;
      if (col + 1 < n) pin(&s, i, i + 1, Vec2(-29.5 + col, 20.0 - row));
      if (row + 1 < n) pin(&s, i, i + n, Vec2(-30.0 + col, 19.5 - row));
    }
  }
  // The wheel, turning, on a static axle at (10, 10).
  const Vec2 axle(10.0, 10.0);
  SceneBody anchor = ball_body(axle, 0.1, 1.0);
  anchor.def.type = BodyType::kStatic;
  const int axle_body = push(&s, std::move(anchor));
  const int hub = push(&s, ball_body(axle, 1.0, 10.0));
  pin(&s, axle_body, hub, axle);
  for (int k = 0; k < 30; ++k) {
    const SinCos sc = det_sincos(2.0 * kPi * k / 30.0);
    const Vec2 dir(sc.cos, sc.sin);
    SceneBody spoke = ball_body(axle + 3.0 * dir, 0.2, 1.0);
    spoke.def.linear_velocity = Vec2(-dir.y(), dir.x());
    const int b = push(&s, std::move(spoke));
    pin(&s, hub, b, axle + 3.0 * dir);
    if (k == 29) {
      auto& limited = std::get<RevoluteJointDef>(s.joints.back().def);
      limited.enable_limit = true;
      limited.lower_angle = -0.5;
      limited.upper_angle = 0.5;
    }
  }
  // The chain, from a static anchor at (20, 15), each box's pin 0.4 m short of its place.
  SceneBody top = ball_body(Vec2(20.0, 15.0), 0.1, 1.0);
  top.def.type = BodyType::kStatic;
  int prev = push(&s, std::move(top));
  for (int i = 0; i < 12; ++i) {
    const int link =
        push(&s, box_body(BodyType::kDynamic, Vec2(21.0 + 1.4 * i, 15.0), 0.5, 0.125, 1.0));
    RevoluteJointDef def;
    def.local_anchor_a = i == 0 ? Vec2::Zero() : Vec2(0.5, 0.0);
    def.local_anchor_b = Vec2(-0.5, 0.0);
    s.joints.push_back(SceneJoint{prev, link, def});
    prev = link;
  }
  return require(build_world(s), "pins", "build_world");
}

}  // namespace

const std::vector<GoldenScenario>& golden_scenarios() {
  static const std::vector<GoldenScenario> scenarios = {
      {"pyramid", 240, build_pyramid, no_edits},
      {"ragdolls", 240, build_ragdolls, no_edits},
      {"rope_cloth", 240, build_rope_cloth, no_edits},
      {"sleep_wake", 480, build_sleep_wake, edit_sleep_wake},
      {"edits", 480, build_edits, edit_edits},
      {"joints", 360, build_joints, edit_joints},
      {"lanes", 240, build_lanes, no_edits},
      {"recovery", 240, build_recovery, no_edits},
      {"pins", 180, build_pins, no_edits},
  };
  return scenarios;
}

std::vector<uint64_t> run_golden(const GoldenScenario& scenario, int threads) {
  World world = scenario.build();
  require(world.set_threads(threads), scenario.name, "set_threads");
  std::vector<uint64_t> hashes;
  hashes.reserve(static_cast<size_t>(scenario.ticks));
  for (int i = 0; i < scenario.ticks; ++i) {
    scenario.edits(world, world.tick());
    world.step();
    hashes.push_back(world.state_hash());
  }
  return hashes;
}

uint64_t combine_hashes(std::span<const uint64_t> hashes) {
  // splitmix64's finaliser (a bijection) over the running value xor each hash in turn.
  uint64_t h = 0x9E3779B97F4A7C15ull ^ static_cast<uint64_t>(hashes.size());
  for (uint64_t x : hashes) {
    h ^= x;
    h = (h ^ (h >> 30)) * 0xBF58476D1CE4E5B9ull;
    h = (h ^ (h >> 27)) * 0x94D049BB133111EBull;
    h ^= h >> 31;
  }
  return h;
}

}  // namespace fulcrum::golden
