#include "frictiond/server/identification_jobs.h"

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "frictiond/server/identification_json.h"
#include "frictiond/server/library.h"
#include "frictiond/storage/job_state.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;

// Strokes whose (Fn, v) stay in a corner of the default plan's span
// (fn 0.5-4.5 N, v 15-80 mm/s): too little coverage for one job.
StrokeData CornerStroke(std::uint64_t seed) {
  testing::SimulationSpec spec;
  spec.strokes = 6;
  spec.fn_min_n = 0.6;
  spec.fn_max_n = 1.0;
  spec.v_min_mm_s = 16.0;
  spec.v_max_mm_s = 22.0;
  return testing::SimulateStrokes(spec, seed);
}

// Strokes over the whole span: enough coverage at once.
StrokeData WideStroke(std::uint64_t seed) {
  testing::SimulationSpec spec;
  spec.strokes = 40;
  return testing::SimulateStrokes(spec, seed);
}

StrokeSender Robot(const std::string& name) {
  StrokeSender s;
  s.robot = name;
  s.actor = "lcm:" + name;
  s.role = "robot";
  s.action = "LCM stroke_chunk_v2";
  s.is_signed = true;
  return s;
}

JobStrokeCollectorOptions Worker(const std::string& id, int max_strokes = 3) {
  JobStrokeCollectorOptions o;
  o.worker_id = id;
  o.max_strokes_per_job = max_strokes;
  return o;
}

LibraryOptions SmallCaps() {
  LibraryOptions o;
  o.max_open_requests = 3;
  o.max_open_requests_per_requester = 2;
  return o;
}

class IdentificationJobsTest : public ::testing::Test {
 protected:
  IdentificationJobsTest() : lib_(OpenStore(":memory:"), SmallCaps()) {}
  IdentificationJob Open(const std::string& material,
                         const std::string& by = "robot-1") {
    const IdentificationRequest r =
        lib_.RequestIdentification(material, "default", by);
    EXPECT_TRUE(r.requested) << r.reason;
    return *lib_.jobs().Find(r.job_id);
  }
  FrictionLibrary lib_;
};

TEST(JobStateTest, NamesAreTheStoredTextsAndParseBack) {
  const std::pair<JobState, const char*> names[] = {
      {JobState::kRequested, "requested"},
      {JobState::kStroking, "stroking"},
      {JobState::kEnoughCoverage, "enough_coverage"},
      {JobState::kFitted, "fitted"},
      {JobState::kFailed, "failed"}};
  for (const auto& [state, text] : names) {
    EXPECT_STREQ(JobStateName(state), text);
    EXPECT_EQ(ParseJobState(text), state) << text;
  }
  EXPECT_FALSE(ParseJobState("Fitted"));
  EXPECT_FALSE(ParseJobState(""));
  EXPECT_TRUE(IsOpenJobState(JobState::kEnoughCoverage));
  EXPECT_FALSE(IsOpenJobState(JobState::kFitted));
  EXPECT_FALSE(IsOpenJobState("no such state"));
  EXPECT_EQ(OpenJobStatesSql(), "('requested','stroking','enough_coverage')");
}

// The typed plan carries LibraryOptions::plan; its JSON is the stored text
// and reads back to the same plan.
TEST_F(IdentificationJobsTest, PlanIsTypedAndRoundTripsThroughTheStore) {
  const StrokePlan p = lib_.MakeStrokePlan("felt", "tip2");
  EXPECT_EQ(p.material, "felt");
  EXPECT_EQ(p.fingertip, "tip2");
  EXPECT_EQ(p.fn_min_n, 0.5);
  EXPECT_EQ(p.fn_max_n, 4.5);
  EXPECT_EQ(p.v_min_mm_s, 15.0);
  EXPECT_EQ(p.v_max_mm_s, 80.0);
  EXPECT_EQ(p.min_span_pct, 50.0);
  ASSERT_TRUE(p.lugre);
  EXPECT_EQ(p.lugre->fn_n, 2.5);  // the middle of the span
  EXPECT_EQ(p.lugre->fast_strokes, 4);
  EXPECT_NE(p.instructions.find("/v1/materials/felt/strokes?fingertip=tip2"),
            std::string::npos);
  const json j = StrokePlanToJson(p);
  EXPECT_EQ(j["fn_n"], json({0.5, 4.5}));
  EXPECT_EQ(j["lugre"]["fast"]["strokes"], 4);
  EXPECT_EQ(StrokePlanToJson(StrokePlanFromJson(j)), j);

  const IdentificationJob job = Open("felt");
  EXPECT_EQ(json::parse(job.plan_json),
            StrokePlanToJson(IdentificationJobs::PlanOf(job)));
  EXPECT_EQ(json::parse(job.plan_json),
            StrokePlanToJson(lib_.MakeStrokePlan("felt", "default")));
  // A plan stored before the LuGre pair existed asks for none.
  json old = j;
  old.erase("lugre");
  old.erase("max_duration_s");
  const StrokePlan o = StrokePlanFromJson(old);
  EXPECT_FALSE(o.lugre);
  EXPECT_EQ(o.max_duration_s, 120.0);
  try {
    StrokePlanFromJson(json{{"fn_n", {1}}});
    FAIL() << "a plan without [min, max] spans was read";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("fn_n:", 0), 0u) << e.what();
  }
}

