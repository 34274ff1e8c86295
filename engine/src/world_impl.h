// The world's internal state. Bodies, shapes and contacts live in pools indexed by id; the
// solver copies what it touches into compact per-step arrays (contact_solver.h) so that the hot
// loops read little memory.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include "contact_lanes.h"
#include "contact_solver.h"
#include "dynamic_tree.h"
#include "fulcrum/state.h"
#include "fulcrum/world.h"
#include "joint_lanes.h"
#include "joint_solver.h"
#include "large_pages.h"
#include "manifold.h"
#include "pair_set.h"

namespace fulcrum {

// What tells a recovering contact for one step (budget.cpp): one pushed out at the cap
// (rate times overlap, the rate twice as high against a body of infinite mass) while both its
// bodies move slower than the cap.
struct RecoveryRule {
  double rate = 0.0;        // soft push-out rate between two dynamic bodies, 1/s
  double fixed_rate = 0.0;  // against a body of infinite mass
  double cap = 0.0;         // max_correction_speed
};

// The constants of the contact budgets' prediction for one step (budget.cpp).
struct ContactPress {
  double per_impulse = 0.0;  // the load of an impulse kept per world substep: S / dt
  double per_load = 0.0;     // compression per unit of K times load: 1 / omega_c^2
  double rest_speed2 = 0.0;  // (|g| dt)^2: faster bodies are not at rest on their contacts
};

// Walks over records that a large world holds more of than the caches do fetch the record this
// many places ahead: the joint pool (or a list of joints in id order; 384 bytes a joint, the
// joint grid's 7.6 MB), the awake bodies' records (256 bytes each, the many pyramids' 5.6 MB)
// and the touching contacts, a sparse walk through the contact pool. The hardware does not
// keep up with the stride.
inline constexpr size_t kFetchAhead = 8;

// Fetches a joint's first two cache lines, where state.h keeps what a tick reads of it.
inline void fetch_joint(const Joint& j) {
  const char* p = reinterpret_cast<const char*>(&j);
  __builtin_prefetch(p);
  __builtin_prefetch(p + 64);
}

// Whether a joint has a finite break limit (break_joints checks only those).
inline bool may_break(const Joint& j) {
  return !std::isinf(j.break_force) || !std::isinf(j.break_torque);
}

// A contact's two bodies (body indices), as Contact has them.
struct ContactBodies {
  int a = kNullIndex, b = kNullIndex;
};

class WorldImpl {
 public:
  explicit WorldImpl(const WorldSettings& s) : settings(s) {}

  WorldSettings settings;
  int64_t tick = 0;
  uint32_t step_stamp = 0;

  LargeVector<Body> bodies;
  std::vector<int> free_bodies;  // reused last-freed first
  LargeVector<Shape> shapes;
  std::vector<int> free_shapes;
  LargeVector<Contact> contacts;
  LargeVector<ManifoldCache> manifold_caches;  // one per contact slot (contact.cpp)
  std::vector<int> free_contacts;
  LargeVector<Joint> joints;
  // Whether any joint may break: set when a finite break limit is set (or restored), never
  // cleared. Until then break_joints has nothing to check and reads no joint.
  bool breakable_joints = false;
  std::vector<int> free_joints;
  std::vector<JointId> pending_joint_events;  // destroyed with a body, reported next step
  std::vector<AttractorDef> attractors;       // applied in this order (forces.cpp)
  // Every live contact's pair of shapes (pair_key): the broad phase asks for each candidate
  // pair whether it already has one. Only looked up, never iterated (pair_set.h), so its
  // layout never reaches the results; snapshot restore rebuilds it from the contact pool.
  PairSet contact_pairs;
  std::vector<int> awake_bodies;  // unordered set (swap-remove); sorted when a step uses it
  int body_count = 0;
  int kinematic_bodies = 0;  // alive ones (plan_budgets)
  // Every awake body's rest timer is zero (update_sleep with sleep off cleared them, and
  // nothing has set one since). Not state: a restored world starts without it.
  bool awake_timers_zero = false;
  int shape_count = 0;

