#pragma once
/// @file
/// The process's heap allocator, as the daemon sees it: which one runs,
/// how much it holds, and handing its free memory back to the system.
///
/// The `frictiond` executable links jemalloc when the build found it
/// (CMake `FRICTIOND_HAVE_JEMALLOC`; Debian libjemalloc-dev); libraries,
/// tests and sanitizer builds keep glibc's malloc. Nothing here names
/// jemalloc at link time: `mallctl` is looked up as a weak symbol, so this
/// file builds and runs with either allocator and reports the one in use.
///
/// Why jemalloc in the daemon (measured, docs/ingest.md "Stop 33"): a
/// refit's buffers are allocated on an upload's thread and freed on a fit
/// worker (and back); glibc's arenas paid that in malloc/free locking and
/// consolidation (about 15 % of the daemon's CPU under two clients) and
/// kept freed pages between live blocks resident (RSS growth 20 % in the
/// 60 s soak). With jemalloc's per-thread caches the daemon's CPU per
/// upload fell 1.83 -> 1.72 ms and two clients no longer cost more CPU per
/// upload than one.

#include <cstdint>
#include <string>

namespace frictiond {

/// Which allocator serves malloc in this process.
enum class HeapAllocator { kGlibc, kJemalloc };

/// The allocator in use (jemalloc when its `mallctl` is linked in).
HeapAllocator CurrentHeapAllocator();

/// "glibc" or "jemalloc".
std::string ToString(HeapAllocator a);

/// Bytes the allocator holds: in use by the program and held free.
struct HeapStats {
  /// Allocated and not freed (glibc: mallinfo2 uordblks + hblkhd;
  /// jemalloc: stats.allocated).
  std::uint64_t in_use = 0;
  /// Freed but kept by the allocator (glibc: mallinfo2 fordblks;
  /// jemalloc: stats.resident - stats.allocated, the resident pages beyond
  /// live blocks, its metadata included).
  std::uint64_t kept_free = 0;
};

/// The allocator's current figures. Thread-safe.
HeapStats ReadHeapStats();

/// Settings for a daemon whose uploads each allocate and free a few MB.
/// glibc: see allocator.cc (arena count, mmap and trim thresholds);
/// jemalloc: nothing (its defaults suit). Call once, first thing in main.
void TuneHeapAllocator();

/// Hands free memory back to the system (glibc: malloc_trim(0); jemalloc:
/// purges every arena's unused dirty pages). For a periodic timer, not per
/// request: pages used again fault back in.
void ReleaseFreeHeap();

}  // namespace frictiond
