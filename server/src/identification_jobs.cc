// Identification jobs (identification_jobs.h): requests, the stroke plan,
// the job state machine, and one worker's stroke collection with the span
// coverage decisions of paper 000, III-E and Fig. 10.
#include "frictiond/server/identification_jobs.h"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <utility>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/identification_json.h"
#include "frictiond/server/library.h"
#include "frictiond/server/request_error.h"
#include "frictiond/server/text.h"

namespace frictiond {

using nlohmann::json;

// --- IdentificationJobs ------------------------------------------------------

IdentificationJobs::IdentificationJobs(Store& store,
                                       const LibraryOptions& options)
    : store_(store), options_(options) {}

StrokePlan IdentificationJobs::MakeStrokePlan(
    const std::string& material, const std::string& fingertip) const {
  const StrokePlanOptions& o = options_.plan;
  StrokePlan p;
  p.material = material;
  p.fingertip = fingertip;
  p.fn_min_n = o.fn_min_n;
  p.fn_max_n = o.fn_max_n;
  p.v_min_mm_s = o.v_min_mm_s;
  p.v_max_mm_s = o.v_max_mm_s;
  p.max_duration_s = o.max_duration_s;
  p.min_span_pct = o.min_span_pct;
  p.instructions =
      "slide the fingertip on the surface in repeated strokes with "
      "rests between them, sweeping normal "
      "force over fn_n and peak sliding speed over v_mm_s; then POST "
      "the samples as a stroke CSV (t_s, "
      "fn_n, ft_n, v_mm_s) to /v1/materials/" +
      material + "/strokes?fingertip=" + fingertip;
  if (o.lugre_pair) {
    LuGrePairPlan l;
    l.fn_n = o.lugre_fn_n > 0 ? o.lugre_fn_n : 0.5 * (o.fn_min_n + o.fn_max_n);
    l.slow_accel_mm_s2 = o.lugre_slow_accel_mm_s2;
    l.slow_peak_mm_s = o.lugre_slow_peak_mm_s;
    l.fast_strokes = o.lugre_fast_strokes;
    l.fast_accel_mm_s2 = o.lugre_fast_accel_mm_s2;
    l.fast_peak_mm_s = o.lugre_fast_peak_mm_s;
    l.rest_s = o.lugre_rest_s;
    l.instructions =
        "end the stroke with the LuGre identifying pair at normal force "
        "fn_n: a slow triangle 0 -> slow.peak_mm_s -> 0 at |dv/dt| = "
        "slow.accel_mm_s2, then fast.strokes triangles 0 -> fast.peak_mm_s "
        "-> 0 at fast.accel_mm_s2, with rest_s of rest between triangles "
        "(rest_s / 2 before the first and after the last)";
    p.lugre = std::move(l);
  }
  return p;
}

IdentificationRequest IdentificationJobs::Request(
    const std::string& material,
    const std::string& fingertip,
    const std::string& requested_by) {
  CheckText(requested_by, "robot", 128);
  IdentificationRequest out;
  out.plan = MakeStrokePlan(material, fingertip);
  {
    // Reads must not grow the store without bound: an open job for the
    // pair is reused, and new ones stop at the caps (the store's listing
    // of open jobs is bounded by the same caps).
    std::lock_guard<std::mutex> lock(request_mu_);
    const int total_cap = std::max(options_.max_open_requests, 0);
    bool pair_open = false;
    int open_total = 0, open_mine = 0;
    for (const IdentificationJob& j :
         store_.ListJobsPage(/*open_only=*/true, 0, total_cap + 1)) {
      ++open_total;
      if (j.requested_by == requested_by) ++open_mine;
      if (j.material == material && j.fingertip == fingertip) pair_open = true;
    }
    if (!pair_open && open_total >= total_cap) {
      out.reason = std::to_string(open_total) +
                   " identification requests are open (the daemon's cap); "
                   "none was recorded";
    } else if (!pair_open &&
               open_mine >= options_.max_open_requests_per_requester) {
      out.reason = "requester '" + ShownText(requested_by, 64) + "' has " +
                   std::to_string(open_mine) +
                   " open identification requests (the cap per "
                   "requester); none was recorded";
    }
    if (!out.reason.empty()) return out;
  }
  IdentificationJob job;
  job.material = material;
  job.fingertip = fingertip;
  job.state = JobStateName(JobState::kRequested);
  job.plan_json = StrokePlanToJson(out.plan).dump();
  job.requested_by = requested_by;
  job.detail = "waiting for a test stroke";
  const IdentificationJob j = store_.RequestIdentification(job);
  out.requested = true;
  out.job_id = j.id;
  out.state = StateOf(j);
  out.created_at = j.created_at;
  out.plan = PlanOf(j);  // the open job's plan (it may predate this one)
  return out;
}

std::optional<IdentificationJob> IdentificationJobs::Find(std::int64_t id) {
  if (id <= 0) return std::nullopt;
  return store_.GetJob(id);
}

std::optional<IdentificationJob> IdentificationJobs::FindOpenFor(
    std::int64_t job_id,
    const std::string& material,
    const std::string& fingertip,
    std::string* field,
    std::string* message) {
  std::optional<IdentificationJob> job = Find(job_id);
  auto fail = [&](const char* f, std::string m) {
    *field = f;
    *message = std::move(m);
    return std::nullopt;
  };
  if (!job)
    return fail("job_id",
                "job_id = " + std::to_string(job_id) +
                    " (no such identification job; query the "
                    "material first)");
  if (!IsOpenJobState(StateOf(*job)))
    return fail("job_id",
                "job_id = " + std::to_string(job_id) + " (the job is " +
                    job->state + "; query the material again)");
  if (material != job->material)
    return fail("material",
                "material = '" + material.substr(0, 64) + "' (job " +
                    std::to_string(job->id) + " is for '" + job->material +
                    "')");
  if (fingertip != job->fingertip)
    return fail("fingertip",
                "fingertip = '" + fingertip.substr(0, 64) + "' (job " +
                    std::to_string(job->id) + " is for '" + job->fingertip +
                    "')");
  return job;
}

JobState IdentificationJobs::StateOf(const IdentificationJob& job) {
  return ParseJobState(job.state).value_or(JobState::kFailed);
}

StrokePlan IdentificationJobs::PlanOf(const IdentificationJob& job) {
  const json plan = json::parse(job.plan_json, nullptr, false);
  if (plan.is_discarded())
    throw std::invalid_argument("plan: the stroke plan of job " +
                                std::to_string(job.id) + " is not JSON");
  return StrokePlanFromJson(plan);
}

bool IdentificationJobs::Transition(IdentificationJob* job,
                                    JobState to,
                                    const std::string& detail) {
  if (!IsOpenJobState(StateOf(*job))) return false;
  if (!store_.UpdateJob(job->id, JobStateName(to), detail)) return false;
  job->state = JobStateName(to);
  job->detail = detail;
  return true;
}

// --- JobStrokeCollector
// --------------------------------------------------------

JobStrokeCollector::JobStrokeCollector(FrictionLibrary& library,
                                       JobStrokeCollectorOptions options)
    : library_(library), options_(std::move(options)) {
  if (options_.max_strokes_per_job < 1)
    throw std::invalid_argument("max_strokes_per_job must be >= 1");
  if (!(options_.claim_renew_s >= 0))
    throw std::invalid_argument(
        "claim_renew_s = " + std::to_string(options_.claim_renew_s) +
        " (must be >= 0)");
  if (options_.worker_id.empty())
    throw std::invalid_argument("worker_id: empty (it names this worker)");
}

ChunkAdmission JobStrokeCollector::Admit(const IdentificationJob& job,
                                         int stroke,
                                         double now_s,
                                         std::string* field,
                                         std::string* message) {
  // In a fleet every daemon hears the chunks; the one that claims the job
  // (once, in the shared store) acts on it, the others stay silent.
  // The claim is a lease, renewed while chunks arrive, so that the job of
  // a daemon that died is taken over (Store::ClaimJob).
  auto claim = claimed_.find(job.id);
  if (claim == claimed_.end() ||
      now_s - claim->second > options_.claim_renew_s) {
    if (!library_.store().ClaimJob(job.id, options_.worker_id)) {
      if (claim != claimed_.end()) claimed_.erase(claim);
      return ChunkAdmission::kIgnore;
    }
    claimed_[job.id] = now_s;
  }
  Progress& progress = ProgressOf(job);
  if (progress.done_strokes.count(stroke)) return ChunkAdmission::kIgnore;
  if (stroke >= options_.max_strokes_per_job) {
    *field = "stroke";
    *message = "stroke = " + std::to_string(stroke) + " (at most " +
               std::to_string(options_.max_strokes_per_job) +
               " strokes per job)";
    return ChunkAdmission::kReject;
  }
  return ChunkAdmission::kAccept;
}

void JobStrokeCollector::NoteReceiving(IdentificationJob* job,
                                       int stroke,
                                       const std::string& robot) {
  if (IdentificationJobs::StateOf(*job) != JobState::kRequested) return;
  library_.jobs().Transition(job,
                             JobState::kStroking,
                             "receiving stroke " + std::to_string(stroke) +
                                 " from " +
                                 (robot.empty() ? "a robot" : robot));
}

// Adds a complete stroke to the job's progress, with its slipping (Fn, v)
// samples for the span coverage (paper 000 III-E), labelled as the fit
// will label them (the pair's labelling, else the defaults).
void JobStrokeCollector::AddToProgress(const IdentificationJob& job,
                                       StrokeData stroke,
                                       Progress* progress) {
  SlipLabelOptions labelling;
  if (auto prev = library_.FindModel(job.material, job.fingertip);
      prev && prev->set.stochastic)
    labelling = prev->set.stochastic->labelling;
  StrokeData labelled = stroke;
  EnsureLabels(&labelled, labelling);
  const std::vector<bool> mask = CalcFitMask(labelled, labelling);
  for (std::size_t i = 0; i < labelled.size(); ++i) {
    if (!mask[i]) continue;
    progress->slip_fn_n.push_back(labelled.fn_n[i]);
    progress->slip_v_mm_s.push_back(labelled.v_mm_s[i]);
  }
  progress->strokes.push_back(std::move(stroke));
}

// The job's progress; on first use in this process it starts from the
// strokes the store keeps for the job (after a restart, or for a job taken
// over from a daemon that died).
JobStrokeCollector::Progress& JobStrokeCollector::ProgressOf(
    const IdentificationJob& job) {
  if (auto it = jobs_.find(job.id); it != jobs_.end()) return it->second;
  const auto kept = library_.store().ListJobStrokes(job.id);
  Progress& progress = jobs_[job.id];
  for (const auto& [index, csv] : kept) {
    try {
      AddToProgress(job, ParseStrokeCsv(csv), &progress);
      progress.done_strokes.insert(index);
    } catch (const std::exception& e) {
      std::cerr << "frictiond: kept stroke " << index << " of job " << job.id
                << " unreadable, asked again: " << e.what() << "\n";
    }
  }
  return progress;
}

// Forgets a closed job's progress and its kept strokes.
void JobStrokeCollector::Close(std::int64_t job_id) {
  jobs_.erase(job_id);
  claimed_.erase(job_id);
  try {
    library_.store().DeleteJobStrokes(job_id);
  } catch (const std::exception& e) {
    std::cerr << "frictiond: kept strokes of job " << job_id
              << " not deleted: " << e.what() << "\n";
  }
}

namespace {

// Audit log entry for a write of a job's strokes: the sender's actor and
// role, the job's pair, and `detail` (status, version or why). A fitted
// job's entry is committed with its upload (IngestOptions::audit); a failed
// job's is appended by AuditStrokeWrite, where a store that is down loses
// the entry, not the answer to the robot.
AuditEntry StrokeWriteEntry(const IdentificationJob& job,
                            const StrokeSender& sender,
                            json detail) {
  AuditEntry e;
  e.actor = sender.actor.substr(0, 128);
  e.role = sender.role;
  e.action = sender.action;
  e.material = job.material;
  detail["job"] = job.id;
  detail["fingertip"] = job.fingertip;
  detail["signed"] = sender.is_signed;
  e.detail = detail.dump();
  return e;
}

void AuditStrokeWrite(Store& store,
                      const IdentificationJob& job,
                      const StrokeSender& sender,
                      json detail) {
  try {
    store.AppendAudit(StrokeWriteEntry(job, sender, std::move(detail)));
  } catch (const std::exception& ex) {
    std::cerr << "frictiond: audit of an LCM write lost: " << ex.what() << "\n";
  }
}

}  // namespace

StrokeOutcome JobStrokeCollector::AddStroke(IdentificationJob* job,
                                            int stroke,
                                            StrokeData data,
                                            const StrokeSender& sender) {
  StrokeOutcome out;
  out.state = IdentificationJobs::StateOf(*job);
  Progress& progress = ProgressOf(*job);
  const StrokePlan plan = IdentificationJobs::PlanOf(*job);
  const double duration_s =
      data.empty() ? 0.0 : data.t_s.back() - data.t_s.front();
  if (!(duration_s <= plan.max_duration_s)) {
    out.kind = StrokeOutcome::Kind::kRejected;
    out.message = "t_s: the stroke lasts " + std::to_string(duration_s) +
                  " s (the plan allows max_duration_s = " +
                  std::to_string(plan.max_duration_s) + " s)";
    out.field = "t_s";
    out.detail = "stroke rejected: " + out.message;
    return out;
  }
  // Kept in the store until the job closes: a restart (or a daemon taking
  // the job over) continues with it instead of asking for it again.
  try {
    library_.store().PutJobStroke(job->id, stroke, FormatStrokeCsv(data));
  } catch (const std::exception& e) {
    out.kind = StrokeOutcome::Kind::kNotKept;
    out.field = "store";
    out.message = std::string("the stroke could not be kept (store: ") +
                  e.what() + "); send it again";
    out.detail = out.message;
    return out;
  }
  progress.done_strokes.insert(stroke);
  AddToProgress(*job, std::move(data), &progress);
  const SpanCoverage cov =
      CalcSpanCoverage(progress.slip_fn_n, progress.slip_v_mm_s, plan.span());
  out.span_pct = cov.span_pct;
  char span_text[160];
  std::snprintf(span_text,
                sizeof span_text,
                "span %.1f %% of the plan (needs %.1f %%) from %d slipping "
                "samples in %zu stroke(s)",
                cov.span_pct,
                plan.min_span_pct,
                cov.samples,
                progress.strokes.size());
  if (!(cov.span_pct < plan.min_span_pct)) {
    out.kind = StrokeOutcome::Kind::kEnoughCoverage;
    out.detail = span_text;
    library_.jobs().Transition(job, JobState::kEnoughCoverage, out.detail);
    out.state = JobState::kEnoughCoverage;
    return out;
  }
  if (static_cast<int>(progress.strokes.size()) >=
      options_.max_strokes_per_job) {
    out.kind = StrokeOutcome::Kind::kFailed;
    out.detail = std::string("too little span coverage: ") + span_text +
                 " after the maximum of " +
                 std::to_string(options_.max_strokes_per_job) + " strokes";
    library_.jobs().Transition(job, JobState::kFailed, out.detail);
    out.state = JobState::kFailed;
    AuditStrokeWrite(
        library_.store(), *job, sender, {{"status", 422}, {"why", out.detail}});
    Close(job->id);  // before the robot hears of it
    return out;
  }
  // A follow-up stroke for the missing region instead of a weak model.
  out.kind = StrokeOutcome::Kind::kFollowUp;
  out.follow_up_stroke = stroke + 1;
  out.missing = cov.missing;
  char region[200];
  std::snprintf(region,
                sizeof region,
                "; follow-up stroke %d asked for fn_n %.2f-%.2f N, "
                "v_mm_s %.1f-%.1f mm/s",
                out.follow_up_stroke,
                cov.missing.fn_min_n,
                cov.missing.fn_max_n,
                cov.missing.v_min_mm_s,
                cov.missing.v_max_mm_s);
  out.detail = span_text + std::string(region);
  library_.jobs().Transition(job, JobState::kStroking, out.detail);
  out.state = JobState::kStroking;
  return out;
}

StrokeOutcome JobStrokeCollector::Fit(IdentificationJob* job,
                                      const StrokeOutcome& coverage,
                                      const StrokeSender& sender) {
  StrokeOutcome out;
  out.span_pct = coverage.span_pct;
  Progress& progress = ProgressOf(*job);
  // One upload of all the job's strokes: later strokes are shifted to
  // start 1 s after the previous one ended (a gap = an unrecorded rest).
  StrokeData all;
  for (const StrokeData& s : progress.strokes) {
    StrokeData shifted = s;
    if (!all.empty()) {
      const double shift = all.t_s.back() + 1.0 - s.t_s.front();
      for (double& t : shifted.t_s) t += shift;
    }
    all.Append(shifted);
  }
  IngestOptions io;
  io.fingertip = job->fingertip;
  io.robot = sender.actor.substr(0, 128);
  // The write's audit entry is committed with it (Store::CommitUpload).
  io.audit = StrokeWriteEntry(
      *job, sender, {{"status", 201}, {"strokes", progress.strokes.size()}});
  try {
    const IngestResult r =
        library_.IngestStrokes(job->material, FormatStrokeCsv(all), io);
    out.kind = StrokeOutcome::Kind::kFitted;
    out.version = r.version;
    out.detail = "fitted version " + std::to_string(r.version) + " (" +
                 r.fit_status + (r.fit_note.empty() ? "" : ": " + r.fit_note) +
                 "); " + coverage.detail;
    library_.jobs().Transition(job, JobState::kFitted, out.detail);
    out.state = JobState::kFitted;
    Close(job->id);  // before the robot hears of it
  } catch (const RequestError& e) {
    out.kind = StrokeOutcome::Kind::kFailed;
    out.field = e.field();
    out.message = e.what();
    out.detail = std::string("identification failed: ") + e.what();
    library_.jobs().Transition(job, JobState::kFailed, out.detail);
    out.state = JobState::kFailed;
    AuditStrokeWrite(library_.store(),
                     *job,
                     sender,
                     {{"status", HttpStatusFor(e.code())},
                      {"code", StatusCodeName(e.code())},
                      {"field", e.field()},
                      {"why", out.detail}});
    Close(job->id);
  }
  return out;
}

}  // namespace frictiond