  // The running sums behind each body's mass (update_mass), indexed like `bodies`. They are
  // derived from the shapes, so they are not state: restore recomputes them. Adding a shape
  // adds its terms in the order a full recomputation would, so the bits are the same either
  // way, and a body of n shapes is built in O(n), not O(n^2).
  struct MassSums {
    double mass = 0.0;
    Vec2 weighted = Vec2::Zero();  // mass times centre, summed
    double inertia_origin = 0.0;   // about the body origin
  };
  std::vector<MassSums> mass_sums;
  static void add_mass_terms(MassSums& sums, const Shape& shape);
  // What each shape's geometry gives, indexed like `shapes`. The geometry never changes, so
  // none of it is state: derive_shape sets it when a shape is added and restore recomputes it.
  // The thickness (geometry_thickness), for the contact budgets.
  std::vector<double> shape_thickness;
  // The outline: what the shape's box at a transform needs (shape_box), packed apart from the
  // shape record, whose geometry spans six cache lines. Every tick boxes every awake shape, and
  // in a large pile most of that time was waiting on those lines.
  struct ShapeOutline {
    double radius = 0.0;
    double half_diagonal = 0.0;  // of the box in the shape's own frame (box_reach)
    int count = 0;               // points; 0: a polygon with more than fit, read from the shape
    ShapeType type = ShapeType::kCircle;
    std::array<Vec2, 4> points;  // circle: centre; capsule, segment: ends; polygon: vertices
  };
  LargeVector<ShapeOutline> shape_outlines;
  void derive_shape(int shape);
  // The shape's box at xf: compute_aabb's, bit for bit, from the outline.
  AABB shape_box(int shape, const Transform& xf) const;
  // Per contact id, what the contact budgets read (budget.cpp), computed by press_contact as
  // collide refreshes each contact of the awake bodies: the worst point's predicted compression
  // over the thinner shape's thickness, and the same per newton of load. Scratch, not state.
  std::vector<double> contact_pressed, contact_reach;
  // Per contact id: 1 when its load is not known (a body faster than rest, or a point new this
  // tick), so that its island keeps the world's velocity passes (budget.cpp).
  std::vector<uint8_t> contact_unsettled;
  // The constants press_contact needs, or none when contact budgets are off.
  std::optional<ContactPress> contact_press() const;
  double press_contact(int contact, const ContactPress& press);
  // The rule for recovering contacts, or none when recovery budgets are off (budget.cpp).
  std::optional<RecoveryRule> recovery_rule() const;
  bool recovering(const Contact& contact, const RecoveryRule& rule) const;
  // Work done by edits since the world was built or restored (World::edit_work): shapes and
  // joints created, broad-phase leaves visited and bodies woken. Not state.
  uint64_t edit_work = 0;

  // The broad phase's boxes: shapes of static bodies in a tree of their own, which no step
  // rebuilds and which moved static shapes never query; the others (dynamic and kinematic) in
  // `tree`. A body's type never changes, so a shape's tree is its body's (tree_of).
  DynamicTree tree;
  DynamicTree static_tree;
  DynamicTree& tree_of(const Shape& s) {
    return bodies[s.body].type == BodyType::kStatic ? static_tree : tree;
  }
  const DynamicTree& tree_of(const Shape& s) const {
    return bodies[s.body].type == BodyType::kStatic ? static_tree : tree;
  }
  // Each shape's broad-phase box, by shape index: a dense copy of its tree leaf's, kept equal
  // to it wherever a leaf's box is set (create_proxy, moves, restore). The narrow phase's
  // overlap test and the moved-box checks read it without touching the shape or the tree.
  LargeVector<AABB> fat_boxes;
  // Each awake shape's box and its body's velocity as the narrow phase starts (collide's first
  // round fills them when it has many contacts to refresh); `call` says which collide call
  // filled it. Not state: an entry filled by an earlier call is never read (collide_calls only
  // grows; a restore makes a new WorldImpl).
  //
  // `box` is also kept between ticks: wherever a shape's box is computed at its body's
  // transform (create_proxy; find_moves, after every tick's move and every set_transform) it is
  // stored here and `placed` set, so that collide's fill need not compute it again. A body's
  // transform changes nowhere else, so a placed box is always the box at the current transform.
  struct alignas(64) AwakeBox {
    AABB box;
    Vec2 v = Vec2::Zero();
    uint64_t call = 0;
    ShapeType type = ShapeType::kCircle;
    bool placed = false;
  };
  LargeVector<AwakeBox> awake_boxes;
  void place_box(int si, const AABB& box) {
    AwakeBox& r = awake_boxes[si];
    r.box = box;
    r.type = shape_outlines[si].type;
    r.placed = true;
  }
  uint64_t collide_calls = 0;
  std::vector<int> move_buffer;  // shape indices whose proxies moved or were created
  std::vector<std::pair<int, AABB>> pending_moves;  // proxy and new fat box (commit_moves)
  double tree_built_cost = 0.0;  // tree.cost() after its last rebuild (commit_moves)

