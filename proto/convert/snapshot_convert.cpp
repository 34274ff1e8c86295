// Snapshot conversion: engine records <-> proto messages, field by field and bit for bit.
#include "snapshot_convert.h"

#include "fulcrum/fingerprint.h"

#include <google/protobuf/descriptor.h>

#include <cstring>
#include <variant>

#include "scene_convert.h"

namespace fulcrum {

namespace {

void put(const Vec2& v, v1::Vec2* out) {
  out->set_x(v.x());
  out->set_y(v.y());
}
Vec2 get(const v1::Vec2& v) {
  return Vec2(v.x(), v.y());
}

void body_to_proto(const Body& b, v1::SnapshotBody* out) {
  out->set_alive(b.alive);
  out->set_generation(b.generation);
  if (!b.alive) return;
  out->set_type(static_cast<v1::BodyType>(b.type));
  put(b.xf.p, out->mutable_position());
  out->set_rotation_c(b.xf.q.c);
  out->set_rotation_s(b.xf.q.s);
  put(b.local_center, out->mutable_local_center());
  put(b.center, out->mutable_center());
  put(b.v, out->mutable_linear_velocity());
  out->set_angular_velocity(b.w);
  put(b.force, out->mutable_force());
  out->set_torque(b.torque);
  put(b.constant_force, out->mutable_constant_force());
  out->set_constant_torque(b.constant_torque);
  out->set_mass(b.mass);
  out->set_inv_mass(b.inv_mass);
  out->set_inertia(b.inertia);
  out->set_inv_inertia(b.inv_inertia);
  out->set_linear_damping(b.linear_damping);
  out->set_angular_damping(b.angular_damping);
  out->set_gravity_scale(b.gravity_scale);
  out->set_drag(b.drag);
  out->set_fixed_rotation(b.fixed_rotation);
  out->set_awake(b.awake);
  out->set_enable_sleep(b.enable_sleep);
  out->set_sleep_time(b.sleep_time);
  out->set_user_data(b.user_data);
  for (int si : b.shapes) out->add_shapes(si);
  for (int ji : b.joints) out->add_joints(ji);
  out->set_contact_list(b.contact_list);
  out->set_contact_count(b.contact_count);
}

Body body_from_proto(const v1::SnapshotBody& p) {
  Body b;
  b.alive = p.alive();
  b.generation = p.generation();
  if (!b.alive) return b;
  b.type = static_cast<BodyType>(p.type());
  b.xf.p = get(p.position());
  b.xf.q = Rot{p.rotation_c(), p.rotation_s()};
  b.local_center = get(p.local_center());
  b.center = get(p.center());
  b.v = get(p.linear_velocity());
  b.w = p.angular_velocity();
  b.force = get(p.force());
  b.torque = p.torque();
  b.constant_force = get(p.constant_force());
  b.constant_torque = p.constant_torque();
  b.mass = p.mass();
  b.inv_mass = p.inv_mass();
  b.inertia = p.inertia();
  b.inv_inertia = p.inv_inertia();
  b.linear_damping = p.linear_damping();
  b.angular_damping = p.angular_damping();
  b.gravity_scale = p.gravity_scale();
  b.drag = p.drag();
  b.fixed_rotation = p.fixed_rotation();
  b.awake = p.awake();
  b.enable_sleep = p.enable_sleep();
  b.sleep_time = p.sleep_time();
  b.user_data = p.user_data();
  b.shapes.assign(p.shapes().begin(), p.shapes().end());
  b.joints.assign(p.joints().begin(), p.joints().end());
  b.contact_list = p.contact_list();
  b.contact_count = p.contact_count();
  return b;
}

void shape_to_proto(const Shape& s, const AABB& box, v1::SnapshotShape* out) {
  out->set_alive(s.alive);
  out->set_generation(s.generation);
  if (!s.alive) return;
  out->set_body(s.body);
  if (const auto* c = std::get_if<Circle>(&s.geometry)) {
    put(c->center, out->mutable_circle()->mutable_center());
    out->mutable_circle()->set_radius(c->radius);
  } else if (const auto* k = std::get_if<Capsule>(&s.geometry)) {
    put(k->center1, out->mutable_capsule()->mutable_center1());
    put(k->center2, out->mutable_capsule()->mutable_center2());
    out->mutable_capsule()->set_radius(k->radius);
  } else if (const auto* g = std::get_if<Segment>(&s.geometry)) {
    put(g->point1, out->mutable_segment()->mutable_point1());
    put(g->point2, out->mutable_segment()->mutable_point2());
  } else if (const auto* poly = std::get_if<Polygon>(&s.geometry)) {
    v1::SnapshotPolygon* p = out->mutable_polygon();
    for (int i = 0; i < poly->count; ++i) {
      put(poly->vertices[i], p->add_vertices());
      put(poly->normals[i], p->add_normals());
    }
    put(poly->centroid, p->mutable_centroid());
    p->set_radius(poly->radius);
  }
  out->set_density(s.density);
  out->set_friction(s.friction);
  out->set_restitution(s.restitution);
  scene_filter_to_proto(s.filter, out->mutable_filter());
  // Every filter field written, so that a default filter reads back the same.
  out->mutable_filter()->set_category_bits(s.filter.category_bits);
  out->mutable_filter()->set_mask_bits(s.filter.mask_bits);
  out->mutable_filter()->set_group_index(s.filter.group_index);
  out->set_is_sensor(s.is_sensor);
  out->set_user_data(s.user_data);
  put(box.lower, out->mutable_box_lower());
  put(box.upper, out->mutable_box_upper());
}

Status shape_from_proto(const v1::SnapshotShape& p, const std::string& path, Shape* s, AABB* box) {
  s->alive = p.alive();
  s->generation = p.generation();
  if (!s->alive) return {};
  s->body = p.body();
  switch (p.geometry_case()) {
    case v1::SnapshotShape::kCircle:
      s->geometry = Circle{get(p.circle().center()), p.circle().radius()};
      break;
    case v1::SnapshotShape::kCapsule:
      s->geometry =
          Capsule{get(p.capsule().center1()), get(p.capsule().center2()), p.capsule().radius()};
      break;
    case v1::SnapshotShape::kSegment:
      s->geometry = Segment{get(p.segment().point1()), get(p.segment().point2())};
      break;
    case v1::SnapshotShape::kPolygon: {
      const v1::SnapshotPolygon& pp = p.polygon();
      const int n = pp.vertices_size();
      if (n < 3 || n > kMaxPolygonVertices || pp.normals_size() != n) {
        return data_loss("snapshot: " + path + ".polygon: needs 3 to " +
                         std::to_string(kMaxPolygonVertices) + " vertices and one normal each");
      }
      Polygon poly;
      poly.count = n;
      for (int i = 0; i < n; ++i) {
        poly.vertices[i] = get(pp.vertices(i));
        poly.normals[i] = get(pp.normals(i));
      }
      poly.centroid = get(pp.centroid());
      poly.radius = pp.radius();
      s->geometry = poly;
      break;
    }
    default:
      return data_loss("snapshot: " + path + ": a live shape needs a geometry");
  }
  s->density = p.density();
  s->friction = p.friction();
  s->restitution = p.restitution();
  s->filter = Filter{p.filter().category_bits(), p.filter().mask_bits(), p.filter().group_index()};
  s->is_sensor = p.is_sensor();
  s->user_data = p.user_data();
  *box = AABB{get(p.box_lower()), get(p.box_upper())};
  return {};
}

void contact_to_proto(const Contact& c, const ManifoldCache& kept, v1::SnapshotContact* out) {
  out->set_alive(c.alive);
  if (!c.alive) return;
  out->set_touching(c.touching);
  out->set_sensor(c.sensor);
  out->set_shape_a(c.shape_a);
  out->set_shape_b(c.shape_b);
  out->set_body_a(c.body_a);
  out->set_body_b(c.body_b);
  out->set_friction(c.friction);
  out->set_restitution(c.restitution);
  put(c.manifold.normal, out->mutable_normal());
  for (int i = 0; i < c.manifold.count; ++i) {
    const ManifoldPoint& mp = c.manifold.points[i];
    v1::SnapshotContactPoint* p = out->add_points();
    put(mp.point, p->mutable_point());
    p->set_separation(mp.separation);
    p->set_id(mp.id);
    p->set_normal_impulse(mp.normal_impulse);
    p->set_tangent_impulse(mp.tangent_impulse);
    p->set_persisted(mp.persisted);
  }
  out->set_edge_a_prev(c.edges[0].prev);
  out->set_edge_a_next(c.edges[0].next);
  out->set_edge_b_prev(c.edges[1].prev);
  out->set_edge_b_next(c.edges[1].next);
  out->set_stamp(c.stamp);
  if (kept.valid) {
    v1::SnapshotManifoldCache* k = out->mutable_cache();
    put(kept.pose.p, k->mutable_pose_position());
    k->set_pose_cos(kept.pose.q.c);
    k->set_pose_sin(kept.pose.q.s);
    k->set_normal_on_b(kept.normal_on_b);
    put(kept.normal, k->mutable_normal());
    for (int i = 0; i < c.manifold.count; ++i) {
      put(kept.points[i], k->add_points());
      k->add_separations(kept.separations[i]);
    }
  }
}

Status contact_from_proto(const v1::SnapshotContact& p, const std::string& path, Contact* c,
                          ManifoldCache* kept) {
  c->alive = p.alive();
  if (!c->alive) return {};
  c->touching = p.touching();
  c->sensor = p.sensor();
  c->shape_a = p.shape_a();
  c->shape_b = p.shape_b();
  c->body_a = p.body_a();
  c->body_b = p.body_b();
  c->friction = p.friction();
  c->restitution = p.restitution();
  c->manifold.normal = get(p.normal());
  if (p.points_size() > 2) return data_loss("snapshot: " + path + ".points: more than 2");
  c->manifold.count = p.points_size();
  for (int i = 0; i < p.points_size(); ++i) {
    const v1::SnapshotContactPoint& pp = p.points(i);
    ManifoldPoint& mp = c->manifold.points[i];
    mp.point = get(pp.point());
    mp.separation = pp.separation();
    mp.id = pp.id();
    mp.normal_impulse = pp.normal_impulse();
    mp.tangent_impulse = pp.tangent_impulse();
    mp.persisted = pp.persisted();
  }
  c->edges[0] = ContactEdge{p.edge_a_prev(), p.edge_a_next()};
  c->edges[1] = ContactEdge{p.edge_b_prev(), p.edge_b_next()};
  c->stamp = p.stamp();
  *kept = ManifoldCache{};
  if (p.has_cache()) {
    const v1::SnapshotManifoldCache& k = p.cache();
    if (k.points_size() != c->manifold.count || k.separations_size() != c->manifold.count) {
      return data_loss("snapshot: " + path + ".cache: " + std::to_string(k.points_size()) +
                       " points and " + std::to_string(k.separations_size()) +
                       " separations for a manifold of " + std::to_string(c->manifold.count));
    }
    kept->valid = true;
    kept->pose.p = get(k.pose_position());
    kept->pose.q = Rot{k.pose_cos(), k.pose_sin()};
    kept->normal_on_b = k.normal_on_b();
    kept->normal = get(k.normal());
    for (int i = 0; i < c->manifold.count; ++i) {
      kept->points[i] = get(k.points(i));
      kept->separations[i] = k.separations(i);
    }
  }
  return {};
}

void joint_to_proto(const Joint& j, v1::SnapshotJoint* out) {
  out->set_alive(j.alive);
  out->set_generation(j.generation);
  if (!j.alive) return;
  out->set_type(static_cast<uint32_t>(j.type));
  out->set_body_a(j.body_a);
  out->set_body_b(j.body_b);
  out->set_collide_connected(j.collide_connected);
  put(j.local_a, out->mutable_local_a());
  put(j.local_b, out->mutable_local_b());
  out->set_length(j.length);
  out->set_min_length(j.min_length);
  out->set_max_length(j.max_length);
  out->set_reference_angle(j.reference_angle);
  out->set_enable_limit(j.enable_limit);
  out->set_enable_motor(j.enable_motor);
  out->set_enable_spring(j.enable_spring);
  out->set_lower_angle(j.lower_angle);
  out->set_upper_angle(j.upper_angle);
  out->set_motor_speed(j.motor_speed);
  out->set_max_motor_torque(j.max_motor_torque);
  out->set_target_angle(j.target_angle);
  out->set_hertz(j.hertz);
  out->set_damping_ratio(j.damping_ratio);
  out->set_angular_hertz(j.angular_hertz);
  out->set_angular_damping_ratio(j.angular_damping_ratio);
  put(j.local_axis, out->mutable_local_axis());
  out->set_max_motor_force(j.max_motor_force);
  put(j.target, out->mutable_target());
  out->set_max_force(j.max_force);
  out->set_break_force(j.break_force);
  out->set_break_torque(j.break_torque);
  put(j.linear_impulse, out->mutable_linear_impulse());
  out->set_axial_impulse(j.axial_impulse);
  out->set_lower_impulse(j.lower_impulse);
  out->set_upper_impulse(j.upper_impulse);
  out->set_motor_impulse(j.motor_impulse);
  out->set_spring_impulse(j.spring_impulse);
  out->set_target_translation(j.target_translation);
  out->set_correction_factor(j.correction_factor);
  out->set_curve_type(static_cast<uint32_t>(j.curve_type));
  for (const Vec2& p : j.curve_points) put(p, out->add_curve_points());
  out->set_curve_radius(j.curve_radius);
  out->set_stiffness(j.stiffness);
  out->set_damping(j.damping);
}

Joint joint_from_proto(const v1::SnapshotJoint& p) {
  Joint j;
  j.alive = p.alive();
  j.generation = p.generation();
  if (!j.alive) return j;
  // Out-of-range types are caught by World::restore's check.
  j.type = static_cast<JointType>(std::min<uint32_t>(p.type(), 255));
  j.body_a = p.body_a();
  j.body_b = p.body_b();
  j.collide_connected = p.collide_connected();
  j.local_a = get(p.local_a());
  j.local_b = get(p.local_b());
  j.length = p.length();
  j.min_length = p.min_length();
  j.max_length = p.max_length();
  j.reference_angle = p.reference_angle();
  j.enable_limit = p.enable_limit();
  j.enable_motor = p.enable_motor();
  j.enable_spring = p.enable_spring();
  j.lower_angle = p.lower_angle();
  j.upper_angle = p.upper_angle();
  j.motor_speed = p.motor_speed();
  j.max_motor_torque = p.max_motor_torque();
  j.target_angle = p.target_angle();
  j.hertz = p.hertz();
  j.damping_ratio = p.damping_ratio();
  j.angular_hertz = p.angular_hertz();
  j.angular_damping_ratio = p.angular_damping_ratio();
  j.local_axis = get(p.local_axis());
  j.max_motor_force = p.max_motor_force();
  j.target = get(p.target());
  j.max_force = p.max_force();
  j.break_force = p.break_force();
  j.break_torque = p.break_torque();
  j.linear_impulse = get(p.linear_impulse());
  j.axial_impulse = p.axial_impulse();
  j.lower_impulse = p.lower_impulse();
  j.upper_impulse = p.upper_impulse();
  j.motor_impulse = p.motor_impulse();
  j.spring_impulse = p.spring_impulse();
  j.target_translation = p.target_translation();
  j.correction_factor = p.correction_factor();
  // Out-of-range curve types are caught by World::restore's check.
  j.curve_type = static_cast<CurveType>(std::min<uint32_t>(p.curve_type(), 255));
  for (const v1::Vec2& v : p.curve_points()) j.curve_points.push_back(get(v));
  j.curve_radius = p.curve_radius();
  j.stiffness = p.stiffness();
  j.damping = p.damping();
  return j;
}

template <typename List>
std::vector<int> ints(const List& list) {
  return std::vector<int>(list.begin(), list.end());
}

}  // namespace

uint64_t fnv1a64(std::string_view bytes) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

v1::Snapshot snapshot_to_proto(const WorldSnapshot& s) {
  v1::Snapshot out;
  world_settings_to_proto(s.settings, out.mutable_settings());
  out.set_tick(s.tick);
  out.set_step_stamp(s.step_stamp);
  for (const Body& b : s.bodies) body_to_proto(b, out.add_bodies());
  for (int i : s.free_bodies) out.add_free_bodies(i);
  for (size_t i = 0; i < s.shapes.size(); ++i) {
    shape_to_proto(s.shapes[i], s.shape_boxes[i], out.add_shapes());
  }
  for (int i : s.free_shapes) out.add_free_shapes(i);
  for (size_t i = 0; i < s.contacts.size(); ++i) {
    contact_to_proto(s.contacts[i], s.manifold_caches[i], out.add_contacts());
  }
  for (int i : s.free_contacts) out.add_free_contacts(i);
  for (const Joint& j : s.joints) joint_to_proto(j, out.add_joints());
  for (int i : s.free_joints) out.add_free_joints(i);
  for (const JointId& id : s.pending_joint_events) {
    v1::Handle* h = out.add_pending_joint_events();
    h->set_index(id.index);
    h->set_generation(id.generation);
  }
  for (int i : s.awake_bodies) out.add_awake_bodies(i);
  for (int i : s.move_buffer) out.add_move_buffer(i);
  for (const AttractorDef& a : s.attractors) scene_attractor_to_proto(a, out.add_attractors());
  out.set_state_hash(s.state_hash);
  return out;
}

Result<WorldSnapshot> snapshot_from_proto(const v1::Snapshot& p) {
  WorldSnapshot s;
  // Absent settings fields would silently take defaults: a snapshot writes every one.
  const v1::WorldSettings& ps = p.settings();
  if (!p.has_settings() || !ps.has_dt() || !ps.has_substeps() || !ps.has_time_to_sleep()) {
    return data_loss("snapshot: settings: every field must be present");
  }
  Status settings = world_settings_from_proto(ps, "settings", &s.settings);
  if (!settings.ok()) return data_loss("snapshot: " + settings.message());
  s.tick = p.tick();
  s.step_stamp = p.step_stamp();
  s.bodies.reserve(p.bodies_size());
  for (const v1::SnapshotBody& b : p.bodies()) {
    if (!v1::BodyType_IsValid(b.type())) {
      return data_loss("snapshot: bodies[" + std::to_string(s.bodies.size()) +
                       "].type: unknown body type " + std::to_string(b.type()));
    }
    s.bodies.push_back(body_from_proto(b));
  }
  s.free_bodies = ints(p.free_bodies());
  s.shapes.resize(p.shapes_size());
  s.shape_boxes.resize(p.shapes_size());
  for (int i = 0; i < p.shapes_size(); ++i) {
    Status st = shape_from_proto(p.shapes(i), "shapes[" + std::to_string(i) + "]", &s.shapes[i],
                                 &s.shape_boxes[i]);
    if (!st.ok()) return st;
  }
  s.free_shapes = ints(p.free_shapes());
  s.contacts.resize(p.contacts_size());
  s.manifold_caches.resize(p.contacts_size());
  for (int i = 0; i < p.contacts_size(); ++i) {
    Status st = contact_from_proto(p.contacts(i), "contacts[" + std::to_string(i) + "]",
                                   &s.contacts[i], &s.manifold_caches[i]);
    if (!st.ok()) return st;
  }
  s.free_contacts = ints(p.free_contacts());
  s.joints.reserve(p.joints_size());
  for (const v1::SnapshotJoint& j : p.joints()) s.joints.push_back(joint_from_proto(j));
  s.free_joints = ints(p.free_joints());
  for (const v1::Handle& h : p.pending_joint_events()) {
    s.pending_joint_events.push_back(JointId{h.index(), h.generation()});
  }
  s.awake_bodies = ints(p.awake_bodies());
  s.move_buffer = ints(p.move_buffer());
  // Derived from the lists; indices out of range are left for World::restore to refuse.
  for (size_t k = 0; k < s.awake_bodies.size(); ++k) {
    int bi = s.awake_bodies[k];
    if (bi >= 0 && static_cast<size_t>(bi) < s.bodies.size()) {
      s.bodies[bi].awake_slot = static_cast<int>(k);
    }
  }
  for (int si : s.move_buffer) {
    if (si >= 0 && static_cast<size_t>(si) < s.shapes.size()) s.shapes[si].in_move_buffer = true;
  }
  for (int i = 0; i < p.attractors_size(); ++i) {
    AttractorDef a;
    Status st =
        scene_attractor_from_proto(p.attractors(i), "attractors[" + std::to_string(i) + "]", &a);
    if (!st.ok()) return data_loss("snapshot: " + st.message());
    s.attractors.push_back(a);
  }
  s.state_hash = p.state_hash();
  return s;
}

v1::SnapshotFile wrap_snapshot(const v1::Snapshot& snapshot) {
  v1::SnapshotFile file;
  file.set_format(kSnapshotFormat);
  file.set_version(kSnapshotVersion);
  file.set_writer(kWriterName);
  file.set_fingerprint(kDeterminismFingerprint);
  snapshot.SerializeToString(file.mutable_payload());
  file.set_checksum(fnv1a64(file.payload()));
  return file;
}

// Messages name the SnapshotFile field at fault ("snapshot.version"); those about the payload's
// content (snapshot_from_proto) start "snapshot: " and name the place inside it.
Result<v1::Snapshot> unwrap_snapshot(const v1::SnapshotFile& file) {
  if (file.format().empty()) return data_loss("snapshot.format: empty: not a snapshot");
  if (file.format() != kSnapshotFormat) {
    return Status(StatusCode::kFailedPrecondition, "snapshot.format: \"" + file.format() +
                                                       "\", expected \"" + kSnapshotFormat + "\"");
  }
  if (file.version() != kSnapshotVersion) {
    return Status(StatusCode::kFailedPrecondition,
                  "snapshot.version: " + std::to_string(file.version()) + " (written by \"" +
                      file.writer() + "\"); this build reads version " +
                      std::to_string(kSnapshotVersion));
  }
  if (fnv1a64(file.payload()) != file.checksum()) {
    return data_loss(
        "snapshot.checksum: does not match the payload (checksum mismatch: the data "
        "is damaged)");
  }
  v1::Snapshot snapshot;
  if (!snapshot.ParseFromString(file.payload())) {
    return data_loss("snapshot.payload: does not parse");
  }
  return snapshot;
}

std::string encode_snapshot(const World& world) {
  return wrap_snapshot(snapshot_to_proto(world.snapshot())).SerializeAsString();
}

Status restore_encoded(World* world, std::string_view bytes) {
  v1::SnapshotFile file;
  if (!file.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    return data_loss("snapshot: not a snapshot file, or truncated (" +
                     std::to_string(bytes.size()) + " bytes)");
  }
  Result<v1::Snapshot> snapshot = unwrap_snapshot(file);
  if (!snapshot.ok()) return snapshot.status();
  Result<WorldSnapshot> records = snapshot_from_proto(*snapshot);
  if (!records.ok()) return records.status();
  return world->restore(*records);
}

// --- Deltas ---------------------------------------------------------------------------------

namespace {

// A body record without the fields a moving body changes: equal definitions compare equal.
std::string body_definition(v1::SnapshotBody b) {
  b.clear_position();
  b.clear_rotation_c();
  b.clear_rotation_s();
  b.clear_center();
  b.clear_linear_velocity();
  b.clear_angular_velocity();
  b.clear_force();
  b.clear_torque();
  b.clear_sleep_time();
  b.clear_awake();
  b.clear_contact_list();
  b.clear_contact_count();
  return b.SerializeAsString();
}

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// The body origin as the engine derives it from the centre of mass after every step.
Vec2 derived_position(const v1::SnapshotBody& b) {
  Rot q{b.rotation_c(), b.rotation_s()};
  return get(b.center()) - q.rotate(get(b.local_center()));
}

template <typename Records, typename Add>
void diff_records(const Records& base, const Records& next, Add add) {
  for (int i = 0; i < next.size(); ++i) {
    if (i >= base.size() || base[i].SerializeAsString() != next[i].SerializeAsString()) {
      add(i, next[i]);
    }
  }
}

template <typename A, typename B>
bool same_list(const A& a, const B& b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin());
}

bool same_attractors(const v1::Snapshot& a, const v1::Snapshot& b) {
  if (a.attractors_size() != b.attractors_size()) return false;
  for (int i = 0; i < a.attractors_size(); ++i) {
    if (a.attractors(i).SerializeAsString() != b.attractors(i).SerializeAsString()) return false;
  }
  return true;
}

}  // namespace

