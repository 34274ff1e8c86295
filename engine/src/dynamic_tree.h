// A dynamic AABB tree (bounding volume hierarchy) for the broad phase and for queries. Leaves
// hold fattened boxes so that a shape moving a little does not change the tree. Insertion picks
// the sibling by the surface-area heuristic and the tree is kept balanced by rotations.
// Everything is deterministic: the same sequence of calls builds the same tree and visits
// leaves in the same order.
#pragma once

#include <cstdint>
#include <vector>

#include "large_pages.h"

#include "fulcrum/geometry.h"
#include "fulcrum/math.h"

namespace fulcrum {

class WorkerPool;

inline constexpr int kNullNode = -1;

class DynamicTree {
 public:
  DynamicTree();

  // Inserts a leaf with this (already fattened) box and collision filter bits; returns its
  // proxy id. Ids of destroyed proxies are reused, most recently freed first.
  int create_proxy(const AABB& fat_aabb, uint64_t user_data, uint64_t category_bits = ~0ull,
                   uint64_t mask_bits = ~0ull);
  void destroy_proxy(int proxy_id);
  // Replaces a leaf's box (re-inserting the leaf).
  void move_proxy(int proxy_id, const AABB& fat_aabb);
  // Replaces many leaves' boxes at once: set_leaf_box for each (the tree is not valid in
  // between), then one rebuild(), which builds every internal node anew, top down, splitting
  // the leaves at the median of their centres along the wider axis. Cheaper than a
  // move_proxy each when a large share of the leaves moved.
  // With a pool, a large tree's parts are built on its threads (the same tree).
  void set_leaf_box(int proxy_id, const AABB& fat_aabb) { nodes_[proxy_id].aabb = fat_aabb; }
  void rebuild(WorkerPool* pool = nullptr);
  // After set_leaf_box calls, the cheaper alternative to rebuild(): every internal node's box
  // (and bits and height) refitted from its children, the structure kept. Returns cost().
  // The subtrees below the top levels are refitted one per chunk, on the pool's threads when
  // there is one; the sums come out the same at any thread count.
  double refit_all(WorkerPool* pool = nullptr);
  // The sum of the internal nodes' perimeters over the leaves': a query's walk grows with it.
  // Infinite when the leaves have no extent.
  double cost() const;

  // Replaces a leaf's filter bits (and its ancestors' unions of them).
  void set_leaf_filter(int proxy_id, uint64_t category_bits, uint64_t mask_bits);

  const AABB& fat_aabb(int proxy_id) const { return nodes_[proxy_id].aabb; }
  uint64_t user_data(int proxy_id) const { return user_data_[proxy_id]; }

  // Calls callback(proxy_id) for every leaf whose box overlaps `aabb`; the callback returns
  // false to stop the query.
  template <typename Callback>
  void query(const AABB& aabb, Callback&& callback) const;
  // The same, but only leaves whose filter bits could pass against a querying shape with
  // these bits: category & the shape's mask and the shape's category & mask both nonzero.
  // Whole subtrees that hold no such leaf are skipped (every node keeps the union of its
  // leaves' bits), so a crowd of shapes that never collide with each other costs no walk.
  template <typename Callback>
  void query_filtered(const AABB& aabb, uint64_t category_bits, uint64_t mask_bits,
                      Callback&& callback) const;

  // Calls callback(input, proxy_id) for every leaf whose box the ray crosses, nearest-first is
  // not guaranteed. The callback returns the new max fraction: 0 ends the cast, a value in
  // (0, input.max_fraction) clips the ray, input.max_fraction (or more) keeps it.
  template <typename Callback>
  void ray_cast(const RayCastInput& input, Callback&& callback) const;

  // Every pair of overlapping leaves, one of this tree and one of `other` (or, with other being
  // this tree, every unordered pair of two of its leaves), at least one of them marked, found by
  // walking the two trees together: a subtree pair is entered only when the boxes overlap, the
  // filter bits could pass both ways and one side holds a marked leaf. When most leaves moved
  // this costs far less than a query per leaf. `marks` and `other_marks` are indexed by node
  // (node_capacity() long), set for the marked leaves and their ancestors (mark_with_ancestors).
  // The work is split into tasks (join_tasks: at least `want` where the trees allow), each
  // walked by join(); report(leaf_of_this, leaf_of_other) returns false to stop that task.
  struct JoinTask {
    int a, b;  // a == b in a join of a tree with itself: the pairs within a's subtree
  };
  std::vector<JoinTask> join_tasks(const DynamicTree& other, int want) const;
  template <typename Report>
  void join(const DynamicTree& other, JoinTask task, const uint8_t* marks,
            const uint8_t* other_marks, Report&& report) const;
  // Marks `leaf` and its ancestors in `marks`, up to the first already marked.
  void mark_with_ancestors(int leaf, uint8_t* marks) const {
    for (int n = leaf; n != kNullNode && marks[n] == 0; n = nodes_[n].parent_or_next) marks[n] = 1;
  }

