// Snapshots: the world's records copied out, and copied back after a check of every range and
// every link between records. A snapshot that passes the check is rebuilt into a fresh
// WorldImpl (the broad-phase tree from the stored fat boxes) and must hash to the value it was
// saved with; only then does it replace the world, so a bad snapshot changes nothing.
#include <cstdio>
#include <string>

#include "fulcrum/state.h"
#include "validation.h"
#include "world_impl.h"

namespace fulcrum {

WorldSnapshot World::snapshot() const {
  const WorldImpl& w = *impl_;
  WorldSnapshot s;
  s.settings = w.settings;
  s.tick = w.tick;
  s.step_stamp = w.step_stamp;
  s.bodies.assign(w.bodies.begin(), w.bodies.end());
  s.free_bodies = w.free_bodies;
  s.shapes.assign(w.shapes.begin(), w.shapes.end());
  s.free_shapes = w.free_shapes;
  s.shape_boxes.resize(w.shapes.size());
  for (size_t i = 0; i < w.shapes.size(); ++i) {
    Shape& shape = s.shapes[i];
    if (shape.alive) s.shape_boxes[i] = w.fat_boxes[i];
    shape.proxy = kNullIndex;
  }
  s.contacts.assign(w.contacts.begin(), w.contacts.end());
  s.manifold_caches.assign(w.manifold_caches.begin(), w.manifold_caches.end());
  s.free_contacts = w.free_contacts;
  s.joints.assign(w.joints.begin(), w.joints.end());
  s.free_joints = w.free_joints;
  s.pending_joint_events = w.pending_joint_events;
  s.awake_bodies = w.awake_bodies;
  s.move_buffer = w.move_buffer;
  s.attractors = w.attractors;
  s.state_hash = state_hash();
  return s;
}

namespace {

std::string at(const char* kind, size_t index, const char* field) {
  return std::string(kind) + "[" + std::to_string(index) + "]." + field;
}

Status corrupt(const std::string& what) {
  return data_loss("snapshot: " + what);
}

bool in_range(int index, size_t size) {
  return index >= 0 && static_cast<size_t>(index) < size;
}

// A free list names every dead slot once and nothing else.
template <typename Record>
Status check_free_list(const char* name, const std::vector<int>& free,
                       const std::vector<Record>& slots) {
  std::vector<char> seen(slots.size(), 0);
  for (int i : free) {
    if (!in_range(i, slots.size()) || slots[i].alive || seen[i]) {
      return corrupt(std::string(name) + ": entry " + std::to_string(i) +
                     " is not a dead slot, or is listed twice");
    }
    seen[i] = 1;
  }
  size_t dead = 0;
  for (const Record& r : slots) dead += r.alive ? 0 : 1;
  if (dead != free.size()) {
    return corrupt(std::string(name) + ": lists " + std::to_string(free.size()) + " of " +
                   std::to_string(dead) + " dead slots");
  }
  return {};
}

Status check_number(const std::string& field, double x) {
  if (!std::isfinite(x)) return corrupt(field + " is not finite");
  return {};
}
Status check_number(const std::string& field, const Vec2& v) {
  if (!is_finite(v)) return corrupt(field + " is not finite");
  return {};
}
// Finite and within kMaxInputMagnitude, as every definition and edit that sets the value is
// (validation.h): a snapshot may hold only what the engine's own calls could have made.
template <typename Value>
Status check_bounded(const std::string& field, const Value& x) {
  Status st = check_finite(field, x);
  if (!st.ok()) return corrupt(st.message());
  return {};
}
// Parameters that may be infinite (break limits, rope lengths) but never NaN.
Status check_not_nan(const std::string& field, double x) {
  if (std::isnan(x)) return corrupt(field + " is NaN");
  return {};
}

Status check_body(const WorldSnapshot& s, size_t bi) {
  const Body& b = s.bodies[bi];
  if (b.generation == 0) return corrupt(at("body", bi, "generation") + " is 0");
  if (!b.alive) {
    if (!b.shapes.empty() || !b.joints.empty() || b.contact_list != kNullIndex ||
        b.awake_slot != kNullIndex) {
      return corrupt("body[" + std::to_string(bi) + "] is dead but still linked");
    }
    return {};
  }
  if (static_cast<int>(b.type) > static_cast<int>(BodyType::kParticle)) {
    return corrupt(at("body", bi, "type") + " is unknown");
  }
  const std::pair<const char*, Vec2> vecs[] = {
      {"position", b.xf.p}, {"local_center", b.local_center},
      {"center", b.center}, {"linear_velocity", b.v},
      {"force", b.force},   {"constant_force", b.constant_force}};
  for (const auto& [name, v] : vecs) FULCRUM_RETURN_IF_ERROR(check_number(at("body", bi, name), v));
  const std::pair<const char*, double> nums[] = {{"rotation.c", b.xf.q.c},
                                                 {"rotation.s", b.xf.q.s},
                                                 {"angular_velocity", b.w},
                                                 {"torque", b.torque},
                                                 {"constant_torque", b.constant_torque},
                                                 {"mass", b.mass},
                                                 {"inv_mass", b.inv_mass},
                                                 {"inertia", b.inertia},
                                                 {"inv_inertia", b.inv_inertia},
                                                 {"linear_damping", b.linear_damping},
                                                 {"angular_damping", b.angular_damping},
                                                 {"gravity_scale", b.gravity_scale},
                                                 {"drag", b.drag},
                                                 {"sleep_time", b.sleep_time}};
  for (const auto& [name, x] : nums) FULCRUM_RETURN_IF_ERROR(check_number(at("body", bi, name), x));
  if (b.mass < 0.0 || b.inv_mass < 0.0 || b.inertia < 0.0 || b.inv_inertia < 0.0) {
    return corrupt("body[" + std::to_string(bi) + "] has a negative mass property");
  }
  for (int si : b.shapes) {
    if (!in_range(si, s.shapes.size()) || !s.shapes[si].alive ||
        s.shapes[si].body != static_cast<int>(bi)) {
      return corrupt(at("body", bi, "shapes") + " names shape " + std::to_string(si) +
                     ", which is not a live shape of this body");
    }
  }
  for (int ji : b.joints) {
    if (!in_range(ji, s.joints.size()) || !s.joints[ji].alive ||
        (s.joints[ji].body_a != static_cast<int>(bi) &&
         s.joints[ji].body_b != static_cast<int>(bi))) {
      return corrupt(at("body", bi, "joints") + " names joint " + std::to_string(ji) +
                     ", which is not a live joint of this body");
    }
  }
  if (b.awake_slot != kNullIndex &&
      (!in_range(b.awake_slot, s.awake_bodies.size()) ||
       s.awake_bodies[b.awake_slot] != static_cast<int>(bi) || !b.awake)) {
    return corrupt(at("body", bi, "awake_slot") + " does not match awake_bodies");
  }
  if (b.awake && b.type != BodyType::kStatic && b.awake_slot == kNullIndex) {
    return corrupt("body[" + std::to_string(bi) + "] is awake but not in awake_bodies");
  }
  return {};
}

Status check_shape(const WorldSnapshot& s, size_t si) {
  const Shape& sh = s.shapes[si];
  if (sh.generation == 0) return corrupt(at("shape", si, "generation") + " is 0");
  if (!sh.alive) {
    if (sh.in_move_buffer) return corrupt("shape[" + std::to_string(si) + "] is dead but moved");
    return {};
  }
  if (!in_range(sh.body, s.bodies.size()) || !s.bodies[sh.body].alive) {
    return corrupt(at("shape", si, "body") + " is not a live body");
  }
  Status geometry = validate_geometry(sh.geometry);
  if (!geometry.ok()) return corrupt("shape[" + std::to_string(si) + "]: " + geometry.message());
  const std::pair<const char*, double> nums[] = {
      {"density", sh.density}, {"friction", sh.friction}, {"restitution", sh.restitution}};
  for (const auto& [name, x] : nums) {
    FULCRUM_RETURN_IF_ERROR(check_number(at("shape", si, name), x));
    if (x < 0.0) return corrupt(at("shape", si, name) + " is negative");
  }
  const AABB& box = s.shape_boxes[si];
  FULCRUM_RETURN_IF_ERROR(check_number(at("shape", si, "box.lower"), box.lower));
  FULCRUM_RETURN_IF_ERROR(check_number(at("shape", si, "box.upper"), box.upper));
  if (box.lower.x() > box.upper.x() || box.lower.y() > box.upper.y()) {
    return corrupt(at("shape", si, "box") + " is inverted");
  }
  return {};
}

Status check_contact(const WorldSnapshot& s, size_t ci) {
  const Contact& c = s.contacts[ci];
  if (!c.alive) return {};
  auto live_shape = [&](int si) { return in_range(si, s.shapes.size()) && s.shapes[si].alive; };
  if (!live_shape(c.shape_a) || !live_shape(c.shape_b) || c.shape_a == c.shape_b) {
    return corrupt(at("contact", ci, "shape_a/shape_b") + " are not two live shapes");
  }
  if (c.body_a != s.shapes[c.shape_a].body || c.body_b != s.shapes[c.shape_b].body) {
    return corrupt(at("contact", ci, "body_a/body_b") + " differ from the shapes' bodies");
  }
  if (c.manifold.count < 0 || c.manifold.count > 2) {
    return corrupt(at("contact", ci, "manifold.count") + " is outside [0, 2]");
  }
  FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "friction"), c.friction));
  FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "restitution"), c.restitution));
  FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "manifold.normal"), c.manifold.normal));
  for (int k = 0; k < c.manifold.count; ++k) {
    const ManifoldPoint& p = c.manifold.points[k];
    std::string field = at("contact", ci, "manifold.points[") + std::to_string(k) + "]";
    FULCRUM_RETURN_IF_ERROR(check_number(field + ".point", p.point));
    for (double x : {p.separation, p.normal_impulse, p.tangent_impulse}) {
      FULCRUM_RETURN_IF_ERROR(check_number(field, x));
    }
  }
  const ManifoldCache& k = s.manifold_caches[ci];
  if (!k.valid) return {};
  if (c.manifold.count == 0) {
    return corrupt(at("contact", ci, "cache") + " is kept for a manifold without points");
  }
  // The narrow phase moves a kept manifold on without looking at the shapes again.
  if (c.sensor || !flat(s.shapes[c.shape_a].geometry) || !flat(s.shapes[c.shape_b].geometry)) {
    return corrupt(at("contact", ci, "cache") +
                   " is kept for a sensor or a shape without flat faces");
  }
  FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "cache.pose"), k.pose.p));
  FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "cache.pose"), k.pose.q.c));
  FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "cache.pose"), k.pose.q.s));
  FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "cache.normal"), k.normal));
  for (int i = 0; i < c.manifold.count; ++i) {
    FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "cache.points"), k.points[i]));
    FULCRUM_RETURN_IF_ERROR(check_number(at("contact", ci, "cache.separations"), k.separations[i]));
  }
  return {};
}