v1::SnapshotDelta make_delta(const v1::Snapshot& base, const v1::Snapshot& next) {
  v1::SnapshotDelta d;
  d.set_version(kSnapshotVersion);
  d.set_base_tick(base.tick());
  d.set_base_hash(base.state_hash());
  d.set_tick(next.tick());
  d.set_step_stamp(next.step_stamp());
  d.set_state_hash(next.state_hash());
  d.set_body_slots(next.bodies_size());
  d.set_shape_slots(next.shapes_size());
  d.set_contact_slots(next.contacts_size());
  d.set_joint_slots(next.joints_size());
  for (int i = 0; i < next.bodies_size(); ++i) {
    const v1::SnapshotBody& b = next.bodies(i);
    if (i < base.bodies_size()) {
      const v1::SnapshotBody& a = base.bodies(i);
      if (a.SerializeAsString() == b.SerializeAsString()) continue;
      if (a.alive() && b.alive() && a.generation() == b.generation() &&
          body_definition(a) == body_definition(b)) {
        v1::BodyMotion* m = d.add_moved();
        m->set_index(i);
        for (double x : {b.center().x(), b.center().y(), b.rotation_c(), b.rotation_s(),
                         b.linear_velocity().x(), b.linear_velocity().y(), b.angular_velocity()}) {
          m->add_state(x);
        }
        Vec2 p = derived_position(b);
        if (!same_bits(p.x(), b.position().x()) || !same_bits(p.y(), b.position().y())) {
          m->set_position_x(b.position().x());
          m->set_position_y(b.position().y());
        }
        if (!same_bits(a.sleep_time(), b.sleep_time())) m->set_sleep_time(b.sleep_time());
        if (!same_bits(a.force().x(), b.force().x())) m->set_force_x(b.force().x());
        if (!same_bits(a.force().y(), b.force().y())) m->set_force_y(b.force().y());
        if (!same_bits(a.torque(), b.torque())) m->set_torque(b.torque());
        if (a.awake() != b.awake()) m->set_awake(b.awake());
        if (a.contact_list() != b.contact_list()) m->set_contact_list(b.contact_list());
        if (a.contact_count() != b.contact_count()) m->set_contact_count(b.contact_count());
        continue;
      }
    }
    v1::IndexedBody* whole = d.add_bodies();
    whole->set_index(i);
    *whole->mutable_body() = b;
  }
  diff_records(base.shapes(), next.shapes(), [&](int i, const v1::SnapshotShape& s) {
    v1::IndexedShape* r = d.add_shapes();
    r->set_index(i);
    *r->mutable_shape() = s;
  });
  diff_records(base.contacts(), next.contacts(), [&](int i, const v1::SnapshotContact& c) {
    v1::IndexedContact* r = d.add_contacts();
    r->set_index(i);
    *r->mutable_contact() = c;
  });
  diff_records(base.joints(), next.joints(), [&](int i, const v1::SnapshotJoint& j) {
    v1::IndexedJoint* r = d.add_joints();
    r->set_index(i);
    *r->mutable_joint() = j;
  });
  bool lists_same = base.settings().SerializeAsString() == next.settings().SerializeAsString() &&
                    same_list(base.free_bodies(), next.free_bodies()) &&
                    same_list(base.free_shapes(), next.free_shapes()) &&
                    same_list(base.free_contacts(), next.free_contacts()) &&
                    same_list(base.free_joints(), next.free_joints()) &&
                    same_list(base.awake_bodies(), next.awake_bodies()) &&
                    same_list(base.move_buffer(), next.move_buffer()) &&
                    same_attractors(base, next) &&
                    base.pending_joint_events().size() == next.pending_joint_events().size();
  for (int i = 0; lists_same && i < next.pending_joint_events_size(); ++i) {
    lists_same = base.pending_joint_events(i).SerializeAsString() ==
                 next.pending_joint_events(i).SerializeAsString();
  }
  if (!lists_same) {
    v1::IndexLists* l = d.mutable_lists();
    *l->mutable_settings() = next.settings();
    *l->mutable_free_bodies() = next.free_bodies();
    *l->mutable_free_shapes() = next.free_shapes();
    *l->mutable_free_contacts() = next.free_contacts();
    *l->mutable_free_joints() = next.free_joints();
    *l->mutable_pending_joint_events() = next.pending_joint_events();
    *l->mutable_awake_bodies() = next.awake_bodies();
    *l->mutable_move_buffer() = next.move_buffer();
    *l->mutable_attractors() = next.attractors();
  }
  return d;
}