  int height() const;
  int proxy_count() const { return proxy_count_; }
  int node_capacity() const { return static_cast<int>(nodes_.size()); }
  // Sum of internal node perimeters over the root perimeter (a quality measure).
  double area_ratio() const;
  // Checks parent links, heights and boxes; returns false if the structure is broken.
  bool validate() const;

 private:
  // One cache line: what a query reads of each node it visits. A leaf's user data is kept
  // apart (user_data_), read only for the leaves a query reports.
  struct alignas(64) Node {
    AABB aabb;
    // A leaf's filter bits; an internal node's, the union of its leaves'.
    uint64_t category_bits = 0, mask_bits = 0;
    int parent_or_next = kNullNode;  // parent, or the next free node while on the free list
    int child1 = kNullNode;
    int child2 = kNullNode;
    int height = -1;  // leaf = 0, free = -1
    bool is_leaf() const { return child1 == kNullNode; }
  };
  static_assert(sizeof(Node) == 64);

  // Whether two nodes' subtrees may hold a pair join() reports.
  static bool may_pair(const Node& a, const Node& b) {
    return (a.category_bits & b.mask_bits) != 0 && (b.category_bits & a.mask_bits) != 0 &&
           a.aabb.overlaps(b.aabb);
  }
  // What one join() walks with: the two trees' marks and the report.
  template <typename Report>
  struct JoinWalk {
    const uint8_t* marks;
    const uint8_t* other_marks;
    Report& report;
  };
  template <typename Report>
  bool join_pair(const DynamicTree& other, int a, int b, JoinWalk<Report>& walk) const;
  template <typename Report>
  bool join_self(int node, JoinWalk<Report>& walk) const;

  template <bool kFiltered, typename Callback>
  void walk(const AABB& aabb, uint64_t category_bits, uint64_t mask_bits,
            Callback&& callback) const;

  // A traversal stack local to one query or ray cast (defined in dynamic_tree_inl.h): a fixed
  // array with a heap fallback, so traversals are const, re-entrant and allocation-free.
  class TraversalStack;

  int allocate_node();
  void free_node(int node);
  void insert_leaf(int leaf);
  void remove_leaf(int leaf);
  // The sibling for a new leaf with this box, by the surface-area heuristic.
  int find_best_sibling(const AABB& box) const;
  // Restores the height balance of the subtree at `index` (whose child subtrees are balanced)
  // and refits its box and height; may swap nodes below it, never `index` itself.
  void balance(int index);
  // Swaps `child` of `index` with `grandchild`, a child of `other` (index's other child).
  void swap_with_grandchild(int index, int child, int other, int grandchild);
  // Balances and refits `index` and every ancestor up to the root.
  void balance_upward(int index);
  // Box and height of an internal node from its children.
  void refit(int index);
  // refit() over the subtree at `index`, children first; adds the perimeters to the sums.
  void refit_subtree(int index, double& internal, double& leaves);
  // Adds the perimeters of the internal nodes and of the leaves to the sums, in node order.
  void perimeter_sums(double& internal, double& leaves) const;
  void replace_child(int parent, int old_child, int new_child);
  struct LeafCentre {
    double c[2];  // centre of the leaf's box
    int leaf;
  };
  // The subtree over leaves[0, count) (rebuild), its internal nodes slots[0, count - 1);
  // returns its root.
  int build_range(LeafCentre* leaves, int count, const int* slots);
  // Orders leaves[0, count) about their median centre along the wider axis; returns count / 2.
  int split_range(LeafCentre* leaves, int count);
  // Makes `node` the parent of `left` and `right`, refitted; returns it.
  int join(int node, int left, int right);

  LargeVector<Node> nodes_;
  LargeVector<uint64_t> user_data_;  // per node; meaningful for leaves only
  int root_ = kNullNode;
  int free_list_ = kNullNode;
  int node_count_ = 0;  // nodes in the tree (leaves and internal), not on the free list
  int proxy_count_ = 0;
  std::vector<LeafCentre> scratch_leaves_;  // rebuild
  std::vector<int> scratch_slots_;          // rebuild
  std::vector<int> scratch_tops_;           // refit_all: the nodes above its subtrees
  std::vector<int> scratch_subtrees_;       // refit_all
  std::vector<double> scratch_sums_;        // refit_all: each subtree's two perimeter sums
};

}  // namespace fulcrum

#include "dynamic_tree_inl.h"