// Each body's contact list must be a proper doubly linked list through live contacts that
// name the body on the edge's side, and every live contact must sit in both of its lists.
Status check_contact_lists(const WorldSnapshot& s) {
  size_t edges = 0;
  for (size_t bi = 0; bi < s.bodies.size(); ++bi) {
    const Body& b = s.bodies[bi];
    if (!b.alive) continue;
    int count = 0;
    int prev = kNullIndex;
    for (int e = b.contact_list; e != kNullIndex; ++count) {
      int ci = edge_contact(e);
      if (count >= b.contact_count || !in_range(ci, s.contacts.size()) || !s.contacts[ci].alive) {
        return corrupt(at("body", bi, "contact_list") + " is broken at edge " + std::to_string(e));
      }
      const Contact& c = s.contacts[ci];
      int side = edge_side(e);
      if ((side == 0 ? c.body_a : c.body_b) != static_cast<int>(bi) || c.edges[side].prev != prev) {
        return corrupt(at("contact", static_cast<size_t>(ci), "edges") +
                       " do not link back to body " + std::to_string(bi));
      }
      prev = e;
      e = c.edges[side].next;
    }
    if (count != b.contact_count) {
      return corrupt(at("body", bi, "contact_count") + " differs from its list's length");
    }
    edges += static_cast<size_t>(count);
  }
  size_t live = 0;
  for (const Contact& c : s.contacts) live += c.alive ? 1 : 0;
  if (edges != 2 * live) return corrupt("contacts: not every live contact is in both lists");
  return {};
}