TEST_F(IdentificationJobsTest, RequestRecordsOneOpenJobPerPair) {
  const IdentificationRequest a =
      lib_.RequestIdentification("felt", "default", "robot-1");
  ASSERT_TRUE(a.requested) << a.reason;
  EXPECT_GT(a.job_id, 0);
  EXPECT_EQ(a.state, JobState::kRequested);
  EXPECT_FALSE(a.created_at.empty());
  const IdentificationRequest b =
      lib_.RequestIdentification("felt", "default", "robot-2");
  EXPECT_EQ(b.job_id, a.job_id);
  const json j = IdentificationRequestToJson(a);
  EXPECT_EQ(j["requested"], true);
  EXPECT_EQ(j["state"], "requested");
  EXPECT_EQ(j["job_id"], a.job_id);
  EXPECT_EQ(j["stroke"]["material"], "felt");
  const IdentificationJob stored = *lib_.jobs().Find(a.job_id);
  EXPECT_EQ(stored.state, "requested");
  EXPECT_EQ(stored.requested_by, "robot-1");
  EXPECT_FALSE(lib_.jobs().Find(0));
  EXPECT_FALSE(lib_.jobs().Find(a.job_id + 100));
  EXPECT_THROW(lib_.RequestIdentification("felt", "default", "bad\nname"),
               RequestError);
}

// Reads do not grow the store without bound: past a cap nothing is
// recorded and the result says which cap.
TEST_F(IdentificationJobsTest, CapsOfLibraryOptionsStopNewJobs) {
  Open("a", "robot-1");
  Open("b", "robot-1");
  const IdentificationRequest mine =
      lib_.RequestIdentification("c", "default", "robot-1");
  EXPECT_FALSE(mine.requested);
  EXPECT_NE(mine.reason.find("cap per requester"), std::string::npos)
      << mine.reason;
  EXPECT_EQ(mine.plan.material, "c");  // the plan is still given
  // The open job of a pair is found even at the cap.
  EXPECT_TRUE(lib_.RequestIdentification("a", "default", "robot-1").requested);
  Open("c", "robot-2");
  const IdentificationRequest all =
      lib_.RequestIdentification("d", "default", "robot-3");
  EXPECT_FALSE(all.requested);
  EXPECT_NE(all.reason.find("the daemon's cap"), std::string::npos)
      << all.reason;
  EXPECT_EQ(IdentificationRequestToJson(all)["requested"], false);
  EXPECT_EQ(lib_.store().ListJobs(false).size(), 3u);
  // A closed job frees its place.
  IdentificationJob a = *lib_.jobs().Find(1);
  ASSERT_TRUE(lib_.jobs().Transition(&a, JobState::kFailed, "test"));
  EXPECT_TRUE(lib_.RequestIdentification("d", "default", "robot-3").requested);
}

TEST_F(IdentificationJobsTest, ClosedJobsNeverChangeState) {
  IdentificationJob job = Open("felt");
  ASSERT_TRUE(lib_.jobs().Transition(&job, JobState::kStroking, "s"));
  EXPECT_EQ(job.state, "stroking");
  EXPECT_EQ(lib_.jobs().Find(job.id)->detail, "s");
  ASSERT_TRUE(lib_.jobs().Transition(&job, JobState::kFitted, "v1"));
  EXPECT_FALSE(lib_.jobs().Transition(&job, JobState::kStroking, "again"));
  EXPECT_EQ(lib_.jobs().Find(job.id)->state, "fitted");
  EXPECT_EQ(lib_.jobs().Find(job.id)->detail, "v1");
  IdentificationJob odd = job;
  odd.state = "no such state";
  EXPECT_EQ(IdentificationJobs::StateOf(odd), JobState::kFailed);
}

