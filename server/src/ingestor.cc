#include "frictiond/server/ingestor.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "frictiond/estimators/stroke_csv.h"

namespace frictiond {

namespace {

bool SameLabelling(const SlipLabelOptions& a, const SlipLabelOptions& b) {
  return a.peak_mm_s == b.peak_mm_s && a.floor_mm_s == b.floor_mm_s &&
         a.median_window_s == b.median_window_s && a.max_fn_n == b.max_fn_n &&
         a.max_v_mm_s == b.max_v_mm_s && a.gap_factor == b.gap_factor;
}

std::string Key(const std::string& material, const std::string& fingertip) {
  return material + '\n' + fingertip;
}

}  // namespace

void PrepareUpload(StrokeData* data, const SlipLabelOptions& labelling) {
  EnsureLabels(data, labelling);
  AddDerivedFeatures(data, labelling);
}

FitChoice SelectFitUploads(const std::vector<std::size_t>& samples,
                           std::size_t cap) {
  const std::size_t n = samples.size();
  FitChoice out;
  // Nested strata: the smallest power-of-two stride whose uploads (the
  // multiples of it, each of at most `cap` samples) fit; stride 1 takes
  // every such upload. For a fixed stride the sum only grows as uploads are
  // appended, so the stride never shrinks and an upload off the stride is
  // never chosen again (docs/ingest.md).
  for (std::size_t stride = 1;; stride *= 2) {
    std::size_t sum = 0;
    for (std::size_t i = 0; i < n; i += stride)
      if (samples[i] <= cap) sum += samples[i];
    if (sum > cap) continue;  // ends: at stride >= n only upload 0 is left
    for (std::size_t i = 0; i < n; i += stride)
      if (samples[i] <= cap) out.indices.push_back(i);
    out.stride = stride;
    if (!out.indices.empty() || n == 0) return out;
    break;  // every upload of the stride is above the cap
  }
  // No stratum fits: the newest upload that fits, else the newest (whole,
  // even above the cap: a refit is never left with the new upload alone).
  std::size_t best = n - 1;
  for (std::size_t i = n; i-- > 0;) {
    if (samples[i] <= cap) {
      best = i;
      break;
    }
  }
  out.indices = {best};
  out.stride = 0;
  return out;
}

struct Ingestor::Pair {
  std::mutex mu;                   // the pair lock
  std::atomic<bool> stale{false};  // set by Invalidate, cleared on use
  std::uint64_t last_use = 0;      // guarded by pairs_mu_
  // Guarded by mu:
  bool loaded = false;
  SlipLabelOptions labelling;
  // Every readable stored upload of the pair: its stroke id and sample
  // count, ascending by id in two parallel vectors (what SelectFitUploads
  // reads, without walking a tree of the whole history per upload). Kept
  // when the cache sheds the parsed data, so that a refit loads only the
  // uploads SelectFitUploads chooses (not the whole pair).
  std::vector<std::int64_t> ids;
  std::vector<std::size_t> sizes;
  std::size_t samples_stored = 0;              // sum of sizes
  std::map<std::int64_t, StrokeData> uploads;  // prepared, by stroke id
  std::size_t samples = 0;                     // of `uploads` (cached)
  std::int64_t known_through = 0;  // every stroke id of the pair <= it is known
  // The last refit's FitChoice::stride: an upload at an index that is not a
  // multiple of it (> 1) is never chosen again, so its parsed data goes.
  std::size_t stride = 1;
  // Per-stroke results of the pair's refits (thread-safe on its own).
  IdentificationMemo memo;
  // The last refit's eq. (2) fit: the next one's starting point.
  ConditionalSlipLikelihood conditional_start;
};

Ingestor::PairLock::PairLock(std::shared_ptr<Pair> pair,
                             std::string material,
                             std::string fingertip)
    : pair_(std::move(pair)),
      lock_(pair_->mu),
      material_(std::move(material)),
      fingertip_(std::move(fingertip)) {}

Ingestor::Ingestor(Store& store, IngestorOptions options)
    : store_(store), options_(options) {}

Ingestor::~Ingestor() = default;

Ingestor::PairLock Ingestor::Lock(const std::string& material,
                                  const std::string& fingertip) {
  std::shared_ptr<Pair> pair;
  {
    std::lock_guard<std::mutex> lock(pairs_mu_);
    auto& slot = pairs_[Key(material, fingertip)];
    if (!slot) slot = std::make_shared<Pair>();
    slot->last_use = ++clock_;
    pair = slot;
  }
  return PairLock(std::move(pair), material, fingertip);
}

void Ingestor::Shed(Pair& pair) {
  cached_samples_ -= pair.samples;
  pair.uploads.clear();
  pair.samples = 0;
  pair.memo.Clear();
}

IdentificationMemo& Ingestor::PairLock::memo() const { return pair_->memo; }

ConditionalSlipLikelihood& Ingestor::PairLock::conditional_start() const {
  return pair_->conditional_start;
}

void Ingestor::Drop(Pair& pair) {
  Shed(pair);
  pair.stride = 1;
  pair.ids.clear();
  pair.sizes.clear();
  pair.samples_stored = 0;
  pair.known_through = 0;
  pair.loaded = false;
  pair.conditional_start = ConditionalSlipLikelihood{};
}

bool Ingestor::Cache(Pair& pair, std::int64_t id, const std::string& csv) {
  const StrokeCsvOptions csv_options{options_.max_samples_per_upload, 64};
  StrokeData d;
  try {
    d = ParseStrokeCsv(csv, csv_options);
  } catch (const StrokeCsvError&) {
    return false;  // validated when stored; unreadable now: skip it
  }
  PrepareUpload(&d, pair.labelling);
  Insert(pair, id, std::move(d));
  return true;
}

void Ingestor::Insert(Pair& pair, std::int64_t id, StrokeData upload) {
  const std::size_t n = upload.size();
  // Ids arrive ascending (load, catch-up and commits in id order), so the
  // insertion is normally an append.
  const auto at = std::lower_bound(pair.ids.begin(), pair.ids.end(), id);
  if (at == pair.ids.end() || *at != id) {
    pair.sizes.insert(pair.sizes.begin() + (at - pair.ids.begin()), n);
    pair.ids.insert(at, id);
    pair.samples_stored += n;
  }
  if (pair.uploads.emplace(id, std::move(upload)).second) {
    pair.samples += n;
    cached_samples_ += n;
  }
}

void Ingestor::Load(Pair& pair,
                    const std::string& material,
                    const std::string& fingertip,
                    const SlipLabelOptions& labelling) {
  Drop(pair);
  pair.labelling = labelling;
  for (StrokeRecord& r :
       store_.ListStrokesAfter(material, fingertip, 0, /*with_csv=*/true)) {
    pair.known_through = std::max(pair.known_through, r.id);
    Cache(pair, r.id, r.csv);
  }
  pair.loaded = true;
}

void Ingestor::CatchUp(Pair& pair,
                       const std::string& material,
                       const std::string& fingertip) {
  // Strokes another writer (a fleet daemon) stored: ids only, then the
  // unknown ones. Normally it lists only the previous upload of this daemon.
  for (const StrokeRecord& r : store_.ListStrokesAfter(
           material, fingertip, pair.known_through, /*with_csv=*/false)) {
    pair.known_through = std::max(pair.known_through, r.id);
    if (std::binary_search(pair.ids.begin(), pair.ids.end(), r.id)) continue;
    auto full = store_.GetStroke(r.id);
    ++store_reads_;
    if (!full) continue;
    Cache(pair, r.id, full->csv);
  }
}

FitData Ingestor::AssembleFitData(PairLock& lock,
                                  const SlipLabelOptions& labelling,
                                  const StrokeData& upload) {
  Pair& pair = *lock.pair_;
  if (pair.stale.exchange(false) || !pair.loaded ||
      !SameLabelling(pair.labelling, labelling)) {
    Load(pair, lock.material(), lock.fingertip(), labelling);
  } else {
    CatchUp(pair, lock.material(), lock.fingertip());
  }
  FitData out;
  out.uploads_stored = static_cast<int>(pair.ids.size());
  out.samples_stored = pair.samples_stored;
  const FitChoice choice =
      SelectFitUploads(pair.sizes, options_.fit_sample_cap);
  // The chosen uploads by id: an upload that is gone leaves the index below
  // (positions shift; ids do not).
  std::vector<std::int64_t> chosen;
  chosen.reserve(choice.indices.size());
  for (std::size_t i : choice.indices) chosen.push_back(pair.ids[i]);
  // A pair the cache shed keeps its index: read back only the chosen
  // uploads it no longer holds (a bounded refit reads a bounded number).
  for (std::int64_t id : chosen) {
    if (pair.uploads.count(id)) continue;
    auto full = store_.GetStroke(id);
    ++store_reads_;
    if (!full || !Cache(pair, id, full->csv)) {
      // Gone or unreadable now: it leaves the index.
      const auto at = std::lower_bound(pair.ids.begin(), pair.ids.end(), id);
      const auto k = at - pair.ids.begin();
      pair.samples_stored -= pair.sizes[static_cast<std::size_t>(k)];
      pair.sizes.erase(pair.sizes.begin() + k);
      pair.ids.erase(at);
    }
  }
  // The chosen uploads still held, found once each.
  std::vector<const StrokeData*> parts;
  parts.reserve(chosen.size());
  for (std::int64_t id : chosen) {
    auto it = pair.uploads.find(id);
    if (it == pair.uploads.end()) continue;
    parts.push_back(&it->second);
    out.samples_used += it->second.size();
  }
  out.uploads_used = static_cast<int>(parts.size());
  out.strokes.Reserve(upload.size() + out.samples_used);
  for (const StrokeData* part : parts) out.strokes.Append(*part);
  if (out.strokes.empty()) {
    out.strokes = upload;  // first upload of the pair: no merge needed
  } else {
    out.strokes.Append(upload);
  }
  // Uploads off the stride are never chosen again (FitChoice): drop their
  // parsed data, so a pair keeps about `fit_sample_cap` samples.
  pair.stride = choice.stride;
  if (pair.stride > 1) {
    for (auto it = pair.uploads.begin(); it != pair.uploads.end();) {
      const auto at =
          std::lower_bound(pair.ids.begin(), pair.ids.end(), it->first);
      const auto index = static_cast<std::size_t>(at - pair.ids.begin());
      if (index % pair.stride == 0) {
        ++it;
        continue;
      }
      pair.samples -= it->second.size();
      cached_samples_ -= it->second.size();
      it = pair.uploads.erase(it);
    }
  }
  EvictBeyondCap(&pair);
  return out;
}

void Ingestor::Append(PairLock& lock,
                      std::int64_t stroke_id,
                      StrokeData upload) {
  Pair& pair = *lock.pair_;
  if (!pair.loaded) return;  // nothing cached: the next upload loads it all
  Insert(pair, stroke_id, std::move(upload));
  EvictBeyondCap(&pair);
}

void Ingestor::Invalidate(const std::string& material,
                          const std::string& fingertip) {
  const std::string prefix = material + '\n';
  std::lock_guard<std::mutex> lock(pairs_mu_);
  for (auto& [key, pair] : pairs_) {
    const bool match =
        material.empty() ||
        (fingertip.empty() ? key.compare(0, prefix.size(), prefix) == 0
                           : key == Key(material, fingertip));
    if (!match) continue;
    pair->stale = true;
    // Free the memory now unless an upload of the pair runs (it reloads).
    std::unique_lock<std::mutex> pair_lock(pair->mu, std::try_to_lock);
    if (pair_lock.owns_lock()) Drop(*pair);
  }
}

void Ingestor::EvictBeyondCap(const Pair* keep) {
  if (cached_samples_.load() <= options_.cache_sample_cap) return;
  // Least recently used first; a pair whose upload is running is skipped.
  std::vector<std::pair<std::uint64_t, std::shared_ptr<Pair>>> order;
  {
    std::lock_guard<std::mutex> lock(pairs_mu_);
    for (auto& [key, pair] : pairs_)
      if (pair.get() != keep) order.emplace_back(pair->last_use, pair);
  }
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
    return a.first < b.first;
  });
  for (auto& [use, pair] : order) {
    if (cached_samples_.load() <= options_.cache_sample_cap) break;
    std::unique_lock<std::mutex> lock(pair->mu, std::try_to_lock);
    if (lock.owns_lock()) Shed(*pair);
  }
}

}  // namespace frictiond