  StepEvents events;

  // --- lookups (return kNullIndex for stale or unknown handles) ---
  int body_index(BodyId id) const;
  int shape_index(ShapeId id) const;
  BodyId body_id(int index) const { return BodyId{index, bodies[index].generation}; }
  ShapeId shape_id(int index) const { return ShapeId{index, shapes[index].generation}; }
  int joint_index(JointId id) const;
  JointId joint_id(int index) const { return JointId{index, joints[index].generation}; }

  // --- joints (joint.cpp and one file per type) ---
  // A new joint of `type` between two live, distinct bodies (its type-specific fields at
  // their defaults); wakes both and drops their contacts unless collide_connected.
  Result<int> add_joint(JointType type, BodyId body_a, BodyId body_b, bool collide_connected);
  void destroy_joint_at(int joint);
  // Whether a joint between the two bodies forbids their contact.
  bool joint_blocks_contact(int body_a, int body_b) const;
  // Prepares the awake joints' rows and colours their revolute joints (joint_lanes.h). The rows
  // of revolute joints are kept only with `every_row` (the reference solver reads them);
  // otherwise a tick whose rows are laid out as the last one's writes them straight into their
  // lanes.
  void prepare_joints(const std::vector<int>& awake, double h, bool every_row = false);
  // The revolute joints first, in lanes (on `workers`' threads when not null), then every other
  // row in row order. Without `lanes`, the lanes' warm start is left out (the last relax pass
  // gathered it, solve_group).
  void warm_start_joints(WorkerPool* workers, bool lanes = true);
  // With `warm_next`, the revolute joints' lanes also add their accumulated impulses to it, for
  // the next substep's warm start (PointRule::warm_next). `mass`: whether the lanes keep or read
  // their rows' 1 / det K (PointMassUse).
  void solve_joints(bool use_bias, WorkerPool* workers, VelocityBefore* warm_next = nullptr,
                    PointMassUse mass = {});
  // Writes the tick's impulses of the revolute joints' lanes back to their joints.
  void store_joint_impulses(WorkerPool* workers);
  // Spring force elements: one substep's forces into the solver bodies' velocities.
  void apply_spring_forces(double h);
  // Removes joints whose last tick's reaction passed their break limits.
  void break_joints();

  // --- bodies (world.cpp) ---
  // Recomputes the body's mass sums from all its shapes, then its mass (finish_mass).
  void update_mass(int body);
  // Adds one new shape's terms to the body's sums, then finishes its mass.
  void add_shape_mass(int body, int shape);
  // Mass, inverse mass, centre and inertia from the body's sums.
  void finish_mass(int body);
  void set_awake_flag(int body, bool awake);
  // Wakes a sleeping dynamic body and everything resting on it (its former island).
  void wake_island(int body);
  // The attractors' acceleration of dynamic body b with its centre of mass at x (forces.cpp).
  Vec2 attraction(const Body& b, const Vec2& x) const;
  // Wakes sleeping bodies whose shapes' boxes overlap `box`.
  void wake_in_box(const AABB& box);