Status check_joint(const WorldSnapshot& s, size_t ji) {
  const Joint& j = s.joints[ji];
  if (j.generation == 0) return corrupt(at("joint", ji, "generation") + " is 0");
  if (!j.alive) return {};
  if (static_cast<int>(j.type) > static_cast<int>(JointType::kSpring)) {
    return corrupt(at("joint", ji, "type") + " is unknown");
  }
  if (static_cast<int>(j.curve_type) > static_cast<int>(CurveType::kPolyline)) {
    return corrupt(at("joint", ji, "curve_type") + " is unknown");
  }
  for (const Vec2& p : j.curve_points) {
    FULCRUM_RETURN_IF_ERROR(check_bounded(at("joint", ji, "curve_points"), p));
  }
  auto lists = [&](int bi) {
    if (!in_range(bi, s.bodies.size()) || !s.bodies[bi].alive) return false;
    for (int k : s.bodies[bi].joints) {
      if (k == static_cast<int>(ji)) return true;
    }
    return false;
  };
  if (!lists(j.body_a) || !lists(j.body_b) || j.body_a == j.body_b) {
    return corrupt(at("joint", ji, "body_a/body_b") +
                   " are not two live bodies that list the joint");
  }
  // Bounded as the joint definitions and edits bound them: an anchor of 4e143 m (a fuzz
  // finding) made the solver's lever-arm products overflow to infinity within two ticks.
  auto field = [&](const char* name) { return at("joint", ji, name); };
  const Status bounded[] = {check_bounded(field("local_a"), j.local_a),
                            check_bounded(field("local_b"), j.local_b),
                            check_bounded(field("local_axis"), j.local_axis),
                            check_bounded(field("target"), j.target),
                            check_bounded(field("reference_angle"), j.reference_angle),
                            check_bounded(field("target_angle"), j.target_angle),
                            check_bounded(field("motor_speed"), j.motor_speed),
                            check_bounded(field("target_translation"), j.target_translation)};
  for (const Status& st : bounded) FULCRUM_RETURN_IF_ERROR(st);
  FULCRUM_RETURN_IF_ERROR(check_number(at("joint", ji, "linear_impulse"), j.linear_impulse));
  for (double x : {j.length,
                   j.min_length,
                   j.max_length,
                   j.reference_angle,
                   j.lower_angle,
                   j.upper_angle,
                   j.motor_speed,
                   j.max_motor_torque,
                   j.target_angle,
                   j.hertz,
                   j.damping_ratio,
                   j.angular_hertz,
                   j.angular_damping_ratio,
                   j.max_motor_force,
                   j.max_force,
                   j.break_force,
                   j.break_torque,
                   j.axial_impulse,
                   j.lower_impulse,
                   j.upper_impulse,
                   j.motor_impulse,
                   j.spring_impulse,
                   j.target_translation,
                   j.correction_factor,
                   j.curve_radius,
                   j.stiffness,
                   j.damping}) {
    FULCRUM_RETURN_IF_ERROR(check_not_nan(at("joint", ji, "parameter"), x));
  }
  return {};
}

