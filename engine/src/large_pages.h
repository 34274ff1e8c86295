// The engine's large arrays on 2 MB pages.
//
// A big world's step walks arrays of several megabytes in an order the cache cannot follow:
// bodies and contacts by id, the solver's blocks colour by colour, the bodies again from every
// block. On 4 KB pages each such array spans hundreds of pages, more than the processor's
// translation cache holds, and a miss there costs a walk of the page tables (two nested walks
// in a virtual machine). Linux's transparent huge pages in "madvise" mode, as on this
// project's machines, go only to memory that asks for them: LargeAllocator asks for every
// allocation of kLargeBytes or more, and leaves smaller ones to std::allocator. Where
// the kernel has none to give, the memory is ordinary pages; nothing else changes, the
// numbers least of all.
#pragma once

#include <cstddef>
#include <memory>
#include <new>
#include <vector>

// Whether large arrays are mapped by hand (Linux). Not under AddressSanitizer, which checks the
// bounds only of what operator new gives, and whose leak check does not look for pointers in
// memory mapped by hand (a body's list of shapes would seem leaked): there they come from
// operator new, 2 MB aligned, at their exact size.
#if defined(__SANITIZE_ADDRESS__)
#define FULCRUM_LARGE_PAGES_MAPPED 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(leak_sanitizer)
#define FULCRUM_LARGE_PAGES_MAPPED 0
#endif
#endif
#if !defined(FULCRUM_LARGE_PAGES_MAPPED)
#if defined(__linux__)
#define FULCRUM_LARGE_PAGES_MAPPED 1
#else
#define FULCRUM_LARGE_PAGES_MAPPED 0
#endif
#endif

namespace fulcrum {

// Allocations from this size on are mapped on their own, 2 MB aligned and rounded up to whole
// 2 MB pages (so at most half of such a mapping is slack, and a vector's spare capacity may
// already be as much).
inline constexpr size_t kLargeBytes = size_t{1} << 20;

// `bytes` (>= kLargeBytes) bytes, 2 MB aligned, advised to the kernel as huge-page
// memory where they are mapped; throws std::bad_alloc when the system has no room. free_large takes
// back the same number of bytes.
void* allocate_large(size_t bytes);
void free_large(void* p, size_t bytes) noexcept;

template <class T>
struct LargeAllocator {
  using value_type = T;
  LargeAllocator() = default;
  template <class U>
  LargeAllocator(const LargeAllocator<U>&) noexcept {}  // implicit, as allocators convert

  T* allocate(size_t n) {
    if (n * sizeof(T) >= kLargeBytes) return static_cast<T*>(allocate_large(n * sizeof(T)));
    return std::allocator<T>().allocate(n);
  }
  void deallocate(T* p, size_t n) noexcept {
    if (n * sizeof(T) >= kLargeBytes) {
      free_large(p, n * sizeof(T));
    } else {
      std::allocator<T>().deallocate(p, n);
    }
  }
  template <class U>
  bool operator==(const LargeAllocator<U>&) const noexcept {
    return true;
  }
};

// A vector whose elements go on 2 MB pages once it is large.
template <class T>
using LargeVector = std::vector<T, LargeAllocator<T>>;

}  // namespace fulcrum
