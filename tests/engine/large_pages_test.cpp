// LargeAllocator (large_pages.h): large arrays mapped on whole 2 MB pages with the kernel's
// huge-page advice, small ones left to operator new, and a vector's elements kept as it moves
// between the two.
#include "large_pages.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>

#include "fulcrum/scene.h"
#include "fulcrum/scenes.h"
#include "world_impl.h"

namespace fulcrum {
namespace {

constexpr uintptr_t kTwoMegabytes = uintptr_t{2} << 20;

#if FULCRUM_LARGE_PAGES_MAPPED
// The VmFlags line of the mapping in /proc/self/smaps that holds [p, p + bytes), or "" if no
// one mapping does.
std::string flags_of_mapping(const void* p, size_t bytes) {
  std::ifstream smaps("/proc/self/smaps");
  const uintptr_t lo = reinterpret_cast<uintptr_t>(p), hi = lo + bytes;
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    uintptr_t start = 0, end = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> start >> dash >> end && dash == '-') {
      inside = start <= lo && hi <= end;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return "";
}
#endif

TEST(LargePages, ALargeArrayIsOnWholeTwoMegabytePagesWithTheHugePageAdvice) {
  // 3 MB of doubles: above the threshold, so mapped on its own and rounded up to 4 MB.
  const size_t n = (size_t{3} << 20) / sizeof(double);
  LargeVector<double> big(n, 1.5);
  ASSERT_GE(n * sizeof(double), kLargeBytes);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(big.data()) % kTwoMegabytes, 0u);
#if FULCRUM_LARGE_PAGES_MAPPED
  // The advice sets the mapping's "hg" flag wherever the kernel has transparent huge pages
  // at all (in any mode); without them madvise refuses it and the pages stay small.
  if (!std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled").good()) {
    GTEST_SKIP() << "this kernel has no transparent huge pages";
  }
  const std::string flags = flags_of_mapping(big.data(), size_t{4} << 20);
  ASSERT_FALSE(flags.empty()) << "no one mapping holds the array's 4 MB";
  EXPECT_NE(flags.find(" hg"), std::string::npos) << flags;
#endif
}

TEST(LargePages, AVectorKeepsItsElementsAsItGrowsOntoLargePagesAndShrinksOffThem) {
  LargeVector<int64_t> v;
  const int64_t count = static_cast<int64_t>(kLargeBytes / sizeof(int64_t)) * 3;
  for (int64_t i = 0; i < count; ++i) v.push_back(i * 7 - 3);  // small, then large, mappings
  ASSERT_GE(v.capacity() * sizeof(int64_t), kLargeBytes);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(v.data()) % kTwoMegabytes, 0u);
  for (int64_t i = 0; i < count; ++i) ASSERT_EQ(v[static_cast<size_t>(i)], i * 7 - 3) << i;
  v.resize(100);
  v.shrink_to_fit();  // back to operator new
  ASSERT_LT(v.capacity() * sizeof(int64_t), kLargeBytes);
  for (int64_t i = 0; i < 100; ++i) EXPECT_EQ(v[static_cast<size_t>(i)], i * 7 - 3) << i;
}

TEST(LargePages, ACopyOfALargeVectorIsItsOwn) {
  LargeVector<double> a((size_t{2} << 20) / sizeof(double), 2.0);
  LargeVector<double> b = a;
  b[0] = 3.0;
  b.back() = 4.0;
  EXPECT_NE(a.data(), b.data());
  EXPECT_EQ(a[0], 2.0);
  EXPECT_EQ(a.back(), 2.0);
  EXPECT_EQ(b[1], 2.0);
}

bool on_large_pages(const void* p) {
  return reinterpret_cast<uintptr_t>(p) % kTwoMegabytes == 0;
}

TEST(LargePages, ABigWorldKeepsItsBodiesContactsAndSolverBlocksOnThem) {
  // The large pyramid: 5050 boxes (1.6 MB of bodies), about 10 000 contacts (1.9 MB), and
  // about 1 300 blocks of coloured contacts (2 MB) after a tick.
  World w = std::move(build_world(scenes::builtin("large_pyramid").value()).value());
  w.step();
  const WorldImpl& impl = w.impl();
  ASSERT_GE(impl.bodies.capacity() * sizeof(Body), kLargeBytes);
  ASSERT_GE(impl.contacts.capacity() * sizeof(Contact), kLargeBytes);
  ASSERT_GE(impl.coloured_contacts.blocks.capacity() * sizeof(ContactBlock), kLargeBytes);
  EXPECT_TRUE(on_large_pages(impl.bodies.data()));
  EXPECT_TRUE(on_large_pages(impl.shapes.data()));
  EXPECT_TRUE(on_large_pages(impl.contacts.data()));
  EXPECT_TRUE(on_large_pages(impl.coloured_contacts.blocks.data()));
}

}  // namespace
}  // namespace fulcrum
