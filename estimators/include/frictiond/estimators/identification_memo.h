#pragma once
/// @file
/// Results of identification steps that depend on one run or one stroke of
/// samples only, kept by the caller between identifications of the same
/// material (IdentifyMaterial, MaterialIdentificationOptions::memo). A
/// bounded refit (the daemon's ingestor) sees mostly the strokes of the
/// previous one, so a step recomputed per stroke on every upload (the LuGre
/// stroke recognition of a run, the hull of a stroke's slipping samples)
/// is looked up instead.
///
/// Exact: an entry is keyed by a 128-bit hash of every input the step reads
/// (the samples' bit patterns, their count and the step's parameters), so
/// a hit returns what the step would compute, not an approximation. The
/// hash is not cryptographic; a memo belongs to one material-fingertip pair
/// (the daemon keeps one per pair), so only that pair's own uploads share
/// entries.
///
/// Bounded: Sweep() drops every entry not used since the previous Sweep.
/// IdentifyMaterial sweeps at its end, so a memo holds what the last call
/// used (one refit's strokes). A run or stroke of more than
/// kMaxMemoSamples samples is computed, never kept (a huge upload's
/// results do not outlive its refit).
///
/// Thread-safe (one mutex per table): IdentifyMaterial's two shares use it
/// at once.
///
/// @code
///   IdentificationMemo memo;  // one per material, kept
///   MaterialIdentificationOptions o;
///   o.memo = &memo;
///   IdentifyMaterial(strokes, o);          // computes and keeps
///   IdentifyMaterial(strokes_plus_one, o);  // looks up the older strokes
/// @endcode

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <utility>
#include <vector>

#include "frictiond/estimators/lugre_identification.h"

namespace frictiond {

/// Largest run or stroke (samples) whose results a memo keeps.
inline constexpr std::size_t kMaxMemoSamples = 65'536;

/// 128-bit key of a memo entry: a hash of the step's inputs.
struct MemoKey {
  std::uint64_t a = 0, b = 0;
  bool operator==(const MemoKey& o) const { return a == o.a && b == o.b; }
};

/// Builds a MemoKey from the bit patterns of what is added: two 64-bit
/// streams with one multiply per word each (xor-multiply, and
/// add-multiply-rotate, with different odd constants), mixed at the end by
/// SplitMix64's finaliser. About 1 ns per word: a 250-sample run of five
/// columns costs ~1 us, against ~10 us to recognise it.
class MemoKeyBuilder {
 public:
  explicit MemoKeyBuilder(std::uint64_t domain) { Add(domain); }
  MemoKeyBuilder& Add(std::uint64_t x) {
    a_ = (a_ ^ x) * 0x9e3779b97f4a7c15ULL;
    b_ = (b_ + x) * 0xd6e8feb86659fd93ULL;
    b_ = (b_ << 29) | (b_ >> 35);
    ++n_;
    return *this;
  }
  MemoKeyBuilder& Add(double x) {
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    return Add(bits);
  }
  /// Adds x[begin, end) and its length. Eight words or more go four at a
  /// time through four lanes per stream (each lane the same xor-multiply
  /// and add-multiply-rotate, from its own start), folded into the streams
  /// at the end: the lanes' multiplies overlap, where one stream waits for
  /// each. The keys of a bounded refit's 17 runs (memo hits, 4,250 samples
  /// of five columns): the LuGre recognition's lookup 54 -> 35 us.
  MemoKeyBuilder& Add(const std::vector<double>& x,
                      std::size_t begin,
                      std::size_t end) {
    const std::size_t n = end - begin;
    Add(static_cast<std::uint64_t>(n));
    const double* p = x.data() + begin;
    // Words [0, bulk) go through the lanes, [bulk, n) one at a time.
    const std::size_t bulk = n >= 8 ? n - n % 4 : 0;
    if (bulk > 0) {
      std::uint64_t a[4], b[4];
      for (int j = 0; j < 4; ++j) {
        a[j] = a_ + 0x632be59bd9b4e019ULL * static_cast<std::uint64_t>(j + 1);
        b[j] = b_ + 0x8cb92ba72f3d8dd7ULL * static_cast<std::uint64_t>(j + 1);
      }
      for (std::size_t i = 0; i < bulk; i += 4) {
        for (int j = 0; j < 4; ++j) {
          std::uint64_t w;
          std::memcpy(&w, p + i + static_cast<std::size_t>(j), sizeof w);
          a[j] = (a[j] ^ w) * 0x9e3779b97f4a7c15ULL;
          b[j] = (b[j] + w) * 0xd6e8feb86659fd93ULL;
          b[j] = (b[j] << 29) | (b[j] >> 35);
        }
      }
      for (int j = 0; j < 4; ++j) Add(Mix(a[j])).Add(Mix(b[j]));
    }
    for (std::size_t i = bulk; i < n; ++i) Add(p[i]);
    return *this;
  }
  MemoKey Key() const {
    return {Mix(a_ ^ n_), Mix(b_ + 0x94d049bb133111ebULL * n_)};
  }