TEST_F(IdentificationJobsTest, ChunksMustNameAnOpenJobOfTheirPair) {
  IdentificationJob job = Open("felt");
  std::string field, message;
  EXPECT_TRUE(
      lib_.jobs().FindOpenFor(job.id, "felt", "default", &field, &message));
  EXPECT_FALSE(
      lib_.jobs().FindOpenFor(job.id, "cork", "default", &field, &message));
  EXPECT_EQ(field, "material");
  EXPECT_EQ(message, "material = 'cork' (job 1 is for 'felt')");
  EXPECT_FALSE(
      lib_.jobs().FindOpenFor(job.id, "felt", "tip", &field, &message));
  EXPECT_EQ(field, "fingertip");
  EXPECT_FALSE(
      lib_.jobs().FindOpenFor(99, "felt", "default", &field, &message));
  EXPECT_EQ(field, "job_id");
  EXPECT_NE(message.find("no such identification job"), std::string::npos);
  lib_.jobs().Transition(&job, JobState::kFailed, "x");
  EXPECT_FALSE(
      lib_.jobs().FindOpenFor(job.id, "felt", "default", &field, &message));
  EXPECT_EQ(message,
            "job_id = 1 (the job is failed; query the material again)");
}

// Too little span: a follow-up stroke for the missing region, then the job
// fails after max_strokes_per_job strokes (audited, kept strokes dropped).
TEST_F(IdentificationJobsTest, TooLittleCoverageAsksFollowUpThenFails) {
  JobStrokeCollector c(lib_, Worker("w1", /*max_strokes=*/2));
  IdentificationJob job = Open("felt");
  std::string field, message;
  ASSERT_EQ(c.Admit(job, 0, 0.0, &field, &message), ChunkAdmission::kAccept);
  c.NoteReceiving(&job, 0, "r1");
  EXPECT_EQ(job.state, "stroking");
  EXPECT_EQ(lib_.jobs().Find(job.id)->detail, "receiving stroke 0 from r1");
  const StrokeOutcome first =
      c.AddStroke(&job, 0, CornerStroke(1), Robot("r1"));
  ASSERT_EQ(first.kind, StrokeOutcome::Kind::kFollowUp) << first.detail;
  EXPECT_EQ(first.state, JobState::kStroking);
  EXPECT_EQ(first.follow_up_stroke, 1);
  EXPECT_GE(first.span_pct, 0.0);
  EXPECT_LT(first.span_pct, 50.0);
  EXPECT_GT(first.missing.Area(), 0.0);
  EXPECT_NE(first.detail.find("follow-up stroke 1 asked for"),
            std::string::npos)
      << first.detail;
  EXPECT_EQ(lib_.jobs().Find(job.id)->detail, first.detail);
  EXPECT_EQ(lib_.store().ListJobStrokes(job.id).size(), 1u);
  // The stroke already received is a late duplicate; beyond the maximum a
  // stroke number is rejected.
  EXPECT_EQ(c.Admit(job, 0, 0.1, &field, &message), ChunkAdmission::kIgnore);
  EXPECT_EQ(c.Admit(job, 2, 0.1, &field, &message), ChunkAdmission::kReject);
  EXPECT_EQ(field, "stroke");
  EXPECT_EQ(message, "stroke = 2 (at most 2 strokes per job)");

  const StrokeOutcome second =
      c.AddStroke(&job, 1, CornerStroke(2), Robot("r1"));
  ASSERT_EQ(second.kind, StrokeOutcome::Kind::kFailed);
  EXPECT_EQ(second.state, JobState::kFailed);
  EXPECT_NE(second.detail.find("too little span coverage"), std::string::npos);
  EXPECT_EQ(lib_.jobs().Find(job.id)->state, "failed");
  EXPECT_TRUE(lib_.store().ListJobStrokes(job.id).empty());
  EXPECT_EQ(c.open_jobs(), 0u);
  const auto audit = lib_.store().ListAudit(0, 100, "felt");
  ASSERT_FALSE(audit.empty());
  const json detail = json::parse(audit.front().detail);
  EXPECT_EQ(detail["status"], 422);
  EXPECT_EQ(detail["job"], job.id);
  EXPECT_EQ(detail["signed"], true);
  EXPECT_EQ(audit.front().actor, "lcm:r1");
  EXPECT_FALSE(lib_.FindModel("felt", "default"));
}

