// The allocator module in a process without jemalloc (tests link glibc's
// malloc; the daemon's jemalloc is checked through GET /metrics in
// tests/http_api_test.cc).
#include "frictiond/server/allocator.h"

#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/testing/sanitizers.h"

namespace frictiond {
namespace {

TEST(AllocatorTest, ReportsGlibcWhenJemallocIsNotLinked) {
  EXPECT_EQ(CurrentHeapAllocator(), HeapAllocator::kGlibc);
  EXPECT_EQ(ToString(HeapAllocator::kGlibc), "glibc");
  EXPECT_EQ(ToString(HeapAllocator::kJemalloc), "jemalloc");
}

TEST(AllocatorTest, HeapInUseCountsLiveBlocks) {
#ifdef FRICTIOND_TEST_ASAN
  GTEST_SKIP() << "AddressSanitizer's malloc: mallinfo2 reads zeros";
#endif
  const HeapStats before = ReadHeapStats();
  // 64 blocks of 64 KiB: below the tuned mmap threshold or above glibc's
  // default, counted either way (uordblks or hblkhd).
  std::vector<std::unique_ptr<char[]>> blocks;
  for (int i = 0; i < 64; ++i) {
    blocks.emplace_back(new char[64 << 10]);
    blocks.back()[0] = static_cast<char>(i);
  }
  const HeapStats during = ReadHeapStats();
  EXPECT_GE(during.in_use, before.in_use + (4u << 20) - (256u << 10));
  blocks.clear();
  const HeapStats after = ReadHeapStats();
  EXPECT_LT(after.in_use, during.in_use);
}

TEST(AllocatorTest, TuneAndReleaseAreSafeAtAnyTime) {
  TuneHeapAllocator();
  std::vector<std::unique_ptr<char[]>> blocks;
  for (int i = 0; i < 32; ++i) blocks.emplace_back(new char[1 << 20]);
  blocks.resize(8);
  ReleaseFreeHeap();
  const HeapStats s = ReadHeapStats();
#ifndef FRICTIOND_TEST_ASAN
  EXPECT_GT(s.in_use, 8u << 20);
#else
  (void)s;
#endif
}

}  // namespace
}  // namespace frictiond
