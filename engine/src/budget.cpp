// Per-island solver budgets: substeps where an island's joints or contacts need them.
//
// A soft joint (feedback at joint_hertz, omega = 2 pi joint_hertz) holding a load F between
// bodies of inverse masses ima and imb gives like a spring of stiffness omega^2 / (ima + imb):
// by F (ima + imb) / omega^2. The load a joint can carry at rest is at most the weight of the
// bodies jointed to it, so each set of bodies joined by joints (a joint component) predicts
//   give = |g| M K / omega^2
// with M its mass and K the largest ima + imb of its joints (the lightest pair: the weakest
// spring). A chain of light links under a heavy end, a hanging grid or cloth predicts
// centimetres to metres; a ragdoll or a motor's rotor fractions of a millimetre.
//
// Substeps and joint stiffness go together (joint feedback is stable to about a quarter of
// the substep rate), so an island run with n substeps instead of the world's S has its joints
// at joint_hertz n / S, and its give falls as (S / n)^2. Substeps do more than iterations
// for the same passes, so the island keeps about the world's biased passes per tick where its
// substeps allow: I S / n velocity iterations per substep (at least 1) instead of I. The island
// (bodies joined by joints and touching contacts) gets the least n that brings its largest
// predicted give within joint_give_tolerance, capped at max_substeps; islands that need none stay
// at S and are solved as before, bit for bit.
//
// Contacts give the same way: a soft contact point carrying a load F is pressed in by
// F K / omega_c^2 (K its effective inverse mass along the normal, omega_c = 2 pi contact_hertz,
// doubled against a body of infinite mass as the solver does). What that costs depends on the
// shapes: a millimetre is nothing to a 1 m box and most of a 2 mm plank, and a stack of planks
// sinks by the sum of its contacts' compressions. So each contact point predicts the ratio of
// its compression to the thickness of the thinner dynamic shape it touches, from the load it
// carried last tick (its warm-start impulse), and the island gets the least n that brings its
// largest ratio within contact_give_tolerance, with its contacts at contact_hertz n / S.
// Contact impulses are kept between ticks per world substep (dt / S) whatever an island ran,
// so the load read back does not depend on last tick's budget. Only contacts at rest count
// (both bodies slower than |g| dt, what gravity adds in one tick), and a point's load is taken
// as at most its island's weight, so that an impact's impulse does not buy a budget; without
// gravity there is no weight and no contact budget.
//
// Overlaps recover: a soft contact pushes out at its bias rate times the overlap, capped at
// max_correction_speed, and the relax passes take the push-out back out of the velocities. A
// deep overlap at the cap pushes no harder than a shallow one (a jammed packing never finds
// its balance), and one relax pass leaves part of a push-out shared among many contacts as
// real speed. So a contact pushed out at the cap while both its bodies are slower than the cap
// makes its island recover: kRecoveryRelax times the relax passes and kRecoveryCap times the
// cap. The narrow phase lists such contacts (recovering) as it refreshes them.
//
// One pass: a soft contact solved with one velocity pass per substep instead of two gives more
// under the same load, and the difference grows with the load. An island whose resting
// contacts are all predicted to be pressed in by at most one_pass_give_tolerance of their
// thickness (0.2 % at the default) has little to lose, and runs one velocity pass per substep.
// Measured with one pass everywhere: the arch (pressed 0.4 %) drops 2.18 cm instead of 1.9
// (its limit is 2) and the large pyramid (0.7 %) fails to stand, while twenty pyramids of base
// 10 (0.06 %) and a stack of 20 boxes stand as before. The prediction needs a known load, so a
// contact with a point new this tick or a body faster than rest (unsettled) keeps its island
// at the world's passes: impacts get both (counted as light, the 400:1 case sank 9.5 cm
// against its limit of 10 instead of 6.1). An island with a joint keeps the world's passes (a
// ragdoll pile's limits need them), and so do a recovering island and one touching a
// kinematic body (solved with the world's passes, like its kinematic body). Without gravity
// nothing rests, and every island keeps the world's passes. When no island runs a budget of
// its own the test is made for the whole world at once, which needs no islands: one contact
// pressed beyond the tolerance or unsettled, one awake joint or kinematic body, or one
// recovering overlap keeps the whole tick at the world's passes.
//
// The budget is a pure function of the bodies' masses and velocities, the joints, the contacts
// and their impulses, all state, so snapshots and replays reproduce it. Islands touching a
// moving kinematic body, or driven by a motor against a static one, keep the world's substeps.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

#include "union_find.h"
#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

// A recovering island (see the file comment): kRecoveryRelax times the relax passes and
// kRecoveryCap times the cap on push-out speed.
constexpr int kRecoveryRelax = 3;
constexpr double kRecoveryCap = 2.0;

int substeps_for(const WorldSettings& s, double ratio) {
  if (!(ratio > 1.0)) return s.substeps;
  const double need = std::ceil(s.substeps * std::sqrt(ratio));
  return need >= s.max_substeps ? s.max_substeps : std::max(s.substeps, static_cast<int>(need));
}

