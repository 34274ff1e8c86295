// fulcrum_box2d_compare: builds the same builtin scenes in Fulcrum and in Box2D 2.4.1 and runs
// both in this process, printing a Markdown table. The Box2D world is converted from the very
// SceneDef Fulcrum builds from, so both engines start from identical bodies, shapes, materials
// and settings (as far as Box2D can express them; see convert() for what differs).
//
// For each scene and engine: ms per step over steps 1..N-1 (step 0 creates the first contacts
// and is excluded), median over R repeats; the largest penetration after the last step; the
// number of dynamic bodies whose centre of mass moved more than 0.5 m; and Fulcrum/Box2D time.
//
//   build/bin/fulcrum_box2d_compare                          # the default table
//   build/bin/fulcrum_box2d_compare --scene tumbler --steps 300 --repeats 5
//   build/bin/fulcrum_box2d_compare --b2-vel 10 --b2-pos 8
#include <sys/utsname.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include <box2d/box2d.h>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/world.h"

namespace {

struct Entry {
  std::string scene;
  int steps = 0;
};

// One engine's figures for one scene.
struct Figures {
  double ms_per_step = 0.0;
  double max_penetration = 0.0;
  int moved = 0;
  // How the moved bodies moved, to tell a collapse (large sideways or downward moves) from a
  // structure that merely expanded or drifted: mean displacement, largest, and lowest dy.
  double sum_dx = 0.0, sum_dy = 0.0, max_move = 0.0, min_dy = 0.0;
  int dynamic_bodies = 0;
};

// What the conversion could not carry over exactly, so the output can say so.
struct ConversionNotes {
  int skipped_capsules = 0;
  int rounded_polygons = 0;  // polygon radius dropped (Box2D's skin is fixed)
  int wide_filters = 0;      // filter bits beyond Box2D's 16 (truncated)
  int skipped_joints = 0;    // joint kinds the twin does not convert (weld, prismatic, ...)
};

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

bool is_dynamic(fulcrum::BodyType t) {
  // Particles are dynamic bodies without rotation; Box2D gets them as fixed-rotation bodies.
  return t == fulcrum::BodyType::kDynamic || t == fulcrum::BodyType::kParticle;
}

void count_move(double dx, double dy, Figures* f) {
  double d = std::hypot(dx, dy);
  if (d <= 0.5) return;
  ++f->moved;
  f->sum_dx += dx;
  f->sum_dy += dy;
  f->max_move = std::max(f->max_move, d);
  f->min_dy = f->moved == 1 ? dy : std::min(f->min_dy, dy);
}

std::string describe_moves(const char* engine, const Figures& f) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "%s: %d moved, mean displacement (%.3f, %.3f) m, largest %.3f m, lowest dy %.3f m",
                engine, f.moved, f.sum_dx / f.moved, f.sum_dy / f.moved, f.max_move, f.min_dy);
  return buf;
}

// --- Fulcrum ---------------------------------------------------------------------------------

Figures run_fulcrum(const fulcrum::SceneDef& scene, int steps) {
  fulcrum::World world = std::move(fulcrum::build_world(scene).value());
  std::vector<fulcrum::Vec2> start;
  for (fulcrum::BodyId id : world.bodies()) start.push_back(world.body_state(id)->center);

  world.step();
  auto t0 = Clock::now();
  for (int i = 1; i < steps; ++i) world.step();
  auto t1 = Clock::now();

  Figures f;
  f.ms_per_step = std::chrono::duration<double, std::milli>(t1 - t0).count() / (steps - 1);
  f.max_penetration = world.metrics().max_penetration;
  size_t k = 0;
  for (fulcrum::BodyId id : world.bodies()) {
    fulcrum::BodyState s = *world.body_state(id);
    if (is_dynamic(s.type)) {
      ++f.dynamic_bodies;
      count_move(s.center.x() - start[k].x(), s.center.y() - start[k].y(), &f);
    }
    ++k;
  }
  return f;
}

// --- Box2D -----------------------------------------------------------------------------------

b2Vec2 to_b2(const fulcrum::Vec2& v) {
  return b2Vec2(static_cast<float>(v.x()), static_cast<float>(v.y()));
}

b2BodyType to_b2(fulcrum::BodyType t) {
  switch (t) {
    case fulcrum::BodyType::kStatic:
      return b2_staticBody;
    case fulcrum::BodyType::kKinematic:
      return b2_kinematicBody;
    case fulcrum::BodyType::kDynamic:
    case fulcrum::BodyType::kParticle:
      break;
  }
  return b2_dynamicBody;
}