namespace {

// Grows or checks a pool to `slots` records (pools never shrink).
template <typename Records>
Status fit(const char* name, Records* records, uint32_t slots) {
  if (slots < static_cast<uint32_t>(records->size())) {
    return data_loss(std::string("snapshot delta: ") + name + " slots shrink below the base's");
  }
  while (static_cast<uint32_t>(records->size()) < slots) records->Add();
  return {};
}

template <typename Records, typename Entries, typename Get>
Status place(const char* name, Records* records, const Entries& entries, Get get) {
  for (const auto& e : entries) {
    if (e.index() < 0 || e.index() >= records->size()) {
      return data_loss(std::string("snapshot delta: ") + name + " index " +
                       std::to_string(e.index()) + " is out of range");
    }
    *records->Mutable(e.index()) = get(e);
  }
  return {};
}

}  // namespace

Result<v1::Snapshot> apply_delta(const v1::Snapshot& base, const v1::SnapshotDelta& d) {
  if (d.version() != kSnapshotVersion) {
    return Status(StatusCode::kFailedPrecondition,
                  "snapshot delta: version " + std::to_string(d.version()) +
                      "; this build reads version " + std::to_string(kSnapshotVersion));
  }
  if (d.base_tick() != base.tick() || d.base_hash() != base.state_hash()) {
    return Status(StatusCode::kFailedPrecondition,
                  "snapshot delta: made against the snapshot of tick " +
                      std::to_string(d.base_tick()) + ", not this one (tick " +
                      std::to_string(base.tick()) + ")");
  }
  v1::Snapshot s = base;
  s.set_tick(d.tick());
  s.set_step_stamp(d.step_stamp());
  s.set_state_hash(d.state_hash());
  FULCRUM_RETURN_IF_ERROR(fit("body", s.mutable_bodies(), d.body_slots()));
  FULCRUM_RETURN_IF_ERROR(fit("shape", s.mutable_shapes(), d.shape_slots()));
  FULCRUM_RETURN_IF_ERROR(fit("contact", s.mutable_contacts(), d.contact_slots()));
  FULCRUM_RETURN_IF_ERROR(fit("joint", s.mutable_joints(), d.joint_slots()));
  FULCRUM_RETURN_IF_ERROR(place("body", s.mutable_bodies(), d.bodies(),
                                [](const v1::IndexedBody& e) { return e.body(); }));
  FULCRUM_RETURN_IF_ERROR(place("shape", s.mutable_shapes(), d.shapes(),
                                [](const v1::IndexedShape& e) { return e.shape(); }));
  FULCRUM_RETURN_IF_ERROR(place("contact", s.mutable_contacts(), d.contacts(),
                                [](const v1::IndexedContact& e) { return e.contact(); }));
  FULCRUM_RETURN_IF_ERROR(place("joint", s.mutable_joints(), d.joints(),
                                [](const v1::IndexedJoint& e) { return e.joint(); }));
  for (const v1::BodyMotion& m : d.moved()) {
    if (m.index() < 0 || m.index() >= s.bodies_size() || m.state_size() != 7) {
      return data_loss("snapshot delta: moved body " + std::to_string(m.index()) +
                       " is out of range or has not 7 state values");
    }
    v1::SnapshotBody& b = *s.mutable_bodies(m.index());
    b.mutable_center()->set_x(m.state(0));
    b.mutable_center()->set_y(m.state(1));
    b.set_rotation_c(m.state(2));
    b.set_rotation_s(m.state(3));
    b.mutable_linear_velocity()->set_x(m.state(4));
    b.mutable_linear_velocity()->set_y(m.state(5));
    b.set_angular_velocity(m.state(6));
    Vec2 p = derived_position(b);
    b.mutable_position()->set_x(m.has_position_x() ? m.position_x() : p.x());
    b.mutable_position()->set_y(m.has_position_y() ? m.position_y() : p.y());
    if (m.has_sleep_time()) b.set_sleep_time(m.sleep_time());
    if (m.has_force_x()) b.mutable_force()->set_x(m.force_x());
    if (m.has_force_y()) b.mutable_force()->set_y(m.force_y());
    if (m.has_torque()) b.set_torque(m.torque());
    if (m.has_awake()) b.set_awake(m.awake());
    if (m.has_contact_list()) b.set_contact_list(m.contact_list());
    if (m.has_contact_count()) b.set_contact_count(m.contact_count());
  }
  if (d.has_lists()) {
    const v1::IndexLists& l = d.lists();
    *s.mutable_settings() = l.settings();
    *s.mutable_free_bodies() = l.free_bodies();
    *s.mutable_free_shapes() = l.free_shapes();
    *s.mutable_free_contacts() = l.free_contacts();
    *s.mutable_free_joints() = l.free_joints();
    *s.mutable_pending_joint_events() = l.pending_joint_events();
    *s.mutable_awake_bodies() = l.awake_bodies();
    *s.mutable_move_buffer() = l.move_buffer();
    *s.mutable_attractors() = l.attractors();
  }
  return s;
}