// A body's position in `awake` if it is there, else -1, from the solver's body slots
// (plan_budgets sets slot[awake[k]] = k + 1; other bodies' entries may be stale) instead of its
// record.
int awake_place(const std::vector<int>& slot, const std::vector<int>& awake, int body) {
  const int k = slot[body] - 1;
  return k >= 0 && k < static_cast<int>(awake.size()) && awake[k] == body ? k : -1;
}

// Takes take(end_of(joint, k, other)) for each live joint and each of its ends that is an awake
// dynamic body: k that body's position in `awake` (w.solver_scratch.body_slot is set), other the
// body at the joint's other end. With most bodies awake it walks the joint pool in id order,
// reading each joint once, and otherwise the awake bodies' joint lists, where a joint between
// two awake bodies comes up from both (take keeps maxima, flags and components, the same in any
// order). The walk over the pool also lists the awake joints (those with an awake body at
// either end) in id order for prepare_joints (WorldImpl::tick_joints), so that the tick walks
// the pool once. With the world's threads it walks chunks of the pool at once, each thread
// taking its ends with take_shared, which must give take's results in any order and from
// several threads at once; the chunks' joint lists are joined in chunk order.
template <class EndFn, class TakeFn, class SharedTakeFn>
void each_awake_joint_end(WorldImpl& w, const std::vector<int>& awake, EndFn end_of, TakeFn take,
                          SharedTakeFn take_shared) {
  const std::vector<int>& slot = w.solver_scratch.body_slot;
  const std::vector<uint8_t>& dynamic = w.budget.dynamic;
  const int n = static_cast<int>(awake.size());
  const std::vector<WorldImpl::JointHead>& heads = w.joint_heads;
  if (2 * awake.size() < static_cast<size_t>(w.body_count)) {
    for (int k = 0; k < n; ++k) {
      const int bi = awake[k];
      if (!dynamic[k]) continue;
      for (int ji : w.bodies[bi].joints) {
        const WorldImpl::JointHead& j = heads[ji];
        take(end_of(j, ji, k, j.body_a == bi ? j.body_b : j.body_a));
      }
    }
    return;
  }
  WorldImpl::TickJoints& listed = w.tick_joints;
  listed.joints.clear();
  listed.springs = 0;
  listed.stamp = w.step_stamp;
  // Joints [lo, hi) of the pool: fn(j, ji) for each awake one, found(j, ji, k, other) for its
  // ends.
  auto walk = [&](size_t lo, size_t hi, auto&& fn, auto&& found) {
    for (size_t ji = lo; ji < hi; ++ji) {
      const WorldImpl::JointHead& j = heads[ji];
      if (!j.alive) continue;
      const int ka = awake_place(slot, awake, j.body_a), kb = awake_place(slot, awake, j.body_b);
      if (ka >= 0 || kb >= 0) fn(j, ji);
      if (ka >= 0 && dynamic[ka]) found(j, ji, ka, j.body_b);
      if (kb >= 0 && dynamic[kb]) found(j, ji, kb, j.body_a);
    }
  };
  constexpr size_t kJointsPerWalk = 1024;
  const size_t count = heads.size();
  const int chunks = static_cast<int>((count + kJointsPerWalk - 1) / kJointsPerWalk);
  if (w.pool == nullptr || chunks < 2) {
    walk(
        0, count,
        [&](const WorldImpl::JointHead& j, size_t ji) {
          listed.joints.push_back(static_cast<int>(ji));
          listed.springs += j.type == JointType::kSpring;
        },
        [&](const WorldImpl::JointHead& j, size_t ji, int k, int other) {
          take(end_of(j, ji, k, other));
        });
    return;
  }
  std::vector<WorldImpl::JointWalkChunk>& out = w.scratch_joint_walk;
  if (out.size() < static_cast<size_t>(chunks)) out.resize(chunks);
  auto chunk = [&](int c) {
    WorldImpl::JointWalkChunk& mine = out[c];
    mine.joints.clear();
    mine.springs = 0;
    const size_t lo = static_cast<size_t>(c) * kJointsPerWalk;
    walk(
        lo, std::min(lo + kJointsPerWalk, count),
        [&](const WorldImpl::JointHead& j, size_t ji) {
          mine.joints.push_back(static_cast<int>(ji));
          mine.springs += j.type == JointType::kSpring;
        },
        [&](const WorldImpl::JointHead& j, size_t ji, int k, int other) {
          take_shared(end_of(j, ji, k, other));
        });
  };
  run_chunks(w.pool, chunks, chunk, true);
  for (int c = 0; c < chunks; ++c) {
    listed.joints.insert(listed.joints.end(), out[c].joints.begin(), out[c].joints.end());
    listed.springs += out[c].springs;
  }
}

}  // namespace

