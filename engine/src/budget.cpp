// Per-island solver budgets: substeps where an island's joints need them.
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
// at S and are solved as before, bit for bit. The budget is a pure function of the bodies' masses,
// the joints and the contacts, so snapshots and replays reproduce it.
#include <algorithm>
#include <cmath>

#include "world_impl.h"

namespace fulcrum {

namespace {

int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

void unite(std::vector<int>& parent, int a, int b) {
  a = find_root(parent, a);
  b = find_root(parent, b);
  if (a != b) parent[std::max(a, b)] = std::min(a, b);
}

}  // namespace

int budget_substeps(const WorldSettings& s, double give) {
  if (!(give > s.joint_give_tolerance)) return s.substeps;
  const double need = std::ceil(s.substeps * std::sqrt(give / s.joint_give_tolerance));
  return need >= s.max_substeps ? s.max_substeps : std::max(s.substeps, static_cast<int>(need));
}

int budget_iterations(int iterations, int substeps, int budget) {
  return std::max(1, iterations * substeps / budget);
}

bool WorldImpl::plan_budgets(const std::vector<int>& awake) {
  budget.islands = 0;
  budget.max_substeps = settings.substeps;
  budget.groups.clear();
  const double g = std::sqrt(settings.gravity.x() * settings.gravity.x() +
                             settings.gravity.y() * settings.gravity.y());
  if (settings.max_substeps <= settings.substeps || settings.joint_hertz == 0.0 || g == 0.0) {
    return false;
  }
  const int n = static_cast<int>(awake.size());
  std::vector<int>& slot = solver_scratch.body_slot;  // body -> 1 + position in `awake`
  if (slot.size() < bodies.size()) slot.resize(bodies.size(), 0);
  for (int k = 0; k < n; ++k) slot[awake[k]] = k + 1;

  // Joint components: mass and weakest joint (first per body, then per component).
  std::vector<int>& parent = scratch_parent;
  parent.resize(n);
  for (int k = 0; k < n; ++k) parent[k] = k;
  std::vector<double>& mass = budget.mass;
  std::vector<double>& weakest = budget.weakest;
  weakest.assign(n, 0.0);
  bool any = false;
  for (int k = 0; k < n; ++k) {
    const int bi = awake[k];
    if (!bodies[bi].is_dynamic()) continue;
    for (int ji : bodies[bi].joints) {
      const Joint& j = joints[ji];
      if (j.type == JointType::kSpring) continue;
      any = true;
      const int other = j.body_a == bi ? j.body_b : j.body_a;
      const Body& o = bodies[other];
      weakest[k] = std::max(weakest[k], bodies[bi].inv_mass + o.inv_mass);
      if (o.is_dynamic() && o.awake) unite(parent, k, slot[other] - 1);
    }
  }
  if (!any) return false;
  mass.assign(n, 0.0);
  for (int k = 0; k < n; ++k) {
    const Body& b = bodies[awake[k]];
    if (!b.is_dynamic()) continue;
    const int r = find_root(parent, k);
    mass[r] += b.mass;
    if (r != k) weakest[r] = std::max(weakest[r], weakest[k]);
  }
  const double omega = 2.0 * 3.14159265358979323846 * settings.joint_hertz;
  std::vector<int>& need = budget.need;
  need.assign(n, settings.substeps);
  bool more = false;
  for (int k = 0; k < n; ++k) {
    if (find_root(parent, k) != k || weakest[k] == 0.0) continue;
    need[k] = budget_substeps(settings, g * mass[k] * weakest[k] / (omega * omega));
    more = more || need[k] > settings.substeps;
  }
  if (!more) return false;

  // Islands: joint components joined by touching contacts. One touching a kinematic body keeps
  // the world's substeps (the kinematic body moves once, with the base group).
  std::vector<int> component(n);
  for (int k = 0; k < n; ++k) component[k] = find_root(parent, k);
  std::vector<int>& island_need = budget.island_need;
  island_need.assign(n, 0);
  for (int k = 0; k < n; ++k) {
    const int bi = awake[k];
    if (!bodies[bi].is_dynamic()) continue;
    for (int ji : bodies[bi].joints) {
      const Joint& j = joints[ji];
      const Body& o = bodies[j.body_a == bi ? j.body_b : j.body_a];
      if (o.awake && !o.is_dynamic()) island_need[k] = -1;
    }
    for (int e = bodies[bi].contact_list; e != kNullIndex;) {
      const Contact& c = contacts[edge_contact(e)];
      e = c.edges[edge_side(e)].next;
      if (!c.touching || c.sensor) continue;
      const int other = c.body_a == bi ? c.body_b : c.body_a;
      const Body& o = bodies[other];
      if (o.type == BodyType::kKinematic) {
        island_need[k] = -1;
      } else if (o.is_dynamic() && o.awake) {
        unite(parent, k, slot[other] - 1);
      }
    }
  }
  for (int k = 0; k < n; ++k) {
    const int r = find_root(parent, k);
    if (island_need[k] < 0 || island_need[r] < 0) {
      island_need[r] = -1;
    } else {
      island_need[r] = std::max(island_need[r], need[component[k]]);
    }
  }
  // Groups by substeps, ascending; bodies in id order within each.
  std::vector<int> counts;
  for (int k = 0; k < n; ++k) {
    const int r = find_root(parent, k);
    const int sub = !bodies[awake[k]].is_dynamic() || island_need[r] <= 0
                        ? settings.substeps
                        : std::max(island_need[r], settings.substeps);
    auto it = std::find_if(budget.groups.begin(), budget.groups.end(),
                           [&](const BudgetGroup& grp) { return grp.substeps == sub; });
    if (it == budget.groups.end()) {
      budget.groups.push_back(BudgetGroup{sub, {}});
      it = budget.groups.end() - 1;
    }
    it->bodies.push_back(awake[k]);
    if (r == k && sub > settings.substeps) ++budget.islands;
    budget.max_substeps = std::max(budget.max_substeps, sub);
  }
  if (budget.groups.size() < 2 && budget.groups[0].substeps == settings.substeps) return false;
  std::sort(budget.groups.begin(), budget.groups.end(),
            [](const BudgetGroup& a, const BudgetGroup& b) { return a.substeps < b.substeps; });
  return true;
}

void WorldImpl::solve(const std::vector<int>& awake) {
  if (!plan_budgets(awake)) {
    solve_group(awake);
    return;
  }
  const int substeps = settings.substeps;
  const int iterations = settings.velocity_iterations;
  const double joint_hertz = settings.joint_hertz;
  for (const BudgetGroup& grp : budget.groups) {
    settings.substeps = grp.substeps;
    settings.velocity_iterations = budget_iterations(iterations, substeps, grp.substeps);
    settings.joint_hertz = joint_hertz * grp.substeps / substeps;
    solve_group(grp.bodies);
  }
  settings.substeps = substeps;
  settings.velocity_iterations = iterations;
  settings.joint_hertz = joint_hertz;
  // Later stages read the slots of the whole awake set.
  std::vector<int>& slot = solver_scratch.body_slot;
  for (size_t k = 0; k < awake.size(); ++k) slot[awake[k]] = static_cast<int>(k + 1);
}

}  // namespace fulcrum
