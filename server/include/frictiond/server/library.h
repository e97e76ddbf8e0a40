#pragma once
/// @file
/// The friction library service core: the logic behind every endpoint
/// (HTTP today, LCM beside it), independent of the transport. It validates
/// input, fits models, writes through the Store and serves reads from an
/// in-memory cache that writes invalidate.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/proto/joint_json.h"
#include "frictiond/proto/model_json.h"
#include "frictiond/server/fit_workers.h"
#include "frictiond/server/identification_jobs.h"
#include "frictiond/server/ingestor.h"
#include "frictiond/server/request_error.h"
#include "frictiond/storage/store.h"

namespace frictiond {

/// Span a test stroke should cover (paper 000, II-C: 0-5 N, slow ~15 to
/// fast ~80 mm/s).
struct StrokePlanOptions {
  double fn_min_n = 0.5;
  double fn_max_n = 4.5;
  double v_min_mm_s = 15.0;
  double v_max_mm_s = 80.0;
  double max_duration_s = 120.0;
  double min_span_pct =
      50.0;  ///< coverage of the reference span that suffices (Fig. 10)
  // The LuGre identifying pair (paper 001, Section III) that ends each
  // requested stroke (docs/lcm.md "Stroke plan"), at one normal force: a
  // slow triangle for the quasi-static step (<= 3 mm/s^2) and fast ones for
  // the dynamic step (>= 5 mm/s^2; the daemon combines up to 4).
  bool lugre_pair = true;   ///< false: the plan asks for no pair
  double lugre_fn_n = 0.0;  ///< [N]; 0: the middle of [fn_min_n, fn_max_n]
  double lugre_slow_accel_mm_s2 = 2.0;   ///< in (0, 3]
  double lugre_slow_peak_mm_s = 20.0;    ///< > 0
  int lugre_fast_strokes = 4;            ///< 1..12
  double lugre_fast_accel_mm_s2 = 20.0;  ///< >= 5
  double lugre_fast_peak_mm_s = 10.0;    ///< > 0
  double lugre_rest_s = 1.0;             ///< between two triangles [s], >= 0.6
};

/// A model version as served: the parsed model and its JSON text.
struct CachedModel {
  ModelSet set;
  std::string json_text;  ///< serialised ModelSetToJson(set)
};

/// What a PUT of a material sets; a field left unset keeps its stored value
/// (the name defaults to the id). The HTTP route reads it from the JSON
/// body {"name","description","tags"} (routes_core.cc); the library checks
/// the values.
struct MaterialUpdate {
  std::optional<std::string> name;               ///< text, <= 200 bytes
  std::optional<std::string> description;        ///< UTF-8, <= 4000 bytes
  std::optional<std::vector<std::string>> tags;  ///< <= 64 of <= 64 bytes
};

/// Result of IngestStrokes.
struct IngestResult {
  std::int64_t stroke_id = 0;
  int version = 0;
  bool material_created = false;
  std::size_t samples = 0;
  std::shared_ptr<const CachedModel> model;
  std::string fit_status;  ///< "ok" or "partial"
  std::string fit_note;    ///< e.g. which slopes were not identified
};

/// Options of one stroke upload (query parameters of the HTTP route).
struct IngestOptions {
  std::string fingertip = "default";
  std::string robot;
  /// Slip labelling; when unset, the pair's previous labelling (or the
  /// defaults) is used.
  std::optional<SlipLabelOptions> labelling;
  /// Who made the upload (actor, role, remote, action, material, detail):
  /// when set, the entry is stored in the upload's own transaction
  /// (Store::CommitUpload), with `fingertip`, `samples`, `fit_status`,
  /// `stroke_id`, `version` and `material_created` added to its detail.
  /// Nothing is logged for an upload that is refused.
  std::optional<AuditEntry> audit;
};

/// Service options.
struct LibraryOptions {
  StrokePlanOptions plan;
  std::size_t max_samples_per_upload = 5'000'000;
  /// Reads record identification requests (docs/security.md "Reads do not
  /// write"): at most one open job per (material, fingertip), at most
  /// `max_open_requests_per_requester` open jobs requested by one requester
  /// and `max_open_requests` open jobs in all. Beyond a cap the caller still
  /// gets the stroke plan, with "requested": false and the reason.
  int max_open_requests_per_requester = 64;
  int max_open_requests = 4096;
  /// Stroke cache and bounded refit of IngestStrokes (ingestor.h); its
  /// max_samples_per_upload is taken from the field above.
  IngestorOptions ingest;
  /// A stroke upload of more CSV bytes than this is "large": its parse,
  /// labels, features and refit copy peak at about 25 bytes of memory per
  /// CSV byte (an outside attack run: one 16 MB upload peaked at ~390 MB,
  /// four at once took the daemon to 1.6 GB). At most
  /// `max_large_uploads` are processed at once; one more is answered 503
  /// (field "body", retry) before it is parsed. Smaller uploads, a robot's
  /// ordinary strokes, never wait for them.
  std::size_t large_upload_bytes = 1u << 20;
  int max_large_uploads = 1;
};

/// Thread-safe service core. Not copyable or movable.
class FrictionLibrary {
 public:
  FrictionLibrary(std::unique_ptr<Store> store, LibraryOptions options = {});
  ~FrictionLibrary();
  FrictionLibrary(const FrictionLibrary&) = delete;
  FrictionLibrary& operator=(const FrictionLibrary&) = delete;