// --- Field-level comparison -------------------------------------------------------------------

namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::Reflection;

std::string value_text(const Message& m, const FieldDescriptor* f, int index) {
  const Reflection* r = m.GetReflection();
  char buf[40];
  auto num = [&](double x) {
    std::snprintf(buf, sizeof buf, "%.17g", x);
    return std::string(buf);
  };
  const bool rep = f->is_repeated();
  switch (f->cpp_type()) {
    case FieldDescriptor::CPPTYPE_DOUBLE:
      return num(rep ? r->GetRepeatedDouble(m, f, index) : r->GetDouble(m, f));
    case FieldDescriptor::CPPTYPE_FLOAT:
      return num(rep ? r->GetRepeatedFloat(m, f, index) : r->GetFloat(m, f));
    case FieldDescriptor::CPPTYPE_INT32:
      return std::to_string(rep ? r->GetRepeatedInt32(m, f, index) : r->GetInt32(m, f));
    case FieldDescriptor::CPPTYPE_INT64:
      return std::to_string(rep ? r->GetRepeatedInt64(m, f, index) : r->GetInt64(m, f));
    case FieldDescriptor::CPPTYPE_UINT32:
      return std::to_string(rep ? r->GetRepeatedUInt32(m, f, index) : r->GetUInt32(m, f));
    case FieldDescriptor::CPPTYPE_UINT64:
      return std::to_string(rep ? r->GetRepeatedUInt64(m, f, index) : r->GetUInt64(m, f));
    case FieldDescriptor::CPPTYPE_BOOL:
      return (rep ? r->GetRepeatedBool(m, f, index) : r->GetBool(m, f)) ? "true" : "false";
    case FieldDescriptor::CPPTYPE_ENUM:
      return std::to_string(rep ? r->GetRepeatedEnumValue(m, f, index) : r->GetEnumValue(m, f));
    case FieldDescriptor::CPPTYPE_STRING:
      return "\"" + (rep ? r->GetRepeatedString(m, f, index) : r->GetString(m, f)) + "\"";
    case FieldDescriptor::CPPTYPE_MESSAGE:
      return "(message)";
  }
  return "?";
}

