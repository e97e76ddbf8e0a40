#pragma once
/// @file
/// The stroke ingestor of the service core: per (material, fingertip) pair
/// one lock and one cache of the pair's parsed, labelled uploads keyed by
/// stroke id, and the bounded data a refit is given. Transport-free (no
/// HTTP, LCM or JSON types); FrictionLibrary::IngestStrokes drives it:
///
/// @code
///   Ingestor::PairLock lock = ingestor.Lock(material, fingertip);
///   FitData data = ingestor.AssembleFitData(lock, labelling, upload);
///   ... fit on data.strokes, commit stroke + model ...
///   ingestor.Append(lock, commit.stroke_id, std::move(upload));
/// @endcode
///
/// Cost of an upload: the new samples (parse, label, append) plus a refit on
/// at most IngestorOptions::fit_sample_cap samples of older uploads. The
/// pair's history is read from the store once (one query) and kept; each
/// upload asks the store only for strokes it does not know (one query for
/// ids, normally empty).
///
/// Departure from a refit on everything (docs/storage.md "Bounded refit"):
/// eq. (1)'s eps quantiles, the slip sigmoid, eps's time model and the
/// family fitters (LuGre recognition, eq. (2)) need samples, not sufficient
/// statistics, so the refit gets every older upload while their samples stay
/// within `fit_sample_cap`, and above the cap a deterministic, stratified
/// choice of whole older uploads (SelectFitUploads): the uploads at
/// multiples of a power-of-two stride in upload order, so old and new data
/// stay represented, a stroke's time series stays intact, and consecutive
/// refits share their older uploads (the cache keeps only those a refit can
/// still choose). The new upload is always included whole, last.

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "frictiond/estimators/identification_memo.h"
#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/slip_likelihood.h"
#include "frictiond/estimators/stroke_data.h"
#include "frictiond/storage/store.h"

namespace frictiond {

/// Options of the Ingestor.
struct IngestorOptions {
  /// Samples of older uploads a refit is given at most (the new upload comes
  /// on top, whole). Below it a refit sees every stored sample of the pair.
  std::size_t fit_sample_cap = 4'000;
  /// Parsed samples kept over all pairs; beyond it the least recently used
  /// pairs' caches are dropped (reloaded from the store on their next
  /// upload). A pair keeps only the uploads its refits can still choose
  /// (FitChoice::stride), about `fit_sample_cap` samples once its history
  /// is above that, so this bounds how many pairs stay warm. About 80 bytes
  /// per sample without covariates (~40 MB at the default).
  std::size_t cache_sample_cap = 500'000;
  /// Largest upload a stored stroke may be (parser limit).
  std::size_t max_samples_per_upload = 5'000'000;
};

/// The data of one refit.
struct FitData {
  /// Chosen older uploads (oldest first), then the new upload last; stroke
  /// ids made distinct by StrokeData::Append.
  StrokeData strokes;
  int uploads_stored = 0;          ///< older uploads the pair holds
  int uploads_used = 0;            ///< of which the refit got
  std::size_t samples_stored = 0;  ///< samples of the older uploads
  std::size_t samples_used = 0;    ///< of which the refit got
};

/// The older uploads a refit gets (SelectFitUploads).
struct FitChoice {
  /// Indices into the pair's uploads in upload order, ascending.
  std::vector<std::size_t> indices;
  /// Every chosen index is a multiple of it, and so is every index a later
  /// choice over the same uploads plus newer ones makes: an upload whose
  /// index is not a multiple is never chosen again (its parsed data need
  /// not be kept), unless a later choice falls back. 1 when every upload is
  /// chosen; 0 for the fallback (no promise).
  std::size_t stride = 1;
};

/// The uploads, of the given sample counts in upload order, that a refit
/// gets: nested strata, the uploads at multiples of the smallest
/// power-of-two stride whose uploads sum to at most `cap` (an upload of
/// more than `cap` samples is left out); stride 1 when every upload fits,
/// else between about half the cap and the cap is used. The stride never
/// shrinks as uploads are appended, so consecutive refits share their older
/// uploads and an upload dropped from the choice is never chosen again.
/// When every upload of that stride is above the cap, the newest upload
/// that fits, else the newest (so the refit may exceed the cap by one older
/// upload, itself bounded by the upload limit). Deterministic.
FitChoice SelectFitUploads(const std::vector<std::size_t>& samples,
                           std::size_t cap);

/// Labels a parsed upload and adds CONTRACT.md's derived features; labels,
/// strokes and derived features are per upload (time gaps, dwell and
/// distance restart with each upload). Given labels are kept.
void PrepareUpload(StrokeData* data, const SlipLabelOptions& labelling);

/// Thread-safe. Not copyable or movable.
class Ingestor {
 private:
  struct Pair;

