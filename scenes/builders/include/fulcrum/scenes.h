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

// A static box ground placed anywhere: its top surface's centre at `center`, turned by
// `angle` about that point, `2 half_width` long and `thickness` thick (hand_scenes.cpp).
// Returns its index in scene->bodies.
struct GroundOptions {
  Vec2 center = Vec2::Zero();  // centre of the top surface, m
  double half_width = 50.0;    // m, > 0
  double angle = 0.0;          // rad: the surface's slope (counter-clockwise)
  double thickness = 2.0;      // m, > 0
  double friction = 0.6;       // >= 0
};
int add_ground(SceneDef* scene, const GroundOptions& options);

// A chain of `links` jointed links (capsules or boxes) hanging from a static anchor at
// `anchor`, laid out along `angle` (0: to the right, horizontal: released it swings down, as
// HARD_CASES 10), link i's far end jointed to link i + 1's near end, the first link's near end
// to the anchor. end_mass > 0 adds a ball of end_mass times one link's mass (radius
// end_radius) jointed to the last link's far end, its centre end_radius beyond it (HARD_CASES
// 10 and 19: 100 and 1000). Jointed links do not collide with each other. Returns the index of
// the anchor body in scene->bodies (the links, then the ball, follow it).
struct JointChainOptions {
  enum class LinkShape { kCapsule = 0, kBox = 1 };
  enum class JointKind { kRevolute = 0, kWeld = 1 };
  Vec2 anchor = Vec2(0.0, 20.0);  // m
  int links = 20;                 // >= 1
  double link_length = 1.0;       // m, joint to joint, > link_width
  double link_width = 0.25;       // m, > 0: the capsule's diameter or the box's height
  LinkShape shape = LinkShape::kCapsule;
  JointKind joint = JointKind::kRevolute;
  double angle = 0.0;       // rad: direction from the anchor along the chain
  double density = 1.0;     // kg/m^2, > 0
  double friction = 0.6;    // >= 0
  double end_mass = 0.0;    // >= 0: the ball's mass in link masses (0: no ball)
  double end_radius = 0.5;  // m, > 0
};
int add_joint_chain(SceneDef* scene, const JointChainOptions& options);

// A house of cards on the ground: `levels` storeys; storey k (from 0 at the bottom) is
// levels - k tents of two cards leaning `lean` from the vertical against each other, with a
// flat card across each pair of neighbouring tents' apexes, on which the next storey stands.
// (3 n^2 + n) / 2 cards for n levels. Cards are boxes card_length x card_thickness, created
// resting (feet on the floor below, apexes touching). Returns the index of the first card.
struct CardHouseOptions {
  Vec2 origin = Vec2::Zero();    // centre of the bottom storey's floor line, m
  int levels = 3;                // >= 1
  double card_length = 1.0;      // m, > 0
  double card_thickness = 0.05;  // m, > 0, <= card_length / 20
  double lean = 0.35;            // rad from the vertical, in [0.05, 0.45]
  double friction = 0.6;         // >= 0
  double density = 1.0;          // kg/m^2, > 0
};
int add_card_house(SceneDef* scene, const CardHouseOptions& options);

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