std::string compare(const Message& a, const Message& b, const std::string& path);

std::string compare_field(const Message& a, const Message& b, const FieldDescriptor* f,
                          const std::string& path) {
  const Reflection* ra = a.GetReflection();
  const Reflection* rb = b.GetReflection();
  std::string name = path.empty() ? f->name() : path + "." + f->name();
  if (f->is_repeated()) {
    int na = ra->FieldSize(a, f), nb = rb->FieldSize(b, f);
    for (int i = 0; i < std::min(na, nb); ++i) {
      std::string item = name + "[" + std::to_string(i) + "]";
      if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE) {
        std::string d =
            compare(ra->GetRepeatedMessage(a, f, i), rb->GetRepeatedMessage(b, f, i), item);
        if (!d.empty()) return d;
      } else if (value_text(a, f, i) != value_text(b, f, i)) {
        return item + ": expected " + value_text(a, f, i) + ", got " + value_text(b, f, i);
      }
    }
    if (na != nb) {
      return name + ": expected " + std::to_string(na) + " entries, got " + std::to_string(nb);
    }
    return {};
  }
  if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE) {
    return compare(ra->GetMessage(a, f), rb->GetMessage(b, f), name);
  }
  if (f->cpp_type() == FieldDescriptor::CPPTYPE_DOUBLE) {
    double x = ra->GetDouble(a, f), y = rb->GetDouble(b, f);
    if (same_bits(x, y)) return {};
  } else if (value_text(a, f, 0) == value_text(b, f, 0)) {
    return {};
  }
  return name + ": expected " + value_text(a, f, 0) + ", got " + value_text(b, f, 0);
}

std::string compare(const Message& a, const Message& b, const std::string& path) {
  const google::protobuf::Descriptor* desc = a.GetDescriptor();
  for (int i = 0; i < desc->field_count(); ++i) {
    std::string d = compare_field(a, b, desc->field(i), path);
    if (!d.empty()) return d;
  }
  return {};
}

}  // namespace

std::string first_difference(const v1::Snapshot& expected, const v1::Snapshot& actual) {
  // Records first, in the order bodies, joints, contacts, shapes; then everything else.
  const google::protobuf::Descriptor* desc = v1::Snapshot::descriptor();
  for (const char* name : {"bodies", "joints", "contacts", "shapes"}) {
    std::string d = compare_field(expected, actual, desc->FindFieldByName(name), "");
    if (!d.empty()) return d;
  }
  return compare(expected, actual, "");
}

}  // namespace fulcrum
