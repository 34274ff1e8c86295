// A set of 64-bit keys (pairs of shape indices, pair_key) with open addressing: one flat array,
// linear probing from a multiplicative hash, at most half full, and deletion by shifting later
// entries of the probe run back (no tombstones), so lookups stay short however many contacts
// come and go. The broad phase asks it, for every candidate pair a moved shape finds, whether
// the pair has a contact already; a node-based hash map spent most of that time on cache misses.
// Only looked up, never iterated, so its layout never reaches the results. Key 0 marks an empty
// slot: pair_key never gives it (a pair has two different shapes).
#pragma once

#include <cassert>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "large_pages.h"

namespace fulcrum {

class PairSet {
 public:
  bool contains(uint64_t key) const {
    if (slots_.empty()) return false;
    for (size_t i = home(key);; i = (i + 1) & mask()) {
      if (slots_[i] == key) return true;
      if (slots_[i] == 0) return false;
    }
  }

  // Starts loading the key's home slot, for a lookup soon after.
  void prefetch(uint64_t key) const {
    if (!slots_.empty()) __builtin_prefetch(&slots_[home(key)]);
  }

  // Returns false if the key was there already.
  bool insert(uint64_t key) {
    assert(key != 0);
    if (2 * (size_ + 1) > slots_.size()) grow();
    size_t i = home(key);
    for (; slots_[i] != 0; i = (i + 1) & mask()) {
      if (slots_[i] == key) return false;
    }
    slots_[i] = key;
    ++size_;
    return true;
  }

  // Returns false if the key was not there.
  bool erase(uint64_t key) {
    if (slots_.empty()) return false;
    size_t i = home(key);
    for (; slots_[i] != key; i = (i + 1) & mask()) {
      if (slots_[i] == 0) return false;
    }
    // Close the gap: a later key of the run moves into it unless its home lies cyclically in
    // (gap, j], where it is already as near its home as the gap would put it.
    size_t gap = i;
    for (size_t j = (gap + 1) & mask(); slots_[j] != 0; j = (j + 1) & mask()) {
      const size_t h = home(slots_[j]);
      const bool stays = gap <= j ? (gap < h && h <= j) : (gap < h || h <= j);
      if (!stays) {
        slots_[gap] = slots_[j];
        gap = j;
      }
    }
    slots_[gap] = 0;
    --size_;
    return true;
  }

  void clear() {
    slots_.clear();
    size_ = 0;
    shift_ = 64;
  }
  size_t size() const { return size_; }

 private:
  size_t mask() const { return slots_.size() - 1; }
  // Fibonacci hashing: the top bits of key * 2^64 / phi.
  size_t home(uint64_t key) const {
    return static_cast<size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  void grow() {
    LargeVector<uint64_t> old;
    old.swap(slots_);
    const size_t capacity = old.empty() ? 16 : 2 * old.size();
    slots_.assign(capacity, 0);
    shift_ = 64 - __builtin_ctzll(capacity);
    size_ = 0;
    for (uint64_t key : old) {
      if (key != 0) insert(key);
    }
  }

  LargeVector<uint64_t> slots_;
  size_t size_ = 0;
  int shift_ = 64;
};

}  // namespace fulcrum
