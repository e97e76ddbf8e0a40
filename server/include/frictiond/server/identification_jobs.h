#pragma once
/// @file
/// Identification jobs (paper 000, Fig. 11: a lookup of an unknown pair asks
/// a robot for a test stroke; its strokes are checked for span coverage,
/// III-E and Fig. 10, and fitted), independent of the transport so that they
/// are tested without a socket:
/// - IdentificationJobs records requests (the caps of LibraryOptions), makes
///   the typed stroke plan, and is the only class that changes a job's state
///   (JobState, storage/job_state.h; the store keeps the same texts).
/// - JobStrokeCollector is one endpoint's working state of the jobs it acts
///   on: claim leases (time passed in, as StrokeReassembler does), the
///   complete strokes received so far, and the decisions on them: reject,
///   ask a follow-up stroke for the missing region, fail after too many
///   strokes, or fit.
/// The transports convert the plan and the request to their own form in one
/// place each (identification_json.h for HTTP and the stored plan; the LCM
/// endpoint for identification_request_v1/v2).

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "frictiond/estimators/span_coverage.h"
#include "frictiond/estimators/stroke_data.h"
#include "frictiond/storage/job_state.h"
#include "frictiond/storage/store.h"

namespace frictiond {

class FrictionLibrary;
struct LibraryOptions;

/// The LuGre identifying pair that ends a requested stroke (paper 001,
/// Section III; docs/lcm.md "Stroke plan").
struct LuGrePairPlan {
  double fn_n = 0.0;              ///< normal force of the pair [N]
  double slow_accel_mm_s2 = 0.0;  ///< slow triangle |dv/dt|
  double slow_peak_mm_s = 0.0;    ///< slow triangle peak speed
  int fast_strokes = 0;           ///< fast triangles
  double fast_accel_mm_s2 = 0.0;  ///< fast triangles |dv/dt|
  double fast_peak_mm_s = 0.0;    ///< fast triangles peak speed
  double rest_s = 0.0;            ///< rest between triangles [s]
  std::string instructions;       ///< for a person or a robot program
};

/// The stroke a robot should perform for a pair.
struct StrokePlan {
  std::string material;
  std::string fingertip;
  double fn_min_n = 0.0;  ///< normal force span [N]
  double fn_max_n = 0.0;
  double v_min_mm_s = 0.0;  ///< peak sliding speed span [mm/s]
  double v_max_mm_s = 0.0;
  double max_duration_s = 120.0;  ///< longest stroke accepted [s]
  double min_span_pct = 50.0;     ///< coverage that suffices (Fig. 10)
  std::string instructions;       ///< how to perform and upload it (HTTP)
  /// The LuGre pair; nullopt when the plan asks for none (or was stored
  /// before the pair existed).
  std::optional<LuGrePairPlan> lugre;

  /// The (Fn, v) rectangle the strokes should cover.
  SpanRect span() const {
    return SpanRect{fn_min_n, fn_max_n, v_min_mm_s, v_max_mm_s};
  }
};

/// What RequestIdentification did.
struct IdentificationRequest {
  /// True: a job is open for the pair (newly recorded or found); false: a
  /// cap of LibraryOptions was reached and nothing was stored (`reason`).
  bool requested = false;
  std::int64_t job_id = 0;                ///< when requested
  JobState state = JobState::kRequested;  ///< when requested
  std::string created_at;                 ///< when requested
  StrokePlan plan;     ///< the open job's plan, or the plan to perform
  std::string reason;  ///< when not requested: which cap, in words
};

/// Who sent a job's strokes: names the actor of audit entries and uploads.
struct StrokeSender {
  std::string robot;   ///< as the robot named itself ("" unknown)
  std::string actor;   ///< audit actor and upload robot, e.g. "lcm:r1"
  std::string role;    ///< audit role ("robot" for a verified sender)
  std::string action;  ///< audit action, e.g. "LCM stroke_chunk_v2"
  bool is_signed = false;
};

/// Records identification requests and changes job states: the only writer
/// of IdentificationJob::state. Thread-safe (requests are serialised for
/// the caps; state changes go to the store one call each). Not copyable.
class IdentificationJobs {
 public:
  /// `store` and `options` must outlive this object.
  IdentificationJobs(Store& store, const LibraryOptions& options);
  IdentificationJobs(const IdentificationJobs&) = delete;
  IdentificationJobs& operator=(const IdentificationJobs&) = delete;

  /// The stroke to perform for a pair (LibraryOptions::plan).
  StrokePlan MakeStrokePlan(const std::string& material,
                            const std::string& fingertip) const;

  /// Records (or finds the open) job for a pair. Reads must not grow the
  /// store without bound: an open job of the pair is reused, and a new one
  /// stops at max_open_requests (all) and max_open_requests_per_requester;
  /// then nothing is stored and the result says why.
  /// @throws RequestError(StatusCode::kInvalidArgument) when `requested_by` is
  /// not valid text (text.h; at most 128 bytes).
  IdentificationRequest Request(const std::string& material,
                                const std::string& fingertip,
                                const std::string& requested_by);

  /// The job, or nullopt when there is none (ids <= 0 included).
  std::optional<IdentificationJob> Find(std::int64_t id);

  /// The job a chunk of (material, fingertip) names, checked: it must exist,
  /// be open and belong to the pair. On a failure returns nullopt and sets
  /// *field and *message ("job_id = 7 (the job is fitted; ...)").
  std::optional<IdentificationJob> FindOpenFor(std::int64_t job_id,
                                               const std::string& material,
                                               const std::string& fingertip,
                                               std::string* field,
                                               std::string* message);

  /// The state a job's stored text names; an unknown text reads as failed
  /// (closed), so that no transport acts on it.
  static JobState StateOf(const IdentificationJob& job);