b2Filter to_b2(const fulcrum::Filter& f, ConversionNotes* notes) {
  // Box2D 2.4.1 has 16-bit categories and groups; every builtin scene uses the defaults, which
  // survive the truncation (all-ones mask, category 1, group 0).
  b2Filter out;
  out.categoryBits = static_cast<uint16>(f.category_bits & 0xFFFF);
  out.maskBits = static_cast<uint16>(f.mask_bits & 0xFFFF);
  out.groupIndex = static_cast<int16>(f.group_index);
  bool mask_ok = f.mask_bits == ~uint64_t{0} || (f.mask_bits >> 16) == 0;
  if ((f.category_bits >> 16) != 0 || !mask_ok || f.group_index != out.groupIndex) {
    ++notes->wide_filters;
  }
  return out;
}

void add_edge(b2Body* body, const fulcrum::Vec2& p1, const fulcrum::Vec2& p2, double friction,
              double restitution, float threshold, const b2Filter& filter, bool sensor) {
  // Fulcrum segments (and chain links) are two-sided; 2.4.1's chain shapes are one-sided, so
  // every link becomes its own two-sided edge.
  b2EdgeShape edge;
  edge.SetTwoSided(to_b2(p1), to_b2(p2));
  b2FixtureDef fd;
  fd.shape = &edge;
  fd.density = 0.0f;
  fd.friction = static_cast<float>(friction);
  fd.restitution = static_cast<float>(restitution);
  fd.restitutionThreshold = threshold;
  fd.filter = filter;
  fd.isSensor = sensor;
  body->CreateFixture(&fd);
}

void add_shape(b2Body* body, const fulcrum::ShapeDef& sd, float threshold, ConversionNotes* notes) {
  b2Filter filter = to_b2(sd.filter, notes);
  b2FixtureDef fd;
  fd.density = static_cast<float>(sd.density);
  fd.friction = static_cast<float>(sd.friction);
  fd.restitution = static_cast<float>(sd.restitution);
  // Fulcrum's world-wide restitution threshold is per fixture in 2.4.1 (mixed as the max).
  fd.restitutionThreshold = threshold;
  fd.filter = filter;
  fd.isSensor = sd.is_sensor;

  if (const auto* poly = std::get_if<fulcrum::Polygon>(&sd.geometry)) {
    b2Vec2 pts[b2_maxPolygonVertices];
    int n = std::min(poly->count, static_cast<int>(b2_maxPolygonVertices));
    for (int i = 0; i < n; ++i) pts[i] = to_b2(poly->vertices[i]);
    b2PolygonShape shape;
    shape.Set(pts, n);
    if (poly->radius > 0.0) ++notes->rounded_polygons;
    fd.shape = &shape;
    body->CreateFixture(&fd);
  } else if (const auto* circle = std::get_if<fulcrum::Circle>(&sd.geometry)) {
    b2CircleShape shape;
    shape.m_p = to_b2(circle->center);
    shape.m_radius = static_cast<float>(circle->radius);
    fd.shape = &shape;
    body->CreateFixture(&fd);
  } else if (const auto* seg = std::get_if<fulcrum::Segment>(&sd.geometry)) {
    add_edge(body, seg->point1, seg->point2, sd.friction, sd.restitution, threshold, filter,
             sd.is_sensor);
  } else {
    // Box2D 2.4.1 has no capsule; none of the default table's scenes use one.
    ++notes->skipped_capsules;
  }
}

