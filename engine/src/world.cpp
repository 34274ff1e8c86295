// The world: object lifetimes, edits, and the step orchestrator.
#include "fulcrum/world.h"

#include <algorithm>
#include <string>

#include "fulcrum/trig.h"
#include "validation.h"
#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

std::string handle_text(const char* kind, int32_t index, uint32_t generation) {
  return std::string(kind) + " {" + std::to_string(index) + ", " + std::to_string(generation) + "}";
}

Status stale_body(BodyId id) {
  return not_found(handle_text("body", id.index, id.generation) +
                   ": unknown or destroyed body handle");
}
Status stale_shape(ShapeId id) {
  return not_found(handle_text("shape", id.index, id.generation) +
                   ": unknown or destroyed shape handle");
}

}  // namespace

// --- WorldImpl: lookups, mass, sleep flags ----------------------------------------------------

int WorldImpl::body_index(BodyId id) const {
  if (id.index < 0 || id.index >= static_cast<int>(bodies.size())) return kNullIndex;
  const Body& b = bodies[id.index];
  return b.alive && b.generation == id.generation ? id.index : kNullIndex;
}

int WorldImpl::shape_index(ShapeId id) const {
  if (id.index < 0 || id.index >= static_cast<int>(shapes.size())) return kNullIndex;
  const Shape& s = shapes[id.index];
  return s.alive && s.generation == id.generation ? id.index : kNullIndex;
}

void WorldImpl::add_mass_terms(MassSums& sums, const Shape& s) {
  if (s.density == 0.0) return;
  MassData md = compute_mass(s.geometry, s.density);
  sums.mass += md.mass;
  sums.weighted += md.mass * md.center;
  sums.inertia_origin += md.rotational_inertia + md.mass * dot(md.center, md.center);
}

void WorldImpl::update_mass(int bi) {
  MassSums& sums = mass_sums[bi];
  sums = MassSums{};
  for (int si : bodies[bi].shapes) add_mass_terms(sums, shapes[si]);
  finish_mass(bi);
}

void WorldImpl::add_shape_mass(int bi, int si) {
  add_mass_terms(mass_sums[bi], shapes[si]);
  finish_mass(bi);
}

// Mass, centre of mass and inertia from the shapes' densities. Static and kinematic bodies have
// infinite mass (inverse 0). A dynamic body without mass gets 1 kg so it still falls.
void WorldImpl::finish_mass(int bi) {
  Body& b = bodies[bi];
  b.mass = b.inv_mass = b.inertia = b.inv_inertia = 0.0;
  b.local_center = Vec2::Zero();
  if (!b.is_dynamic()) {
    b.center = b.xf.p;
    return;
  }
  const double mass = mass_sums[bi].mass;
  const Vec2 weighted = mass_sums[bi].weighted;
  const double inertia_origin = mass_sums[bi].inertia_origin;
  if (mass > 0.0) {
    b.mass = mass;
    b.inv_mass = 1.0 / mass;
    b.local_center = weighted * b.inv_mass;
    // Parallel axis theorem: move the inertia from the origin to the centre of mass.
    double inertia = inertia_origin - mass * dot(b.local_center, b.local_center);
    if (b.rotates() && inertia > 0.0) {
      b.inertia = inertia;
      b.inv_inertia = 1.0 / inertia;
    }
  } else {
    b.mass = 1.0;
    b.inv_mass = 1.0;
  }
  // Keep the velocity of the origin continuous while the centre of mass moves.
  Vec2 old_center = b.center;
  b.center = b.xf.apply(b.local_center);
  b.v += cross(b.w, b.center - old_center);
}

void WorldImpl::set_awake_flag(int bi, bool awake) {
  Body& b = bodies[bi];
  if (b.type == BodyType::kStatic || b.awake == awake) return;
  b.awake = awake;
  b.sleep_time = 0.0;
  if (awake) {
    b.awake_slot = static_cast<int>(awake_bodies.size());
    awake_bodies.push_back(bi);
  } else {
    int slot = b.awake_slot;
    int last = awake_bodies.back();
    awake_bodies[slot] = last;
    bodies[last].awake_slot = slot;
    awake_bodies.pop_back();
    b.awake_slot = kNullIndex;
    b.v = Vec2::Zero();
    b.w = 0.0;
    b.force = Vec2::Zero();
    b.torque = 0.0;
  }
}