  Store& store() { return *store_; }
  const LibraryOptions& options() const { return options_; }
  /// The stroke cache of IngestStrokes (its counters, for tests and
  /// metrics).
  const Ingestor& ingestor() const { return *ingestor_; }

  // --- materials ----------------------------------------------------------
  std::vector<Material> ListMaterials();
  /// @throws RequestError(StatusCode::kNotFound) when unknown (no
  /// identification is requested).
  Material GetMaterial(const std::string& id);
  /// Creates or updates a material.
  /// @return true when created. @throws
  /// RequestError(StatusCode::kInvalidArgument) naming the field (too long,
  /// invalid text, too many tags); nothing is stored then.
  bool PutMaterial(const std::string& id, const MaterialUpdate& update);
  /// @return false when it did not exist.
  bool DeleteMaterial(const std::string& id);

  // --- fingertips -----------------------------------------------------------
  /// Creates or replaces a fingertip (id, name, description; each text of
  /// at most 4000 bytes, valid UTF-8 without control characters; the
  /// description may break lines: text.h). @return true when created.
  /// @throws RequestError(StatusCode::kInvalidArgument) naming the field.
  bool PutFingertip(const Fingertip& fingertip);

  // --- robots and reference images ------------------------------------------
  /// Creates or replaces a robot description (joint friction references
  /// name a material and a joint by id). @return true when created.
  /// @throws RequestError(StatusCode::kInvalidArgument) naming the field
  /// ("id", "joints[i].friction.material", ...); nothing is stored then.
  bool PutRobot(const std::string& id, const RobotDescription& robot);
  /// Checks that reference images may be added to material `id`.
  /// @throws RequestError(StatusCode::kInvalidArgument, "id") for an
  /// invalid id, RequestError(StatusCode::kNotFound, "id") for an unknown
  /// material (the message says to create it first).
  void RequireImageMaterial(const std::string& id);
  /// Stores a reference image's features for `image.material`, checked by
  /// RequireImageMaterial; `image.id` and `created_at` are set by the store.
  /// @return the image id. @throws what RequireImageMaterial throws.
  std::int64_t AddReferenceImage(const ImageRecord& image);

