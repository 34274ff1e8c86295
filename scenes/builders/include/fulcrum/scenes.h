// Scene builders shared by tests, benchmarks and the CLI. Each appends bodies to a SceneDef;
// the named scenes are the cases of the hard-case table and the benchmark table.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/status.h"
#include "fulcrum/world.h"

namespace fulcrum::scenes {

// A static box ground whose top surface is at y = top, spanning x in [-half_width, half_width].
void add_ground(SceneDef* scene, double half_width, double top = 0.0, double friction = 0.6);

struct PyramidOptions {
  int base = 20;               // boxes in the bottom row, >= 1
  double box_size = 1.0;       // edge length, m
  double spacing = 1.0;        // horizontal centre distance within a row, m (>= box_size)
  Vec2 origin = Vec2::Zero();  // centre of the bottom row's bottom edge, m
  double density = 1.0;        // kg/m^2
  double friction = 0.6;
  double top_density = -1.0;  // density of the top box; < 0 means `density`
};
// Rows from the bottom up; row r has base - r boxes resting exactly on the row below.
void add_pyramid(SceneDef* scene, const PyramidOptions& options);

struct StackOptions {
  int count = 20;              // boxes, >= 1
  double box_size = 1.0;       // m
  double offset = 0.01;        // sideways offset, alternately +offset and -offset, m
  Vec2 origin = Vec2::Zero();  // centre of the bottom box's bottom edge, m
  double density = 1.0;
  double friction = 0.6;
};
void add_stack(SceneDef* scene, const StackOptions& options);

// A rope of particles: `count` particles of radius `radius` from `start` toward `end`, each
// tied to the next by a distance joint that is slack below the segment length (max length
// only). The first particle is pinned to a static body when `pin_start`. Returns the index of
// the first particle in scene->bodies.
struct RopeOptions {
  Vec2 start = Vec2(0.0, 10.0);  // m
  Vec2 end = Vec2(10.0, 10.0);   // m
  int count = 20;                // particles, >= 2
  double radius = 0.05;          // m
  double density = 10.0;         // kg/m^2
  bool pin_start = true;
  bool collide = true;  // whether the rope's particles collide with other shapes
};
int add_rope(SceneDef* scene, const RopeOptions& options);

// A cloth of particles on a grid (rows from the top down), with structural distance joints
// to the right and lower neighbours and shear joints along both diagonals; the listed
// particles are pinned (made static). Particles of one cloth never collide with each other.
struct ClothOptions {
  Vec2 top_left = Vec2(-3.0, 8.0);  // m
  int columns = 30;
  int rows = 30;
  double spacing = 0.2;                                         // m
  double radius = 0.05;                                         // m, particle radius
  double density = 10.0;                                        // kg/m^2
  std::vector<std::pair<int, int>> pinned = {{0, 0}, {29, 0}};  // (column, row)
  int32_t group = -7;  // collision group shared by the cloth's particles (< 0: never collide)
};
int add_cloth(SceneDef* scene, const ClothOptions& options);

// A plank bridge (HARD_CASES 11): `planks` boxes of 1 m x 0.25 m, density 20, laid end to
// end along y = 0 from x = -planks / 2 to planks / 2, each pinned to the next by a revolute
// joint at their shared end and the two end planks pinned to one static anchor body at the
// origin. The chain is exactly as long as the span, so it can sag only as far as its joints
// stretch. Returns the index of the anchor body in scene->bodies (the planks follow it).
struct BridgeOptions {
  int planks = 160;             // >= 1
  double linear_damping = 0.0;  // 1/s, >= 0: every plank's BodyDef::linear_damping
};
int add_bridge(SceneDef* scene, const BridgeOptions& options);

// A ragdoll of 11 capsules (pelvis, torso, head, upper and lower arms, thighs, shins) on 10
// revolute joints with human-like angle limits and a little joint friction (a motor with
// target speed 0 and a small torque limit), standing with its feet at `feet` (side view).
// Its shapes share collision group `group` (< 0: a ragdoll never collides with itself).
// Returns the index of its pelvis in scene->bodies.
struct RagdollOptions {
  Vec2 feet = Vec2::Zero();      // m
  double scale = 1.0;            // > 0: 1 is about 1.75 m tall
  int32_t group = -1;            // collision group of all its shapes
  double joint_friction = 0.05;  // N m at scale 1 (scaled by scale^2)
  double density = 1.0;          // kg/m^2
};
int add_ragdoll(SceneDef* scene, const RagdollOptions& options);

// Box2D v3's ragdoll (its benchmark's "human"): 11 capsules (friction 0.2) and two foot plates
// (friction 0.05, touching only category 1, the ground), 10 limited revolute joints, each with
// joint friction (a motor at speed 0 up to a share of friction_torque) and a spring.
struct HumanOptions {
  Vec2 feet = Vec2::Zero();       // m
  double scale = 1.0;             // > 0: 1 is about 1.6 m tall
  int32_t group = -1;             // collision group of all its shapes
  double friction_torque = 0.05;  // N m at scale 1
  double hertz = 0.0;             // joint springs (0: none)
  double damping_ratio = 0.0;
};
int add_human(SceneDef* scene, const HumanOptions& options);

// Creates a scene's bodies (with shapes and chains) and joints in an existing world, in order;
// its settings are ignored. Returns the new bodies' handles, in the scene's order. On error
// what was created before it stays.
Result<std::vector<BodyId>> add_to_world(World& world, const SceneDef& part);

// A built-in scene that edits itself between ticks, as Box2D v3's rain spawns and destroys
// ragdolls: call before_step(world, step) before each World::step(), with step counting from
// 0. Deterministic: the edits are a function of the step and the driver's own history.
class SceneDriver {
 public:
  virtual ~SceneDriver() = default;
  virtual Status before_step(World& world, int64_t step) = 0;
};

// Named scenes (HARD_CASES.md and the benchmark table), ground included.
std::vector<std::string> builtin_names();
Result<SceneDef> builtin(std::string_view name);
// The driver of a built-in scene that has one ("rain"); null for the others.
std::unique_ptr<SceneDriver> builtin_driver(std::string_view name);

}  // namespace fulcrum::scenes
