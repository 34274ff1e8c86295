#include "dynamic_tree.h"

#include <algorithm>
#include <cassert>
#include <cstdlib>
#include <initializer_list>
#include <limits>

#include "worker_pool.h"

namespace fulcrum {

namespace {

// Height balance: an internal node's two subtrees differ in height by at most this. With the
// limit k, the sparsest tree of height H has N(H) = N(H - 1) + N(max(0, H - 1 - k)) leaves;
// for k = 2 it is at least 1.4656^H (x^3 = x^2 + 1), so H <= 1.82 log2(n). The strict
// AVL limit of 1 leaves the rotations too little freedom to follow the surface-area heuristic:
// queries on 20k-100k random boxes visited 2.5-5x more nodes than with k = 2, while k = 2
// comes within ~15% of an unbalanced pure-SAH tree.
constexpr int kMaxImbalance = 2;

}  // namespace

DynamicTree::DynamicTree() {
  nodes_.reserve(16);
}

int DynamicTree::allocate_node() {
  int index;
  if (free_list_ != kNullNode) {
    // Most recently freed first: the free list is a stack.
    index = free_list_;
    free_list_ = nodes_[index].parent_or_next;
  } else {
    // Grows only when every node is in use, so steady-state churn does not allocate.
    index = static_cast<int>(nodes_.size());
    nodes_.emplace_back();
    user_data_.push_back(0);
  }
  nodes_[index] = Node{};
  nodes_[index].height = 0;
  ++node_count_;
  return index;
}

void DynamicTree::free_node(int index) {
  assert(0 <= index && index < static_cast<int>(nodes_.size()) && nodes_[index].height >= 0);
  Node& node = nodes_[index];
  node = Node{};  // height -1 marks it free
  node.parent_or_next = free_list_;
  free_list_ = index;
  --node_count_;
}

int DynamicTree::create_proxy(const AABB& fat_aabb, uint64_t user_data, uint64_t category_bits,
                              uint64_t mask_bits) {
  assert(fat_aabb.lower.x() <= fat_aabb.upper.x() && fat_aabb.lower.y() <= fat_aabb.upper.y());
  const int proxy = allocate_node();
  nodes_[proxy].aabb = fat_aabb;
  user_data_[proxy] = user_data;
  nodes_[proxy].category_bits = category_bits;
  nodes_[proxy].mask_bits = mask_bits;
  insert_leaf(proxy);
  ++proxy_count_;
  return proxy;
}

void DynamicTree::destroy_proxy(int proxy_id) {
  assert(0 <= proxy_id && proxy_id < static_cast<int>(nodes_.size()));
  assert(nodes_[proxy_id].height == 0);
  // remove_leaf frees the leaf's parent before the leaf itself is freed, so the proxy id is
  // the most recently freed node and the next create_proxy returns it.
  remove_leaf(proxy_id);
  free_node(proxy_id);
  --proxy_count_;
}

void DynamicTree::move_proxy(int proxy_id, const AABB& fat_aabb) {
  assert(0 <= proxy_id && proxy_id < static_cast<int>(nodes_.size()));
  assert(nodes_[proxy_id].height == 0);
  assert(fat_aabb.lower.x() <= fat_aabb.upper.x() && fat_aabb.lower.y() <= fat_aabb.upper.y());
  remove_leaf(proxy_id);
  nodes_[proxy_id].aabb = fat_aabb;
  insert_leaf(proxy_id);
}

void DynamicTree::set_leaf_filter(int proxy_id, uint64_t category_bits, uint64_t mask_bits) {
  assert(0 <= proxy_id && proxy_id < static_cast<int>(nodes_.size()));
  assert(nodes_[proxy_id].height == 0);
  nodes_[proxy_id].category_bits = category_bits;
  nodes_[proxy_id].mask_bits = mask_bits;
  for (int index = nodes_[proxy_id].parent_or_next; index != kNullNode;
       index = nodes_[index].parent_or_next) {
    Node& node = nodes_[index];
    node.category_bits = nodes_[node.child1].category_bits | nodes_[node.child2].category_bits;
    node.mask_bits = nodes_[node.child1].mask_bits | nodes_[node.child2].mask_bits;
  }
}

std::vector<DynamicTree::JoinTask> DynamicTree::join_tasks(const DynamicTree& other,
                                                           int want) const {
  std::vector<JoinTask> tasks;
  const bool self = &other == this;
  if (root_ == kNullNode || other.root_ == kNullNode) return tasks;
  if (self) {
    tasks.push_back({root_, root_});
  } else if (may_pair(nodes_[root_], other.nodes_[other.root_])) {
    tasks.push_back({root_, other.root_});
  }
  // Each round splits every task that can be split, in order, so the tasks depend only on the
  // trees. A self task yields its two children's self tasks and their pair; a pair task, the
  // pairs of the taller side's children with the other side.
  std::vector<JoinTask> next;
  while (static_cast<int>(tasks.size()) < want) {
    next.clear();
    bool split = false;
    auto add_pair = [&](int a, int b) {
      if (may_pair(nodes_[a], other.nodes_[b])) next.push_back({a, b});
    };
    for (const JoinTask& t : tasks) {
      const Node& na = nodes_[t.a];
      const Node& nb = other.nodes_[t.b];
      if (self && t.a == t.b) {
        if (na.is_leaf()) continue;  // no pairs within one leaf
        next.push_back({na.child1, na.child1});
        next.push_back({na.child2, na.child2});
        add_pair(na.child1, na.child2);
        split = true;
      } else if (na.is_leaf() && nb.is_leaf()) {
        next.push_back(t);
      } else if (nb.is_leaf() || (!na.is_leaf() && na.height >= nb.height)) {
        add_pair(na.child1, t.b);
        add_pair(na.child2, t.b);
        split = true;
      } else {
        add_pair(t.a, nb.child1);
        add_pair(t.a, nb.child2);
        split = true;
      }
    }
    tasks.swap(next);
    if (!split) break;
  }
  return tasks;
}

void DynamicTree::rebuild(WorkerPool* pool) {
  if (root_ == kNullNode) return;
  // The leaves in id order, and every internal node freed, in one pass over the nodes: a build
  // that depends only on the leaves, not on the old tree.
  std::vector<LeafCentre>& leaves = scratch_leaves_;
  leaves.clear();
  for (int index = 0; index < static_cast<int>(nodes_.size()); ++index) {
    const Node& node = nodes_[index];
    if (node.height == 0) {
      const Vec2 c = node.aabb.center();
      leaves.push_back({{c.x(), c.y()}, index});
    } else if (node.height > 0) {
      free_node(index);
    }
  }
  const int count = static_cast<int>(leaves.size());
  // The internal nodes the build fills, taken before it starts, so that it allocates nothing
  // and its parts may run at once: the subtree over leaves [i, i + n) fills slots [i, i + n - 1).
  std::vector<int>& slots = scratch_slots_;
  slots.resize(count - 1);
  for (int& slot : slots) slot = allocate_node();
  // A large tree's four quarters are built on the pool's threads (the same tree as in one
  // thread: the splits and the slots are fixed by the leaves), then joined here.
  constexpr int kParallelLeaves = 1024;
  if (pool != nullptr && count >= kParallelLeaves) {
    const int half = split_range(leaves.data(), count);
    const int q1 = split_range(leaves.data(), half);
    const int q2 = split_range(leaves.data() + half, count - half);
    const int first[5] = {0, q1, half, half + q2, count};
    int roots[4];
    auto part = [&](int i) {
      roots[i] =
          build_range(leaves.data() + first[i], first[i + 1] - first[i], slots.data() + first[i]);
    };
    run_chunks(pool, 4, part, true);
    const int left = join(slots[q1 - 1], roots[0], roots[1]);
    const int right = join(slots[half + q2 - 1], roots[2], roots[3]);
    root_ = join(slots[half - 1], left, right);
  } else {
    root_ = build_range(leaves.data(), count, slots.data());
  }
  nodes_[root_].parent_or_next = kNullNode;
}

int DynamicTree::split_range(LeafCentre* leaves, int count) {
  double lo[2] = {leaves[0].c[0], leaves[0].c[1]};
  double hi[2] = {lo[0], lo[1]};
  for (int i = 1; i < count; ++i) {
    for (int k = 0; k < 2; ++k) {
      lo[k] = std::min(lo[k], leaves[i].c[k]);
      hi[k] = std::max(hi[k], leaves[i].c[k]);
    }
  }
  const int axis = hi[0] - lo[0] >= hi[1] - lo[1] ? 0 : 1;
  const int half = count / 2;
  std::nth_element(leaves, leaves + half, leaves + count,
                   [axis](const LeafCentre& a, const LeafCentre& b) {
                     return a.c[axis] != b.c[axis] ? a.c[axis] < b.c[axis] : a.leaf < b.leaf;
                   });
  return half;
}

int DynamicTree::join(int node, int left, int right) {
  Node& n = nodes_[node];
  n.child1 = left;
  n.child2 = right;
  nodes_[left].parent_or_next = node;
  nodes_[right].parent_or_next = node;
  refit(node);
  return node;
}

int DynamicTree::build_range(LeafCentre* leaves, int count, const int* slots) {
  if (count == 1) return leaves[0].leaf;
  const int half = split_range(leaves, count);
  const int left = build_range(leaves, half, slots);
  const int right = build_range(leaves + half, count - half, slots + half);
  return join(slots[half - 1], left, right);
}

// Cost of a sibling S for new leaf L: the perimeter of the new parent, perimeter(S u L), plus
// the growth of every ancestor of S, perimeter(A u L) - perimeter(A). The search descends from
// the root keeping the cheapest node seen; below a node C, no sibling can cost less than
// perimeter(L) + growth of C and its ancestors, which bounds the search. At each level it
// follows the child with the lower bound (a greedy branch-and-bound: one path, no queue).
int DynamicTree::find_best_sibling(const AABB& box) const {
  const double leaf_area = box.perimeter();
  int best = root_;
  double best_cost = union_of(nodes_[root_].aabb, box).perimeter();
  double inherited = 0.0;  // growth of the current node and its ancestors
  int index = root_;
  while (!nodes_[index].is_leaf()) {
    const Node& node = nodes_[index];
    inherited += union_of(node.aabb, box).perimeter() - node.aabb.perimeter();

    int next = kNullNode;
    double next_bound = 0.0;
    for (const int child : {node.child1, node.child2}) {
      const Node& c = nodes_[child];
      const double combined = union_of(c.aabb, box).perimeter();
      const double direct = combined + inherited;
      if (direct < best_cost) {
        best_cost = direct;
        best = child;
      }
      if (!c.is_leaf()) {
        const double bound = leaf_area + inherited + (combined - c.aabb.perimeter());
        bool take = next == kNullNode || bound < next_bound;
        if (!take && bound == next_bound) {
          // Equal bounds usually mean the leaf lies inside both children's boxes; the child
          // whose centre is nearer keeps the new leaf with its neighbours.
          take = length_squared(c.aabb.center() - box.center()) <
                 length_squared(nodes_[next].aabb.center() - box.center());
        }
        if (take) {
          next = child;
          next_bound = bound;
        }
      }
    }
    // Nothing below can beat the best found so far (compared after both children updated it).
    if (next == kNullNode || next_bound >= best_cost) break;
    index = next;
  }
  return best;
}

void DynamicTree::replace_child(int parent, int old_child, int new_child) {
  if (parent == kNullNode) {
    root_ = new_child;
    return;
  }
  Node& p = nodes_[parent];
  if (p.child1 == old_child) {
    p.child1 = new_child;
  } else {
    assert(p.child2 == old_child);
    p.child2 = new_child;
  }
}

void DynamicTree::insert_leaf(int leaf) {
  if (root_ == kNullNode) {
    root_ = leaf;
    nodes_[leaf].parent_or_next = kNullNode;
    return;
  }
  const int sibling = find_best_sibling(nodes_[leaf].aabb);
  const int old_parent = nodes_[sibling].parent_or_next;
  // allocate_node may grow nodes_, so no references are held across it.
  const int new_parent = allocate_node();
  Node& np = nodes_[new_parent];
  np.parent_or_next = old_parent;
  np.child1 = sibling;
  np.child2 = leaf;
  replace_child(old_parent, sibling, new_parent);
  nodes_[sibling].parent_or_next = new_parent;
  nodes_[leaf].parent_or_next = new_parent;
  // Starts at the new parent itself: a tall sibling makes it unbalanced right away.
  balance_upward(new_parent);
}

void DynamicTree::remove_leaf(int leaf) {
  if (leaf == root_) {
    root_ = kNullNode;
    return;
  }
  const int parent = nodes_[leaf].parent_or_next;
  const int grandparent = nodes_[parent].parent_or_next;
  const int sibling = nodes_[parent].child1 == leaf ? nodes_[parent].child2 : nodes_[parent].child1;
  // The sibling takes the parent's place.
  replace_child(grandparent, parent, sibling);
  nodes_[sibling].parent_or_next = grandparent;
  nodes_[leaf].parent_or_next = kNullNode;
  free_node(parent);
  balance_upward(grandparent);
}

void DynamicTree::refit(int index) {
  Node& node = nodes_[index];
  const Node& c1 = nodes_[node.child1];
  const Node& c2 = nodes_[node.child2];
  node.aabb = union_of(c1.aabb, c2.aabb);
  node.height = 1 + std::max(c1.height, c2.height);
  node.category_bits = c1.category_bits | c2.category_bits;
  node.mask_bits = c1.mask_bits | c2.mask_bits;
}

void DynamicTree::balance_upward(int index) {
  while (index != kNullNode) {
    balance(index);
    index = nodes_[index].parent_or_next;
  }
}

void DynamicTree::swap_with_grandchild(int index, int child, int other, int grandchild) {
  replace_child(index, child, grandchild);
  nodes_[grandchild].parent_or_next = index;
  replace_child(other, grandchild, child);
  nodes_[child].parent_or_next = other;
}

// Every rotation swaps a child X of node A with a grandchild Y under A's other child Z:
//
//   A(X, Z(Y, W))   ->   A(Y, Z(X, W))
//
// A keeps its place and its box, so nothing above it needs relinking; only Z's box changes,
// from Z to X u W. Leaves carry no order, so any such swap is allowed, and AVL's single and
// double rotations are both special cases.
//
// A swap is forced when A's children differ in height by more than kMaxImbalance: X is then
// the short child and Y one of the tall child's children. Of the swaps that restore the limit
// the one giving Z the smaller box wins. Otherwise a swap is taken only if it shrinks Z's box
// (the surface-area heuristic, which repairs the quality lost to insertion order and motion)
// while keeping every height difference within the limit and not raising A's height.
//
// Why forced swaps always succeed: let X have height h and Z height hz > h + k, with Z's
// children Y (taller) and W, so hy = hz - 1 and hw >= hy - k >= h. Swapping X with Y gives
// Z' = (X, W). If hw - h <= k, Z' has height hw + 1, within [hy - k + 1, hy + 1] of Y. If not
// (only right after an insert pairs a leaf with a tall sibling), Z' is balanced recursively;
// that "join" of two balanced trees of heights h < hw has height hw or hw + 1, again within
// the limit of Y. Either way A's new height is at most its height before the swap, so an
// insert grows each ancestor by at most one level and a removal grows none: every imbalance
// met on the way up is at most kMaxImbalance + 1, which one forced swap repairs.
void DynamicTree::balance(int index) {
  Node& a = nodes_[index];
  if (a.is_leaf()) return;
  const int c1 = a.child1;
  const int c2 = a.child2;
  const int h1 = nodes_[c1].height;
  const int h2 = nodes_[c2].height;

  if (std::abs(h1 - h2) > kMaxImbalance) {
    const int x = h1 < h2 ? c1 : c2;  // the short child
    const int z = h1 < h2 ? c2 : c1;  // the tall child, necessarily internal
    const int hx = nodes_[x].height;
    const int f = nodes_[z].child1;
    const int g = nodes_[z].child2;
    const int hmax = std::max(nodes_[f].height, nodes_[g].height);
    int best_y = kNullNode;
    double best_cost = 0.0;
    for (const int y : {f, g}) {
      const int w = y == f ? g : f;
      const int hy = nodes_[y].height;
      const int hw = nodes_[w].height;
      bool valid;
      if (std::abs(hx - hw) <= kMaxImbalance) {
        valid = std::abs(1 + std::max(hx, hw) - hy) <= kMaxImbalance;
      } else {
        valid = hy == hmax;  // a join: only the taller Y is proven to stay within the limit
      }
      if (!valid) continue;
      const double cost = union_of(nodes_[x].aabb, nodes_[w].aabb).perimeter();
      if (best_y == kNullNode || cost < best_cost) {
        best_y = y;
        best_cost = cost;
      }
    }
    assert(best_y != kNullNode);
    swap_with_grandchild(index, x, z, best_y);
    balance(z);  // refits Z, recursing only for a join
    refit(index);
    return;
  }

  refit(index);
  // Optional SAH swap: the candidate that shrinks Z's box the most, first found on ties.
  const int ha = a.height;
  int best_x = kNullNode;
  int best_z = kNullNode;
  int best_y = kNullNode;
  double best_gain = 0.0;
  for (const int x : {c1, c2}) {
    const int z = x == c1 ? c2 : c1;
    const Node& zn = nodes_[z];
    if (zn.is_leaf()) continue;
    const int hx = nodes_[x].height;
    const double z_area = zn.aabb.perimeter();
    for (const int y : {zn.child1, zn.child2}) {
      const int w = y == zn.child1 ? zn.child2 : zn.child1;
      const int hy = nodes_[y].height;
      const int hw = nodes_[w].height;
      const int hz = 1 + std::max(hx, hw);
      if (std::abs(hx - hw) > kMaxImbalance || std::abs(hy - hz) > kMaxImbalance ||
          1 + std::max(hy, hz) > ha) {
        continue;
      }
      const double gain = z_area - union_of(nodes_[x].aabb, nodes_[w].aabb).perimeter();
      if (gain > best_gain) {
        best_gain = gain;
        best_x = x;
        best_z = z;
        best_y = y;
      }
    }
  }
  if (best_x == kNullNode) return;
  swap_with_grandchild(index, best_x, best_z, best_y);
  refit(best_z);
  refit(index);
}

int DynamicTree::height() const {
  return root_ == kNullNode ? 0 : nodes_[root_].height;
}

void DynamicTree::refit_subtree(int index, double& internal, double& leaves) {
  const Node& node = nodes_[index];
  if (node.is_leaf()) {
    leaves += node.aabb.perimeter();
    return;
  }
  // The walk is a chase through nodes scattered over the pool: the second child is fetched
  // now, while the first child's subtree is walked.
  __builtin_prefetch(&nodes_[node.child2]);
  refit_subtree(node.child1, internal, leaves);
  refit_subtree(node.child2, internal, leaves);
  refit(index);
  internal += nodes_[index].aabb.perimeter();
}

namespace {

double cost_of(double internal, double leaves) {
  return leaves > 0.0 ? internal / leaves : std::numeric_limits<double>::infinity();
}

}  // namespace

double DynamicTree::refit_all(WorkerPool* pool) {
  if (root_ == kNullNode) return 0.0;
  // The nodes down to kSplitDepth (in pre-order) and the subtrees below them (in the same
  // walk's order): the split depends on the tree alone, so the sums are added in one order
  // whatever the thread count.
  constexpr int kSplitDepth = 5;
  std::vector<int>& tops = scratch_tops_;
  std::vector<int>& subtrees = scratch_subtrees_;
  tops.clear();
  subtrees.clear();
  auto split = [&](auto&& self, int index, int depth) -> void {
    const Node& node = nodes_[index];
    if (node.is_leaf() || depth == kSplitDepth) {
      subtrees.push_back(index);
      return;
    }
    tops.push_back(index);
    self(self, node.child1, depth + 1);
    self(self, node.child2, depth + 1);
  };
  split(split, root_, 0);
  const int n = static_cast<int>(subtrees.size());
  std::vector<double>& sums = scratch_sums_;
  sums.assign(2 * static_cast<size_t>(n), 0.0);
  auto chunk = [&](int i) { refit_subtree(subtrees[i], sums[2 * i], sums[2 * i + 1]); };
  run_chunks(proxy_count_ >= 2048 ? pool : nullptr, n, chunk, true);
  double internal = 0.0, leaves = 0.0;
  for (int i = 0; i < n; ++i) {
    internal += sums[2 * i];
    leaves += sums[2 * i + 1];
  }
  // The top nodes, children before parents.
  for (auto it = tops.rbegin(); it != tops.rend(); ++it) {
    refit(*it);
    internal += nodes_[*it].aabb.perimeter();
  }
  return cost_of(internal, leaves);
}

void DynamicTree::perimeter_sums(double& internal, double& leaves) const {
  for (const Node& node : nodes_) {
    if (node.height > 0) internal += node.aabb.perimeter();
    if (node.height == 0) leaves += node.aabb.perimeter();
  }
}

double DynamicTree::cost() const {
  if (root_ == kNullNode) return 0.0;
  double internal = 0.0, leaves = 0.0;
  perimeter_sums(internal, leaves);
  return cost_of(internal, leaves);
}

double DynamicTree::area_ratio() const {
  if (root_ == kNullNode) return 0.0;
  const double root_area = nodes_[root_].aabb.perimeter();
  if (!(root_area > 0.0)) return 0.0;
  double internal = 0.0, leaves = 0.0;
  perimeter_sums(internal, leaves);
  return internal / root_area;
}

bool DynamicTree::validate() const {
  const int capacity = static_cast<int>(nodes_.size());
  auto in_range = [capacity](int index) { return 0 <= index && index < capacity; };

  // Free list: in range, marked free, no cycle, and its length matches the bookkeeping.
  int free_count = 0;
  for (int index = free_list_; index != kNullNode; index = nodes_[index].parent_or_next) {
    if (!in_range(index) || nodes_[index].height != -1) return false;
    if (++free_count > capacity) return false;
  }
  if (node_count_ + free_count != capacity) return false;

  if (root_ == kNullNode) return node_count_ == 0 && proxy_count_ == 0;
  if (!in_range(root_) || nodes_[root_].parent_or_next != kNullNode) return false;

  // Every node reachable from the root exactly once: each child must point back at its
  // parent, and a node has a single parent link, so no node can be reached twice.
  std::vector<int> stack{root_};
  int reached = 0;
  int leaves = 0;
  while (!stack.empty()) {
    const int index = stack.back();
    stack.pop_back();
    if (++reached > node_count_) return false;
    const Node& node = nodes_[index];
    if (node.is_leaf()) {
      if (node.child2 != kNullNode || node.height != 0) return false;
      ++leaves;
      continue;
    }
    const int c1 = node.child1;
    const int c2 = node.child2;
    if (!in_range(c1) || !in_range(c2) || c1 == c2) return false;
    const Node& n1 = nodes_[c1];
    const Node& n2 = nodes_[c2];
    if (n1.parent_or_next != index || n2.parent_or_next != index) return false;
    if (n1.height < 0 || n2.height < 0) return false;
    if (node.height != 1 + std::max(n1.height, n2.height)) return false;
    if (std::abs(n1.height - n2.height) > kMaxImbalance) return false;
    if (!node.aabb.contains(n1.aabb) || !node.aabb.contains(n2.aabb)) return false;
    if (node.category_bits != (n1.category_bits | n2.category_bits)) return false;
    if (node.mask_bits != (n1.mask_bits | n2.mask_bits)) return false;
    stack.push_back(c1);
    stack.push_back(c2);
  }
  return reached == node_count_ && leaves == proxy_count_;
}

}  // namespace fulcrum