  // --- models ---------------------------------------------------------------
  /// Newest model of the pair, or nullptr when there is none.
  std::shared_ptr<const CachedModel> FindModel(const std::string& material,
                                               const std::string& fingertip);
  /// A given version, or nullptr.
  std::shared_ptr<const CachedModel> FindModelVersion(
      const std::string& material, const std::string& fingertip, int version);
  /// Newest model, or throws RequestError(StatusCode::kNotFound) whose extra()
  /// holds the identification request (job and stroke plan) it recorded.
  std::shared_ptr<const CachedModel> RequireModel(
      const std::string& material,
      const std::string& fingertip,
      const std::string& requested_by);
  /// Records (or finds the open) identification job for an unknown pair
  /// (IdentificationJobs::Request): requested with the job, or not
  /// requested with the reason when a cap of LibraryOptions is reached
  /// (nothing is stored then). identification_json.h gives its JSON.
  /// @throws RequestError(StatusCode::kInvalidArgument) when `requested_by` is
  /// not valid text (text.h; at most 128 bytes).
  IdentificationRequest RequestIdentification(const std::string& material,
                                              const std::string& fingertip,
                                              const std::string& requested_by);
  /// The stroke to perform for a pair.
  StrokePlan MakeStrokePlan(const std::string& material,
                            const std::string& fingertip) const;
  /// Identification jobs: the only writer of a job's state.
  IdentificationJobs& jobs() { return jobs_; }

  /// Validates a stroke CSV, refits the pair's model and stores stroke +
  /// model version in one transaction. Uploads of one (material, fingertip)
  /// pair run one at a time in arrival order (versions follow it); other
  /// pairs proceed in parallel. The refit gets the pair's stored uploads
  /// from the ingestor's cache, all of them up to
  /// LibraryOptions::ingest.fit_sample_cap older samples and a stratified
  /// choice above it (ingestor.h, docs/storage.md "Bounded refit"). The
  /// returned model is the committed version, built without re-reading it.
  /// @throws RequestError (400 bad CSV naming line and field, 413 too many
  /// samples, 422 no usable slip) and stores nothing then.
  IngestResult IngestStrokes(const std::string& material,
                             const std::string& csv,
                             const IngestOptions& options);

  /// Stores an already fitted model as a new version (e.g. from diagnosis).
  std::shared_ptr<const CachedModel> AddModelVersion(
      const std::string& material,
      const std::string& fingertip,
      const StochasticFrictionModel& model,
      const std::string& reason,
      const nlohmann::json& extra_families = nlohmann::json::object());

  /// Stores a new model version of a pair that replaces one family (e.g.
  /// "joint") and carries every other family of the newest version over
  /// unchanged. Creates the material (name = id) when it does not exist.
  std::shared_ptr<const CachedModel> AddFamilyVersion(
      const std::string& material,
      const std::string& fingertip,
      const std::string& family,
      const nlohmann::json& family_json,
      const std::string& reason);

  /// All stored strokes of a pair, parsed and appended (stroke ids distinct).
  /// Each upload is labelled (given labels kept, else `labelling`, else the
  /// newest model's labelling) and gets the derived features of CONTRACT.md.
  StrokeData LoadStrokes(
      const std::string& material,
      const std::string& fingertip,
      std::optional<SlipLabelOptions> labelling = std::nullopt);

  /// Loads the bundled datasets described by DIR/datasets.json into an empty
  /// library. Returns the number of materials loaded (0 when the library
  /// already had materials). @throws std::runtime_error on a broken bundle.
  int LoadBundledData(const std::string& dir);

  /// Fits an additional model family (e.g. "lugre") when strokes arrive.
  /// Gets the refit's strokes of the pair (labelled; the new upload last;
  /// above the ingestor's sample cap a stratified choice of the older
  /// uploads, see IngestStrokes), the new
  /// upload alone, and the pair's previous model set (nullptr for none).
  /// Returns the family's JSON, or null when the data cannot identify it
  /// (then the previous version of the family, if any, is kept); may set
  /// *note to say why. Must not throw for unusable data.
  using FamilyFitter = std::function<nlohmann::json(const StrokeData& all,
                                                    const StrokeData& upload,
                                                    const CachedModel* previous,
                                                    std::string* note)>;
  /// Registers a family fitter under its JSON key (before serving starts).
  void AddFamilyFitter(const std::string& family, FamilyFitter fitter);

  /// Drops the cached model of a pair (or of every pair) so the next read
  /// goes to the store: for writes made by another daemon on a shared
  /// database (fleet back ends call this when notified).
  void InvalidateCached(const std::string& material,
                        const std::string& fingertip);
  void InvalidateAllCached();