// Flood fill over touching contacts: a sleeping island wakes as a whole.
void WorldImpl::wake_island(int start) {
  if (bodies[start].type == BodyType::kStatic || bodies[start].awake) return;
  std::vector<int> stack{start};
  set_awake_flag(start, true);
  while (!stack.empty()) {
    int bi = stack.back();
    stack.pop_back();
    if (!bodies[bi].is_dynamic()) continue;  // kinematic bodies do not link islands
    for (int e = bodies[bi].contact_list; e != kNullIndex;) {
      const Contact& c = contacts[edge_contact(e)];
      int other = edge_side(e) == 0 ? c.body_b : c.body_a;
      if (c.touching && !c.sensor && bodies[other].type != BodyType::kStatic &&
          !bodies[other].awake) {
        ++edit_work;
        set_awake_flag(other, true);
        stack.push_back(other);
      }
      e = c.edges[edge_side(e)].next;
    }
    for (int ji : bodies[bi].joints) {
      const Joint& j = joints[ji];
      int other = j.body_a == bi ? j.body_b : j.body_a;
      if (bodies[other].type != BodyType::kStatic && !bodies[other].awake) {
        ++edit_work;
        set_awake_flag(other, true);
        stack.push_back(other);
      }
    }
  }
}

void WorldImpl::wake_in_box(const AABB& box) {
  std::vector<int> hits;
  for (const DynamicTree* t : {&tree, &static_tree}) {
    t->query(box, [&](int proxy) {
      hits.push_back(static_cast<int>(t->user_data(proxy)));
      return true;
    });
  }
  edit_work += hits.size();
  std::sort(hits.begin(), hits.end());
  for (int si : hits) wake_island(shapes[si].body);
}

// --- World: lifetime and settings ------------------------------------------------------------

World::World(const WorldSettings& settings) : impl_(std::make_unique<WorldImpl>(settings)) {}
World::~World() = default;

Status World::set_threads(int threads) {
  if (threads < 1 || threads > kMaxThreads) {
    return invalid_argument("threads: " + std::to_string(threads) + " is outside [1, " +
                            std::to_string(kMaxThreads) + "]");
  }
  if (threads == this->threads()) return {};
  pool_ = threads > 1 ? std::make_unique<WorkerPool>(threads) : nullptr;
  return {};
}

int World::threads() const {
  return pool_ != nullptr ? pool_->threads() : 1;
}
World::World(World&&) noexcept = default;
World& World::operator=(World&&) noexcept = default;

Status World::set_settings(const WorldSettings& settings) {
  FULCRUM_RETURN_IF_ERROR(validate_settings(settings));
  impl_->settings = settings;
  return {};
}

const WorldSettings& World::settings() const {
  return impl_->settings;
}

// --- Bodies ------------------------------------------------------------------------------------

Result<BodyId> World::create_body(const BodyDef& def) {
  FULCRUM_RETURN_IF_ERROR(validate_body_def(def));
  WorldImpl& w = *impl_;
  int bi;
  if (!w.free_bodies.empty()) {
    bi = w.free_bodies.back();
    w.free_bodies.pop_back();
  } else {
    bi = static_cast<int>(w.bodies.size());
    w.bodies.emplace_back();
    w.mass_sums.emplace_back();
  }
  Body& b = w.bodies[bi];
  uint32_t generation = b.generation + 1;
  b = Body{};
  b.generation = generation;
  b.alive = true;
  b.type = def.type;
  b.xf.p = def.position;
  b.xf.q = def.type == BodyType::kParticle ? Rot{} : Rot::from_angle(def.angle);
  b.center = b.xf.p;
  b.linear_damping = def.linear_damping;
  b.angular_damping = def.angular_damping;
  b.gravity_scale = def.gravity_scale;
  b.drag = def.drag;
  b.fixed_rotation = def.fixed_rotation;
  b.enable_sleep = def.enable_sleep;
  b.user_data = def.user_data;
  if (b.is_dynamic()) {
    b.constant_force = def.constant_force;
    b.constant_torque = b.rotates() ? def.constant_torque : 0.0;
  }
  if (def.type != BodyType::kStatic) {
    b.v = def.linear_velocity;
    b.w = b.rotates() || def.type == BodyType::kKinematic ? def.angular_velocity : 0.0;
  }
  w.update_mass(bi);
  w.set_awake_flag(bi, def.type != BodyType::kStatic && def.awake);
  ++w.body_count;
  w.kinematic_bodies += def.type == BodyType::kKinematic;
  return w.body_id(bi);
}