// Builds the Box2D twin of `scene`. Bodies are created in scene order, so the i-th body of the
// returned list is scene.bodies[i].
std::unique_ptr<b2World> convert(const fulcrum::SceneDef& scene, std::vector<b2Body*>* bodies,
                                 ConversionNotes* notes) {
  auto world = std::make_unique<b2World>(to_b2(scene.settings.gravity));
  world->SetAllowSleeping(scene.settings.enable_sleep);
  const float threshold = static_cast<float>(scene.settings.restitution_threshold);
  for (const fulcrum::SceneBody& sb : scene.bodies) {
    const fulcrum::BodyDef& d = sb.def;
    b2BodyDef bd;
    bd.type = to_b2(d.type);
    bd.position = to_b2(d.position);
    bd.angle = static_cast<float>(d.angle);
    // Both engines take the velocity of the body origin here: 2.4.1's ResetMassData shifts the
    // stored centre velocity by w x (c - origin) once the fixtures move the centre of mass.
    // The tumbler's kinematic frame gets its spin this way (same as SetAngularVelocity).
    bd.linearVelocity = to_b2(d.linear_velocity);
    bd.angularVelocity = static_cast<float>(d.angular_velocity);
    bd.linearDamping = static_cast<float>(d.linear_damping);
    bd.angularDamping = static_cast<float>(d.angular_damping);
    bd.gravityScale = static_cast<float>(d.gravity_scale);
    bd.fixedRotation = d.fixed_rotation || d.type == fulcrum::BodyType::kParticle;
    bd.awake = d.awake;
    bd.allowSleep = d.enable_sleep;
    b2Body* body = world->CreateBody(&bd);
    for (const fulcrum::ShapeDef& sd : sb.shapes) add_shape(body, sd, threshold, notes);
    for (const fulcrum::ChainDef& chain : sb.chains) {
      b2Filter filter = to_b2(chain.filter, notes);
      size_t n = chain.points.size();
      size_t links = chain.loop ? n : n - 1;
      for (size_t i = 0; i < links; ++i) {
        add_edge(body, chain.points[i], chain.points[(i + 1) % n], chain.friction,
                 chain.restitution, threshold, filter, false);
      }
    }
    bodies->push_back(body);
  }
  // Joints: the same anchors, limits and motors (Box2D 2.4.1 has no revolute spring, and its
  // distance joint's min/max are its own; both are noted when they would differ).
  for (const fulcrum::SceneJoint& sj : scene.joints) {
    b2Body* a = (*bodies)[sj.body_a];
    b2Body* b = (*bodies)[sj.body_b];
    if (const auto* r = std::get_if<fulcrum::RevoluteJointDef>(&sj.def)) {
      b2RevoluteJointDef jd;
      jd.bodyA = a;
      jd.bodyB = b;
      jd.localAnchorA = to_b2(r->local_anchor_a);
      jd.localAnchorB = to_b2(r->local_anchor_b);
      jd.referenceAngle = static_cast<float>(r->reference_angle);
      jd.enableLimit = r->enable_limit;
      jd.lowerAngle = static_cast<float>(r->lower_angle);
      jd.upperAngle = static_cast<float>(r->upper_angle);
      jd.enableMotor = r->enable_motor;
      jd.motorSpeed = static_cast<float>(r->motor_speed);
      jd.maxMotorTorque = static_cast<float>(r->max_motor_torque);
      jd.collideConnected = r->collide_connected;
      world->CreateJoint(&jd);
    } else if (const auto* d = std::get_if<fulcrum::DistanceJointDef>(&sj.def)) {
      b2DistanceJointDef jd;
      jd.bodyA = a;
      jd.bodyB = b;
      jd.localAnchorA = to_b2(d->local_anchor_a);
      jd.localAnchorB = to_b2(d->local_anchor_b);
      jd.length = static_cast<float>(d->length);
      jd.minLength = static_cast<float>(d->min_length);
      jd.maxLength = static_cast<float>(d->max_length);
      jd.collideConnected = d->collide_connected;
      world->CreateJoint(&jd);
    } else {
      ++notes->skipped_joints;
    }
  }
  return world;
}

// Largest overlap over the touching contacts' points. 2.4.1's world-manifold separation is
// measured between the skinned surfaces (each polygon grows by b2_polygonRadius = 0.01 m), so
// this is skin overlap, not overlap of the polygons as given.
double box2d_max_penetration(b2World& world) {
  double worst = 0.0;
  for (b2Contact* c = world.GetContactList(); c != nullptr; c = c->GetNext()) {
    if (!c->IsTouching() || !c->IsEnabled()) continue;
    if (c->GetFixtureA()->IsSensor() || c->GetFixtureB()->IsSensor()) continue;
    b2WorldManifold wm;
    c->GetWorldManifold(&wm);
    int points = c->GetManifold()->pointCount;
    for (int i = 0; i < points; ++i)
      worst = std::max(worst, -static_cast<double>(wm.separations[i]));
  }
  return worst;
}