  /// Subscribes to the store's change notifications (PostgreSQL back end;
  /// a no-op on SQLite): another daemon's write drops the affected cached
  /// models and, when it made a new model version, calls the model listeners
  /// (e.g. the LCM model-update broadcast) once for that version.
  void WatchStoreChanges();

  /// Called after every new model version (from any thread).
  using ModelListener = std::function<void(const CachedModel&)>;
  void AddModelListener(ModelListener listener);

 private:
  /// What FitModelSet identified.
  struct ModelSetFit {
    FitStatus status = FitStatus::kFailed;
    std::string why;    ///< eq. (1)'s reason (status not ok)
    std::string field;  ///< the input eq. (1)'s failure traces to, if any
    std::string note;   ///< the family fitters' notes, "family: note; ..."
    ModelSet set;       ///< every family; version and created_at unset
  };
  /// THE fit step of an upload: identifies every model family of the pair
  /// from `strokes` (the ingestor's bounded data, the new upload last):
  /// eq. (1) with eps (keeping an extended previous model's terms when the
  /// data has their inputs) on this thread, the registered family fitters on
  /// a second one, and the previous version's other families carried over.
  /// Reads only its arguments and fitters_ (no store, no cache); `memo` is
  /// the pair's (Ingestor::PairLock::memo()): the older strokes' per-stroke
  /// steps are looked up there, with the same results. `conditional_start`
  /// (the pair's, Ingestor::PairLock::conditional_start()) starts eq. (2)'s
  /// Newton steps and is replaced by this refit's eq. (2) when it is valid.
  ModelSetFit FitModelSet(const std::string& material,
                          const std::string& fingertip,
                          const StrokeData& strokes,
                          const StrokeData& upload,
                          const CachedModel* previous,
                          const SlipLabelOptions& labelling,
                          const FitWorkers::InFlight& slot,
                          IdentificationMemo* memo,
                          ConditionalSlipLikelihood* conditional_start) const;
  /// Caches a version just committed (made from what was committed).
  std::shared_ptr<const CachedModel> Publish(const nlohmann::json& doc,
                                             const ModelRecord& record);
  std::shared_ptr<const CachedModel> Decode(const ModelRecord& record) const;
  void Invalidate(const std::string& material, const std::string& fingertip);
  void Notify(const std::shared_ptr<const CachedModel>& model);
  void OnStoreChange(const std::string& material, const std::string& fingertip);
  void ForgetAnnounced(const std::string& material);

  std::unique_ptr<Store> store_;
  LibraryOptions options_;
  IdentificationJobs jobs_{*store_, options_};
  std::shared_mutex cache_mu_;
  std::unordered_map<std::string, std::shared_ptr<const CachedModel>>
      cache_;  // key: material '\n' fingertip
  // Invalidated entries, served only while the store is unavailable.
  std::unordered_map<std::string, std::shared_ptr<const CachedModel>> stale_;
  // Per-pair locks (versions follow upload order within a pair) and the
  // pairs' parsed uploads.
  std::unique_ptr<Ingestor> ingestor_;
  // The second share of every refit (IdentifyMaterial's `post`).
  std::unique_ptr<FitWorkers> fit_workers_;
  std::vector<std::pair<std::string, FamilyFitter>> fitters_;
  std::mutex listeners_mu_;
  std::vector<ModelListener> listeners_;
  // Large uploads being processed (LibraryOptions::max_large_uploads).
  std::atomic<int> large_uploads_{0};
  // Bumped by every invalidation: a store read that raced with one is not
  // cached (it may predate the change).
  std::atomic<std::uint64_t> cache_gen_{0};
  std::unordered_map<std::string, int> notified_;  // newest announced version
  bool watching_ = false;
};

/// Parses slip-labelling overrides from query-style parameters
/// (slip_peak_mm_s, slip_floor_mm_s, median_window_s, max_fn_n, max_v_mm_s).
/// `get` returns the raw value or nullopt. Returns nullopt when none is given.
/// @throws RequestError(StatusCode::kInvalidArgument) naming the parameter.
std::optional<SlipLabelOptions> ParseLabelling(
    const std::function<std::optional<std::string>(const std::string&)>& get,
    const SlipLabelOptions& base);

}  // namespace frictiond