Status World::destroy_body(BodyId id) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  // Whatever rested on it must fall.
  for (int e = w.bodies[bi].contact_list; e != kNullIndex;) {
    const Contact& c = w.contacts[edge_contact(e)];
    int other = edge_side(e) == 0 ? c.body_b : c.body_a;
    w.wake_island(other);
    e = c.edges[edge_side(e)].next;
  }
  w.destroy_body_contacts(bi);
  while (!w.bodies[bi].joints.empty()) {
    int ji = w.bodies[bi].joints.back();
    const Joint& j = w.joints[ji];
    w.wake_island(j.body_a == bi ? j.body_b : j.body_a);
    w.pending_joint_events.push_back(w.joint_id(ji));
    w.destroy_joint_at(ji);
  }
  for (int si : w.bodies[bi].shapes) {
    w.destroy_proxy(si);
    Shape& s = w.shapes[si];
    s.alive = false;
    w.free_shapes.push_back(si);
    --w.shape_count;
  }
  w.set_awake_flag(bi, false);
  Body& b = w.bodies[bi];
  b.alive = false;
  b.shapes.clear();
  w.free_bodies.push_back(bi);
  --w.body_count;
  w.kinematic_bodies -= b.type == BodyType::kKinematic;
  return {};
}

bool World::is_valid(BodyId id) const {
  return impl_->body_index(id) != kNullIndex;
}
bool World::is_valid(ShapeId id) const {
  return impl_->shape_index(id) != kNullIndex;
}

Result<BodyState> World::body_state(BodyId id) const {
  int bi = impl_->body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  const Body& b = impl_->bodies[bi];
  BodyState s;
  s.type = b.type;
  s.transform = b.xf;
  s.center = b.center;
  s.linear_velocity = b.v;
  s.angular_velocity = b.w;
  s.mass = b.is_dynamic() ? b.mass : 0.0;
  s.rotational_inertia = b.inertia;
  s.awake = b.awake;
  s.user_data = b.user_data;
  s.constant_force = b.constant_force;
  s.constant_torque = b.constant_torque;
  return s;
}

std::vector<BodyId> World::bodies() const {
  std::vector<BodyId> out;
  out.reserve(impl_->body_count);
  for (int i = 0; i < static_cast<int>(impl_->bodies.size()); ++i) {
    if (impl_->bodies[i].alive) out.push_back(impl_->body_id(i));
  }
  return out;
}

std::vector<JointId> World::joints() const {
  std::vector<JointId> out;
  for (int i = 0; i < static_cast<int>(impl_->joints.size()); ++i) {
    if (impl_->joints[i].alive) out.push_back(impl_->joint_id(i));
  }
  return out;
}

int World::body_count() const {
  return impl_->body_count;
}

int World::shape_count() const {
  return impl_->shape_count;
}

Result<int> World::body_shape_count(BodyId id) const {
  int bi = impl_->body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  return static_cast<int>(impl_->bodies[bi].shapes.size());
}

uint64_t World::edit_work() const {
  return impl_->edit_work;
}

// --- Shapes ------------------------------------------------------------------------------------

namespace {

int allocate_shape(WorldImpl& w) {
  if (!w.free_shapes.empty()) {
    int si = w.free_shapes.back();
    w.free_shapes.pop_back();
    return si;
  }
  w.shapes.emplace_back();
  return static_cast<int>(w.shapes.size()) - 1;
}

int add_shape(WorldImpl& w, int bi, const ShapeDef& def) {
  int si = allocate_shape(w);
  Shape& s = w.shapes[si];
  uint32_t generation = s.generation + 1;
  s = Shape{};
  s.generation = generation;
  s.alive = true;
  s.body = bi;
  s.geometry = def.geometry;
  s.density = def.density;
  s.friction = def.friction;
  s.restitution = def.restitution;
  s.filter = def.filter;
  s.is_sensor = def.is_sensor;
  s.user_data = def.user_data;
  w.bodies[bi].shapes.push_back(si);
  w.derive_shape(si);
  w.create_proxy(si);
  ++w.shape_count;
  ++w.edit_work;
  return si;
}

}  // namespace