Figures run_box2d(const fulcrum::SceneDef& scene, int steps, int vel_iters, int pos_iters,
                  ConversionNotes* notes) {
  std::vector<b2Body*> bodies;
  std::unique_ptr<b2World> world = convert(scene, &bodies, notes);
  std::vector<b2Vec2> start;
  for (b2Body* b : bodies) start.push_back(b->GetWorldCenter());
  const float dt = static_cast<float>(scene.settings.dt);

  world->Step(dt, vel_iters, pos_iters);
  auto t0 = Clock::now();
  for (int i = 1; i < steps; ++i) world->Step(dt, vel_iters, pos_iters);
  auto t1 = Clock::now();

  Figures f;
  f.ms_per_step = std::chrono::duration<double, std::milli>(t1 - t0).count() / (steps - 1);
  f.max_penetration = box2d_max_penetration(*world);
  for (size_t k = 0; k < bodies.size(); ++k) {
    if (bodies[k]->GetType() != b2_dynamicBody) continue;
    ++f.dynamic_bodies;
    b2Vec2 d = bodies[k]->GetWorldCenter() - start[k];
    count_move(d.x, d.y, &f);
  }
  return f;
}

// --- Table -----------------------------------------------------------------------------------

struct Row {
  Entry entry;
  Figures fulcrum;
  Figures box2d;
  ConversionNotes notes;
};

Row run(const Entry& e, int repeats, int vel_iters, int pos_iters) {
  Row row;
  row.entry = e;
  const fulcrum::SceneDef scene = fulcrum::scenes::builtin(e.scene).value();
  std::vector<double> ft, bt;
  // Alternate the engines within each repeat so both see the same machine load.
  for (int r = 0; r < repeats; ++r) {
    row.fulcrum = run_fulcrum(scene, e.steps);
    ft.push_back(row.fulcrum.ms_per_step);
    row.notes = ConversionNotes{};
    row.box2d = run_box2d(scene, e.steps, vel_iters, pos_iters, &row.notes);
    bt.push_back(row.box2d.ms_per_step);
  }
  // Both engines are deterministic in-process, so the last repeat's accuracy figures stand for
  // all of them; only the timings vary.
  row.fulcrum.ms_per_step = median(ft);
  row.box2d.ms_per_step = median(bt);
  return row;
}

std::string fulcrum_settings(const fulcrum::WorldSettings& s) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "substeps %d, velocity_iterations %d, relax_iterations %d, contact_hertz %g",
                s.substeps, s.velocity_iterations, s.relax_iterations, s.contact_hertz);
  return buf;
}

