// Kept manifolds (WorldSettings::manifold_reuse_distance, contact.cpp): a touching manifold
// between flat shapes is moved with the bodies while they move little relative to each other,
// and found afresh once they have moved more.
//
// The probe below redoes a step's narrow phase on a copy of the world and compares each contact's
// manifold with what the manifold functions give for the same poses and reach.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "fulcrum/scenes.h"
#include "fulcrum/world.h"
#include "manifold.h"
#include "scene_fixture.h"
#include "world_impl.h"

namespace fulcrum {
namespace {

using testing::build;

// A copy of w whose narrow phase has just run, as the next step's would.
World probe_of(const World& w) {
  World probe(w.settings());
  EXPECT_TRUE(probe.restore(w.snapshot()).ok());
  ++probe.impl().step_stamp;
  probe.impl().update_pairs();
  probe.impl().collide();
  return probe;
}

// What the manifold functions give for contact c at the probe's poses, with the step's reach.
Manifold fresh(const WorldImpl& impl, const Contact& c) {
  const Body& a = impl.bodies[c.body_a];
  const Body& b = impl.bodies[c.body_b];
  const double reach = impl.settings.speculative_distance + impl.settings.dt * length(b.v - a.v);
  return collide(impl.shapes[c.shape_a].geometry, a.xf, impl.shapes[c.shape_b].geometry, b.xf,
                 reach);
}

// Whether the contact's manifold was moved, not found, in the probe's narrow phase: a found one
// is kept with the poses it was found at.
bool moved_this_tick(const WorldImpl& impl, size_t ci) {
  const Contact& c = impl.contacts[ci];
  const ManifoldCache& kept = impl.manifold_caches[ci];
  const Transform now = inv_mul(impl.bodies[c.body_a].xf, impl.bodies[c.body_b].xf);
  return kept.valid &&
         (now.p != kept.pose.p || now.q.c != kept.pose.q.c || now.q.s != kept.pose.q.s);
}

// A pyramid that never sleeps, so that its contacts are refreshed every tick.
SceneDef awake_pyramid(int base) {
  SceneDef s = testing::pyramid(base);
  s.settings.enable_sleep = false;
  return s;
}

// A resting pyramid of base 20 (210 boxes) moves by micrometres a tick, so after it settles
// nearly every manifold is moved rather than found. A moved manifold has the found one's points
// (same ids, same count) and the same normal (a face normal turned with its body: equal up to
// rounding, bounded at 1e-6). Its points are the moved features' midpoints, where the found
// ones are clipped afresh: they differ by up to the drift since the manifold was found (at most
// 1 mm; measured 0.37 mm). The separations differ by that drift times the faces' tilt to each
// other, a second-order quantity: bounded at 1e-6 m, a thousandth of the drift (measured
// 2.6e-7 m, against the 5 mm slop the contacts resolve).
TEST(KeptManifold, AMovedManifoldMatchesAFoundOneToSecondOrder) {
  World w = build(awake_pyramid(20));
  for (int i = 0; i < 120; ++i) w.step();
  World probe = probe_of(w);
  const WorldImpl& impl = probe.impl();
  int touching = 0, moved = 0;
  double worst_separation = 0.0, worst_normal = 0.0, worst_point = 0.0;
  for (size_t ci = 0; ci < impl.contacts.size(); ++ci) {
    const Contact& c = impl.contacts[ci];
    if (!c.alive || c.manifold.count == 0) continue;
    ++touching;
    if (!moved_this_tick(impl, ci)) continue;
    ++moved;
    const Manifold f = fresh(impl, c);
    ASSERT_EQ(f.count, c.manifold.count);
    worst_normal = std::max(worst_normal, length(f.normal - c.manifold.normal));
    for (int i = 0; i < f.count; ++i) {
      const ManifoldPoint& p = c.manifold.points[i];
      ASSERT_EQ(f.points[i].id, p.id);
      worst_separation =
          std::max(worst_separation, std::abs(f.points[i].separation - p.separation));
      worst_point = std::max(worst_point, length(f.points[i].point - p.point));
    }
  }
  EXPECT_GT(touching, 400);
  EXPECT_GT(moved, 0.9 * touching);
  EXPECT_LT(worst_separation, 1e-6);
  EXPECT_LT(worst_normal, 1e-6);
  EXPECT_LT(worst_point, 1e-3);
}

// A box sliding at 3 to 1.8 m/s moves 3 to 5 cm a tick relative to the ground, far beyond 1 mm: its
// manifold is found every tick, bit for bit what the manifold functions give.
TEST(KeptManifold, ASlidingBoxIsFoundAfreshEveryTick) {
  SceneDef s;
  scenes::add_ground(&s, 40.0);
  SceneBody box;
  box.def.type = BodyType::kDynamic;
  box.def.position = Vec2(-10.0, 0.5);
  box.def.linear_velocity = Vec2(3.0, 0.0);
  ShapeDef shape;
  shape.geometry = make_box(0.5, 0.5);
  shape.friction = 0.1;
  box.shapes.push_back(shape);
  s.bodies.push_back(box);
  World w = build(s);
  for (int i = 0; i < 30; ++i) {
    w.step();
    World probe = probe_of(w);
    const WorldImpl& impl = probe.impl();
    int touching = 0;
    for (size_t ci = 0; ci < impl.contacts.size(); ++ci) {
      const Contact& c = impl.contacts[ci];
      if (!c.alive || c.manifold.count == 0) continue;
      ++touching;
      EXPECT_FALSE(moved_this_tick(impl, ci)) << "tick " << i;
      const Manifold f = fresh(impl, c);
      ASSERT_EQ(f.count, c.manifold.count);
      EXPECT_EQ(f.normal, c.manifold.normal);
      for (int k = 0; k < f.count; ++k) {
        EXPECT_EQ(f.points[k].point, c.manifold.points[k].point);
        EXPECT_EQ(f.points[k].separation, c.manifold.points[k].separation);
      }
    }
    EXPECT_EQ(touching, 1) << "tick " << i;
  }
  EXPECT_GT(w.body_state(w.bodies().back())->linear_velocity.x(), 1.0);  // still sliding
}

// With manifold_reuse_distance = 0 nothing is kept: every manifold is found every tick.
// Circles and rounded polygons are never kept either (their normals turn as they roll or
// slide, not with a face).
TEST(KeptManifold, ZeroDistanceOrRoundShapesKeepNothing) {
  SceneDef off = awake_pyramid(10);
  off.settings.manifold_reuse_distance = 0.0;
  SceneDef round;
  scenes::add_ground(&round, 40.0);
  for (int i = 0; i < 10; ++i) {
    SceneBody b;
    b.def.type = BodyType::kDynamic;
    b.def.position = Vec2(-5.0 + i, 0.5);
    ShapeDef shape;
    if (i % 2 == 0) {
      shape.geometry = Circle{Vec2::Zero(), 0.5};
    } else {
      Polygon p = make_box(0.4, 0.4);
      p.radius = 0.1;
      shape.geometry = p;
    }
    b.shapes.push_back(shape);
    round.bodies.push_back(b);
  }
  for (const SceneDef* s : {&off, &round}) {
    World w = build(*s);
    int touching = 0;
    for (int i = 0; i < 60; ++i) {
      w.step();
      const WorldImpl& impl = w.impl();
      for (size_t ci = 0; ci < impl.contacts.size(); ++ci) {
        const Contact& c = impl.contacts[ci];
        if (!c.alive || c.manifold.count == 0) continue;
        ++touching;
        ASSERT_FALSE(impl.manifold_caches[ci].valid) << "tick " << i;
      }
    }
    EXPECT_GT(touching, 60);
  }
}

// Kept manifolds are state: a world restored from a snapshot (the engine's or the encoded one,
// which snapshot_test and the scene round trips check) continues bit for bit, and so does one
// stepped on several threads.
TEST(KeptManifold, ARestoredOrThreadedWorldContinuesBitForBit) {
  World w = build(awake_pyramid(12));
  for (int i = 0; i < 40; ++i) w.step();
  World restored(w.settings());
  ASSERT_TRUE(restored.restore(w.snapshot()).ok());
  World threaded(w.settings());
  ASSERT_TRUE(threaded.restore(w.snapshot()).ok());
  ASSERT_TRUE(threaded.set_threads(3).ok());
  for (int i = 0; i < 40; ++i) {
    w.step();
    restored.step();
    threaded.step();
    ASSERT_EQ(w.state_hash(), restored.state_hash()) << "tick " << i;
    ASSERT_EQ(w.state_hash(), threaded.state_hash()) << "tick " << i;
  }
}

TEST(KeptManifold, ADistanceOutsideItsRangeIsRefusedByName) {
  for (double bad : {-0.001, 2.0, std::nan("")}) {
    WorldSettings s;
    s.manifold_reuse_distance = bad;
    World w;
    const Status st = w.set_settings(s);
    ASSERT_FALSE(st.ok()) << bad;
    EXPECT_NE(st.message().find("settings.manifold_reuse_distance"), std::string::npos)
        << st.message();
    EXPECT_EQ(w.settings().manifold_reuse_distance, WorldSettings{}.manifold_reuse_distance);
  }
}

}  // namespace
}  // namespace fulcrum