bool one_pass_rule(const WorldSettings& s) {
  return s.one_pass_give_tolerance > 0.0 && s.velocity_iterations > 1 &&
         s.max_substeps > s.substeps && s.contact_hertz != 0.0 &&
         (s.gravity.x() != 0.0 || s.gravity.y() != 0.0);
}

int budget_substeps(const WorldSettings& s, double give) {
  return substeps_for(s, give / s.joint_give_tolerance);
}

int contact_budget_substeps(const WorldSettings& s, double ratio) {
  return substeps_for(s, ratio / s.contact_give_tolerance);
}

double geometry_thickness(const Geometry& geometry) {
  if (const auto* c = std::get_if<Circle>(&geometry)) return 2.0 * c->radius;
  if (const auto* c = std::get_if<Capsule>(&geometry)) return 2.0 * c->radius;
  if (const auto* p = std::get_if<Polygon>(&geometry)) {
    // Across each edge's normal, the farthest vertex; the narrowest of those.
    double width = std::numeric_limits<double>::infinity();
    for (int i = 0; i < p->count; ++i) {
      double far = 0.0;
      for (int k = 0; k < p->count; ++k) {
        far = std::max(far, p->normals[i].dot(p->vertices[i] - p->vertices[k]));
      }
      width = std::min(width, far);
    }
    return width + 2.0 * p->radius;
  }
  return 0.0;
}

int budget_iterations(int iterations, int substeps, int budget) {
  return std::max(1, iterations * substeps / budget);
}

std::optional<ContactPress> WorldImpl::contact_press() const {
  const double g = std::sqrt(settings.gravity.x() * settings.gravity.x() +
                             settings.gravity.y() * settings.gravity.y());
  if (settings.max_substeps <= settings.substeps || settings.contact_hertz == 0.0 || g == 0.0) {
    return std::nullopt;
  }
  const double omega = 2.0 * 3.14159265358979323846 * settings.contact_hertz;
  ContactPress press;
  press.per_impulse = settings.substeps / settings.dt;
  press.per_load = 1.0 / (omega * omega);
  press.rest_speed2 = g * settings.dt * g * settings.dt;
  return press;
}

double WorldImpl::press_contact(int ci, const ContactPress& press) {
  contact_pressed[ci] = contact_reach[ci] = 0.0;
  contact_unsettled[ci] = 0;
  const Contact& c = contacts[ci];
  if (c.sensor || c.manifold.count == 0) return 0.0;
  const Body& a = bodies[c.body_a];
  const Body& b = bodies[c.body_b];
  // Only loads at rest count: a body faster than gravity makes it in one tick is hitting or
  // being pushed, not resting on its contacts. Such a contact, or one with a point new this
  // tick, carries a load nobody knows yet (unsettled).
  if (a.v.squaredNorm() > press.rest_speed2 || b.v.squaredNorm() > press.rest_speed2) {
    contact_unsettled[ci] = 1;
    return 0.0;
  }
  for (int i = 0; i < c.manifold.count; ++i) {
    if (!c.manifold.points[i].persisted) contact_unsettled[ci] = 1;
  }
  double thickness = std::numeric_limits<double>::infinity();
  if (a.is_dynamic()) thickness = shape_thickness[c.shape_a];
  if (b.is_dynamic()) thickness = std::min(thickness, shape_thickness[c.shape_b]);
  if (!(thickness > 0.0) || thickness == std::numeric_limits<double>::infinity()) return 0.0;
  const double ima = a.is_dynamic() ? a.inv_mass : 0.0;
  const double imb = b.is_dynamic() ? b.inv_mass : 0.0;
  const double iia = a.is_dynamic() ? a.inv_inertia : 0.0;
  const double iib = b.is_dynamic() ? b.inv_inertia : 0.0;
  // Against a body of infinite mass the solver's spring is twice as fast: a quarter of the
  // compression.
  const double scale = press.per_load / thickness * (ima == 0.0 || imb == 0.0 ? 0.25 : 1.0);
  const Vec2 normal = c.manifold.normal;
  double pressed = 0.0, reach = 0.0;
  for (int i = 0; i < c.manifold.count; ++i) {
    const ManifoldPoint& p = c.manifold.points[i];
    if (!(p.normal_impulse > 0.0)) continue;
    const double rna = cross(p.point - a.center, normal);
    const double rnb = cross(p.point - b.center, normal);
    const double k_inv = ima + imb + iia * rna * rna + iib * rnb * rnb;
    pressed = std::max(pressed, p.normal_impulse * press.per_impulse * k_inv * scale);
    reach = std::max(reach, k_inv * scale);
  }
  contact_pressed[ci] = pressed;
  contact_reach[ci] = reach;
  return pressed;
}

std::optional<RecoveryRule> WorldImpl::recovery_rule() const {
  if (settings.max_substeps <= settings.substeps || settings.contact_hertz == 0.0 ||
      settings.relax_iterations < 1) {
    return std::nullopt;
  }
  const double h = settings.dt / settings.substeps;
  RecoveryRule rule;
  rule.rate = make_softness(settings.contact_hertz, settings.contact_damping_ratio, h).bias_rate;
  rule.fixed_rate =
      make_softness(2.0 * settings.contact_hertz, settings.contact_damping_ratio, h).bias_rate;
  rule.cap = settings.max_correction_speed;
  return rule;
}

