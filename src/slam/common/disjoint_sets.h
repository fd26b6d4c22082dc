#pragma once
// Disjoint sets over the indices 0..n-1 (union-find with path halving): which elements a set of
// pairwise joins connects, e.g. the keyframes that shared points join into parts of a map.
#include <cstddef>
#include <vector>

namespace pcr {

class DisjointSets {
 public:
  explicit DisjointSets(size_t n) : parent_(n) {
    for (size_t i = 0; i < n; ++i) parent_[i] = i;
  }
  // The representative of i's set (the same for every element of a set, until the next Join).
  size_t Find(size_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void Join(size_t a, size_t b) { parent_[Find(a)] = Find(b); }
  bool Joined(size_t a, size_t b) { return Find(a) == Find(b); }

 private:
  std::vector<size_t> parent_;
};

}  // namespace pcr
