// Queries against the current state: ray casts, box and point overlaps, accuracy metrics.
// Results are sorted so that they never depend on the tree's internal order.
#include <algorithm>
#include <utility>

#include "world_impl.h"

namespace fulcrum {

namespace {

bool passes(const Filter& f, const QueryFilter& q) {
  return (f.category_bits & q.mask_bits) != 0 && (q.category_bits & f.mask_bits) != 0;
}

// Casts against every shape whose box the ray crosses; `clip` shortens the ray to each hit
// (closest-hit queries) or keeps it whole (all-hit queries).
std::vector<RayHit> cast(const WorldImpl& w, const Vec2& origin, const Vec2& translation,
                         const QueryFilter& filter, bool clip) {
  std::vector<RayHit> hits;
  if (!is_finite(origin) || !is_finite(translation)) return hits;
  // Both trees, the static one with the ray as far as the moving one left it.
  double reach = 1.0;
  for (const DynamicTree* t : {&w.tree, &w.static_tree}) {
    const RayCastInput input{origin, translation, reach};
    t->ray_cast(input, [&](const RayCastInput& sub, int proxy) {
      int si = static_cast<int>(t->user_data(proxy));
      const Shape& s = w.shapes[si];
      if (!passes(s.filter, filter)) return sub.max_fraction;
      const Transform& xf = w.bodies[s.body].xf;
      RayCastInput local{xf.inv_apply(sub.origin), xf.q.inv_rotate(sub.translation),
                         sub.max_fraction};
      CastOutput out = ray_cast(s.geometry, local);
      if (!out.hit) return sub.max_fraction;
      hits.push_back(
          RayHit{w.shape_id(si), xf.apply(out.point), xf.q.rotate(out.normal), out.fraction});
      // Keep equal fractions reachable so that ties are broken by shape id below.
      if (clip) reach = std::min(reach, out.fraction);
      return clip ? out.fraction : sub.max_fraction;
    });
  }
  std::sort(hits.begin(), hits.end(), [](const RayHit& a, const RayHit& b) {
    return a.fraction != b.fraction ? a.fraction < b.fraction : a.shape.index < b.shape.index;
  });
  return hits;
}

// Shape indices to handles, in index order.
std::vector<ShapeId> sorted_ids(const WorldImpl& w, std::vector<int> found) {
  std::sort(found.begin(), found.end());
  std::vector<ShapeId> out;
  out.reserve(found.size());
  for (int si : found) out.push_back(w.shape_id(si));
  return out;
}

}  // namespace

std::optional<RayHit> World::ray_cast_closest(const Vec2& origin, const Vec2& translation,
                                              const QueryFilter& filter) const {
  std::vector<RayHit> hits = cast(*impl_, origin, translation, filter, true);
  if (hits.empty()) return std::nullopt;
  return hits.front();
}

std::vector<RayHit> World::ray_cast_all(const Vec2& origin, const Vec2& translation,
                                        const QueryFilter& filter) const {
  return cast(*impl_, origin, translation, filter, false);
}

std::vector<ShapeId> World::overlap_aabb(const AABB& box, const QueryFilter& filter) const {
  const WorldImpl& w = *impl_;
  std::vector<int> found;
  for (const DynamicTree* t : {&w.tree, &w.static_tree}) {
    t->query(box, [&](int proxy) {
      int si = static_cast<int>(t->user_data(proxy));
      const Shape& s = w.shapes[si];
      if (passes(s.filter, filter) && compute_aabb(s.geometry, w.bodies[s.body].xf).overlaps(box)) {
        found.push_back(si);
      }
      return true;
    });
  }
  return sorted_ids(w, std::move(found));
}

std::vector<ShapeId> World::overlap_point(const Vec2& point, const QueryFilter& filter) const {
  const WorldImpl& w = *impl_;
  std::vector<int> found;
  AABB box{point, point};
  for (const DynamicTree* t : {&w.tree, &w.static_tree}) {
    t->query(box, [&](int proxy) {
      int si = static_cast<int>(t->user_data(proxy));
      const Shape& s = w.shapes[si];
      if (passes(s.filter, filter) &&
          contains_point(s.geometry, w.bodies[s.body].xf.inv_apply(point))) {
        found.push_back(si);
      }
      return true;
    });
  }
  return sorted_ids(w, std::move(found));
}

World::Budgets World::budgets() const {
  const WorldImpl& w = *impl_;
  return Budgets{
      w.budget.islands, std::max(w.budget.max_substeps, w.settings.substeps),
      std::max(w.budget.max_relax, w.settings.relax_iterations),
      w.budget.max_iterations > 0 ? w.budget.max_iterations : w.settings.velocity_iterations};
}

WorldMetrics World::metrics() const {
  const WorldImpl& w = *impl_;
  WorldMetrics m;
  m.tick = w.tick;
  m.body_count = w.body_count;
  m.awake_body_count = static_cast<int>(w.awake_bodies.size());
  const Budgets budget = budgets();
  m.budget_islands = budget.islands;
  m.max_substeps = budget.max_substeps;
  m.max_relax_iterations = budget.max_relax_iterations;
  m.max_velocity_iterations = budget.max_velocity_iterations;
  double penetration_sum = 0.0;
  int penetrating = 0;
  for (const Contact& c : w.contacts) {
    if (!c.alive || !c.touching || c.sensor) continue;
    ++m.contact_count;
    for (int i = 0; i < c.manifold.count; ++i) {
      double depth = -c.manifold.points[i].separation;
      if (depth <= 0.0) continue;
      m.max_penetration = std::max(m.max_penetration, depth);
      penetration_sum += depth;
      ++penetrating;
    }
  }
  m.mean_penetration = penetrating > 0 ? penetration_sum / penetrating : 0.0;
  for (const Body& b : w.bodies) {
    if (!b.alive || !b.is_dynamic()) continue;
    m.kinetic_energy += 0.5 * b.mass * length_squared(b.v) + 0.5 * b.inertia * b.w * b.w;
    m.potential_energy -= b.mass * b.gravity_scale * dot(w.settings.gravity, b.center);
    m.linear_momentum += b.mass * b.v;
    m.angular_momentum += b.mass * cross(b.center, b.v) + b.inertia * b.w;
    m.max_speed = std::max(m.max_speed, length(b.v));
  }
  for (int ji = 0; ji < static_cast<int>(w.joints.size()); ++ji) {
    if (!w.joints[ji].alive) continue;
    m.max_joint_error = std::max(m.max_joint_error, joint_state(w.joint_id(ji))->linear_error);
  }
  return m;
}

}  // namespace fulcrum
