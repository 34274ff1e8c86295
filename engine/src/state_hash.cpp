// The state hash: 64 bits over the bit patterns of everything that evolves, visited in id
// order. Never over serialized bytes (protobuf serialization is not canonical).
#include <bit>
#include <cstdio>
#include <cstring>

#include "world_impl.h"

namespace fulcrum {

namespace {

// A word-at-a-time mix (multiply, rotate, multiply as in xxHash64's round), strong enough that
// any single-bit change anywhere changes the result.
class Hasher {
 public:
  void add(uint64_t x) {
    h_ ^= std::rotl(x * 0xC2B2AE3D27D4EB4Full, 31) * 0x9E3779B185EBCA87ull;
    h_ = std::rotl(h_, 27) * 0x9E3779B185EBCA87ull + 0x85EBCA77C2B2AE63ull;
  }
  void add(double x) { add(std::bit_cast<uint64_t>(x)); }
  void add(const Vec2& v) {
    add(v.x());
    add(v.y());
  }
  void add(int x) { add(static_cast<uint64_t>(static_cast<int64_t>(x))); }
  void add(bool x) { add(static_cast<uint64_t>(x)); }
  uint64_t value() const {
    uint64_t h = h_;
    h ^= h >> 33;
    h *= 0xFF51AFD7ED558CCDull;
    h ^= h >> 33;
    return h;
  }

 private:
  uint64_t h_ = 0x27D4EB2F165667C5ull;
};

}  // namespace

uint64_t World::state_hash() const {
  const WorldImpl& w = *impl_;
  Hasher h;
  h.add(static_cast<uint64_t>(w.tick));
  h.add(static_cast<uint64_t>(w.bodies.size()));
  for (const Body& b : w.bodies) {
    h.add(b.alive);
    h.add(static_cast<uint64_t>(b.generation));
    if (!b.alive) continue;
    h.add(static_cast<int>(b.type));
    h.add(b.xf.p);
    h.add(b.xf.q.c);
    h.add(b.xf.q.s);
    h.add(b.center);
    h.add(b.v);
    h.add(b.w);
    h.add(b.force);
    h.add(b.torque);
    // Only when set, so that worlds without constant forces (and snapshots written before
    // they existed) hash as they always did; the tag keeps the two forms apart.
    if (b.constant_force != Vec2::Zero() || b.constant_torque != 0.0) {
      h.add(uint64_t{0xC0F5});
      h.add(b.constant_force);
      h.add(b.constant_torque);
    }
    h.add(b.awake);
    h.add(b.sleep_time);
  }
  h.add(static_cast<uint64_t>(w.shapes.size()));
  for (const Shape& s : w.shapes) {
    h.add(s.alive);
    h.add(static_cast<uint64_t>(s.generation));
  }
  h.add(static_cast<uint64_t>(w.contacts.size()));
  for (size_t ci = 0; ci < w.contacts.size(); ++ci) {
    const Contact& c = w.contacts[ci];
    h.add(c.alive);
    if (!c.alive) continue;
    h.add(c.shape_a);
    h.add(c.shape_b);
    h.add(c.touching);
    h.add(c.manifold.normal);
    h.add(c.manifold.count);
    for (int i = 0; i < c.manifold.count; ++i) {
      const ManifoldPoint& p = c.manifold.points[i];
      h.add(static_cast<uint64_t>(p.id));
      h.add(p.point);
      h.add(p.separation);
      h.add(p.normal_impulse);
      h.add(p.tangent_impulse);
    }
    // The kept manifold decides the next ticks' manifolds: two copies that differ only here
    // would part later.
    const ManifoldCache& kept = w.manifold_caches[ci];
    h.add(kept.valid);
    if (kept.valid) {
      h.add(kept.normal_on_b);
      h.add(kept.pose.p);
      h.add(kept.pose.q.c);
      h.add(kept.pose.q.s);
      h.add(kept.normal);
      for (int i = 0; i < c.manifold.count; ++i) {
        h.add(kept.points[i]);
        h.add(kept.separations[i]);
      }
    }
  }
  h.add(static_cast<uint64_t>(w.joints.size()));
  for (const Joint& j : w.joints) {
    h.add(j.alive);
    h.add(static_cast<uint64_t>(j.generation));
    if (!j.alive) continue;
    h.add(j.linear_impulse);
    h.add(j.axial_impulse);
    h.add(j.lower_impulse);
    h.add(j.upper_impulse);
    h.add(j.motor_impulse);
    h.add(j.spring_impulse);
    h.add(j.motor_speed);
    h.add(j.break_force);
    h.add(j.break_torque);
    h.add(j.target);
    if (j.type == JointType::kMotor) {
      // Its targets change every tick (set_motor_joint_targets).
      h.add(j.local_a);
      h.add(j.reference_angle);
    }
  }
  if (!w.attractors.empty()) {  // only when set, as constant forces above
    h.add(uint64_t{0xA77AC7});
    h.add(static_cast<uint64_t>(w.attractors.size()));
    for (const AttractorDef& a : w.attractors) {
      h.add(a.point);
      h.add(a.strength);
      h.add(static_cast<int>(a.falloff));
      h.add(a.min_distance);
      h.add(a.per_mass);
      h.add(a.mask_bits);
    }
  }
  for (int i : w.free_joints) h.add(i);
  for (int i : w.free_bodies) h.add(i);
  for (int i : w.free_shapes) h.add(i);
  for (int i : w.free_contacts) h.add(i);
  return h.value();
}

std::string World::hash_text(uint64_t hash) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(hash));
  return buf;
}

}  // namespace fulcrum