bool WorldImpl::recovering(const Contact& c, const RecoveryRule& rule) const {
  if (c.sensor || c.manifold.count == 0) return false;
  double depth = 0.0;
  for (int i = 0; i < c.manifold.count; ++i) {
    depth = std::max(depth, -c.manifold.points[i].separation);
  }
  // Most contacts are shallower than the cap's reach even at the stiffer rate: done, without
  // reading the bodies.
  if (rule.fixed_rate * depth < rule.cap) return false;
  const Body& a = bodies[c.body_a];
  const Body& b = bodies[c.body_b];
  const bool fixed = !a.is_dynamic() || !b.is_dynamic();
  if (!fixed && rule.rate * depth < rule.cap) return false;
  const double cap2 = rule.cap * rule.cap;
  return a.v.squaredNorm() <= cap2 && b.v.squaredNorm() <= cap2;
}

bool WorldImpl::plan_joint_needs(const std::vector<int>& awake, double g) {
  const int n = static_cast<int>(awake.size());
  const std::vector<int>& slot = solver_scratch.body_slot;
  std::vector<int>& parent = scratch_parent;
  std::vector<double>& mass = budget.mass;
  std::vector<double>& weakest = budget.weakest;
  weakest.assign(n, 0.0);
  std::vector<uint8_t>& held = budget.held;
  held.assign(n, 0);
  bool any = false;
  // Each joint that is not a spring: its awake dynamic bodies' weakest pair, and both joined
  // when both are awake and dynamic. Any joint: whether it holds its body to a moving
  // kinematic body or drives it against a body of infinite mass (for plan_budgets, in this
  // walk over the joints so that a tick makes one).
  // An other end that is awake and dynamic is read from the dense arrays plan_budgets filled;
  // only another kind of end reads the body record (and the joint's motor flag).
  const std::vector<double>& inv_mass = budget.inv_mass;
  const std::vector<uint8_t>& dynamic = budget.dynamic;
  auto end_of = [&](const JointHead& j, size_t ji, int k, int other) {
    JointEnd e;
    e.k = k;
    e.spring = j.type == JointType::kSpring;
    if (const int ko = awake_place(slot, awake, other); ko >= 0 && dynamic[ko]) {
      if (e.spring) return e;
      e.weakest = inv_mass[k] + inv_mass[ko];
      e.partner = ko;
      return e;
    }
    const Body& o = bodies[other];
    const bool driven = joints[ji].enable_motor || j.type == JointType::kMotor;
    e.held = !o.is_dynamic() && (o.awake || driven);
    if (e.spring) return e;
    e.weakest = inv_mass[k] + o.inv_mass;
    return e;
  };
  auto take = [&](const JointEnd& e) {
    if (e.held) held[e.k] = 1;
    if (e.spring) return;
    any = true;
    weakest[e.k] = std::max(weakest[e.k], e.weakest);
    if (e.partner >= 0) unite(parent, e.k, e.partner);
  };
  // The same from several threads: a flag set, a maximum (of sums of inverse masses, never
  // negative) and the sets, none of which depends on the order.
  std::atomic<bool> any_shared{false};
  auto take_shared = [&](const JointEnd& e) {
    if (e.held) std::atomic_ref<uint8_t>(held[e.k]).store(1, std::memory_order_relaxed);
    if (e.spring) return;
    if (!any_shared.load(std::memory_order_relaxed)) {
      any_shared.store(true, std::memory_order_relaxed);
    }
    std::atomic_ref<double> most(weakest[e.k]);
    double seen = most.load(std::memory_order_relaxed);
    while (e.weakest > seen &&
           !most.compare_exchange_weak(seen, e.weakest, std::memory_order_relaxed)) {
    }
    if (e.partner >= 0) unite_shared(parent, e.k, e.partner);
  };
  each_awake_joint_end(*this, awake, end_of, take, take_shared);
  any = any || any_shared.load(std::memory_order_relaxed);
  if (!any || g == 0.0) return false;
  mass.assign(n, 0.0);
  for (int k = 0; k < n; ++k) {
    if (!budget.dynamic[k]) continue;
    const int r = find_root(parent, k);
    mass[r] += budget.body_mass[k];
    if (r != k) weakest[r] = std::max(weakest[r], weakest[k]);
  }
  const double omega = 2.0 * 3.14159265358979323846 * settings.joint_hertz;
  std::vector<int>& need = budget.need;
  bool more = false;
  for (int k = 0; k < n; ++k) {
    if (find_root(parent, k) != k || weakest[k] == 0.0) continue;
    need[k] = budget_substeps(settings, g * mass[k] * weakest[k] / (omega * omega));
    more = more || need[k] > settings.substeps;
  }
  return more;
}

