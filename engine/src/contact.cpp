// Contacts: one per overlapping pair of fat boxes. Each step refreshes the manifolds of contacts
// that touch an awake body, carries accumulated impulses over by feature id (warm starting),
// and reports touch events.
#include <algorithm>
#include <cmath>

#include "worker_pool.h"
#include "world_impl.h"

namespace fulcrum {

namespace {

void link_edge(LargeVector<Contact>& contacts, LargeVector<Body>& bodies, int ci, int side,
               int bi) {
  Contact& c = contacts[ci];
  int key = 2 * ci + side;
  Body& b = bodies[bi];
  c.edges[side].prev = kNullIndex;
  c.edges[side].next = b.contact_list;
  if (b.contact_list != kNullIndex) {
    contacts[edge_contact(b.contact_list)].edges[edge_side(b.contact_list)].prev = key;
  }
  b.contact_list = key;
  ++b.contact_count;
}

void unlink_edge(LargeVector<Contact>& contacts, LargeVector<Body>& bodies, int ci, int side,
                 int bi) {
  ContactEdge& e = contacts[ci].edges[side];
  if (e.prev != kNullIndex) {
    contacts[edge_contact(e.prev)].edges[edge_side(e.prev)].next = e.next;
  } else {
    bodies[bi].contact_list = e.next;
  }
  if (e.next != kNullIndex) {
    contacts[edge_contact(e.next)].edges[edge_side(e.next)].prev = e.prev;
  }
  e.prev = e.next = kNullIndex;
  --bodies[bi].contact_count;
}

// Whether two shapes overlap (for sensors): a manifold point with negative separation.
bool overlapping(const Manifold& m) {
  for (int i = 0; i < m.count; ++i) {
    if (m.points[i].separation < 0.0) return true;
  }
  return false;
}

// Whether a contact touches by its fresh manifold: a sensor when its shapes overlap, any other
// contact when its manifold has a point (speculative points included).
bool touching_now(const Contact& c) {
  return c.sensor ? overlapping(c.manifold) : c.manifold.count > 0;
}

// Whether `normal` (in the shape's frame) is one of its faces' outward normals.
bool face_normal(const Geometry& g, const Vec2& normal) {
  constexpr double kParallel = 1.0 - 1e-9;
  if (const Polygon* p = std::get_if<Polygon>(&g)) {
    for (int i = 0; i < p->count; ++i) {
      if (dot(p->normals[i], normal) > kParallel) return true;
    }
    return false;
  }
  const Segment& sg = std::get<Segment>(g);
  const Vec2 d = sg.point2 - sg.point1;
  return std::abs(dot(d, normal)) < 1e-9 * length(d);
}

// Keeps a new touching manifold for reuse when its normal is a face normal of A or of B (the
// face that will turn with its body); a normal between closest points (corners meeting) is not
// kept, since it turns as the corners slide.
void cache_manifold(const Contact& c, const Geometry& ga, const Transform& xfa, const Geometry& gb,
                    const Transform& xfb, ManifoldCache& cache) {
  if (c.manifold.count == 0) return;
  const Vec2 n = xfa.q.inv_rotate(c.manifold.normal);
  if (face_normal(ga, n)) {
    cache.normal_on_b = false;
  } else if (face_normal(gb, -xfb.q.inv_rotate(c.manifold.normal))) {
    cache.normal_on_b = true;
  } else {
    return;
  }
  cache.valid = true;
  cache.pose = inv_mul(xfa, xfb);
  cache.normal = n;
  for (int i = 0; i < c.manifold.count; ++i) {
    cache.points[i] = xfa.inv_apply(c.manifold.points[i].point);
    cache.separations[i] = c.manifold.points[i].separation;
  }
}

// Moves a touching contact's kept manifold with the bodies when B has moved little relative to A
// since it was found: by at most `reuse` at each point, and turned by at most reuse / size
// (size: at least the smaller shape's diameter). Returns false, changing nothing, otherwise.
//
// B's motion relative to A since then is x -> turn x + shift in A's frame. Each point (midway
// between the surfaces) moved by d = turn x + shift - x with B; to first order the surfaces'
// gap along the normal grew by d . n, as the solver's substeps reckon it within a tick. The
// normal turns with the body whose face it is. The points keep their ids and impulses.
bool reuse_manifold(const ManifoldCache& cache, const Transform& xfa, const Transform& xfb,
                    double size, double reuse, Contact& c) {
  if (!cache.valid || c.manifold.count == 0) return false;
  const Transform pose = inv_mul(xfa, xfb);
  // The relative motion since: x -> turn x + shift, in A's frame.
  const Rot turn = inv_mul(cache.pose.q, pose.q);
  if (!(turn.c > 0.0) || std::abs(turn.s) * size > reuse) return false;
  const Vec2 shift = pose.p - turn.rotate(cache.pose.p);
  Vec2 moved[2];
  for (int i = 0; i < c.manifold.count; ++i) {
    moved[i] = turn.rotate(cache.points[i]) + shift - cache.points[i];
    if (!(moved[i].squaredNorm() <= reuse * reuse)) return false;
  }
  const Vec2 n = cache.normal_on_b ? turn.rotate(cache.normal) : cache.normal;
  c.manifold.normal = xfa.q.rotate(n);
  for (int i = 0; i < c.manifold.count; ++i) {
    ManifoldPoint& p = c.manifold.points[i];
    p.separation = cache.separations[i] + dot(moved[i], n);
    p.point = xfa.apply(cache.points[i] + 0.5 * moved[i]);
    p.persisted = true;
  }
  return true;
}

}  // namespace

const std::vector<uint8_t>& WorldImpl::awake_flags() {
  scratch_awake_flag.assign(bodies.size(), 0);
  for (int bi : awake_bodies) scratch_awake_flag[bi] = 1;
  return scratch_awake_flag;
}

void WorldImpl::create_contact(int sa, int sb) {
  // The manifold functions want the lower shape type first.
  if (geometry_type(shapes[sb].geometry) < geometry_type(shapes[sa].geometry)) std::swap(sa, sb);
  if (geometry_type(shapes[sa].geometry) == ShapeType::kSegment &&
      geometry_type(shapes[sb].geometry) == ShapeType::kSegment) {
    return;  // segments never meet segments
  }
  int ci;
  if (!free_contacts.empty()) {
    ci = free_contacts.back();
    free_contacts.pop_back();
  } else {
    ci = static_cast<int>(contacts.size());
    contacts.emplace_back();
    manifold_caches.emplace_back();
  }
  Contact& c = contacts[ci];
  c = Contact{};
  manifold_caches[ci].valid = false;
  c.alive = true;
  c.shape_a = sa;
  c.shape_b = sb;
  c.body_a = shapes[sa].body;
  c.body_b = shapes[sb].body;
  c.sensor = shapes[sa].is_sensor || shapes[sb].is_sensor;
  c.friction = std::sqrt(shapes[sa].friction * shapes[sb].friction);
  c.restitution = std::max(shapes[sa].restitution, shapes[sb].restitution);
  link_edge(contacts, bodies, ci, 0, c.body_a);
  link_edge(contacts, bodies, ci, 1, c.body_b);
  contact_pairs.insert(pair_key(sa, sb));
}

void WorldImpl::destroy_contact(int ci, bool report_end) {
  Contact& c = contacts[ci];
  if (report_end && c.touching) {
    if (c.sensor) {
      bool a_sensor = shapes[c.shape_a].is_sensor;
      events.sensor_end.push_back(
          {shape_id(a_sensor ? c.shape_a : c.shape_b), shape_id(a_sensor ? c.shape_b : c.shape_a)});
    } else {
      events.contact_end.push_back({shape_id(c.shape_a), shape_id(c.shape_b)});
    }
  }
  unlink_edge(contacts, bodies, ci, 0, c.body_a);
  unlink_edge(contacts, bodies, ci, 1, c.body_b);
  contact_pairs.erase(pair_key(c.shape_a, c.shape_b));
  c.alive = false;
  free_contacts.push_back(ci);
}

void WorldImpl::destroy_body_contacts(int bi) {
  while (bodies[bi].contact_list != kNullIndex) {
    destroy_contact(edge_contact(bodies[bi].contact_list), true);
  }
}

void WorldImpl::collide() {
  budget.most_pressed = 0.0;
  budget.unsettled = false;
  budget.restitution = false;
  budget.recovering.clear();
  const std::optional<ContactPress> press = contact_press();
  const std::optional<RecoveryRule> recovery = recovery_rule();
  if (press) {
    contact_pressed.resize(contacts.size(), 0.0);
    contact_reach.resize(contacts.size(), 0.0);
    contact_unsettled.resize(contacts.size(), 0);
  }
  // Bodies woken by a touch in one round bring their own contacts into the next round, until
  // no more wake.
  touching_contacts.clear();
  touching_bodies.clear();
  ++collide_calls;
  if (awake_boxes.size() < shapes.size()) awake_boxes.resize(shapes.size());
  size_t first_new = 0;
  int rounds = 0;
  while (first_new < awake_bodies.size()) {
    size_t end = awake_bodies.size();
    collide_round(first_new, end, press, recovery);
    first_new = end;
    ++rounds;
  }
  // Each round lists its own contacts in id order.
  if (rounds > 1) {
    std::sort(touching_contacts.begin(), touching_contacts.end());
    for (size_t t = 0; t < touching_contacts.size(); ++t) {
      const Contact& c = contacts[touching_contacts[t]];
      touching_bodies[t] = ContactBodies{c.body_a, c.body_b};
    }
  }
}

void WorldImpl::fill_awake_boxes() {
  // Each awake shape's box and its body's velocity, which refresh reads first: once per shape
  // here instead of once per contact there. In chunks of bodies, on the world's threads; each
  // shape is written by its body's chunk alone.
  constexpr size_t kBodiesPerChunk = 256;
  const int chunks =
      static_cast<int>((awake_bodies.size() + kBodiesPerChunk - 1) / kBodiesPerChunk);
  auto fill = [&](int i) {
    const size_t hi = std::min(awake_bodies.size(), (i + 1) * kBodiesPerChunk);
    for (size_t k = i * kBodiesPerChunk; k < hi; ++k) {
      const Body& b = bodies[awake_bodies[k]];
      for (int si : b.shapes) {
        AwakeBox& r = awake_boxes[si];
        if (!r.placed) place_box(si, shape_box(si, b.xf));
        r.v = b.v;
        r.call = collide_calls;
      }
    }
  };
  run_chunks(chunks >= 4 ? pool : nullptr, chunks, fill, true);
}

void WorldImpl::collide_round(size_t first, size_t end, const std::optional<ContactPress>& press,
                              const std::optional<RecoveryRule>& recovery) {
  // Gather the contacts of these awake bodies not yet seen this step (each once), in contact
  // id order.
  std::vector<int>& list = scratch_contacts;
  list.clear();
  if (first == 0 && 2 * end >= static_cast<size_t>(body_count)) {
    // Most bodies awake: one pass over the contact pool, in id order, is cheaper than walking
    // every awake body's list and sorting, and finds the same contacts (those with an awake
    // body, the first round's bodies being all the awake ones). The pool is read in chunks of
    // ids, on several threads, and their lists joined in chunk order. It only reads the pool
    // (each contact is found once): stamps would dirty a line of every contact.
    constexpr size_t kPoolChunk = 2048;
    const int chunks = static_cast<int>((contacts.size() + kPoolChunk - 1) / kPoolChunk);
    std::vector<std::vector<int>>& found = scratch_chunk_contacts;
    if (found.size() < static_cast<size_t>(chunks)) found.resize(chunks);
    const std::vector<uint8_t>& awake_flag = awake_flags();
    auto gather = [&](int i) {
      found[i].clear();
      const size_t hi = std::min(contacts.size(), (i + 1) * kPoolChunk);
      for (size_t ci = i * kPoolChunk; ci < hi; ++ci) {
        Contact& c = contacts[ci];
        if (!c.alive) continue;
        if (awake_flag[c.body_a] || awake_flag[c.body_b]) found[i].push_back(static_cast<int>(ci));
      }
    };
    run_chunks(chunks >= 4 ? pool : nullptr, chunks, gather, true);
    for (int i = 0; i < chunks; ++i) list.insert(list.end(), found[i].begin(), found[i].end());
  } else {
    // A contact with a body awake before this round (its place in awake_bodies before `first`)
    // was found by an earlier round; the stamps keep this round from listing one twice.
    auto earlier = [&](int body) {
      const int place = bodies[body].awake_slot;
      return place >= 0 && static_cast<size_t>(place) < first;
    };
    for (size_t k = first; k < end; ++k) {
      for (int e = bodies[awake_bodies[k]].contact_list; e != kNullIndex;) {
        Contact& c = contacts[edge_contact(e)];
        if (c.stamp != step_stamp && !earlier(c.body_a) && !earlier(c.body_b)) {
          c.stamp = step_stamp;
          list.push_back(edge_contact(e));
        }
        e = c.edges[edge_side(e)].next;
      }
    }
    std::sort(list.begin(), list.end());
  }

  // With at least a contact per awake body to refresh, the boxes pay for themselves (a joint
  // grid has none to refresh, a pile several per body). Later rounds refresh the contacts of
  // bodies just woken, whose shapes have no box.
  const bool boxes = first == 0 && list.size() >= awake_bodies.size();
  if (boxes) fill_awake_boxes();

  // New manifolds first: each depends only on its own contact, its shapes and its bodies,
  // none of which the rest of this function changes for another contact, so they may be
  // computed in any order, on several threads, in chunks fixed by the list.
  const double speculative = settings.speculative_distance;
  const double reuse = settings.manifold_reuse_distance;
  // Each contact's state once refreshed: its boxes parted, or they overlap and the id-order pass
  // below has work to do, or nothing there changes (kSteady; kSteadyTouching when it is a
  // touching contact the solver wants).
  enum Refreshed : uint8_t { kParted, kOverlap, kSteady, kSteadyTouching };
  std::vector<uint8_t>& overlap = scratch_overlap;
  overlap.assign(list.size(), kParted);
  // Margin on the boxes' gap, far above the rounding of a point's separation.
  constexpr double kApartMargin = 1e-6;
  auto refresh = [&](size_t k) {
    Contact& c = contacts[list[k]];
    if (!fat_boxes[c.shape_a].overlaps(fat_boxes[c.shape_b])) return;
    overlap[k] = kOverlap;
    // Shapes whose boxes are farther apart than the reach collide would be given (below) get
    // its answer without it (manifold.h, no_points), and neither shape nor body is read. Only from
    // an empty manifold: a kept one (reuse_manifold) could be moved on instead. In a tumbling pile
    // more than half of the contacts are pairs of boxes a few centimetres apart.
    if (boxes && c.manifold.count == 0) {
      const AwakeBox& ra = awake_boxes[c.shape_a];
      const AwakeBox& rb = awake_boxes[c.shape_b];
      const double reach = speculative + settings.dt * length(rb.v - ra.v);
      if (ra.call == collide_calls && rb.call == collide_calls &&
          !ra.box.fattened(reach + kApartMargin).overlaps(rb.box)) {
        c.manifold = no_points(ra.type, rb.type);
        manifold_caches[list[k]].valid = false;
        return;
      }
    }
    const Body& ba = bodies[c.body_a];
    const Body& bb = bodies[c.body_b];
    // How far the bodies' centres close or slide in one tick. A pair moving faster than the
    // reuse distance a tick would move past it by the next: its manifold is neither tried nor
    // kept (a speed test only; the drift since a manifold was found decides).
    const double travel = settings.dt * length(bb.v - ba.v);
    const bool slow = reuse > 0.0 && travel <= reuse;
    // A kept manifold is one of two flat shapes, not a sensor's (it was kept only if so, and
    // neither changes while the contact lives): moving it on reads neither shape.
    if (slow && manifold_caches[list[k]].valid) {
      // The smaller shape's size, from its fat box: width + height is at least its diameter.
      const AABB& fa = fat_boxes[c.shape_a];
      const AABB& fb = fat_boxes[c.shape_b];
      const Vec2 ea = fa.upper - fa.lower, eb = fb.upper - fb.lower;
      const double size = std::min(ea.x() + ea.y(), eb.x() + eb.y());
      if (reuse_manifold(manifold_caches[list[k]], ba.xf, bb.xf, size, reuse, c)) return;
    }
    const Shape& sa = shapes[c.shape_a];
    const Shape& sb = shapes[c.shape_b];
    const bool reusable = slow && !c.sensor && flat(sa.geometry) && flat(sb.geometry);
    // What warm starting needs of the old points: their ids and impulses.
    struct Kept {
      uint32_t id;
      double normal_impulse, tangent_impulse;
    } kept[2];
    const int kept_count = c.manifold.count;
    for (int j = 0; j < kept_count; ++j) {
      const ManifoldPoint& p = c.manifold.points[j];
      kept[j] = {p.id, p.normal_impulse, p.tangent_impulse};
    }
    // Points are kept as far out as the bodies can close in one tick, so that the solver sees
    // a fast body's contact before it arrives (speculative contact).
    const double reach = speculative + travel;
    c.manifold = fulcrum::collide(sa.geometry, ba.xf, sb.geometry, bb.xf, c.sensor ? 0.0 : reach);
    // Warm starting: a point that keeps its feature id keeps its accumulated impulses.
    for (int i = 0; i < c.manifold.count; ++i) {
      ManifoldPoint& p = c.manifold.points[i];
      for (int j = 0; j < kept_count; ++j) {
        if (kept[j].id == p.id) {
          p.normal_impulse = kept[j].normal_impulse;
          p.tangent_impulse = kept[j].tangent_impulse;
          p.persisted = true;
          break;
        }
      }
    }
    ManifoldCache& cache = manifold_caches[list[k]];
    cache.valid = false;
    if (reusable) cache_manifold(c, sa.geometry, ba.xf, sb.geometry, bb.xf, cache);
  };
  constexpr size_t kContactsPerChunk = 64;
  const int chunks = static_cast<int>((list.size() + kContactsPerChunk - 1) / kContactsPerChunk);
  // With contact budgets on, each refreshed contact's load figures (budget.cpp), and each
  // chunk's largest (a maximum, the same in any order).
  std::vector<double>& chunk_pressed = scratch_chunk_pressed;
  chunk_pressed.assign(press ? chunks : 0, 0.0);
  std::vector<uint8_t>& chunk_unsettled = scratch_chunk_unsettled;
  chunk_unsettled.assign(press ? chunks : 0, 0);
  // With recovery budgets on, each chunk's recovering contacts (budget.cpp), gathered in id
  // order.
  std::vector<std::vector<int>>& chunk_recovering = scratch_chunk_recovering;
  if (recovery && chunk_recovering.size() < static_cast<size_t>(chunks)) {
    chunk_recovering.resize(chunks);
  }
  // Each chunk's touching solid contacts with their bodies (in id order, the chunks' lists joined
  // in chunk order make the step's), and the places in `list` the id-order pass must visit.
  std::vector<ChunkTouching>& chunk_touching = scratch_chunk_touching;
  if (chunk_touching.size() < static_cast<size_t>(chunks)) chunk_touching.resize(chunks);
  auto chunk = [&](int i) {
    if (recovery) chunk_recovering[i].clear();
    ChunkTouching& mine = chunk_touching[i];
    mine.contacts.clear();
    mine.bodies.clear();
    mine.visit.clear();
    mine.restitution = false;
    const size_t lo = static_cast<size_t>(i) * kContactsPerChunk;
    const size_t hi = std::min(lo + kContactsPerChunk, list.size());
    for (size_t k = lo; k < hi; ++k) {
      // Each contact is fetched a few ahead of its refresh: the lines of its shapes and of its
      // manifold's count, which every refresh reads.
      if (k + kFetchAhead < hi) {
        const Contact& far = contacts[list[k + kFetchAhead]];
        __builtin_prefetch(&far.shape_a);
        __builtin_prefetch(&far.manifold.count);
      }
      refresh(k);
      if (!overlap[k]) {
        mine.visit.push_back(static_cast<int>(k));
        continue;
      }
      if (press) {
        chunk_pressed[i] = std::max(chunk_pressed[i], press_contact(list[k], *press));
        chunk_unsettled[i] = chunk_unsettled[i] | contact_unsettled[list[k]];
      }
      if (recovery && recovering(contacts[list[k]], *recovery)) {
        chunk_recovering[i].push_back(list[k]);
      }
      // Nothing for the id-order pass: touching as before, and no sleeping body to wake. (That
      // pass only wakes bodies, so one awake now is still awake when it comes to this contact.)
      const Contact& c = contacts[list[k]];
      const bool touching = touching_now(c);
      // The solver's contacts: those touching now, sensors aside, whatever the pass below does
      // (it only wakes bodies and reports).
      if (touching && !c.sensor) {
        mine.contacts.push_back(list[k]);
        mine.bodies.push_back(ContactBodies{c.body_a, c.body_b});
        mine.restitution = mine.restitution || c.restitution != 0.0;
      }
      if (touching == c.touching &&
          (!touching || c.sensor || (bodies[c.body_a].awake && bodies[c.body_b].awake))) {
        overlap[k] = touching && !c.sensor ? kSteadyTouching : kSteady;
      } else {
        mine.visit.push_back(static_cast<int>(k));
      }
    }
  };
  run_chunks(chunks >= 4 ? pool : nullptr, chunks, chunk, true);
  for (double p : chunk_pressed) budget.most_pressed = std::max(budget.most_pressed, p);
  for (uint8_t u : chunk_unsettled) budget.unsettled = budget.unsettled || u != 0;
  if (recovery) {
    for (int i = 0; i < chunks; ++i) {
      budget.recovering.insert(budget.recovering.end(), chunk_recovering[i].begin(),
                               chunk_recovering[i].end());
    }
  }

  for (int i = 0; i < chunks; ++i) {
    const ChunkTouching& theirs = chunk_touching[i];
    touching_contacts.insert(touching_contacts.end(), theirs.contacts.begin(),
                             theirs.contacts.end());
    touching_bodies.insert(touching_bodies.end(), theirs.bodies.begin(), theirs.bodies.end());
    budget.restitution = budget.restitution || theirs.restitution;
  }

  // Then, in id order: boxes that parted destroy their contact; touches wake and report.
  for (int i = 0; i < chunks; ++i) {
    for (const int k : chunk_touching[i].visit) {
      const int ci = list[k];
      if (overlap[k] == kParted) {
        destroy_contact(ci, true);
        continue;
      }
      Contact& c = contacts[ci];
      const Shape& sa = shapes[c.shape_a];
      bool was_touching = c.touching;
      c.touching = touching_now(c);
      // An awake body touching a sleeping one wakes it (and what rests on it).
      if (c.touching && !c.sensor) {
        if (!bodies[c.body_a].awake) wake_island(c.body_a);
        if (!bodies[c.body_b].awake) wake_island(c.body_b);
      }
      if (c.touching == was_touching) continue;
      if (c.sensor) {
        bool a_sensor = sa.is_sensor;
        SensorEvent ev{shape_id(a_sensor ? c.shape_a : c.shape_b),
                       shape_id(a_sensor ? c.shape_b : c.shape_a)};
        (c.touching ? events.sensor_begin : events.sensor_end).push_back(ev);
        continue;
      }
      (c.touching ? events.contact_begin : events.contact_end)
          .push_back({shape_id(c.shape_a), shape_id(c.shape_b)});
    }
  }
}

}  // namespace fulcrum