// A list of distinct indices into `size` slots, each accepted by `ok`.
template <typename Ok>
Status check_index_list(const char* name, const std::vector<int>& list, size_t size, Ok ok) {
  std::vector<char> seen(size, 0);
  for (int i : list) {
    if (!in_range(i, size) || seen[i] || !ok(i)) {
      return corrupt(std::string(name) + ": entry " + std::to_string(i) + " is not valid here");
    }
    seen[i] = 1;
  }
  return {};
}

Status check_snapshot(const WorldSnapshot& s) {
  Status settings = validate_settings(s.settings);
  if (!settings.ok()) return corrupt("settings: " + settings.message());
  if (s.tick < 0) return corrupt("tick is negative");
  if (s.shape_boxes.size() != s.shapes.size()) {
    return corrupt("shape_boxes: one box per shape slot expected");
  }
  if (s.manifold_caches.size() != s.contacts.size()) {
    return corrupt("manifold_caches: one per contact slot expected");
  }
  FULCRUM_RETURN_IF_ERROR(check_free_list("free_bodies", s.free_bodies, s.bodies));
  FULCRUM_RETURN_IF_ERROR(check_free_list("free_shapes", s.free_shapes, s.shapes));
  FULCRUM_RETURN_IF_ERROR(check_free_list("free_contacts", s.free_contacts, s.contacts));
  FULCRUM_RETURN_IF_ERROR(check_free_list("free_joints", s.free_joints, s.joints));
  FULCRUM_RETURN_IF_ERROR(
      check_index_list("awake_bodies", s.awake_bodies, s.bodies.size(), [&](int bi) {
        return s.bodies[bi].alive && s.bodies[bi].awake_slot != kNullIndex &&
               s.awake_bodies[s.bodies[bi].awake_slot] == bi;
      }));
  FULCRUM_RETURN_IF_ERROR(
      check_index_list("move_buffer", s.move_buffer, s.shapes.size(),
                       [&](int si) { return s.shapes[si].alive && s.shapes[si].in_move_buffer; }));
  size_t moved = 0;
  for (const Shape& sh : s.shapes) moved += sh.in_move_buffer ? 1 : 0;
  if (moved != s.move_buffer.size()) return corrupt("move_buffer: misses a moved shape");
  for (size_t i = 0; i < s.bodies.size(); ++i) FULCRUM_RETURN_IF_ERROR(check_body(s, i));
  for (size_t i = 0; i < s.shapes.size(); ++i) FULCRUM_RETURN_IF_ERROR(check_shape(s, i));
  // Every live shape and joint must be listed by its bodies exactly as often as it names them.
  size_t listed_shapes = 0, listed_joints = 0, live_shapes = 0, live_joints = 0;
  for (const Body& b : s.bodies) {
    listed_shapes += b.shapes.size();
    listed_joints += b.joints.size();
  }
  for (const Shape& sh : s.shapes) live_shapes += sh.alive ? 1 : 0;
  for (const Joint& j : s.joints) live_joints += j.alive ? 1 : 0;
  if (listed_shapes != live_shapes) return corrupt("bodies: shape lists miss or repeat shapes");
  if (listed_joints != 2 * live_joints) {
    return corrupt("bodies: joint lists miss or repeat joints");
  }
  for (size_t i = 0; i < s.contacts.size(); ++i) FULCRUM_RETURN_IF_ERROR(check_contact(s, i));
  FULCRUM_RETURN_IF_ERROR(check_contact_lists(s));
  for (size_t i = 0; i < s.joints.size(); ++i) FULCRUM_RETURN_IF_ERROR(check_joint(s, i));
  for (size_t i = 0; i < s.attractors.size(); ++i) {
    Status ok = validate_attractor(s.attractors[i], "attractors[" + std::to_string(i) + "]");
    if (!ok.ok()) return corrupt(ok.message());
  }
  return {};
}

}  // namespace