// Enough span: the job fits through the library and closes.
TEST_F(IdentificationJobsTest, EnoughCoverageFitsAndCloses) {
  JobStrokeCollector c(lib_, Worker("w1"));
  IdentificationJob job = Open("felt");
  std::string field, message;
  ASSERT_EQ(c.Admit(job, 0, 0.0, &field, &message), ChunkAdmission::kAccept);
  const StrokeOutcome o = c.AddStroke(&job, 0, WideStroke(3), Robot("r1"));
  ASSERT_EQ(o.kind, StrokeOutcome::Kind::kEnoughCoverage) << o.detail;
  EXPECT_GE(o.span_pct, 50.0);
  EXPECT_EQ(lib_.jobs().Find(job.id)->state, "enough_coverage");
  const StrokeOutcome fit = c.Fit(&job, o, Robot("r1"));
  ASSERT_EQ(fit.kind, StrokeOutcome::Kind::kFitted) << fit.detail;
  EXPECT_EQ(fit.version, 1);
  EXPECT_EQ(fit.state, JobState::kFitted);
  EXPECT_EQ(lib_.jobs().Find(job.id)->state, "fitted");
  EXPECT_EQ(fit.detail.rfind("fitted version 1 (", 0), 0u) << fit.detail;
  ASSERT_TRUE(lib_.FindModel("felt", "default"));
  EXPECT_EQ(c.open_jobs(), 0u);
}

TEST_F(IdentificationJobsTest, AStrokeLongerThanThePlanIsRejected) {
  JobStrokeCollector c(lib_, Worker("w1"));
  IdentificationJob job = Open("felt");
  StrokeData long_stroke = CornerStroke(4);
  for (double& t : long_stroke.t_s) t *= 100.0;
  const StrokeOutcome o = c.AddStroke(&job, 0, long_stroke, Robot("r1"));
  ASSERT_EQ(o.kind, StrokeOutcome::Kind::kRejected);
  EXPECT_EQ(o.field, "t_s");
  EXPECT_NE(o.message.find("max_duration_s = 120"), std::string::npos)
      << o.message;
  EXPECT_EQ(lib_.jobs().Find(job.id)->state, "requested");
  EXPECT_TRUE(lib_.store().ListJobStrokes(job.id).empty());
}

// A worker that restarts (or takes a job over) continues with the strokes
// the store kept instead of asking for them again.
TEST_F(IdentificationJobsTest, KeptStrokesSurviveARestart) {
  IdentificationJob job = Open("felt");
  std::string field, message;
  {
    JobStrokeCollector before(lib_, Worker("w1"));
    ASSERT_EQ(before.Admit(job, 0, 0.0, &field, &message),
              ChunkAdmission::kAccept);
    ASSERT_EQ(before.AddStroke(&job, 0, CornerStroke(5), Robot("r1")).kind,
              StrokeOutcome::Kind::kFollowUp);
  }
  JobStrokeCollector after(lib_, Worker("w1"));
  EXPECT_EQ(after.Admit(job, 0, 0.0, &field, &message),
            ChunkAdmission::kIgnore);
  EXPECT_EQ(after.Admit(job, 1, 0.0, &field, &message),
            ChunkAdmission::kAccept);
}

// Claims are leases: the worker that holds one acts on the job, another
// stays silent; a claim is renewed in the store only every claim_renew_s
// (time passed in), and a worker whose claim was taken over stops.
TEST_F(IdentificationJobsTest, ClaimLeasesDecideWhoActs) {
  IdentificationJob job = Open("felt");
  JobStrokeCollector a(lib_, Worker("a"));
  JobStrokeCollector b(lib_, Worker("b"));
  std::string field, message;
  EXPECT_EQ(a.Admit(job, 0, 0.0, &field, &message), ChunkAdmission::kAccept);
  EXPECT_EQ(b.Admit(job, 0, 0.0, &field, &message), ChunkAdmission::kIgnore);
  // "a" stops renewing (as if it died); "b" takes the job over once the
  // store's lease (here 1 s) has run out.
  std::this_thread::sleep_for(std::chrono::milliseconds(1300));
  ASSERT_TRUE(lib_.store().ClaimJobWithLease(job.id, "b", 1));
  // Within claim_renew_s "a" trusts its lease without asking the store...
  EXPECT_EQ(a.Admit(job, 0, 5.0, &field, &message), ChunkAdmission::kAccept);
  // ...and at the renewal learns it lost the job.
  EXPECT_EQ(a.Admit(job, 0, 10.5, &field, &message), ChunkAdmission::kIgnore);
  EXPECT_EQ(b.Admit(job, 0, 10.5, &field, &message), ChunkAdmission::kAccept);
}

TEST(JobStrokeCollectorTest, OptionsAreChecked) {
  FrictionLibrary lib(OpenStore(":memory:"));
  try {
    JobStrokeCollector c(lib, Worker("w", 0));
    FAIL() << "max_strokes_per_job = 0 was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "max_strokes_per_job must be >= 1");
  }
  EXPECT_THROW(JobStrokeCollector(lib, Worker("")), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