  // --- broad phase (broad_phase.cpp) ---
  void create_proxy(int shape);
  // How far past a shape its fat box reaches: the speculative distance and a margin (none for
  // a shape travelling `travel` a tick, dt v, of more than half its margin).
  double box_reach(int shape, BodyType body_type, const Vec2& travel) const;
  void destroy_proxy(int shape);
  // Re-fits a body's moved shapes in the tree at once (edits).
  void synchronize_shapes(int body);
  // The step's re-fit of every awake body's shapes: new boxes found in chunks (on the pool),
  // then committed together (commit_moves).
  void synchronize_awake(const std::vector<int>& awake);
  template <class F>
  void find_moves(int body, F&& moved);
  void buffer_move(int shape);
  void commit_moves();  // pending_moves into the tree
  // Finds the new pairs of the moved shapes and creates their contacts. When they would take
  // the live contacts past `contact_limit` (> 0) it creates none, keeps the moved shapes
  // buffered and returns the number of live contacts it would have made (else 0).
  int64_t update_pairs();
  bool join_moves(int64_t room, std::atomic<int64_t>& found);  // update_pairs' walk of trees
  bool should_collide(int shape_a, int shape_b) const;

  // --- contacts (contact.cpp) ---
  void create_contact(int shape_a, int shape_b);
  void destroy_contact(int contact, bool report_end);
  // Refreshes the manifolds of contacts with an awake body; destroys contacts whose boxes
  // stopped overlapping; reports begin/end events; wakes bodies touched by awake ones. Lists
  // the touching contacts it leaves (touching_contacts).
  void collide();
  void fill_awake_boxes();
  // awake_bodies[first, end); with `press`, each contact's load figures too (press_contact),
  // and with `recovery`, the recovering contacts (budget.recovering).
  void collide_round(size_t first, size_t end, const std::optional<ContactPress>& press,
                     const std::optional<RecoveryRule>& recovery);
  void destroy_body_contacts(int body);

  // --- islands and sleep (island.cpp) ---
  void update_sleep(const std::vector<int>& awake_sorted);

  // --- solver (contact_solver.cpp) ---
  void solve(const std::vector<int>& awake_sorted);
  // One group's solve (all awake bodies, or one budget group: islands of one substep count,
  // run with settings.substeps and joint_hertz set for it), with its touching solid contacts
  // (touching_contacts, or the group's share of them) and, beside them, their bodies
  // (touching_bodies, or the group's share).
  void solve_group(const std::vector<int>& bodies_sorted, const std::vector<int>& contacts_sorted,
                   const std::vector<ContactBodies>& contact_bodies);
  // One group's solve (solve_group) in batches of whole islands, each solved through all its
  // substeps before the next, so that its rows stay in the caches (budget.cpp); false, having
  // done nothing, when the world does not qualify.
  bool solve_in_batches(const std::vector<int>& awake_sorted);
  // Splits the awake bodies into budget groups (budget.cpp); false when all keep the
  // world's substeps.
  bool plan_budgets(const std::vector<int>& awake_sorted);
  // Whether a tick no island runs a budget of its own solves one velocity pass per substep
  // (WorldSettings::one_pass_give_tolerance; budget.cpp).
  bool one_pass_tick() const;
  // plan_budgets' joint part: joins the joint components in scratch_parent and, unless
  // `gravity` is 0 (joint budgets off), sets each component root's need in budget.need; true
  // when one needs more than the world's substeps. Marks budget.held as it walks the joints.
  bool plan_joint_needs(const std::vector<int>& awake_sorted, double gravity);
  // The reference solver's start of a tick (reference.cpp): what World::step does before its
  // first velocity pass, with one substep of dt: broad phase, collision, the awake set in id
  // order (scratch_awake), solver bodies with the applied forces integrated, contact and joint
  // rows prepared (solver_scratch). It changes the world as a step's first stages do, so the
  // reference calls it on a copy. World::step never calls it.
  void prepare_reference_tick();

  // One byte per body, 1 for the bodies in awake_bodies: what a pass over the contact pool
  // reads instead of the bodies themselves, which are large and cold. Filled anew each call.
  const std::vector<uint8_t>& awake_flags();

