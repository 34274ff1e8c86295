// Union-find over indices 0..n-1 in a plain vector (parent[i] == i for a root), as the islands,
// the budgets and the joint groups use it. Every root is the least index of its set, so the sets
// and their roots do not depend on the order in which pairs are joined.
#pragma once

#include <algorithm>
#include <atomic>
#include <vector>

namespace fulcrum {

inline int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];  // path halving
    i = parent[i];
  }
  return i;
}

inline void unite(std::vector<int>& parent, int a, int b) {
  a = find_root(parent, a);
  b = find_root(parent, b);
  if (a != b) parent[std::max(a, b)] = std::min(a, b);
}

// The same sets joined by several threads at once (Anderson and Woll's wait-free union-find):
// a root is linked under the smaller root by compare-and-swap, and fails (and looks again) if
// another thread linked it first, so every root is still the least index of its set and the sets
// and roots are those of unite in any order. Path halving only rewrites entries that are no
// longer roots, to an ancestor in the same set, and linking only rewrites roots: the two never
// race on one entry. parent must not be read by plain loads until the threads are joined.
inline int find_root_shared(std::vector<int>& parent, int i) {
  for (;;) {
    const int p = std::atomic_ref<int>(parent[i]).load(std::memory_order_relaxed);
    if (p == i) return i;
    const int g = std::atomic_ref<int>(parent[p]).load(std::memory_order_relaxed);
    if (g != p) std::atomic_ref<int>(parent[i]).store(g, std::memory_order_relaxed);
    i = g;
  }
}

inline void unite_shared(std::vector<int>& parent, int a, int b) {
  for (;;) {
    a = find_root_shared(parent, a);
    b = find_root_shared(parent, b);
    if (a == b) return;
    if (a < b) std::swap(a, b);
    int root = a;
    if (std::atomic_ref<int>(parent[a]).compare_exchange_strong(root, b,
                                                                std::memory_order_relaxed)) {
      return;
    }
  }
}

}  // namespace fulcrum
