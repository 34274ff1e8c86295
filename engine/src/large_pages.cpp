#include "large_pages.h"

#include <cstdint>

#if FULCRUM_LARGE_PAGES_MAPPED
#include <sys/mman.h>
#endif

namespace fulcrum {

namespace {

constexpr size_t kHugePage = size_t{2} << 20;

}  // namespace

#if FULCRUM_LARGE_PAGES_MAPPED

namespace {

size_t whole_pages(size_t bytes) {
  return (bytes + kHugePage - 1) / kHugePage * kHugePage;
}

}  // namespace

// One anonymous mapping a page longer than asked, trimmed to start on a 2 MB boundary: mmap
// aligns to 4 KB only, and a huge page needs its 2 MB aligned.
void* allocate_large(size_t bytes) {
  const size_t length = whole_pages(bytes);
  void* raw =
      mmap(nullptr, length + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) throw std::bad_alloc();
  const uintptr_t start = reinterpret_cast<uintptr_t>(raw);
  const uintptr_t aligned = (start + kHugePage - 1) / kHugePage * kHugePage;
  if (aligned > start) munmap(raw, aligned - start);
  const size_t tail = start + kHugePage - aligned;
  if (tail > 0) munmap(reinterpret_cast<void*>(aligned + length), tail);
  void* p = reinterpret_cast<void*>(aligned);
  // Advice only: a kernel without transparent huge pages refuses it, and the pages stay small.
  madvise(p, length, MADV_HUGEPAGE);
  return p;
}

void free_large(void* p, size_t bytes) noexcept {
  munmap(p, whole_pages(bytes));
}

#else

// At the exact size, so that AddressSanitizer checks the array's end.
void* allocate_large(size_t bytes) {
  return ::operator new (bytes, std::align_val_t{kHugePage});
}

void free_large(void* p, size_t) noexcept {
  ::operator delete (p, std::align_val_t{kHugePage});
}

#endif

}  // namespace fulcrum