Result<ShapeId> World::create_shape(BodyId body, const ShapeDef& def) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(body);
  if (bi == kNullIndex) return stale_body(body);
  FULCRUM_RETURN_IF_ERROR(validate_shape_def(def));
  const Body& b = w.bodies[bi];
  if (b.type == BodyType::kParticle) {
    const Circle* c = std::get_if<Circle>(&def.geometry);
    if (c == nullptr || !b.shapes.empty()) {
      return invalid_argument("shape.geometry: a particle has exactly one circle shape");
    }
    if (c->center != Vec2::Zero()) {
      return invalid_argument("shape.circle.center: a particle's circle must be centred at (0, 0)");
    }
    if (!(def.density > 0.0))
      return invalid_argument("shape.density: a particle needs density > 0");
  }
  if (geometry_type(def.geometry) == ShapeType::kSegment && b.is_dynamic()) {
    return invalid_argument(
        "shape.segment: segments have no mass; put them on static or kinematic bodies");
  }
  int si = add_shape(w, bi, def);
  w.add_shape_mass(bi, si);
  w.wake_in_box(w.fat_boxes[si]);
  return w.shape_id(si);
}

Result<std::vector<ShapeId>> World::create_chain(BodyId body, const ChainDef& def) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(body);
  if (bi == kNullIndex) return stale_body(body);
  FULCRUM_RETURN_IF_ERROR(validate_chain_def(def));
  if (w.bodies[bi].is_dynamic()) {
    return invalid_argument("chain: chains have no mass; put them on static or kinematic bodies");
  }
  std::vector<ShapeId> ids;
  size_t n = def.points.size();
  size_t segments = def.loop ? n : n - 1;
  for (size_t i = 0; i < segments; ++i) {
    ShapeDef sd;
    sd.geometry = Segment{def.points[i], def.points[(i + 1) % n]};
    sd.density = 0.0;
    sd.friction = def.friction;
    sd.restitution = def.restitution;
    sd.filter = def.filter;
    sd.user_data = def.user_data;
    int si = add_shape(w, bi, sd);
    w.wake_in_box(w.fat_boxes[si]);
    ids.push_back(w.shape_id(si));
  }
  return ids;
}

Status World::destroy_shape(ShapeId id) {
  WorldImpl& w = *impl_;
  int si = w.shape_index(id);
  if (si == kNullIndex) return stale_shape(id);
  int bi = w.shapes[si].body;
  w.wake_island(bi);
  w.wake_in_box(w.fat_boxes[si]);
  // Destroy the contacts of this shape only.
  for (int e = w.bodies[bi].contact_list; e != kNullIndex;) {
    int ci = edge_contact(e);
    int next = w.contacts[ci].edges[edge_side(e)].next;
    if (w.contacts[ci].shape_a == si || w.contacts[ci].shape_b == si) w.destroy_contact(ci, true);
    e = next;
  }
  w.destroy_proxy(si);
  auto& list = w.bodies[bi].shapes;
  list.erase(std::find(list.begin(), list.end(), si));
  w.shapes[si].alive = false;
  w.free_shapes.push_back(si);
  --w.shape_count;
  w.update_mass(bi);
  return {};
}

Result<ShapeInfo> World::shape_info(ShapeId id) const {
  int si = impl_->shape_index(id);
  if (si == kNullIndex) return stale_shape(id);
  const Shape& s = impl_->shapes[si];
  ShapeInfo info;
  info.body = impl_->body_id(s.body);
  info.type = geometry_type(s.geometry);
  info.geometry = s.geometry;
  info.density = s.density;
  info.friction = s.friction;
  info.restitution = s.restitution;
  info.filter = s.filter;
  info.is_sensor = s.is_sensor;
  info.user_data = s.user_data;
  return info;
}

Result<std::vector<ShapeId>> World::body_shapes(BodyId id) const {
  int bi = impl_->body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  std::vector<ShapeId> out;
  for (int si : impl_->bodies[bi].shapes) out.push_back(impl_->shape_id(si));
  return out;
}

