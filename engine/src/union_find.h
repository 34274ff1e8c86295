// Union-find over indices 0..n-1 in a plain vector (parent[i] == i for a root), as the islands,
// the budgets and the joint groups use it. Every root is the least index of its set, so the sets
// and their roots do not depend on the order in which pairs are joined.
#pragma once

#include <algorithm>
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

}  // namespace fulcrum