Status World::restore(const WorldSnapshot& s) {
  FULCRUM_RETURN_IF_ERROR(check_snapshot(s));
  auto fresh = std::make_unique<WorldImpl>(s.settings);
  WorldImpl& w = *fresh;
  w.tick = s.tick;
  w.step_stamp = s.step_stamp;
  w.bodies.assign(s.bodies.begin(), s.bodies.end());
  w.free_bodies = s.free_bodies;
  w.shapes.assign(s.shapes.begin(), s.shapes.end());
  w.free_shapes = s.free_shapes;
  w.contacts.assign(s.contacts.begin(), s.contacts.end());
  w.manifold_caches.assign(s.manifold_caches.begin(), s.manifold_caches.end());
  w.free_contacts = s.free_contacts;
  for (size_t ci = 0; ci < w.contacts.size(); ++ci) {
    const Contact& c = w.contacts[ci];
    if (c.alive) w.contact_pairs.insert(pair_key(c.shape_a, c.shape_b));
  }
  w.joints.assign(s.joints.begin(), s.joints.end());
  w.free_joints = s.free_joints;
  w.joint_heads.clear();
  for (size_t ji = 0; ji < w.joints.size(); ++ji) w.note_joint(static_cast<int>(ji));
  w.breakable_joints = false;
  for (const Joint& j : w.joints)
    w.breakable_joints = w.breakable_joints || (j.alive && may_break(j));
  w.pending_joint_events = s.pending_joint_events;
  w.awake_bodies = s.awake_bodies;
  w.move_buffer = s.move_buffer;
  w.attractors = s.attractors;
  w.body_count = 0;
  w.kinematic_bodies = 0;
  for (const Body& b : w.bodies) {
    w.body_count += b.alive ? 1 : 0;
    w.kinematic_bodies += b.alive && b.type == BodyType::kKinematic ? 1 : 0;
  }
  w.shape_count = 0;
  for (const Shape& sh : w.shapes) w.shape_count += sh.alive ? 1 : 0;
  // The mass sums are derived: recomputed here, then the body's recorded mass fields are kept
  // (they went into the recorded hash and are checked against it below).
  w.mass_sums.assign(w.bodies.size(), WorldImpl::MassSums{});
  for (size_t bi = 0; bi < w.bodies.size(); ++bi) {
    if (!w.bodies[bi].alive) continue;
    WorldImpl::MassSums& sums = w.mass_sums[bi];
    for (int si : w.bodies[bi].shapes) WorldImpl::add_mass_terms(sums, w.shapes[si]);
  }
  // The tree's shape never reaches the results (pairs and query hits are sorted), only the
  // boxes do, so inserting in id order is enough.
  w.fat_boxes.assign(s.shape_boxes.begin(), s.shape_boxes.end());
  w.awake_boxes.resize(s.shape_boxes.size());
  for (size_t si = 0; si < w.shapes.size(); ++si) {
    Shape& sh = w.shapes[si];
    sh.proxy = sh.alive ? w.tree_of(sh).create_proxy(s.shape_boxes[si], si, sh.filter.category_bits,
                                                     sh.filter.mask_bits)
                        : kNullIndex;
    if (sh.alive) w.derive_shape(static_cast<int>(si));
  }
  std::unique_ptr<WorldImpl> previous = std::move(impl_);
  impl_ = std::move(fresh);
  if (uint64_t got = state_hash(); got != s.state_hash) {
    impl_ = std::move(previous);
    return corrupt("the restored state does not hash to the recorded state_hash (got " +
                   World::hash_text(got) + ", recorded " + World::hash_text(s.state_hash) + ")");
  }
  return {};
}

void World::copy_state(const World& other) {
  if (this == &other) return;
  // Copy-assignment reuses this world's allocations. The pool pointer is set by each step.
  *impl_ = *other.impl_;
  impl_->pool = nullptr;
  impl_->edit_work = 0;  // counted since the world was built or restored, as after restore
}

}  // namespace fulcrum