Status World::set_shape_material(ShapeId id, double friction, double restitution) {
  WorldImpl& w = *impl_;
  int si = w.shape_index(id);
  if (si == kNullIndex) return stale_shape(id);
  // The ranges of ShapeDef's (validate_shape_def in types.cpp).
  FULCRUM_RETURN_IF_ERROR(check_in_range("friction", friction, 0.0, 1e6));
  FULCRUM_RETURN_IF_ERROR(check_in_range("restitution", restitution, 0.0, 1e3));
  w.shapes[si].friction = friction;
  w.shapes[si].restitution = restitution;
  // Contacts mix materials at creation; refresh the ones this shape is part of.
  int bi = w.shapes[si].body;
  for (int e = w.bodies[bi].contact_list; e != kNullIndex;) {
    Contact& c = w.contacts[edge_contact(e)];
    if (c.shape_a == si || c.shape_b == si) {
      const Shape& a = w.shapes[c.shape_a];
      const Shape& b = w.shapes[c.shape_b];
      c.friction = std::sqrt(a.friction * b.friction);
      c.restitution = std::max(a.restitution, b.restitution);
    }
    e = c.edges[edge_side(e)].next;
  }
  w.wake_island(bi);
  return {};
}

Status World::set_shape_filter(ShapeId id, const Filter& filter) {
  WorldImpl& w = *impl_;
  int si = w.shape_index(id);
  if (si == kNullIndex) return stale_shape(id);
  w.shapes[si].filter = filter;
  if (w.shapes[si].proxy != kNullIndex) {
    w.tree_of(w.shapes[si])
        .set_leaf_filter(w.shapes[si].proxy, filter.category_bits, filter.mask_bits);
  }
  int bi = w.shapes[si].body;
  // Drop contacts the new filter forbids; re-test the shape for new pairs.
  for (int e = w.bodies[bi].contact_list; e != kNullIndex;) {
    int ci = edge_contact(e);
    int next = w.contacts[ci].edges[edge_side(e)].next;
    const Contact& c = w.contacts[ci];
    if ((c.shape_a == si || c.shape_b == si) && !w.should_collide(c.shape_a, c.shape_b)) {
      w.destroy_contact(ci, true);
    }
    e = next;
  }
  if (!w.shapes[si].in_move_buffer) {
    w.shapes[si].in_move_buffer = true;
    w.move_buffer.push_back(si);
  }
  w.wake_island(bi);
  return {};
}

// --- Edits -------------------------------------------------------------------------------------

Status World::set_transform(BodyId id, const Vec2& position, double angle) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("position", position));
  FULCRUM_RETURN_IF_ERROR(check_finite("angle", angle));
  Body& b = w.bodies[bi];
  b.xf.p = position;
  if (b.type != BodyType::kParticle) b.xf.q = Rot::from_angle(angle);
  b.center = b.xf.apply(b.local_center);
  w.wake_island(bi);
  w.synchronize_shapes(bi);
  for (int si : b.shapes) w.wake_in_box(w.fat_boxes[si]);
  return {};
}

Status World::set_linear_velocity(BodyId id, const Vec2& v) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("linear_velocity", v));
  if (w.bodies[bi].type == BodyType::kStatic) return {};
  w.bodies[bi].v = v;
  w.wake_island(bi);
  return {};
}

Status World::set_angular_velocity(BodyId id, double av) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("angular_velocity", av));
  Body& b = w.bodies[bi];
  if (b.type == BodyType::kStatic || (b.type != BodyType::kKinematic && !b.rotates())) return {};
  b.w = av;
  w.wake_island(bi);
  return {};
}

Status World::apply_force(BodyId id, const Vec2& force, const Vec2& point) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("force", force));
  FULCRUM_RETURN_IF_ERROR(check_finite("point", point));
  Body& b = w.bodies[bi];
  if (!b.is_dynamic()) return {};
  w.wake_island(bi);
  b.force += force;
  b.torque += cross(point - b.center, force);
  return {};
}

Status World::apply_force_to_center(BodyId id, const Vec2& force) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("force", force));
  if (!w.bodies[bi].is_dynamic()) return {};
  w.wake_island(bi);
  w.bodies[bi].force += force;
  return {};
}

Status World::apply_torque(BodyId id, double torque) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("torque", torque));
  if (!w.bodies[bi].is_dynamic()) return {};
  w.wake_island(bi);
  w.bodies[bi].torque += torque;
  return {};
}

