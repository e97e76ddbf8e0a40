#include "frictiond/server/allocator.h"

#include <cstddef>
#include <string>

#include <malloc.h>

// jemalloc's control interface, weak: null unless jemalloc is linked into
// the executable (Debian's libjemalloc exports it unprefixed).
extern "C" int mallctl(const char* name,
                       void* oldp,
                       std::size_t* oldlenp,
                       void* newp,
                       std::size_t newlen) __attribute__((weak));

namespace frictiond {
namespace {

bool HaveJemalloc() { return &mallctl != nullptr; }

/// A size_t statistic of jemalloc's, 0 when it cannot be read.
std::uint64_t JemallocStat(const char* name) {
  std::size_t value = 0;
  std::size_t len = sizeof(value);
  if (mallctl(name, &value, &len, nullptr, 0) != 0) return 0;
  return value;
}

}  // namespace

HeapAllocator CurrentHeapAllocator() {
  return HaveJemalloc() ? HeapAllocator::kJemalloc : HeapAllocator::kGlibc;
}

std::string ToString(HeapAllocator a) {
  return a == HeapAllocator::kJemalloc ? "jemalloc" : "glibc";
}

HeapStats ReadHeapStats() {
  HeapStats out;
  if (HaveJemalloc()) {
    // jemalloc caches its statistics; writing "epoch" refreshes them.
    std::uint64_t epoch = 1;
    std::size_t len = sizeof(epoch);
    mallctl("epoch", &epoch, &len, &epoch, len);
    out.in_use = JemallocStat("stats.allocated");
    const std::uint64_t resident = JemallocStat("stats.resident");
    out.kept_free = resident > out.in_use ? resident - out.in_use : 0;
    return out;
  }
  const struct mallinfo2 m = ::mallinfo2();
  out.in_use = m.uordblks + m.hblkhd;
  out.kept_free = m.fordblks;
  return out;
}

void TuneHeapAllocator() {
  if (HaveJemalloc()) return;
  // glibc, for a daemon whose uploads each allocate and free a few MB (a
  // bounded refit's copy of up to `fit_sample_cap` samples and its design
  // matrices). By default blocks above a dynamic threshold are mmap'ed and
  // unmapped again, and a thread arena's free top is handed back (madvise)
  // after each upload, so the next upload page-faults the same memory in
  // again: profiled on `bench/run upload_parallel`, page faults, madvise
  // and malloc took about a quarter of the daemon's CPU per upload (stop
  // 20). Blocks below 8 MiB come from the arenas, an arena keeps up to
  // 16 MiB of free top for the next upload, and there are at most 4 arenas
  // (glibc's default is 8 per core; the daemon's threads mostly wait). The
  // cost is memory held, at most 4 x 16 MiB. GLIBC_TUNABLES cannot
  // override this (it is applied after them).
  mallopt(M_ARENA_MAX, 4);
  mallopt(M_MMAP_THRESHOLD, 8 << 20);
  mallopt(M_TRIM_THRESHOLD, 16 << 20);
}

void ReleaseFreeHeap() {
  if (HaveJemalloc()) {
    // "arena.<MALLCTL_ARENAS_ALL>.purge": every arena's unused dirty pages.
    mallctl("arena.4096.purge", nullptr, nullptr, nullptr, 0);
    return;
  }
  // Page-aligned free chunks anywhere in an arena, not only its top.
  ::malloc_trim(0);
}

}  // namespace frictiond
