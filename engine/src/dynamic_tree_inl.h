// Template definitions for DynamicTree: the box query and the ray cast. Included at the end of
// dynamic_tree.h; do not include directly.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace fulcrum {

// Depth-first traversal stack. The tree is height balanced (height <= 1.82 log2(n)), and a
// depth-first walk holds at most height + 1 entries, so the fixed part is never exhausted in
// practice; the vector fallback only keeps a pathological
// tree correct. It lives on the caller's stack so concurrent or nested traversals are safe.
class DynamicTree::TraversalStack {
 public:
  void push(int node) {
    if (count_ < kFixedSize) {
      fixed_[count_++] = node;
    } else {
      overflow_.push_back(node);
    }
  }
  // Overflow entries were pushed last, so they are popped first.
  int pop() {
    if (!overflow_.empty()) {
      int node = overflow_.back();
      overflow_.pop_back();
      return node;
    }
    return fixed_[--count_];
  }
  // The overflow is only used while the fixed part is full, so this covers both.
  bool empty() const { return count_ == 0; }

 private:
  static constexpr int kFixedSize = 256;
  std::array<int, kFixedSize> fixed_;  // left uninitialised: only pushed slots are read
  int count_ = 0;
  std::vector<int> overflow_;  // empty vectors do not allocate
};

template <typename Callback>
void DynamicTree::query(const AABB& aabb, Callback&& callback) const {
  walk<false>(aabb, 0, 0, callback);
}

template <typename Callback>
void DynamicTree::query_filtered(const AABB& aabb, uint64_t category_bits, uint64_t mask_bits,
                                 Callback&& callback) const {
  walk<true>(aabb, category_bits, mask_bits, callback);
}

template <bool kFiltered, typename Callback>
void DynamicTree::walk(const AABB& aabb, uint64_t category_bits, uint64_t mask_bits,
                       Callback&& callback) const {
  auto wanted = [&](const Node& node) {
    if constexpr (kFiltered) {
      if ((node.category_bits & mask_bits) == 0 || (category_bits & node.mask_bits) == 0) {
        return false;
      }
    }
    return node.aabb.overlaps(aabb);
  };
  if (root_ == kNullNode || !wanted(nodes_[root_])) return;
  // Children are tested before they are pushed, so the stack only holds nodes to enter.
  TraversalStack stack;
  stack.push(root_);
  while (!stack.empty()) {
    const int index = stack.pop();
    const Node& node = nodes_[index];
    if (node.is_leaf()) {
      if (!static_cast<bool>(callback(index))) return;
      continue;
    }
    // child1 is pushed last so it is visited first; the order is fixed by the tree's shape.
    const bool enter1 = wanted(nodes_[node.child1]);
    if (wanted(nodes_[node.child2])) stack.push(node.child2);
    if (enter1) stack.push(node.child1);
  }
}

template <typename Report>
bool DynamicTree::join_pair(const DynamicTree& other, int a, int b, JoinWalk<Report>& walk) const {
  if (walk.marks[a] == 0 && walk.other_marks[b] == 0) return true;  // no marked leaf below
  const Node& na = nodes_[a];
  const Node& nb = other.nodes_[b];
  if (!may_pair(na, nb)) return true;
  if (na.is_leaf() && nb.is_leaf()) return static_cast<bool>(walk.report(a, b));
  // The taller side is split (a tie splits this tree's side).
  if (nb.is_leaf() || (!na.is_leaf() && na.height >= nb.height)) {
    return join_pair(other, na.child1, b, walk) && join_pair(other, na.child2, b, walk);
  }
  return join_pair(other, a, nb.child1, walk) && join_pair(other, a, nb.child2, walk);
}

template <typename Report>
bool DynamicTree::join_self(int node, JoinWalk<Report>& walk) const {
  const Node& n = nodes_[node];
  if (n.is_leaf() || walk.marks[node] == 0) return true;
  return join_self(n.child1, walk) && join_self(n.child2, walk) &&
         join_pair(*this, n.child1, n.child2, walk);
}

template <typename Report>
void DynamicTree::join(const DynamicTree& other, JoinTask task, const uint8_t* marks,
                       const uint8_t* other_marks, Report&& report) const {
  JoinWalk<Report> walk{marks, other_marks, report};
  if (&other == this && task.a == task.b) {
    join_self(task.a, walk);
  } else {
    join_pair(other, task.a, task.b, walk);
  }
}

template <typename Callback>
void DynamicTree::ray_cast(const RayCastInput& input, Callback&& callback) const {
  // Also rejects NaN: nothing lies on a segment of negative or undefined length.
  if (root_ == kNullNode || !(input.max_fraction >= 0.0)) return;

  const Vec2 p = input.origin;
  const Vec2 d = input.translation;
  // The segment's normal direction (unnormalised: the separating-axis test is scale free).
  const Vec2 n = left_perp(d);
  const Vec2 abs_n = n.cwiseAbs();
  // Inverse direction for the slab test; an axis the ray does not move along is tested as a
  // plain interval check instead so no 0 * inf = NaN can arise.
  const bool moves_x = d.x() != 0.0;
  const bool moves_y = d.y() != 0.0;
  const double inv_x = moves_x ? 1.0 / d.x() : 0.0;
  const double inv_y = moves_y ? 1.0 / d.y() : 0.0;

  double max_fraction = input.max_fraction;
  RayCastInput sub_input = input;

  // Whether the segment p + t d, t in [0, max_fraction], touches the box.
  auto crosses = [&](const AABB& box) {
    // Separating axis along the segment normal: the box's projected radius against the
    // distance of its centre from the ray's line. Cheap, and rejects most boxes the segment's
    // line misses before any division-based work.
    const Vec2 c = box.center();
    const Vec2 h = 0.5 * (box.upper - box.lower);
    if (std::abs(dot(n, c - p)) > dot(abs_n, h)) return false;
    // Slab test: clip the parameter interval against each axis' slab.
    double t_lo = 0.0;
    double t_hi = max_fraction;
    if (moves_x) {
      double t1 = (box.lower.x() - p.x()) * inv_x;
      double t2 = (box.upper.x() - p.x()) * inv_x;
      if (t1 > t2) std::swap(t1, t2);
      t_lo = std::max(t_lo, t1);
      t_hi = std::min(t_hi, t2);
      if (t_lo > t_hi) return false;
    } else if (p.x() < box.lower.x() || p.x() > box.upper.x()) {
      return false;
    }
    if (moves_y) {
      double t1 = (box.lower.y() - p.y()) * inv_y;
      double t2 = (box.upper.y() - p.y()) * inv_y;
      if (t1 > t2) std::swap(t1, t2);
      t_lo = std::max(t_lo, t1);
      t_hi = std::min(t_hi, t2);
      if (t_lo > t_hi) return false;
    } else if (p.y() < box.lower.y() || p.y() > box.upper.y()) {
      return false;
    }
    return true;
  };

  TraversalStack stack;
  stack.push(root_);
  while (!stack.empty()) {
    const int index = stack.pop();
    const Node& node = nodes_[index];
    if (!crosses(node.aabb)) continue;
    if (node.is_leaf()) {
      sub_input.max_fraction = max_fraction;
      const double value = callback(static_cast<const RayCastInput&>(sub_input), index);
      if (value == 0.0) return;
      // Only a strictly shorter, positive fraction clips; larger values, negative values
      // ("ignore this proxy") and NaN keep the current segment.
      if (value > 0.0 && value < max_fraction) max_fraction = value;
    } else {
      stack.push(node.child2);
      stack.push(node.child1);
    }
  }
}

}  // namespace fulcrum