bool WorldImpl::plan_budgets(const std::vector<int>& awake) {
  budget.islands = 0;
  budget.max_substeps = settings.substeps;
  budget.max_relax = settings.relax_iterations;
  budget.groups.clear();
  budget.plain_bodies = false;
  if (settings.max_substeps <= settings.substeps) return false;
  const double g = std::sqrt(settings.gravity.x() * settings.gravity.x() +
                             settings.gravity.y() * settings.gravity.y());
  const bool joint_budgets = settings.joint_hertz != 0.0 && g != 0.0;
  const bool contact_budgets = contact_press().has_value();
  const bool relax_budgets = !budget.recovering.empty();
  if (!joint_budgets && !contact_budgets && !relax_budgets) return false;
  const int n = static_cast<int>(awake.size());
  std::vector<int>& slot = solver_scratch.body_slot;  // body -> 1 + position in `awake`
  if (slot.size() < bodies.size()) slot.resize(bodies.size(), 0);
  for (int k = 0; k < n; ++k) slot[awake[k]] = k + 1;
  // Whether each awake body is dynamic and holds a joint, and its mass, read once from the
  // large body records (three of their cache lines), in chunks on the world's threads. In a
  // world without joints or kinematic bodies every awake body is dynamic and holds none (static
  // bodies never wake), and the masses are read only if a budget is planned (below).
  std::vector<uint8_t>& dynamic = budget.dynamic;
  std::vector<uint8_t>& jointed = budget.jointed;
  std::vector<double>& body_mass = budget.body_mass;
  body_mass.resize(n);
  constexpr int kBodiesPerChunk = 1024;
  const int chunks = (n + kBodiesPerChunk - 1) / kBodiesPerChunk;
  auto read_masses = [&](int c) {
    for (int k = c * kBodiesPerChunk; k < std::min(n, (c + 1) * kBodiesPerChunk); ++k) {
      body_mass[k] = bodies[awake[k]].mass;
    }
  };
  const bool simple = kinematic_bodies == 0 && joints.size() == free_joints.size();
  bool plain = true;
  if (simple) {
    dynamic.assign(n, 1);
    jointed.assign(n, 0);
  } else {
    dynamic.resize(n);
    jointed.resize(n);
    budget.inv_mass.resize(n);
    std::vector<double>& inv_mass = budget.inv_mass;
    auto read_bodies = [&](int c) {
      for (int k = c * kBodiesPerChunk; k < std::min(n, (c + 1) * kBodiesPerChunk); ++k) {
        const Body& b = bodies[awake[k]];
        dynamic[k] = b.is_dynamic();
        jointed[k] = !b.joints.empty();
        body_mass[k] = b.mass;
        inv_mass[k] = b.inv_mass;
      }
    };
    run_chunks(chunks > 1 ? pool : nullptr, chunks, read_bodies, true);
    for (int k = 0; k < n && plain; ++k) plain = dynamic[k] && !jointed[k];
  }
  budget.plain_bodies = plain;
  // A body's position in `awake` if it is there and dynamic; -1 otherwise.
  auto awake_dynamic = [&](int body) {
    const int k = awake_place(slot, awake, body);
    return k >= 0 && dynamic[k] ? k : -1;
  };

  // Joint components: mass and weakest joint (first per body, then per component).
  std::vector<int>& parent = scratch_parent;
  parent.resize(n);
  for (int k = 0; k < n; ++k) parent[k] = k;
  std::vector<int>& need = budget.need;
  need.assign(n, settings.substeps);
  bool more = false;
  // Joint components are joined whether or not their joints need a budget: a joint's two
  // bodies are always solved in one group.
  more = plan_joint_needs(awake, joint_budgets ? g : 0.0);

  // Contacts at rest: each body's worst point (press_contact computed each contact's as the
  // step collided it): its compression over thickness from last tick's load (`pressed`), and
  // per newton of load (`reach`), which bounds the first by the island's weight below. Skipped
  // when no contact of the step asks for more substeps.
  std::vector<double>& pressed = budget.pressed;
  std::vector<double>& reach = budget.reach;
  pressed.assign(n, 0.0);
  reach.assign(n, 0.0);
  std::vector<uint8_t>& unsettled = budget.body_unsettled;
  unsettled.assign(n, 0);
  // Over the touching contacts collide listed: every touching solid contact of an awake body
  // is there (maxima and an or, the same in any order).
  auto walk_pressed = [&] {
    for (size_t t = 0; t < touching_contacts.size(); ++t) {
      const int ci = touching_contacts[t];
      for (const int bi : {touching_bodies[t].a, touching_bodies[t].b}) {
        const int k = awake_dynamic(bi);
        if (k < 0) continue;
        pressed[k] = std::max(pressed[k], contact_pressed[ci]);
        reach[k] = std::max(reach[k], contact_reach[ci]);
        unsettled[k] = unsettled[k] | contact_unsettled[ci];
      }
    }
    for (int k = 0; k < n; ++k) {
      more = more || contact_budget_substeps(settings, pressed[k]) > settings.substeps;
    }
  };
  bool walked = false;
  if (contact_budgets && budget.most_pressed > settings.contact_give_tolerance) {
    walk_pressed();
    walked = true;
  }
  // Recovering contacts (collide listed them) give their dynamic bodies more relax passes.
  std::vector<int>& relax_need = budget.relax_need;
  relax_need.assign(n, settings.relax_iterations);
  for (int ci : budget.recovering) {
    const Contact& c = contacts[ci];
    for (int bi : {c.body_a, c.body_b}) {
      if (const int k = awake_dynamic(bi); k >= 0) {
        relax_need[k] = kRecoveryRelax * settings.relax_iterations;
        more = true;
      }
    }
  }
  if (!more) return false;
  if (simple) run_chunks(chunks > 1 ? pool : nullptr, chunks, read_masses, true);
  // One-pass islands (see the file comment) need each body's worst point too, unless every
  // contact is within one_pass_give_tolerance. (A tick with no budget to plan makes the test
  // for the whole world from the largest, in solve.)
  const bool one_pass = one_pass_rule(settings);
  if (one_pass && !walked &&
      (budget.most_pressed > settings.one_pass_give_tolerance || budget.unsettled)) {
    walk_pressed();
  }

  // Islands: joint components joined by touching contacts. One touching a kinematic body keeps
  // the world's substeps (the kinematic body moves once, with the base group), and so does one
  // driven by a motor against a body of infinite mass (a tumbler's drum, a spinner's arm):
  // with torque to spare it moves its body as a kinematic one would, and what it pushes
  // carries its drive, not a weight.
  std::vector<int> component(n);
  for (int k = 0; k < n; ++k) component[k] = find_root(parent, k);
  std::vector<int>& island_need = budget.island_need;
  island_need.assign(n, 0);
  std::vector<int>& island_relax = budget.island_relax;
  island_relax.assign(n, settings.relax_iterations);
  // Per island root: whether it must keep the world's velocity passes (a joint, a contact
  // pressed beyond one_pass_give_tolerance, a recovering overlap).
  std::vector<uint8_t>& island_passes = budget.island_passes;
  island_passes.assign(n, one_pass ? 0 : 1);
  // A dynamic body jointed to a moving kinematic body, or driven against a body of infinite
  // mass (plan_joint_needs found them).
  const std::vector<uint8_t>& held = budget.held;
  for (int k = 0; k < n; ++k) {
    if (held[k]) island_need[k] = -1;
  }
  // Touching contacts, from collide's list (in id order: far cheaper than walking every body's
  // list, and the islands are the same whatever the order).
  for (const ContactBodies& c : touching_bodies) {
    const int ka = awake_dynamic(c.a);
    const int kb = awake_dynamic(c.b);
    if (ka >= 0 && kb >= 0) {
      unite(parent, ka, kb);
    } else if (ka >= 0 && bodies[c.b].type == BodyType::kKinematic) {
      island_need[ka] = -1;
    } else if (kb >= 0 && bodies[c.a].type == BodyType::kKinematic) {
      island_need[kb] = -1;
    }
  }
  // A contact carries at most its island's weight: an impact's impulse does not buy a budget.
  std::vector<double>& weight = budget.mass;
  if (contact_budgets) {
    weight.assign(n, 0.0);
    for (int k = 0; k < n; ++k) {
      if (dynamic[k]) weight[find_root(parent, k)] += g * body_mass[k];
    }
  }
  for (int k = 0; k < n; ++k) {
    const int r = find_root(parent, k);
    if (dynamic[k] && (jointed[k] || pressed[k] > settings.one_pass_give_tolerance ||
                       unsettled[k] || relax_need[k] > settings.relax_iterations)) {
      island_passes[r] = 1;
    }
    if (island_need[k] < 0 || island_need[r] < 0) {
      island_need[r] = -1;
      continue;
    }
    int contact_need = settings.substeps;
    if (pressed[k] > 0.0) {
      contact_need = contact_budget_substeps(settings, std::min(pressed[k], weight[r] * reach[k]));
    }
    island_need[r] = std::max({island_need[r], need[component[k]], contact_need});
    island_relax[r] = std::max(island_relax[r], relax_need[k]);
  }
  // Groups by substeps, relax passes and velocity passes, ascending; bodies in id order within
  // each. Islands touching a kinematic body keep the world's passes: the kinematic body is
  // solved once, with the base group of the world's passes.
  const int iterations = settings.velocity_iterations;
  for (int k = 0; k < n; ++k) {
    const int r = find_root(parent, k);
    const bool base = !dynamic[k] || island_need[r] <= 0;
    const int sub = base ? settings.substeps : std::max(island_need[r], settings.substeps);
    const int relax = base ? settings.relax_iterations : island_relax[r];
    const bool one = dynamic[k] && island_need[r] >= 0 && !island_passes[r];
    const int passes = one ? 1 : budget_iterations(iterations, settings.substeps, sub);
    auto it = std::find_if(budget.groups.begin(), budget.groups.end(), [&](const BudgetGroup& grp) {
      return grp.substeps == sub && grp.relax == relax && grp.iterations == passes;
    });
    if (it == budget.groups.end()) {
      budget.groups.push_back(BudgetGroup{sub, relax, passes, {}, {}, {}});
      it = budget.groups.end() - 1;
    }
    it->bodies.push_back(awake[k]);
    if (r == k && (sub > settings.substeps || relax > settings.relax_iterations)) {
      ++budget.islands;
    }
    budget.max_substeps = std::max(budget.max_substeps, sub);
    budget.max_relax = std::max(budget.max_relax, relax);
  }
  if (budget.groups.size() < 2 && budget.groups[0].substeps == settings.substeps &&
      budget.groups[0].relax == settings.relax_iterations &&
      budget.groups[0].iterations == iterations) {
    return false;
  }
  std::sort(budget.groups.begin(), budget.groups.end(),
            [](const BudgetGroup& a, const BudgetGroup& b) {
              if (a.substeps != b.substeps) return a.substeps < b.substeps;
              return a.relax != b.relax ? a.relax < b.relax : a.iterations < b.iterations;
            });
  // Each touching contact goes to the group of its lower-indexed awake body, in id order.
  std::vector<int>& group_of = budget.group_of;
  group_of.resize(n);
  for (size_t i = 0; i < budget.groups.size(); ++i) {
    budget.groups[i].contacts.clear();
    budget.groups[i].contact_bodies.clear();
    for (const int bi : budget.groups[i].bodies) group_of[slot[bi] - 1] = static_cast<int>(i);
  }
  for (size_t t = 0; t < touching_contacts.size(); ++t) {
    const ContactBodies& c = touching_bodies[t];
    const bool awake_a = bodies[c.a].awake, awake_b = bodies[c.b].awake;
    const int owner = awake_a && awake_b ? std::min(c.a, c.b) : (awake_a ? c.a : c.b);
    BudgetGroup& grp = budget.groups[group_of[slot[owner] - 1]];
    grp.contacts.push_back(touching_contacts[t]);
    grp.contact_bodies.push_back(c);
  }
  return true;
}