void usage() {
  std::fprintf(stderr,
               "usage: fulcrum_box2d_compare [--scene NAME]... [--steps N] [--repeats R] "
               "[--b2-vel N] [--b2-pos N]\n");
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<Entry> table = {{"large_pyramid", 500},
                                    {"many_pyramids", 500},
                                    {"vertical_stack", 600},
                                    {"mass_ratio_100", 600},
                                    {"tumbler", 750}};
  std::vector<Entry> chosen;
  int repeats = 3, steps = 0, vel_iters = 8, pos_iters = 3;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "fulcrum_box2d_compare: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--scene") {
      chosen.push_back({value(), 0});
    } else if (a == "--steps") {
      steps = std::atoi(value());
    } else if (a == "--repeats") {
      repeats = std::max(1, std::atoi(value()));
    } else if (a == "--b2-vel") {
      vel_iters = std::max(1, std::atoi(value()));
    } else if (a == "--b2-pos") {
      pos_iters = std::max(0, std::atoi(value()));
    } else {
      usage();
      return 2;
    }
  }
  if (chosen.empty()) chosen = table;
  for (Entry& e : chosen) {
    if (steps > 0) e.steps = steps;
    if (e.steps == 0) {
      auto it = std::find_if(table.begin(), table.end(),
                             [&](const Entry& t) { return t.scene == e.scene; });
      e.steps = it != table.end() ? it->steps : 500;
    }
    // Step 0 is excluded from the timing, so at least two steps are needed.
    e.steps = std::max(e.steps, 2);
    auto scene = fulcrum::scenes::builtin(e.scene);
    if (!scene.ok()) {
      std::fprintf(stderr, "fulcrum_box2d_compare: %s\n", scene.status().message().c_str());
      return 2;
    }
  }

  // Header: date, machine, and the settings each engine runs with.
  char date[32];
  std::time_t now = std::time(nullptr);
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M", std::localtime(&now));
  utsname un{};
  const char* machine = uname(&un) == 0 ? un.machine : "unknown";
  // The 2.4.1 release still sets b2_version to 2.4.0, so print what the library says.
  std::printf(
      "Fulcrum vs Box2D 2.4.1 (b2_version %d.%d.%d), %s, %s, median of %d repeat(s), "
      "dt 1/60 s\n\n",
      b2_version.major, b2_version.minor, b2_version.revision, date, machine, repeats);
  // Settings usually agree across the table: print them once unless a scene differs.
  std::vector<std::string> settings;
  for (const Entry& e : chosen) {
    settings.push_back(fulcrum_settings(fulcrum::scenes::builtin(e.scene)->settings));
  }
  if (std::all_of(settings.begin(), settings.end(),
                  [&](const std::string& s) { return s == settings[0]; })) {
    std::printf("- Fulcrum: %s\n", settings[0].c_str());
  } else {
    for (size_t i = 0; i < chosen.size(); ++i) {
      std::printf("- Fulcrum (%s): %s\n", chosen[i].scene.c_str(), settings[i].c_str());
    }
  }
  std::printf(
      "- Box2D: velocity_iterations %d, position_iterations %d, float, warm starting and "
      "continuous collision on (defaults)\n",
      vel_iters, pos_iters);
  // Sleep differs by scene (the pyramids turn it off); both engines follow the scene.
  std::string sleep;
  for (const Entry& e : chosen) {
    bool on = fulcrum::scenes::builtin(e.scene)->settings.enable_sleep;
    sleep += (sleep.empty() ? "" : ", ") + e.scene + (on ? " on" : " off");
  }
  std::printf("- sleep (both engines, from the scene): %s\n", sleep.c_str());
  std::printf(
      "- Box2D skins every polygon with b2_polygonRadius = %.3g m, so boxes that touch exactly "
      "in the scene start overlapped by %.3g m in Box2D (not compensated); Box2D's "
      "penetration is skin overlap (its world-manifold separation includes the skin)\n",
      static_cast<double>(b2_polygonRadius), 2.0 * static_cast<double>(b2_polygonRadius));
  std::printf(
      "- ms/step over steps 1..N-1; penetration and moved (> 0.5 m, dynamic bodies' centres) "
      "after the last step; ratio = Fulcrum ms / Box2D ms\n\n");

  std::printf(
      "| scene | dynamic bodies | steps | Fulcrum ms/step | Box2D ms/step | ratio F/B2 | "
      "Fulcrum max pen (m) | Box2D max pen (m) | Fulcrum moved | Box2D moved |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<std::string> notes;
  for (const Entry& e : chosen) {
    Row r = run(e, repeats, vel_iters, pos_iters);
    std::string bodies = std::to_string(r.fulcrum.dynamic_bodies);
    if (r.box2d.dynamic_bodies != r.fulcrum.dynamic_bodies) {
      bodies += " / " + std::to_string(r.box2d.dynamic_bodies);
    }
    double ratio = r.box2d.ms_per_step > 0.0 ? r.fulcrum.ms_per_step / r.box2d.ms_per_step : 0.0;
    std::printf("| %s | %s | %d | %.3f | %.3f | %.2f | %.4f | %.4f | %d | %d |\n", e.scene.c_str(),
                bodies.c_str(), e.steps, r.fulcrum.ms_per_step, r.box2d.ms_per_step, ratio,
                r.fulcrum.max_penetration, r.box2d.max_penetration, r.fulcrum.moved, r.box2d.moved);
    std::fflush(stdout);
    const ConversionNotes& n = r.notes;
    if (n.skipped_capsules + n.rounded_polygons + n.wide_filters + n.skipped_joints > 0) {
      char buf[320];
      std::snprintf(buf, sizeof buf,
                    "- %s: Box2D twin skipped %d capsule(s), dropped the radius of %d rounded "
                    "polygon(s), truncated %d filter(s) to 16 bits, skipped %d joint(s)",
                    e.scene.c_str(), n.skipped_capsules, n.rounded_polygons, n.wide_filters,
                    n.skipped_joints);
      notes.push_back(buf);
    }
    for (const auto& [engine, f] : {std::pair{"Fulcrum", r.fulcrum}, std::pair{"Box2D", r.box2d}}) {
      if (f.moved > 0) notes.push_back("- " + e.scene + ", " + describe_moves(engine, f));
    }
  }
  if (!notes.empty()) {
    std::printf("\n");
    for (const std::string& l : notes) std::printf("%s\n", l.c_str());
  }
  return 0;
}
