#include "box2d_twin.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <variant>

namespace fulcrum::bench {

namespace {

b2Vec2 to_b2(const Vec2& v) {
  return b2Vec2(static_cast<float>(v.x()), static_cast<float>(v.y()));
}

b2BodyType to_b2(BodyType t) {
  switch (t) {
    case BodyType::kStatic:
      return b2_staticBody;
    case BodyType::kKinematic:
      return b2_kinematicBody;
    case BodyType::kDynamic:
    case BodyType::kParticle:
      break;
  }
  return b2_dynamicBody;
}

b2Filter to_b2(const Filter& f, TwinNotes* notes) {
  // 2.4.1 has 16-bit categories and masks and a 16-bit group. Masks only matter against
  // categories, so while every category fits in 16 bits a wider mask loses nothing.
  b2Filter out;
  out.categoryBits = static_cast<uint16>(f.category_bits & 0xFFFF);
  out.maskBits = static_cast<uint16>(f.mask_bits & 0xFFFF);
  out.groupIndex = static_cast<int16>(f.group_index);
  if ((f.category_bits >> 16) != 0 || f.group_index != out.groupIndex) ++notes->wide_filters;
  return out;
}

// The fixture settings every shape of one Fulcrum ShapeDef shares. Friction and restitution
// need no adjustment: 2.4.1 mixes them as Fulcrum does (sqrt(a * b) and max(a, b)).
b2FixtureDef fixture(double density, double friction, double restitution, float threshold,
                     const b2Filter& filter, bool sensor) {
  b2FixtureDef fd;
  fd.density = static_cast<float>(density);
  fd.friction = static_cast<float>(friction);
  fd.restitution = static_cast<float>(restitution);
  // Fulcrum's world-wide restitution threshold is per fixture in 2.4.1 (mixed as the max).
  fd.restitutionThreshold = threshold;
  fd.filter = filter;
  fd.isSensor = sensor;
  return fd;
}

void add_edge(b2Body* body, const Vec2& p1, const Vec2& p2, b2FixtureDef fd, TwinNotes* notes) {
  // Fulcrum segments (and chain links) are two-sided; 2.4.1's chain shapes are one-sided, so
  // every link becomes its own two-sided edge. Edges carry the polygon skin, which cannot be
  // taken off a line.
  b2EdgeShape edge;
  edge.SetTwoSided(to_b2(p1), to_b2(p2));
  fd.shape = &edge;
  fd.density = 0.0f;
  body->CreateFixture(&fd);
  ++notes->skinned_segments;
}

// Moves every edge of a convex polygon inward by `d` (outward when d < 0): vertex i, shared by
// edges i - 1 and i with unit normals n1 and n2, moves by -d (n1 + n2) / (1 + n1 . n2).
void inset(const Polygon& poly, double d, b2Vec2* out) {
  for (int i = 0; i < poly.count; ++i) {
    const Vec2& n1 = poly.normals[(i + poly.count - 1) % poly.count];
    const Vec2& n2 = poly.normals[i];
    Vec2 v = poly.vertices[i] - (d / (1.0 + dot(n1, n2))) * (n1 + n2);
    out[i] = to_b2(v);
  }
}

// The polygon's core width across its narrowest side: over the edges, the largest distance of
// a vertex behind the edge, the smallest of those.
double thinnest_width(const Polygon& poly) {
  double thinnest = 1e300;
  for (int i = 0; i < poly.count; ++i) {
    double deepest = 0.0;
    for (int j = 0; j < poly.count; ++j) {
      deepest = std::max(deepest, dot(poly.normals[i], poly.vertices[i] - poly.vertices[j]));
    }
    thinnest = std::min(thinnest, deepest);
  }
  return thinnest;
}

static_assert(kMaxPolygonVertices <= b2_maxPolygonVertices, "a Fulcrum polygon fits in Box2D's");

void add_polygon(b2Body* body, const Polygon& poly, b2FixtureDef fd, const TwinOptions& options,
                 TwinNotes* notes) {
  b2Vec2 pts[b2_maxPolygonVertices];
  const int n = poly.count;
  // Fulcrum's outline is the core grown by poly.radius; 2.4.1's is the core grown by its
  // skin. Insetting the core by the difference makes the outlines' sides agree.
  double d = options.compensate_skin ? b2_polygonRadius - poly.radius : 0.0;
  // 2.4.1 welds core vertices closer than half its linear slop, so a core must stay about a
  // slop thick: a polygon thinner than that plus twice the skin (0.025 m; HARD_CASES 20's 2 mm
  // planks) keeps a core b2_linearSlop thick, and its outline is thicker than Fulcrum's.
  const double width = thinnest_width(poly);
  const bool thin = width - 2.0 * d < b2_linearSlop;
  if (thin) d = 0.5 * (width - b2_linearSlop);
  if (d != 0.0) {
    inset(poly, d, pts);
    if (thin) {
      ++notes->thin_polygons;
    } else {
      ++(poly.radius > 0.0 ? notes->rounded_polygons : notes->inset_polygons);
    }
  } else {
    for (int i = 0; i < n; ++i) pts[i] = to_b2(poly.vertices[i]);
  }
  b2PolygonShape shape;
  shape.Set(pts, n);
  fd.shape = &shape;
  body->CreateFixture(&fd);
}

// 2.4.1 has no capsule: the same outline as a box over the core segment plus a circle at each
// end, all on this body (the mass is set separately). The box's sides are pulled in by the
// skin so that its outline is the capsule's.
void add_capsule(b2Body* body, const Capsule& cap, b2FixtureDef fd, const TwinOptions& options,
                 TwinNotes* notes) {
  for (const Vec2& c : {cap.center1, cap.center2}) {
    b2CircleShape circle;
    circle.m_p = to_b2(c);
    circle.m_radius = static_cast<float>(cap.radius);
    fd.shape = &circle;
    body->CreateFixture(&fd);
  }
  Vec2 axis = cap.center2 - cap.center1;
  double half_length = 0.5 * length(axis);
  double half_width = cap.radius - (options.compensate_skin ? b2_polygonRadius : 0.0);
  half_width = std::max(half_width, 0.5 * cap.radius);
  if (half_length > b2_linearSlop) {
    b2PolygonShape box;
    Vec2 mid = 0.5 * (cap.center1 + cap.center2);
    box.SetAsBox(static_cast<float>(half_length), static_cast<float>(half_width), to_b2(mid),
                 static_cast<float>(std::atan2(axis.y(), axis.x())));
    fd.shape = &box;
    body->CreateFixture(&fd);
  }
  ++notes->capsules;
}

void add_shape(b2Body* body, const ShapeDef& sd, float threshold, const TwinOptions& options,
               TwinNotes* notes) {
  b2FixtureDef fd = fixture(sd.density, sd.friction, sd.restitution, threshold,
                            to_b2(sd.filter, notes), sd.is_sensor);
  if (const auto* poly = std::get_if<Polygon>(&sd.geometry)) {
    add_polygon(body, *poly, fd, options, notes);
  } else if (const auto* circle = std::get_if<Circle>(&sd.geometry)) {
    b2CircleShape shape;
    shape.m_p = to_b2(circle->center);
    shape.m_radius = static_cast<float>(circle->radius);
    fd.shape = &shape;
    body->CreateFixture(&fd);
  } else if (const auto* seg = std::get_if<Segment>(&sd.geometry)) {
    add_edge(body, seg->point1, seg->point2, fd, notes);
  } else if (const auto* cap = std::get_if<Capsule>(&sd.geometry)) {
    add_capsule(body, *cap, fd, options, notes);
  }
}

// --- Joints: one overload per SceneJoint alternative --------------------------------------

template <class Def>
void set_common(Def* jd, b2Body* a, b2Body* b, bool collide_connected) {
  jd->bodyA = a;
  jd->bodyB = b;
  jd->collideConnected = collide_connected;
}

void create(b2World& w, b2Body* a, b2Body* b, const RevoluteJointDef& r, TwinNotes* notes) {
  b2RevoluteJointDef jd;
  set_common(&jd, a, b, r.collide_connected);
  jd.localAnchorA = to_b2(r.local_anchor_a);
  jd.localAnchorB = to_b2(r.local_anchor_b);
  jd.referenceAngle = static_cast<float>(r.reference_angle);
  jd.enableLimit = r.enable_limit;
  jd.lowerAngle = static_cast<float>(r.lower_angle);
  jd.upperAngle = static_cast<float>(r.upper_angle);
  // Joint friction (the ragdolls') is a motor with target speed 0 and a torque cap in both.
  jd.enableMotor = r.enable_motor;
  jd.motorSpeed = static_cast<float>(r.motor_speed);
  jd.maxMotorTorque = static_cast<float>(r.max_motor_torque);
  if (r.enable_spring && r.hertz > 0.0) ++notes->revolute_springs;
  w.CreateJoint(&jd);
}

void create(b2World& w, b2Body* a, b2Body* b, const DistanceJointDef& d, TwinNotes*) {
  // The same range semantics: rigid when min = max, a rope when min = 0, and inside the range
  // a spring toward `length` when it has one (2.4.1 takes stiffness and damping in N/m and
  // N s/m; b2LinearStiffness converts from frequency and ratio with the bodies' masses).
  b2DistanceJointDef jd;
  set_common(&jd, a, b, d.collide_connected);
  jd.localAnchorA = to_b2(d.local_anchor_a);
  jd.localAnchorB = to_b2(d.local_anchor_b);
  jd.length = static_cast<float>(d.length);
  jd.minLength = static_cast<float>(d.min_length);
  jd.maxLength = static_cast<float>(d.max_length);
  if (d.hertz > 0.0) {
    b2LinearStiffness(jd.stiffness, jd.damping, static_cast<float>(d.hertz),
                      static_cast<float>(d.damping_ratio), a, b);
  }
  w.CreateJoint(&jd);
}

void create(b2World& w, b2Body* a, b2Body* b, const WeldJointDef& d, TwinNotes* notes) {
  b2WeldJointDef jd;
  set_common(&jd, a, b, d.collide_connected);
  jd.localAnchorA = to_b2(d.local_anchor_a);
  jd.localAnchorB = to_b2(d.local_anchor_b);
  jd.referenceAngle = static_cast<float>(d.reference_angle);
  if (d.angular_hertz > 0.0) {
    b2AngularStiffness(jd.stiffness, jd.damping, static_cast<float>(d.angular_hertz),
                       static_cast<float>(d.angular_damping_ratio), a, b);
  }
  if (d.linear_hertz > 0.0) ++notes->weld_linear_springs;
  w.CreateJoint(&jd);
}

void create(b2World& w, b2Body* a, b2Body* b, const PrismaticJointDef& d, TwinNotes* notes) {
  b2PrismaticJointDef jd;
  set_common(&jd, a, b, d.collide_connected);
  jd.localAnchorA = to_b2(d.local_anchor_a);
  jd.localAnchorB = to_b2(d.local_anchor_b);
  jd.localAxisA = to_b2(d.local_axis_a);
  jd.referenceAngle = static_cast<float>(d.reference_angle);
  jd.enableLimit = d.enable_limit;
  jd.lowerTranslation = static_cast<float>(d.lower_translation);
  jd.upperTranslation = static_cast<float>(d.upper_translation);
  jd.enableMotor = d.enable_motor;
  jd.motorSpeed = static_cast<float>(d.motor_speed);
  jd.maxMotorForce = static_cast<float>(d.max_motor_force);
  if (d.enable_spring && d.hertz > 0.0) ++notes->prismatic_springs;
  w.CreateJoint(&jd);
}

void create(b2World& w, b2Body* a, b2Body* b, const WheelJointDef& d, TwinNotes*) {
  b2WheelJointDef jd;
  set_common(&jd, a, b, d.collide_connected);
  jd.localAnchorA = to_b2(d.local_anchor_a);
  jd.localAnchorB = to_b2(d.local_anchor_b);
  jd.localAxisA = to_b2(d.local_axis_a);
  jd.enableLimit = d.enable_limit;
  jd.lowerTranslation = static_cast<float>(d.lower_translation);
  jd.upperTranslation = static_cast<float>(d.upper_translation);
  jd.enableMotor = d.enable_motor;
  jd.motorSpeed = static_cast<float>(d.motor_speed);
  jd.maxMotorTorque = static_cast<float>(d.max_motor_torque);
  jd.stiffness = 0.0f;
  jd.damping = 0.0f;
  if (d.enable_spring && d.hertz > 0.0) {
    b2LinearStiffness(jd.stiffness, jd.damping, static_cast<float>(d.hertz),
                      static_cast<float>(d.damping_ratio), a, b);
  }
  w.CreateJoint(&jd);
}

void create(b2World& w, b2Body* a, b2Body* b, const MotorJointDef& d, TwinNotes*) {
  b2MotorJointDef jd;
  set_common(&jd, a, b, d.collide_connected);
  jd.linearOffset = to_b2(d.linear_offset);
  jd.angularOffset = static_cast<float>(d.angular_offset);
  jd.maxForce = static_cast<float>(d.max_force);
  jd.maxTorque = static_cast<float>(d.max_torque);
  jd.correctionFactor = static_cast<float>(d.correction_factor);
  w.CreateJoint(&jd);
}

}  // namespace

std::vector<std::string> TwinNotes::lines() const {
  std::vector<std::string> out;
  auto add = [&](int n, const char* what) {
    if (n > 0) out.push_back(std::to_string(n) + " " + what);
  };
  add(capsules,
      "capsule(s) as a box over the core segment plus a circle at each end, mass and inertia "
      "set to Fulcrum's");
  add(inset_polygons, "polygon core(s) inset by the 0.01 m skin (outline = Fulcrum's)");
  add(rounded_polygons,
      "rounded polygon core(s) grown by Fulcrum's radius less the skin (sides = Fulcrum's, "
      "corners rounded by 0.01 m instead of the radius)");
  add(thin_polygons,
      "polygon(s) thinner than 2.4.1 can make (2 x 0.01 m skin + 0.005 m core): core 0.005 m "
      "thick, outline that much plus 0.02 m thick (thicker than Fulcrum's)");
  add(skinned_segments, "segment(s) as two-sided edges, with 2.4.1's 0.01 m skin on top");
  add(wide_filters, "filter(s) truncated to 16 bits");
  add(revolute_springs, "revolute spring(s) dropped (2.4.1 has none)");
  add(weld_linear_springs, "weld linear spring(s) dropped (2.4.1 softens the angle only)");
  add(prismatic_springs, "prismatic spring(s) dropped (2.4.1 has none)");
  return out;
}

std::vector<BodyMass> fulcrum_masses(const SceneDef& scene) {
  auto world = build_world(scene);
  if (!world.ok()) {
    std::fprintf(stderr, "fulcrum_box2d_compare: %s\n", world.status().to_string().c_str());
    std::exit(2);
  }
  std::vector<BodyMass> out;
  for (BodyId id : world->bodies()) {
    BodyState s = world->body_state(id).value();
    out.push_back({s.mass, s.rotational_inertia, s.transform.inv_apply(s.center)});
  }
  return out;
}

Twin build_box2d_twin(const SceneDef& scene, const std::vector<BodyMass>& masses,
                      const TwinOptions& options, TwinNotes* notes) {
  Twin twin;
  twin.world = std::make_unique<b2World>(to_b2(scene.settings.gravity));
  b2World& w = *twin.world;
  w.SetAllowSleeping(scene.settings.enable_sleep);
  const float threshold = static_cast<float>(scene.settings.restitution_threshold);
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const SceneBody& sb = scene.bodies[i];
    const BodyDef& d = sb.def;
    b2BodyDef bd;
    bd.type = to_b2(d.type);
    bd.position = to_b2(d.position);
    bd.angle = static_cast<float>(d.angle);
    // Both engines take the velocity of the body origin here: 2.4.1's mass updates shift the
    // stored centre velocity by w x (c - origin) once the centre of mass moves.
    bd.linearVelocity = to_b2(d.linear_velocity);
    bd.angularVelocity = static_cast<float>(d.angular_velocity);
    bd.linearDamping = static_cast<float>(d.linear_damping);
    bd.angularDamping = static_cast<float>(d.angular_damping);
    bd.gravityScale = static_cast<float>(d.gravity_scale);
    // Particles are dynamic bodies that never turn.
    bd.fixedRotation = d.fixed_rotation || d.type == BodyType::kParticle;
    bd.awake = d.awake;
    bd.allowSleep = d.enable_sleep;
    b2Body* body = w.CreateBody(&bd);
    for (const ShapeDef& sd : sb.shapes) add_shape(body, sd, threshold, options, notes);
    for (const ChainDef& chain : sb.chains) {
      b2FixtureDef fd = fixture(0.0, chain.friction, chain.restitution, threshold,
                                to_b2(chain.filter, notes), false);
      size_t n = chain.points.size();
      size_t links = chain.loop ? n : n - 1;
      for (size_t k = 0; k < links; ++k) {
        add_edge(body, chain.points[k], chain.points[(k + 1) % n], fd, notes);
      }
    }
    // Fulcrum's mass properties, whatever shapes stand in for its own (capsules, inset cores).
    // 2.4.1 takes the rotational inertia about the body origin.
    if (bd.type == b2_dynamicBody && masses[i].mass > 0.0) {
      const BodyMass& m = masses[i];
      b2MassData md;
      md.mass = static_cast<float>(m.mass);
      md.center = to_b2(m.local_center);
      md.I = static_cast<float>(m.inertia + m.mass * dot(m.local_center, m.local_center));
      body->SetMassData(&md);
    }
    twin.bodies.push_back(body);
  }
  for (const SceneJoint& sj : scene.joints) {
    b2Body* a = twin.bodies[sj.body_a];
    b2Body* b = twin.bodies[sj.body_b];
    std::visit([&](const auto& def) { create(w, a, b, def, notes); }, sj.def);
    ++notes->joints;
  }
  return twin;
}

double box2d_max_penetration(b2World& world) {
  double worst = 0.0;
  for (b2Contact* c = world.GetContactList(); c != nullptr; c = c->GetNext()) {
    if (!c->IsTouching() || !c->IsEnabled()) continue;
    if (c->GetFixtureA()->IsSensor() || c->GetFixtureB()->IsSensor()) continue;
    b2WorldManifold wm;
    c->GetWorldManifold(&wm);
    int points = c->GetManifold()->pointCount;
    for (int i = 0; i < points; ++i) {
      worst = std::max(worst, -static_cast<double>(wm.separations[i]));
    }
  }
  return worst;
}

}  // namespace fulcrum::bench
