// Per-island solver budgets (budget.cpp): which islands get more substeps, that the others are
// solved exactly as without budgets, and what the metrics report.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "fulcrum/world.h"
#include "scene_fixture.h"
#include "world_impl.h"

namespace fulcrum {
namespace {

using namespace fulcrum::testing;

// The substeps follow the predicted give: none below the tolerance, S sqrt(give / tol)
// rounded up above it (the give falls as the square of the substeps), capped.
TEST(Budget, SubstepsGrowWithTheSquareRootOfTheGive) {
  WorldSettings s;  // 4 substeps, tolerance 0.008 m, cap 14
  EXPECT_EQ(budget_substeps(s, 0.0), 4);
  EXPECT_EQ(budget_substeps(s, 0.008), 4);
  EXPECT_EQ(budget_substeps(s, 4.0 * 0.008), 8);         // twice the substeps: a quarter
  EXPECT_EQ(budget_substeps(s, 4.0 * 0.008 + 1e-9), 9);  // rounded up
  EXPECT_EQ(budget_substeps(s, 9.0 * 0.008), 12);
  EXPECT_EQ(budget_substeps(s, 1e6), 14);
  s.max_substeps = 4;
  EXPECT_EQ(budget_substeps(s, 1e6), 4);
  // Iterations: about the world's biased passes per tick, at least one per substep.
  EXPECT_EQ(budget_iterations(2, 4, 4), 2);
  EXPECT_EQ(budget_iterations(2, 4, 7), 1);
  EXPECT_EQ(budget_iterations(8, 4, 16), 2);
  EXPECT_EQ(budget_iterations(2, 4, 16), 1);
}

// The predicted give of a joint component is |g| M K / omega^2: for the very heavy chain
// (40 links of 0.25 kg at density 1, a ball of 1000 links, joints at 60 Hz) 0.146 m, which
// asks for 4 sqrt(0.146 / 0.008) = 17.1, capped at 14 substeps. A ragdoll pile predicts
// 2.6 mm and keeps 4.
TEST(Budget, TheVeryHeavyChainGetsTheCapAndRagdollsKeepTheWorldsSubsteps) {
  World chain = build("very_heavy_chain");
  chain.step();
  EXPECT_EQ(chain.metrics().budget_islands, 1);
  EXPECT_EQ(chain.metrics().max_substeps, 14);
  EXPECT_EQ(chain.budgets().max_substeps, 14);

  World heavy = build("heavy_chain");  // predicts 1.97 cm: 4 sqrt(1.97 / 0.8) = 6.3, so 7
  heavy.step();
  EXPECT_EQ(heavy.metrics().max_substeps, 7);

  World ragdolls = build("ragdolls");
  ragdolls.step();
  EXPECT_EQ(ragdolls.metrics().budget_islands, 0);
  EXPECT_EQ(ragdolls.metrics().max_substeps, 4);
}

// Switched off (max_substeps <= substeps), nothing gets a budget.
TEST(Budget, MaxSubstepsAtTheWorldsSubstepsTurnsBudgetsOff) {
  SceneDef s = scene("very_heavy_chain");
  s.settings.max_substeps = s.settings.substeps;
  World w = build(s);
  w.step();
  EXPECT_EQ(w.metrics().budget_islands, 0);
  EXPECT_EQ(w.metrics().max_substeps, 4);
}

// HARD_CASES 19's chain (40 links, a ball of 1000 link masses), hung far to the side of
// whatever else the scene holds.
void add_very_heavy_chain(SceneDef* s) {
  scenes::JointChainOptions chain;
  chain.anchor = Vec2(100.0, 50.0);
  chain.links = 40;
  chain.end_mass = 1000.0;
  scenes::add_joint_chain(s, chain);
}

// A pile that needs no budget is solved bit for bit as it would be alone, while a very heavy
// chain far away runs 14 substeps in the same world: the pile pays nothing for the chain.
TEST(Budget, AnIslandWithoutABudgetIsSolvedAsIfAlone) {
  SceneDef pile;
  scenes::add_ground(&pile, 20.0);
  scenes::StackOptions stack;
  stack.count = 8;
  scenes::add_stack(&pile, stack);
  SceneDef both = pile;
  add_very_heavy_chain(&both);

  World alone = build(pile);
  World shared = build(both);
  for (int i = 0; i < 120; ++i) {
    alone.step();
    shared.step();
  }
  EXPECT_EQ(shared.metrics().budget_islands, 1);
  EXPECT_EQ(shared.metrics().max_substeps, 14);
  // The pile is light (one_pass_give_tolerance): one velocity pass, alone and beside the chain.
  EXPECT_EQ(alone.budgets().max_velocity_iterations, 1);
  std::vector<BodyId> a = alone.bodies(), b = shared.bodies();
  ASSERT_GE(b.size(), a.size());
  for (size_t k = 0; k < a.size(); ++k) {
    BodyState sa = *alone.body_state(a[k]), sb = *shared.body_state(b[k]);
    EXPECT_EQ(sa.center.x(), sb.center.x()) << "body " << k;
    EXPECT_EQ(sa.center.y(), sb.center.y()) << "body " << k;
    EXPECT_EQ(sa.transform.q.s, sb.transform.q.s) << "body " << k;
    EXPECT_EQ(sa.linear_velocity.x(), sb.linear_velocity.x()) << "body " << k;
    EXPECT_EQ(sa.angular_velocity, sb.angular_velocity) << "body " << k;
  }
  // The chain holds (HARD_CASES 19's bound) beside the pile.
  double worst = 0.0;
  for (JointId j : shared.joints()) worst = std::max(worst, shared.joint_state(j)->linear_error);
  EXPECT_LT(worst, 0.05);
}

// Steps `w` (built from `s`) `before` ticks, restores a copy from its snapshot and builds a
// second world on 2 threads; after `after` more ticks all three have the same state hash, with
// one island on a budget.
void expect_restored_and_threaded_copies_agree(const SceneDef& s, World& w, int before, int after) {
  for (int i = 0; i < before; ++i) w.step();
  World copy;
  ASSERT_TRUE(copy.restore(w.snapshot()).ok());
  World threaded = build(s);
  ASSERT_TRUE(threaded.set_threads(2).ok());
  for (int i = 0; i < before; ++i) threaded.step();
  for (int i = 0; i < after; ++i) {
    w.step();
    copy.step();
    threaded.step();
  }
  EXPECT_EQ(w.metrics().budget_islands, 1);
  EXPECT_EQ(w.state_hash(), copy.state_hash());
  EXPECT_EQ(w.state_hash(), threaded.state_hash());
}

// Budgets are part of the step: a world restored from a snapshot mid-swing continues bit for
// bit, and so does one stepped on 2 threads (a pyramid's 210 boxes beside the chain give the
// threads a share of the contacts).
TEST(Budget, RestoredAndThreadedWorldsContinueBitForBit) {
  SceneDef s;
  scenes::add_ground(&s, 40.0);
  scenes::add_pyramid(&s, scenes::PyramidOptions{});
  add_very_heavy_chain(&s);
  World w = build(s);
  expect_restored_and_threaded_copies_agree(s, w, 30, 60);
  EXPECT_GE(w.metrics().contact_count, 256);  // enough for the threads to share
}

// Contacts follow the same rule against contact_give_tolerance (half the thinner shape's
// thickness): none at or below it, S sqrt(ratio / tol) rounded up above it, capped.
TEST(Budget, ContactSubstepsGrowWithTheSquareRootOfTheCompression) {
  WorldSettings s;  // 4 substeps, contact tolerance 0.5, cap 14
  EXPECT_EQ(contact_budget_substeps(s, 0.0), 4);
  EXPECT_EQ(contact_budget_substeps(s, 0.5), 4);
  EXPECT_EQ(contact_budget_substeps(s, 2.0), 8);
  EXPECT_EQ(contact_budget_substeps(s, 2.0 + 1e-9), 9);
  EXPECT_EQ(contact_budget_substeps(s, 4.5), 12);
  EXPECT_EQ(contact_budget_substeps(s, 1e6), 14);
}

// A shape's thickness is its narrowest width: a circle's or capsule's diameter, a plate's
// thickness however it is turned, a rounded polygon's core plus twice its radius, a
// triangle's least height; a segment has none.
TEST(Budget, ThicknessIsTheNarrowestWidth) {
  EXPECT_DOUBLE_EQ(geometry_thickness(Circle{Vec2(1.0, 2.0), 0.3}), 0.6);
  EXPECT_DOUBLE_EQ(geometry_thickness(Capsule{Vec2(-1.0, 0.0), Vec2(1.0, 0.0), 0.1}), 0.2);
  EXPECT_NEAR(geometry_thickness(make_box(1.0, 0.001)), 0.002, 1e-15);
  EXPECT_NEAR(geometry_thickness(make_offset_box(1.0, 0.001, Vec2(3.0, 1.0), 0.7)), 0.002, 1e-12);
  Polygon rounded = make_box(0.5, 0.25);
  rounded.radius = 0.01;
  EXPECT_NEAR(geometry_thickness(rounded), 0.52, 1e-15);
  const Vec2 corners[] = {Vec2(0.0, 0.0), Vec2(2.0, 0.0), Vec2(0.0, 1.0)};
  Polygon triangle;
  ASSERT_TRUE(make_polygon(corners, 0.0, &triangle).ok());
  EXPECT_NEAR(geometry_thickness(triangle), 2.0 / std::sqrt(5.0), 1e-12);  // 2 area / hypotenuse
  EXPECT_EQ(geometry_thickness(Segment{}), 0.0);
}

// HARD_CASES 20's planks (2 mm) get a contact budget from the load of the stack: each contact
// would be pressed in by several times a plank's thickness / 2. A stack of 1 m boxes carrying
// far more weight, the mass-ratio pyramid and the bottom of a 20-box stack, keep the world's
// substeps: millimetres are nothing to a 1 m box. Without gravity there is no weight to carry
// and no contact budget.
TEST(Budget, ThinPlanksGetAContactBudgetAndBoxStacksDoNot) {
  World planks = build("thin_planks");
  for (int i = 0; i < 60; ++i) planks.step();
  EXPECT_EQ(planks.metrics().budget_islands, 1);
  EXPECT_GE(planks.metrics().max_substeps, 8);
  for (const char* name : {"vertical_stack", "mass_ratio_100", "many_pyramids"}) {
    World w = build(name);
    int budgets = 0;
    for (int i = 0; i < 120; ++i) {
      w.step();
      budgets += w.metrics().budget_islands;
    }
    EXPECT_EQ(budgets, 0) << name;
  }
  SceneDef weightless = scene("thin_planks");
  weightless.settings.gravity = Vec2::Zero();
  for (SceneBody& b : weightless.bodies) b.def.linear_velocity = Vec2(0.0, -0.5);
  World w = build(weightless);
  int budgets = 0;
  for (int i = 0; i < 60; ++i) {
    w.step();
    budgets += w.metrics().budget_islands;
  }
  EXPECT_EQ(budgets, 0);
}

// The contact budget reads last tick's impulses, kept per world substep whatever the island
// ran, so a world restored mid-run continues bit for bit, as does one on 2 threads.
TEST(Budget, ContactBudgetsContinueBitForBitAfterARestoreAndOnThreads) {
  const SceneDef s = scene("thin_planks");
  World w = build(s);
  expect_restored_and_threaded_copies_agree(s, w, 20, 60);
}

// A body driven by a motor against a body of infinite mass moves as a kinematic body would
// (with torque to spare), so its island keeps the world's substeps as one touching a kinematic
// body does: the tumbler's 2025 boxes in their motor-driven drum get no contact budget, and
// the very heavy chain, hung from a pin that is also a motor, gets no joint budget.
TEST(Budget, IslandsDrivenByAMotorAgainstTheGroundKeepTheWorldsSubsteps) {
  World tumbler = build("tumbler");
  int budgets = 0;
  for (int i = 0; i < 120; ++i) {
    tumbler.step();
    budgets += tumbler.metrics().budget_islands;
  }
  EXPECT_EQ(budgets, 0);

  SceneDef s = scene("very_heavy_chain");
  World free_pin = build(s);
  free_pin.step();
  EXPECT_EQ(free_pin.metrics().budget_islands, 1);
  int motors = 0;
  for (SceneJoint& j : s.joints) {
    auto* revolute = std::get_if<RevoluteJointDef>(&j.def);
    const bool to_ground = s.bodies[j.body_a].def.type == BodyType::kStatic ||
                           s.bodies[j.body_b].def.type == BodyType::kStatic;
    if (revolute == nullptr || !to_ground) continue;
    revolute->enable_motor = true;
    revolute->max_motor_torque = 1e9;
    ++motors;
  }
  ASSERT_EQ(motors, 1);
  World driven = build(s);
  driven.step();
  EXPECT_EQ(driven.metrics().budget_islands, 0);
}

// A contact whose soft push-out reaches max_correction_speed while both its bodies are slower
// than that makes its island recover: three relax passes per substep and twice the cap. The
// pyramid created overlapping by a quarter recovers for its first ticks and not once apart;
// the same boxes thrown faster than the cap do not recover (their motion, not the push-out,
// carries them).
TEST(Budget, DeepOverlapsAtRestRecoverWithMoreRelaxPasses) {
  World w = build("overlap_recovery");
  w.step();
  EXPECT_EQ(w.metrics().budget_islands, 1);
  EXPECT_EQ(w.metrics().max_relax_iterations, 3);
  EXPECT_EQ(w.metrics().max_substeps, 4);
  for (int i = 0; i < 59; ++i) w.step();
  EXPECT_EQ(w.metrics().max_relax_iterations, 1);
  EXPECT_EQ(w.metrics().budget_islands, 0);

  SceneDef s = scene("overlap_recovery");
  for (SceneBody& b : s.bodies) {
    if (b.def.type == BodyType::kDynamic) b.def.linear_velocity = Vec2(4.0, 0.0);
  }
  World thrown = build(s);
  thrown.step();
  EXPECT_EQ(thrown.metrics().max_relax_iterations, 1);

  // Budgets off: no recovery either.
  s = scene("overlap_recovery");
  s.settings.max_substeps = s.settings.substeps;
  World off = build(s);
  off.step();
  EXPECT_EQ(off.metrics().max_relax_iterations, 1);
}

// Recovery is planned from the contacts the narrow phase lists in id order, so a jammed box of
// circles (case 8, recovering every tick) continues bit for bit after a restore and on 2
// threads.
TEST(Budget, RecoveringIslandsContinueBitForBitAfterARestoreAndOnThreads) {
  const SceneDef s = scene("confined");
  World w = build(s);
  expect_restored_and_threaded_copies_agree(s, w, 10, 20);
  EXPECT_EQ(w.metrics().max_relax_iterations, 3);
  EXPECT_GE(w.metrics().contact_count, 256);
}

// --- One velocity pass (WorldSettings::one_pass_give_tolerance) ------------------------------

SceneDef small_pyramid() {
  SceneDef s;
  scenes::add_ground(&s, 20.0);
  scenes::PyramidOptions p;
  p.base = 10;
  scenes::add_pyramid(&s, p);
  return s;
}

// A pyramid of base 10 presses its bottom contacts in by 0.06 % of a box. Its first tick,
// whose contacts are all new, runs the world's two passes (their loads are not known yet);
// from then on every tick runs one, and such a tick is exactly a tick of
// velocity_iterations = 1 (the rule changes the passes and nothing else). The pyramid stands:
// its top box sinks by the contacts' give, under 5 mm.
TEST(OnePass, ALightPyramidRunsOnePassExactlyAsOneIteration) {
  World light = build(small_pyramid());
  const BodyId top = light.bodies().back();
  const double y0 = light.body_state(top)->center.y();
  light.step();
  EXPECT_EQ(light.budgets().max_velocity_iterations, 2);
  light.step();
  ASSERT_EQ(light.budgets().max_velocity_iterations, 1);
  World reference;
  ASSERT_TRUE(reference.restore(light.snapshot()).ok());
  WorldSettings one = reference.settings();
  one.velocity_iterations = 1;
  one.one_pass_give_tolerance = 0.0;
  ASSERT_TRUE(reference.set_settings(one).ok());
  for (int i = 0; i < 300; ++i) {
    light.step();
    reference.step();
    ASSERT_EQ(light.budgets().max_velocity_iterations, 1) << "tick " << i;
    ASSERT_EQ(light.state_hash(), reference.state_hash()) << "tick " << i;
  }
  EXPECT_EQ(light.metrics().max_velocity_iterations, 1);
  EXPECT_LT(std::abs(light.body_state(top)->center.y() - y0), 0.005);
}

// Switched off (0), or with budgets off, the world keeps its passes.
TEST(OnePass, ZeroToleranceOrBudgetsOffKeepTheWorldsPasses) {
  for (int variant = 0; variant < 2; ++variant) {
    SceneDef s = small_pyramid();
    if (variant == 0) s.settings.one_pass_give_tolerance = 0.0;
    if (variant == 1) s.settings.max_substeps = s.settings.substeps;
    World w = build(s);
    for (int i = 0; i < 30; ++i) {
      w.step();
      ASSERT_EQ(w.budgets().max_velocity_iterations, 2) << "variant " << variant << " tick " << i;
    }
  }
}

// The arch's voussoirs are pressed in by about 0.4 % of their thickness: two passes, which keep
// its crown within HARD_CASES 7's 2 cm (one pass everywhere lets it drop 2.18 cm).
TEST(OnePass, APressedArchKeepsTwoPasses) {
  World w = build("arch");
  for (int i = 0; i < 60; ++i) w.step();
  EXPECT_EQ(w.budgets().max_velocity_iterations, 2);
}

// A box resting on the ground runs one pass while another falls toward it from 2 m; the tick
// that stops the falling box (a new contact, a fast body: a load nobody knows) runs two.
TEST(OnePass, AnImpactRunsTheWorldsPasses) {
  SceneDef s;
  scenes::add_ground(&s, 20.0);
  scenes::StackOptions stack;
  stack.count = 1;
  scenes::add_stack(&s, stack);
  stack.origin = Vec2(0.0, 3.0);
  scenes::add_stack(&s, stack);
  World w = build(s);
  const BodyId falling = w.bodies().back();
  int light_ticks = 0;
  bool stopped = false;
  for (int i = 0; i < 60 && !stopped; ++i) {
    const double before = w.body_state(falling)->linear_velocity.y();
    w.step();
    const double after = w.body_state(falling)->linear_velocity.y();
    if (after > 0.5 * before && before < -1.0) {
      stopped = true;  // the tick of impact: it lost half its speed or more
      EXPECT_EQ(w.budgets().max_velocity_iterations, 2) << "tick " << i;
    } else if (w.budgets().max_velocity_iterations == 1) {
      ++light_ticks;
    }
  }
  EXPECT_TRUE(stopped);
  EXPECT_GT(light_ticks, 20);  // the fall takes about 37 ticks
}

// An awake joint anywhere in a world that plans no budget keeps the whole tick at the world's
// passes. Without gravity no load rests to judge by: colliding boxes keep two passes too.
TEST(OnePass, AnAwakeJointOrZeroGravityKeepTheWorldsPasses) {
  SceneDef s = small_pyramid();
  scenes::JointChainOptions chain;
  chain.anchor = Vec2(40.0, 10.0);
  chain.links = 3;
  scenes::add_joint_chain(&s, chain);
  World w = build(s);
  for (int i = 0; i < 30; ++i) {
    w.step();
    ASSERT_EQ(w.budgets().max_substeps, 4);
    ASSERT_EQ(w.budgets().max_velocity_iterations, 2) << "tick " << i;
  }

  SceneDef free;
  free.settings.gravity = Vec2::Zero();
  for (int k = 0; k < 2; ++k) {
    SceneBody b;
    b.def.type = BodyType::kDynamic;
    b.def.position = Vec2(k == 0 ? -2.0 : 2.0, 0.0);
    b.def.linear_velocity = Vec2(k == 0 ? 3.0 : -3.0, 0.0);
    ShapeDef box;
    box.geometry = make_box(0.5, 0.5);
    b.shapes.push_back(box);
    free.bodies.push_back(b);
  }
  World space = build(free);
  for (int i = 0; i < 60; ++i) {
    space.step();
    ASSERT_EQ(space.budgets().max_velocity_iterations, 2) << "tick " << i;
  }
  // They met head on without restitution: the contact stopped them (from 3 m/s each) and they
  // did not pass through each other (1 m apart, less the contacts' give).
  const BodyState a = *space.body_state(space.bodies()[0]);
  const BodyState b = *space.body_state(space.bodies()[1]);
  EXPECT_LT(std::abs(a.linear_velocity.x()), 0.5);
  EXPECT_GT(b.center.x() - a.center.x(), 0.98);
}

// Bad settings are refused with the field named.
TEST(Budget, SettingsOutOfRangeAreRefused) {
  WorldSettings s;
  s.max_substeps = 0;
  Status st = validate_settings(s);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("settings.max_substeps"), std::string::npos) << st.message();
  s = WorldSettings{};
  s.joint_give_tolerance = 0.0;
  st = validate_settings(s);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("settings.joint_give_tolerance"), std::string::npos) << st.message();
  s = WorldSettings{};
  s.contact_give_tolerance = -1.0;
  st = validate_settings(s);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("settings.contact_give_tolerance"), std::string::npos)
      << st.message();
  s = WorldSettings{};
  s.one_pass_give_tolerance = -0.001;
  st = validate_settings(s);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("settings.one_pass_give_tolerance"), std::string::npos)
      << st.message();
}