  // Scratch reused every step (never part of the state).
  std::vector<int> scratch_contacts;
  std::vector<uint8_t> scratch_overlap;  // collide: each contact's Refreshed state
  // collide_round: one chunk's touching solid contacts and their bodies, in id order, and the
  // places in its list the id-order pass visits (contacts that parted or changed).
  struct ChunkTouching {
    std::vector<int> contacts;
    std::vector<ContactBodies> bodies;
    std::vector<int> visit;
    bool restitution = false;  // one of `contacts` has restitution
  };
  std::vector<ChunkTouching> scratch_chunk_touching;
  std::vector<std::vector<int>> scratch_chunk_contacts;  // collide: each chunk's gathered ids
  std::vector<uint8_t> scratch_awake_flag;               // awake_flags()
  // The last collide's touching contacts that are not sensors, in id order: every contact with
  // an awake body that touches, as the step's solver wants them (nothing between collide and
  // the solver changes contacts or puts a body to sleep).
  std::vector<int> touching_contacts;
  // Beside touching_contacts, each one's bodies: the budgets and the islands walk the touching
  // contacts for their bodies alone, and a contact record is large and cold.
  std::vector<ContactBodies> touching_bodies;
  std::vector<double> scratch_chunk_pressed;     // collide: each chunk's largest contact_pressed
  std::vector<uint8_t> scratch_chunk_unsettled;  // collide: whether a chunk has one unsettled
  std::vector<std::vector<int>> scratch_chunk_recovering;  // collide: each chunk's, in id order
  std::vector<int> scratch_awake;
  SolverScratch solver_scratch;
  // The live joints with an awake body at either end, in id order, and how many are springs:
  // listed by plan_joint_needs' walk over the joint pool on the tick whose step_stamp is
  // `stamp`, and taken by that tick's prepare_joints for the whole awake set.
  struct TickJoints {
    std::vector<int> joints;
    size_t springs = 0;
    uint32_t stamp = 0;
  } tick_joints;
  // What plan_joint_needs takes from one end of a joint whose body there is awake and dynamic
  // (its position k in the awake list), found by its walk over the joint pool.
  struct JointEnd {
    double weakest = 0.0;  // the two bodies' inverse masses summed (not read for a spring)
    int k = 0;
    int partner = -1;   // the other body's position in the awake list if awake and dynamic
    bool held = false;  // held to a moving kinematic body, or driven against infinite mass
    bool spring = false;
  };
  // Per joint slot, what the budgets' walk over the joint pool reads of every joint each tick:
  // its bodies, its kind and whether it lives, packed apart from the 384-byte joints (the joint
  // grid's 19 800 heads take 240 kB, their first lines 1.3 MB). Derived, so not state:
  // add_joint and destroy_joint_at keep it (note_joint), restore recomputes it.
  struct JointHead {
    int body_a = kNullIndex, body_b = kNullIndex;
    JointType type = JointType::kDistance;
    bool alive = false;
  };
  std::vector<JointHead> joint_heads;
  void note_joint(int joint) {
    if (joint_heads.size() < joints.size()) joint_heads.resize(joints.size());
    const Joint& j = joints[joint];
    joint_heads[joint] = JointHead{j.body_a, j.body_b, j.type, j.alive};
  }
  // With the world's threads that walk runs in chunks of joints, each listing its awake joints,
  // joined in chunk order (budget.cpp).
  struct JointWalkChunk {
    std::vector<int> joints;
    size_t springs = 0;
  };
  std::vector<JointWalkChunk> scratch_joint_walk;
  struct BudgetGroup {
    int substeps = 0;
    int relax = 0;            // relax passes per substep
    int iterations = 0;       // velocity passes per substep
    std::vector<int> bodies;  // in id order
    // Its touching solid contacts, in id order: those whose lower-indexed awake body is in
    // the group (a contact's awake dynamic bodies are always in one group); and their bodies.
    std::vector<int> contacts;
    std::vector<ContactBodies> contact_bodies;
  };
  struct Budget {
    int islands = 0;         // islands given more substeps or relax passes than the world's
    int max_substeps = 0;    // the most substeps any island ran this tick
    int max_relax = 0;       // the most relax passes per substep any island ran this tick
    int max_iterations = 0;  // the most velocity passes per substep any island ran this tick
    std::vector<BudgetGroup> groups;
    std::vector<double> mass, weakest;    // per joint component root, then island weights
    std::vector<double> pressed, reach;   // per body: its contacts' worst (budget.cpp)
    double most_pressed = 0.0;            // the largest contact_pressed of this step
    bool unsettled = false;               // some contact_unsettled of this step is set
    std::vector<uint8_t> body_unsettled;  // per body: one of its touching contacts is unsettled
    std::vector<uint8_t> dynamic;         // per body: whether it is dynamic
    std::vector<uint8_t> jointed;         // per body: whether it holds a joint
    std::vector<double> body_mass;        // per body: its mass
    std::vector<double> inv_mass;         // per body: its inverse mass (read with `dynamic`)
    // Every awake body is dynamic and holds no joint (read with `dynamic`, for one_pass_tick;
    // false when plan_budgets stopped before reading them).
    bool plain_bodies = false;
    // Some touching solid contact of this step has restitution (collide).
    bool restitution = false;
    std::vector<int> recovering;  // this step's recovering contacts, in id order
    std::vector<int> need, island_need;
    // Per body: a joint holds it to a moving kinematic body or drives it against a body of
    // infinite mass (plan_joint_needs).
    std::vector<uint8_t> held;
    std::vector<int> solved_joints;             // scratch: every group's joints, in id order
    std::vector<int> group_of;                  // per position in the awake set: its group
    std::vector<int> relax_need, island_relax;  // per body, then per island root
    std::vector<uint8_t> island_passes;  // per island root: 1 keeps the world's velocity passes
    // The world's substeps while a group is solved with its own: contact impulses are kept
    // between ticks per substep of this length, whatever the island's budget (budget.cpp).
    int base_substeps = 0;
  } budget;
  ColouredContacts coloured_contacts;
  // solve_in_batches: each batch's lanes, kept from tick to tick (so that a batch whose rows
  // did not change keeps its colours), and each batch's bodies and contacts.
  struct IslandBatch {
    ColouredContacts coloured;
    std::vector<int> bodies;
    std::vector<int> contacts;
    std::vector<ContactBodies> contact_bodies;
  };
  std::vector<IslandBatch> island_batches;
  bool batch_islands = true;   // false: never solve_in_batches (tests compare the two)
  int island_batch_count = 0;  // batches of the last tick's solve (0: one group or budgets)
  ColouredPoints coloured_points;
  // The threads the step may use (World::set_threads); null: the caller's thread alone. Owned
  // by the World, so that restoring a snapshot keeps it.
  WorkerPool* pool = nullptr;
  int64_t contact_limit = 0;                       // World::set_contact_limit, set by each step
  std::vector<std::pair<int, int>> scratch_pairs;  // broad phase
  std::vector<std::vector<std::pair<int, int>>> scratch_chunk_pairs;
  std::vector<uint8_t> scratch_moved_leaf, scratch_moved_static_leaf;  // broad phase (join)
  std::vector<std::vector<std::pair<int, AABB>>> scratch_moves;        // synchronize_awake
  std::vector<int> scratch_owner;   // solve_in_batches: each touching contact's awake body
  std::vector<int> scratch_parent;  // islands
  std::vector<double> scratch_rest, scratch_root_rest;
  std::vector<uint8_t> scratch_chunk_rested;  // update_sleep: per chunk, whether a body rested
};

// The key of an unordered pair of shape indices.
inline uint64_t pair_key(int shape_a, int shape_b) {
  uint32_t lo = static_cast<uint32_t>(std::min(shape_a, shape_b));
  uint32_t hi = static_cast<uint32_t>(std::max(shape_a, shape_b));
  return (static_cast<uint64_t>(lo) << 32) | hi;
}

inline int edge_contact(int edge_key) {
  return edge_key >> 1;
}
inline int edge_side(int edge_key) {
  return edge_key & 1;
}

// The substeps an island predicted to give `give` metres runs with (budget.cpp).
int budget_substeps(const WorldSettings& settings, double give);
// The substeps an island whose contacts are predicted to be pressed in by `ratio` of the
// thinner shape's thickness runs with (budget.cpp).
int contact_budget_substeps(const WorldSettings& settings, double ratio);
// The narrowest width of a shape across any direction (diameter, plate thickness); 0 for a
// segment, which has none (budget.cpp).
double geometry_thickness(const Geometry& geometry);
// The velocity iterations per substep of an island run with `budget` substeps instead of the
// world's `substeps` (`iterations` each): iterations * substeps / budget, at least 1.
int budget_iterations(int iterations, int substeps, int budget);
// Whether the settings let islands run one velocity pass per substep
// (WorldSettings::one_pass_give_tolerance; budget.cpp).
bool one_pass_rule(const WorldSettings& settings);

}  // namespace fulcrum