 private:
  static std::uint64_t Mix(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  std::uint64_t a_ = 0x243f6a8885a308d3ULL, b_ = 0x13198a2e03707344ULL;
  std::uint64_t n_ = 0;
};

/// One table of a memo: values by key, each used or not since the last
/// Sweep. Values are shared and immutable (a hit is not copied).
template <class Value>
class MemoTable {
 public:
  /// The value under `key` (marked used), or null.
  std::shared_ptr<const Value> Find(const MemoKey& key) {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = map_.find(key);
    if (it == map_.end()) {
      ++misses_;
      return nullptr;
    }
    ++hits_;
    it->second.used = true;
    return it->second.value;
  }
  /// Keeps `value` under `key` (marked used); returns it.
  std::shared_ptr<const Value> Insert(const MemoKey& key, Value value) {
    auto v = std::make_shared<const Value>(std::move(value));
    std::lock_guard<std::mutex> lock(mu_);
    map_[key] = Entry{v, true};
    return v;
  }
  /// Drops the entries not used since the previous Sweep.
  void Sweep() {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto it = map_.begin(); it != map_.end();) {
      if (!it->second.used) {
        it = map_.erase(it);
      } else {
        it->second.used = false;
        ++it;
      }
    }
  }
  /// Drops every entry.
  void Clear() {
    std::lock_guard<std::mutex> lock(mu_);
    map_.clear();
  }
  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mu_);
    return map_.size();
  }
  /// Find calls that found their key, and that did not (since creation).
  std::uint64_t hits() const {
    std::lock_guard<std::mutex> lock(mu_);
    return hits_;
  }
  std::uint64_t misses() const {
    std::lock_guard<std::mutex> lock(mu_);
    return misses_;
  }

 private:
  struct Hash {
    std::size_t operator()(const MemoKey& k) const {
      return static_cast<std::size_t>(k.a);
    }
  };
  struct Entry {
    std::shared_ptr<const Value> value;
    bool used = false;
  };
  mutable std::mutex mu_;
  std::unordered_map<MemoKey, Entry, Hash> map_;
  std::uint64_t hits_ = 0, misses_ = 0;
};

/// The value `compute()` gives for a run or stroke of `samples` samples:
/// looked up in `table` under `key()`, and kept there when computed. With
/// no table, or more than kMaxMemoSamples samples, it is computed only (and
/// `key` is not called). `key` is called before `compute`, so `compute`
/// may consume what `key` reads.
template <class Value, class KeyFn, class ComputeFn>
std::shared_ptr<const Value> Memoized(MemoTable<Value>* table,
                                      std::size_t samples,
                                      KeyFn key,
                                      ComputeFn compute) {
  if (table == nullptr || samples > kMaxMemoSamples)
    return std::make_shared<const Value>(compute());
  const MemoKey k = key();
  if (std::shared_ptr<const Value> hit = table->Find(k)) return hit;
  return table->Insert(k, compute());
}

/// A stroke's hull (span_coverage.h): its vertices in lexicographic order
/// (not around the hull: the union of hulls merges these sorted lists),
/// its area and its vertices extreme in the 8 directions of an octagon
/// (-x, -(x+y), -y, x-y, x, x+y, y, y-x; of equal ones, the first),
/// which also give its bounding box.
struct MemoHull {
  std::vector<std::pair<double, double>> vertices;
  double area = 0.0;
  std::array<std::pair<double, double>, 8> extremes{};
};

/// The memo of IdentifyMaterial. Not copyable or movable.
struct IdentificationMemo {
  /// RecognizeLuGreStrokes' strokes of one run (its steps 3-5).
  MemoTable<std::vector<RecognizedStroke>> lugre_runs;
  /// A stroke's hull of its slipping samples: CalcMaterialHullCoverage's, and
  /// CalcSpanCoverage's clamped into its reference (keyed apart).
  MemoTable<MemoHull> stroke_hulls;

  IdentificationMemo() = default;
  IdentificationMemo(const IdentificationMemo&) = delete;
  IdentificationMemo& operator=(const IdentificationMemo&) = delete;

  /// Sweeps every table (MemoTable::Sweep).
  void Sweep() {
    lugre_runs.Sweep();
    stroke_hulls.Sweep();
  }
  /// Drops every entry (MemoTable::Clear).
  void Clear() {
    lugre_runs.Clear();
    stroke_hulls.Clear();
  }
};

}  // namespace frictiond