// A joint breaks whichever budget group solves it. A 1 kg box (10 N) hangs by a pin with a
// 5 N break_force beside the very heavy chain: the box is in the world's group, solved before
// the chain's 14 substeps, and its pin still breaks on the first tick and is reported.
TEST(Budget, JointsBreakInEveryBudgetGroup) {
  SceneDef s;
  add_very_heavy_chain(&s);
  World w = build(s);
  BodyDef anchor_def;
  anchor_def.position = Vec2(-50.0, 50.0);
  BodyId anchor = *w.create_body(anchor_def);
  BodyDef box_def;
  box_def.type = BodyType::kDynamic;
  box_def.position = Vec2(-50.0, 49.0);
  BodyId box = *w.create_body(box_def);
  ShapeDef shape;
  shape.geometry = make_box(0.5, 0.5);
  shape.density = 1.0;
  ASSERT_TRUE(w.create_shape(box, shape).ok());
  RevoluteJointDef pin;
  pin.body_a = anchor;
  pin.body_b = box;
  pin.local_anchor_a = Vec2(0.0, -0.5);
  pin.local_anchor_b = Vec2(0.0, 0.5);
  JointId id = *w.create_revolute_joint(pin);
  ASSERT_TRUE(w.set_joint_break_limits(id, 5.0, std::numeric_limits<double>::infinity()).ok());
  w.step();
  EXPECT_EQ(w.metrics().budget_islands, 1);
  EXPECT_EQ(w.metrics().max_substeps, 14);
  ASSERT_EQ(w.events().joints_broken.size(), 1u);
  EXPECT_EQ(w.events().joints_broken[0], id);
  EXPECT_FALSE(w.is_valid(id));
  // The chain's own joints hold.
  for (JointId j : w.joints()) EXPECT_TRUE(w.is_valid(j));
}

}  // namespace
}  // namespace fulcrum
