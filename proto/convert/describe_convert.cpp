// Reads the world's records (World::snapshot, fulcrum/state.h): they hold every definition
// field exactly as the engine keeps it, local joint anchors included, which the handle
// accessors of world.h do not report. The copy costs what GetSnapshot costs, and a viewer asks
// for a description only when bodies appear. Shapes are written whole (every field present,
// polygons as vertices) rather than in the short form scene files use: a viewer should not need
// to know the defaults or rebuild a box.
#include "describe_convert.h"

#include <variant>

#include "fulcrum/state.h"

namespace fulcrum {

namespace {

void vec(const Vec2& v, v1::Vec2* out) {
  out->set_x(v.x());
  out->set_y(v.y());
}

template <typename Id>
void handle(const Id& id, v1::Handle* out) {
  out->set_index(id.index);
  out->set_generation(id.generation);
}

void geometry(const Geometry& g, v1::Shape* out) {
  if (const auto* c = std::get_if<Circle>(&g)) {
    vec(c->center, out->mutable_circle()->mutable_center());
    out->mutable_circle()->set_radius(c->radius);
  } else if (const auto* cap = std::get_if<Capsule>(&g)) {
    v1::Capsule* m = out->mutable_capsule();
    vec(cap->center1, m->mutable_center1());
    vec(cap->center2, m->mutable_center2());
    m->set_radius(cap->radius);
  } else if (const auto* s = std::get_if<Segment>(&g)) {
    vec(s->point1, out->mutable_segment()->mutable_point1());
    vec(s->point2, out->mutable_segment()->mutable_point2());
  } else if (const auto* p = std::get_if<Polygon>(&g)) {
    v1::Polygon* m = out->mutable_polygon();
    for (int i = 0; i < p->count; ++i) vec(p->vertices[i], m->add_vertices());
    m->set_radius(p->radius);
  }
}

void shape(const Shape& s, v1::Shape* out) {
  geometry(s.geometry, out);
  out->set_density(s.density);
  out->set_friction(s.friction);
  out->set_restitution(s.restitution);
  v1::Filter* f = out->mutable_filter();
  f->set_category_bits(s.filter.category_bits);
  f->set_mask_bits(s.filter.mask_bits);
  f->set_group_index(s.filter.group_index);
  out->set_is_sensor(s.is_sensor);
  out->set_user_data(s.user_data);
}

void body(const WorldSnapshot& w, int index, v1::DescribedBody* out) {
  const Body& s = w.bodies[index];
  handle(BodyId{index, s.generation}, out->mutable_handle());
  v1::Body* b = out->mutable_body();
  b->set_type(static_cast<v1::BodyType>(s.type));
  vec(s.xf.p, b->mutable_position());
  b->set_angle(s.xf.q.angle());
  // A scene gives the velocity of the body origin; the engine keeps the centre of mass's:
  // v_origin = v_center + w x (origin - center).
  const Vec2 r = s.xf.p - s.center;
  vec(s.v + Vec2(-s.w * r.y(), s.w * r.x()), b->mutable_linear_velocity());
  b->set_angular_velocity(s.w);
  b->set_linear_damping(s.linear_damping);
  b->set_angular_damping(s.angular_damping);
  b->set_gravity_scale(s.gravity_scale);
  b->set_drag(s.drag);
  b->set_fixed_rotation(s.fixed_rotation);
  b->set_awake(s.awake);
  b->set_enable_sleep(s.enable_sleep);
  b->set_user_data(s.user_data);
  for (int si : s.shapes) {
    shape(w.shapes[si], b->add_shapes());
    handle(ShapeId{si, w.shapes[si].generation}, out->add_shapes());
  }
  out->set_mass(s.is_dynamic() ? s.mass : 0.0);
  vec(s.center, out->mutable_center());
}

}  // namespace

void describe_world_to_proto(const World& world, v1::DescribeWorldReply* out) {
  const WorldSnapshot w = world.snapshot();
  out->set_tick(w.tick);
  out->set_state_hash(w.state_hash);
  for (int i = 0; i < static_cast<int>(w.bodies.size()); ++i) {
    if (w.bodies[i].alive) body(w, i, out->add_bodies());
  }
  for (int i = 0; i < static_cast<int>(w.joints.size()); ++i) {
    const Joint& j = w.joints[i];
    if (!j.alive) continue;
    const JointId id{i, j.generation};
    v1::DescribedJoint* d = out->add_joints();
    handle(id, d->mutable_handle());
    d->set_type(static_cast<v1::JointType>(j.type));
    handle(BodyId{j.body_a, w.bodies[j.body_a].generation}, d->mutable_body_a());
    handle(BodyId{j.body_b, w.bodies[j.body_b].generation}, d->mutable_body_b());
    vec(j.local_a, d->mutable_local_anchor_a());
    vec(j.local_b, d->mutable_local_anchor_b());
    // World anchors as the engine reports them (the target of a target joint, the closest
    // point on a curve).
    Result<JointState> state = world.joint_state(id);
    if (state.ok()) {
      vec(state->anchor_a, d->mutable_anchor_a());
      vec(state->anchor_b, d->mutable_anchor_b());
    }
    d->set_collide_connected(j.collide_connected);
  }
}

}  // namespace fulcrum