bool WorldImpl::one_pass_tick() const {
  // one_pass_rule implies contact_press(): collide computed most_pressed and unsettled, and
  // plan_budgets read the awake bodies (plain_bodies: every island without a joint or a
  // kinematic body).
  return one_pass_rule(settings) && budget.recovering.empty() && !budget.unsettled &&
         budget.most_pressed <= settings.one_pass_give_tolerance && budget.plain_bodies;
}

void WorldImpl::solve(const std::vector<int>& awake) {
  island_batch_count = 0;
  budget.base_substeps = settings.substeps;
  budget.max_iterations = settings.velocity_iterations;
  if (!plan_budgets(awake)) {
    if (!one_pass_tick()) {
      if (!solve_in_batches(awake)) solve_group(awake, touching_contacts, touching_bodies);
      return;
    }
    const int iterations = settings.velocity_iterations;
    settings.velocity_iterations = budget.max_iterations = 1;
    if (!solve_in_batches(awake)) solve_group(awake, touching_contacts, touching_bodies);
    settings.velocity_iterations = iterations;
    return;
  }
  const int substeps = settings.substeps;
  const int iterations = settings.velocity_iterations;
  const double joint_hertz = settings.joint_hertz;
  const double contact_hertz = settings.contact_hertz;
  const int relax = settings.relax_iterations;
  const double cap = settings.max_correction_speed;
  budget.max_iterations = 0;
  // Each group prepares its own joints (solver_scratch.joints); break_joints wants them all.
  std::vector<int>& solved_joints = budget.solved_joints;
  solved_joints.clear();
  for (const BudgetGroup& grp : budget.groups) {
    settings.substeps = grp.substeps;
    settings.relax_iterations = grp.relax;
    settings.max_correction_speed = grp.relax > relax ? kRecoveryCap * cap : cap;
    settings.velocity_iterations = grp.iterations;
    budget.max_iterations = std::max(budget.max_iterations, grp.iterations);
    settings.joint_hertz = joint_hertz * grp.substeps / substeps;
    settings.contact_hertz = contact_hertz * grp.substeps / substeps;
    solve_group(grp.bodies, grp.contacts, grp.contact_bodies);
    if (budget.groups.size() > 1) {
      solved_joints.insert(solved_joints.end(), solver_scratch.joints.begin(),
                           solver_scratch.joints.end());
    }
  }
  // One group's joints are already all of them, in id order.
  if (budget.groups.size() > 1) {
    std::sort(solved_joints.begin(), solved_joints.end());
    solver_scratch.joints.assign(solved_joints.begin(), solved_joints.end());
  }
  settings.substeps = substeps;
  settings.velocity_iterations = iterations;
  settings.joint_hertz = joint_hertz;
  settings.contact_hertz = contact_hertz;
  settings.relax_iterations = relax;
  settings.max_correction_speed = cap;
  // Later stages read the slots of the whole awake set.
  std::vector<int>& slot = solver_scratch.body_slot;
  for (size_t k = 0; k < awake.size(); ++k) slot[awake[k]] = static_cast<int>(k + 1);
}