  /// The job's stored plan. @throws std::invalid_argument when it is not a
  /// plan (fn_n and v_mm_s spans are required; other fields default).
  static StrokePlan PlanOf(const IdentificationJob& job);

  /// Moves `job` to `to` with `detail` (stored, and set in *job).
  /// Allowed: an open state to any state; a closed job never changes.
  /// @return false (nothing written) when the job is closed or gone.
  bool Transition(IdentificationJob* job,
                  JobState to,
                  const std::string& detail);

 private:
  Store& store_;
  const LibraryOptions& options_;
  std::mutex request_mu_;  // serialises the caps of Request
};

/// Options of a JobStrokeCollector.
struct JobStrokeCollectorOptions {
  /// Strokes per job before it fails for too little span coverage (>= 1).
  int max_strokes_per_job = 5;
  /// A claim is renewed when a chunk arrives this long after the last
  /// renewal [s] (the store lets another worker take a claim not renewed
  /// for Store::kClaimLeaseS).
  double claim_renew_s = 10.0;
  /// Names this worker in claims (Store::ClaimJob); must not be empty.
  std::string worker_id;
};

/// What to do with a chunk of a job (JobStrokeCollector::Admit).
enum class ChunkAdmission {
  kAccept,  ///< reassemble it
  kIgnore,  ///< silently: another worker holds the job, or a late duplicate
            ///< of a stroke already received
  kReject,  ///< answer the sender with the field and message
};

/// The decision on a received stroke or on the fit that follows it.
struct StrokeOutcome {
  enum class Kind {
    kRejected,        ///< stroke unusable (field, message); job unchanged
    kNotKept,         ///< the store could not keep it (message); send again
    kFollowUp,        ///< too little coverage: ask follow_up_stroke
    kEnoughCoverage,  ///< the strokes cover the span: call Fit()
    kFailed,          ///< the job failed (detail; field/message when the
                      ///< fit rejected the strokes)
    kFitted,          ///< the job made model `version`
  };
  Kind kind = Kind::kRejected;
  std::string field;         ///< kRejected, kNotKept, kFailed by the fit
  std::string message;       ///< error text for the sender
  std::string detail;        ///< progress text (the job's stored detail)
  double span_pct = -1;      ///< coverage of the plan's span (-1: not computed)
  int version = 0;           ///< kFitted
  int follow_up_stroke = 0;  ///< kFollowUp: the stroke number to ask for
  SpanRect missing;          ///< kFollowUp: the region still missing
  /// The state to show the sender (the job's state after the decision).
  JobState state = JobState::kStroking;
};

/// One worker's strokes of the jobs it acts on. Time is passed in (seconds
/// on any monotonic clock) so that tests control the claim leases. Not
/// thread-safe (one per endpoint thread); not copyable.
class JobStrokeCollector {
 public:
  /// `library` must outlive this object.
  /// @throws std::invalid_argument for bad options, naming the field.
  JobStrokeCollector(FrictionLibrary& library,
                     JobStrokeCollectorOptions options);
  JobStrokeCollector(const JobStrokeCollector&) = delete;
  JobStrokeCollector& operator=(const JobStrokeCollector&) = delete;

  /// Decides on a chunk of stroke `stroke` for the open job `job`: claims
  /// the job (a lease renewed at most every claim_renew_s; in a fleet one
  /// worker acts on a job, the job of a worker that died is taken over),
  /// ignores strokes already received, rejects stroke numbers beyond
  /// max_strokes_per_job (sets *field, *message).
  ChunkAdmission Admit(const IdentificationJob& job,
                       int stroke,
                       double now_s,
                       std::string* field,
                       std::string* message);

  /// A chunk of `stroke` was accepted: a requested job moves to stroking.
  void NoteReceiving(IdentificationJob* job,
                     int stroke,
                     const std::string& robot);

  /// A complete stroke: checks it against the plan (max_duration_s), keeps
  /// it in the store until the job closes, and decides on the span coverage
  /// of all the job's strokes (paper 000 III-E): kFollowUp (the job stays
  /// stroking), kFailed after max_strokes_per_job (audited, closed) or
  /// kEnoughCoverage (then call Fit); kRejected / kNotKept leave the job as
  /// it was.
  StrokeOutcome AddStroke(IdentificationJob* job,
                          int stroke,
                          StrokeData data,
                          const StrokeSender& sender);

  /// Fits the job's strokes (one upload, later strokes shifted to start 1 s
  /// after the previous one ended) through FrictionLibrary::IngestStrokes,
  /// after AddStroke said kEnoughCoverage: kFitted or kFailed, audited, the
  /// job closed. `coverage` is the outcome AddStroke returned.
  StrokeOutcome Fit(IdentificationJob* job,
                    const StrokeOutcome& coverage,
                    const StrokeSender& sender);

  /// Jobs with working state here (for tests).
  std::size_t open_jobs() const { return jobs_.size(); }

 private:
  struct Progress {
    std::vector<StrokeData> strokes;  // complete strokes not yet ingested
    std::vector<double> slip_fn_n, slip_v_mm_s;
    std::set<int> done_strokes;  // received (duplicates are ignored)
  };
  Progress& ProgressOf(const IdentificationJob& job);
  void AddToProgress(const IdentificationJob& job,
                     StrokeData stroke,
                     Progress* progress);
  void Close(std::int64_t job_id);

  FrictionLibrary& library_;
  JobStrokeCollectorOptions options_;
  std::map<std::int64_t, Progress> jobs_;
  // Jobs this worker claimed, with the time of the last claim renewal.
  std::map<std::int64_t, double> claimed_;
};

}  // namespace frictiond