Status World::apply_linear_impulse(BodyId id, const Vec2& impulse, const Vec2& point) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("impulse", impulse));
  FULCRUM_RETURN_IF_ERROR(check_finite("point", point));
  Body& b = w.bodies[bi];
  if (!b.is_dynamic()) return {};
  w.wake_island(bi);
  b.v += b.inv_mass * impulse;
  b.w += b.inv_inertia * cross(point - b.center, impulse);
  return {};
}

Status World::apply_angular_impulse(BodyId id, double impulse) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  FULCRUM_RETURN_IF_ERROR(check_finite("impulse", impulse));
  Body& b = w.bodies[bi];
  if (!b.is_dynamic()) return {};
  w.wake_island(bi);
  b.w += b.inv_inertia * impulse;
  return {};
}

Status World::set_awake(BodyId id, bool awake) {
  WorldImpl& w = *impl_;
  int bi = w.body_index(id);
  if (bi == kNullIndex) return stale_body(id);
  if (awake) {
    w.wake_island(bi);
  } else if (w.bodies[bi].type != BodyType::kStatic) {
    w.set_awake_flag(bi, false);
  }
  return {};
}

// --- The step ----------------------------------------------------------------------------------

// One tick, stage by stage:
//   update broad phase -> collide -> integrate velocities, warm start, iterate, store impulses,
//   integrate positions (solve) -> synchronize broad phase -> sleep -> clear forces.
// Edits arrive between ticks through the API above, so every edit applies at a tick boundary.
void World::step() {
  Status refused = try_step();
  (void)refused;  // only a contact limit refuses a tick, and step()'s callers set none
}

Status World::try_step() {
  WorldImpl& w = *impl_;
  w.pool = pool_.get();
  w.contact_limit = contact_limit_;
  // The workers spin from the first stage to the last: a tick's stages outside the solver
  // (the broad phase, collide, the budgets, the boxes) would otherwise wake them from sleep
  // one by one.
  const BusySpan busy(w.pool);
  // The broad phase first: it is the one stage that can refuse the tick, and it changes
  // nothing when it does.
  if (int64_t would = w.update_pairs(); would > 0) {
    return Status(StatusCode::kResourceExhausted,
                  "tick " + std::to_string(w.tick) + " would make at least " +
                      std::to_string(would) + " contacts, more than the contact limit of " +
                      std::to_string(contact_limit_));
  }
  w.events = StepEvents{};
  w.events.joints_destroyed.swap(w.pending_joint_events);
  ++w.step_stamp;

  w.collide();

  // The awake set in id order: every later stage visits bodies and contacts in this order.
  // (A world whose bodies neither sleep nor wake keeps awake_bodies in id order: no sort.)
  std::vector<int>& awake = w.scratch_awake;
  awake.assign(w.awake_bodies.begin(), w.awake_bodies.end());
  if (!std::is_sorted(awake.begin(), awake.end())) std::sort(awake.begin(), awake.end());

  w.solve(awake);
  w.break_joints();

  w.synchronize_awake(awake);
  w.update_sleep(awake);

  auto by_shapes = [](const ContactEvent& a, const ContactEvent& b) {
    return a.shape_a.index != b.shape_a.index ? a.shape_a.index < b.shape_a.index
                                              : a.shape_b.index < b.shape_b.index;
  };
  auto by_sensor = [](const SensorEvent& a, const SensorEvent& b) {
    return a.sensor.index != b.sensor.index ? a.sensor.index < b.sensor.index
                                            : a.visitor.index < b.visitor.index;
  };
  std::sort(w.events.contact_begin.begin(), w.events.contact_begin.end(), by_shapes);
  std::sort(w.events.contact_end.begin(), w.events.contact_end.end(), by_shapes);
  std::sort(w.events.sensor_begin.begin(), w.events.sensor_begin.end(), by_sensor);
  std::sort(w.events.sensor_end.begin(), w.events.sensor_end.end(), by_sensor);
  ++w.tick;
  return {};
}

Status World::set_contact_limit(int64_t limit) {
  if (limit < 0) {
    return invalid_argument("contact_limit: must be >= 0, 0 for none (got " +
                            std::to_string(limit) + ")");
  }
  contact_limit_ = limit;
  return {};
}

int64_t World::tick() const {
  return impl_->tick;
}
const StepEvents& World::events() const {
  return impl_->events;
}

}  // namespace fulcrum