// Islands in batches. A world of many islands (a field of piles) solved as one group streams
// every colour's rows through the caches once a pass, a dozen passes a tick: for twenty thousand
// boxes, megabytes a pass. Islands share no dynamic body, so an island's bodies see the same
// operations in the same order whether its contacts are solved with every other island's or
// with a few: a contact's colour is the lowest its own island's earlier contacts leave free, its
// lane changes nothing it computes, and every other stage works body by body or contact by
// contact. So the islands are solved in batches of about kBatchBodies bodies, each batch through
// all its substeps while its rows stay in the caches (a batch's lanes, bodies and rows take
// about 1.2 MB, within one core's second-level cache on the machines measured), with the same
// bits as one group. With several threads they share each batch's colours, as they would one
// group's. Only where nothing couples the batches' solves: no joint (a group's joints decide
// how it warm starts), no restitution (likewise), no kinematic body (solved once, with one
// group), soft contacts in lanes, and no early exit (a pass's largest impulse is the whole
// group's).
bool WorldImpl::solve_in_batches(const std::vector<int>& awake) {
  constexpr size_t kBatchedFrom = 8192;  // awake bodies
  constexpr int kBatchBodies = 2048;
  const int n = static_cast<int>(awake.size());
  if (!batch_islands || awake.size() < kBatchedFrom || settings.contact_hertz == 0.0 ||
      settings.early_exit_tolerance > 0.0 || kinematic_bodies != 0 ||
      joints.size() != free_joints.size() || budget.restitution) {
    return false;
  }
  std::vector<int>& slot = solver_scratch.body_slot;  // body -> 1 + position in `awake`
  if (slot.size() < bodies.size()) slot.resize(bodies.size(), 0);
  for (int k = 0; k < n; ++k) slot[awake[k]] = k + 1;
  // Islands: every awake body is dynamic (no kinematic body; static bodies never wake).
  std::vector<int>& parent = scratch_parent;
  parent.resize(n);
  for (int k = 0; k < n; ++k) parent[k] = k;
  // Each touching contact's awake body (A's position, or B's when A is not awake), for its
  // batch. Collide woke every body a touching contact holds; should one be asleep all the same,
  // the group is solved whole, as before (nothing is changed yet).
  std::vector<int>& owner = scratch_owner;
  owner.resize(touching_bodies.size());
  for (size_t t = 0; t < touching_bodies.size(); ++t) {
    const int ka = awake_place(slot, awake, touching_bodies[t].a);
    const int kb = awake_place(slot, awake, touching_bodies[t].b);
    if (ka >= 0 && kb >= 0) unite(parent, ka, kb);
    owner[t] = ka >= 0 ? ka : kb;
    if (owner[t] < 0) return false;
  }
  // Islands in the order of their first body (each root is its island's least position), a
  // batch closed once it holds kBatchBodies.
  std::vector<int>& batch_of = budget.group_of;  // per position in `awake`, then per root
  batch_of.resize(n);
  int batches = 0, filled = kBatchBodies;
  for (int k = 0; k < n; ++k) {
    const int r = find_root(parent, k);
    if (r == k) {
      if (filled >= kBatchBodies) {
        ++batches;
        filled = 0;
      }
      batch_of[k] = batches - 1;
    } else {
      batch_of[k] = batch_of[r];
    }
    ++filled;
  }
  if (batches < 2) return false;
  if (static_cast<int>(island_batches.size()) < batches) island_batches.resize(batches);
  for (int b = 0; b < batches; ++b) {
    island_batches[b].bodies.clear();
    island_batches[b].contacts.clear();
    island_batches[b].contact_bodies.clear();
  }
  for (int k = 0; k < n; ++k) island_batches[batch_of[k]].bodies.push_back(awake[k]);
  for (size_t t = 0; t < touching_contacts.size(); ++t) {
    IslandBatch& batch = island_batches[batch_of[owner[t]]];
    batch.contacts.push_back(touching_contacts[t]);
    batch.contact_bodies.push_back(touching_bodies[t]);
  }
  island_batch_count = batches;
  for (int b = 0; b < batches; ++b) {
    IslandBatch& batch = island_batches[b];
    std::swap(coloured_contacts, batch.coloured);
    solve_group(batch.bodies, batch.contacts, batch.contact_bodies);
    std::swap(coloured_contacts, batch.coloured);
  }
  // Later stages read the slots of the whole awake set.
  for (int k = 0; k < n; ++k) slot[awake[k]] = k + 1;
  return true;
}

}  // namespace fulcrum