 public:
  /// Holds one pair's lock: uploads of a pair run one at a time, in the
  /// order they take it; other pairs proceed in parallel. Movable only.
  class PairLock {
   public:
    PairLock(PairLock&&) noexcept = default;
    PairLock& operator=(PairLock&&) noexcept = default;
    const std::string& material() const { return material_; }
    const std::string& fingertip() const { return fingertip_; }
    /// The pair's identification memo (identification_memo.h): its
    /// refits' per-stroke results, kept while the pair's uploads are
    /// cached (cleared when they are shed).
    IdentificationMemo& memo() const;
    /// The pair's last refit's eq. (2) fit (not valid before the first):
    /// the next refit's Newton steps start from it
    /// (MaterialIdentificationOptions::conditional_start). Only a start:
    /// the answer does not depend on it.
    ConditionalSlipLikelihood& conditional_start() const;

   private:
    friend class Ingestor;
    PairLock(std::shared_ptr<Pair> pair,
             std::string material,
             std::string fingertip);
    std::shared_ptr<Pair> pair_;
    std::unique_lock<std::mutex> lock_;
    std::string material_;
    std::string fingertip_;
  };

  /// `store` must outlive the ingestor.
  Ingestor(Store& store, IngestorOptions options);
  ~Ingestor();
  Ingestor(const Ingestor&) = delete;
  Ingestor& operator=(const Ingestor&) = delete;

  const IngestorOptions& options() const { return options_; }

  /// Takes the pair's lock (blocks while another upload of the pair runs).
  PairLock Lock(const std::string& material, const std::string& fingertip);

  /// The older uploads of the pair (all, or SelectFitUploads' choice above
  /// the cap) labelled with `labelling`, then `upload` (already prepared
  /// with the same labelling) last. Loads the pair from the store when its
  /// cache is empty, was invalidated or used another labelling, else asks
  /// the store only for strokes it does not know.
  /// @throws what the store throws (e.g. StoreUnavailable); a stored stroke
  /// that no longer parses is skipped, as LoadStrokes always did.
  FitData AssembleFitData(PairLock& lock,
                          const SlipLabelOptions& labelling,
                          const StrokeData& upload);

  /// Adds an upload just committed under `stroke_id` (prepared with the
  /// labelling of the preceding AssembleFitData) to the pair's cache.
  void Append(PairLock& lock, std::int64_t stroke_id, StrokeData upload);

  /// Drops cached uploads: of one pair; of every pair of `material` when
  /// `fingertip` is empty; of every pair when both are empty. Does not wait
  /// for an upload in progress: that pair is marked and reloads from the
  /// store on its next upload.
  void Invalidate(const std::string& material, const std::string& fingertip);

  /// Parsed samples cached over all pairs (for tests and metrics).
  std::size_t cached_samples() const { return cached_samples_.load(); }

  /// Uploads read back from the store one at a time so far: strokes another
  /// writer stored, and chosen uploads whose parsed data the cache no
  /// longer held (a pair's one-query load is not counted). For tests and
  /// metrics.
  std::size_t store_reads() const { return store_reads_.load(); }

 private:
  void Load(Pair& pair,
            const std::string& material,
            const std::string& fingertip,
            const SlipLabelOptions& labelling);
  void CatchUp(Pair& pair,
               const std::string& material,
               const std::string& fingertip);
  // Parses and prepares a stored upload into the pair's cache and index;
  // false when it no longer parses.
  bool Cache(Pair& pair, std::int64_t id, const std::string& csv);
  // Adds a prepared upload to the pair's cache and index (once per id).
  void Insert(Pair& pair, std::int64_t id, StrokeData upload);
  // Frees the pair's parsed uploads, keeping its index (sizes).
  void Shed(Pair& pair);
  // Forgets the pair entirely (the next upload reloads it).
  void Drop(Pair& pair);
  void EvictBeyondCap(const Pair* keep);

  Store& store_;
  IngestorOptions options_;
  std::mutex pairs_mu_;  // guards pairs_ and the use clock
  std::unordered_map<std::string, std::shared_ptr<Pair>> pairs_;
  std::uint64_t clock_ = 0;
  std::atomic<std::size_t> cached_samples_{0};
  std::atomic<std::size_t> store_reads_{0};
};

}  // namespace frictiond
