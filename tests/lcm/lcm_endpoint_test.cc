// The daemon's LCM endpoint in process (FrictionLibrary on an in-memory
// store + LcmEndpoint) on a real udpm provider: queries, bad-message
// rejection naming the field with nothing stored, resend requests and
// give-up for missing chunks.
#include "frictiond/server/lcm_endpoint.h"

#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "lcm_test_inbox.h"
#include "robot_simulator.h"

namespace frictiond {
namespace {

using testing::LcmInbox;

class LcmEndpointTest : public ::testing::Test {
 protected:
  void SetUp() override {
    url_ = testing::MakeTestLcmUrl(11);
    std::string why;
    if (!testing::CheckLcmLoopback(url_, &why)) GTEST_SKIP() << why;
    library_ = std::make_unique<FrictionLibrary>(OpenStore(":memory:"));
    LcmEndpointOptions o;
    o.url = url_;
    o.reassembly.resend_after_s = 0.2;
    o.reassembly.give_up_after_s = 1.0;
    o.max_strokes_per_job = 2;
    // These tests check validation of the chunk fields: unsigned chunks.
    o.security.allow_unsigned = true;
    o.security.send_unsigned = true;  // the inbox reads unsigned messages
    // A stand-in recognition hook: "IMG:<id>" is recognised as <id>,
    // "IMG-BAD" cannot be decoded, anything else is unknown.
    o.recognize = [](const std::string& image) {
      if (image == "IMG-BAD")
        throw std::invalid_argument("cannot decode the image (not PNG/JPEG)");
      ImageRecognition r;
      r.operating_point = 0.74;
      if (image.rfind("IMG:", 0) == 0) {
        r.unknown = false;
        r.candidates.emplace_back(image.substr(4), 0.87);
        r.candidates.emplace_back("felt", 0.05);
        r.reason =
            image.substr(4) + " at 0.87, at or above the 0.74 operating point";
      } else {
        r.candidates.emplace_back("felt", 0.31);
        r.reason = "closest is felt at 0.31, below the 0.74 operating point";
      }
      return r;
    };
    // As the daemon (host:port): the same identity after a restart, so it
    // still holds its claims.
    o.worker_id = "test-daemon";
    endpoint_options_ = o;
    endpoint_ = std::make_unique<LcmEndpoint>(*library_, o);
    endpoint_->Start();
    inbox_ = std::make_unique<LcmInbox>(url_);
    ASSERT_TRUE(inbox_->good());
  }
  void TearDown() override {
    if (endpoint_) endpoint_->Stop();
  }

  material_reply_v1 Query(const std::string& material,
                          const std::string& image = "") {
    material_query_v1 q;
    q.utime = 0;
    q.request_id = "r" + std::to_string(++request_counter_);
    q.robot = "test";
    q.material = material;
    q.fingertip = "";
    q.image.assign(image.begin(), image.end());
    q.image_size = static_cast<int32_t>(q.image.size());
    inbox_->lcm().publish(kLcmQueryChannel, &q);
    material_reply_v1 out;
    out.status = -1;
    inbox_->WaitFor([&] {
      for (const auto& r : inbox_->replies) {
        if (r.request_id == q.request_id) {
          out = r;
          return true;
        }
      }
      return false;
    });
    return out;
  }

  // Sends a chunk and waits for the error it must cause; returns it.
  error_v1 ExpectRejected(const stroke_chunk_v1& c) {
    const std::size_t before = inbox_->errors.size();
    inbox_->lcm().publish(kLcmStrokeChannel, &c);
    error_v1 e;
    e.field = "(no error received)";
    if (inbox_->WaitFor([&] { return inbox_->errors.size() > before; }))
      e = inbox_->errors[before];
    return e;
  }

  static stroke_chunk_v1 MakeChunk(std::int64_t job_id,
                                   int seq,
                                   int total,
                                   bool last) {
    stroke_chunk_v1 c;
    c.utime = 0;
    c.job_id = job_id;
    c.stroke = 0;
    c.robot = "test";
    c.material = "felt";
    c.fingertip = "default";
    c.seq = seq;
    c.total_chunks = total;
    c.last = last;
    c.n_samples = 4;
    for (int i = 0; i < 4; ++i) {
      c.t_s.push_back(seq * 0.04 + i * 0.01);
      c.fn_n.push_back(2.0);
      c.ft_n.push_back(1.0);
      c.v_mm_s.push_back(20.0);
    }
    return c;
  }

  // Waits for the follow-up identification request asking for `stroke`.
  bool WaitForFollowUp(int stroke) {
    return inbox_->WaitFor([&] {
      for (const auto& q : inbox_->requests)
        if (q.follow_up && q.stroke == stroke) return true;
      return false;
    });
  }

  void ExpectNothingStored(const std::string& material) {
    EXPECT_TRUE(library_->store().ListStrokes(material, "default").empty());
    EXPECT_FALSE(library_->store().GetLatestModel(material, "default"));
    EXPECT_FALSE(library_->store().GetMaterial(material));
  }

  std::string url_;
  std::unique_ptr<FrictionLibrary> library_;
  LcmEndpointOptions endpoint_options_;
  std::unique_ptr<LcmEndpoint> endpoint_;
  std::unique_ptr<LcmInbox> inbox_;
  int request_counter_ = 0;
};

TEST_F(LcmEndpointTest, UnknownMaterialOpensAJobAndSendsThePlan) {
  const material_reply_v1 r = Query("felt");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN) << r.reason;
  ASSERT_GT(r.job_id, 0);
  ASSERT_TRUE(inbox_->WaitFor([&] { return !inbox_->requests.empty(); }));
  const identification_request_v1& plan = inbox_->requests.back();
  EXPECT_EQ(plan.job_id, r.job_id);
  EXPECT_EQ(plan.material, "felt");
  EXPECT_FALSE(plan.follow_up);
  const StrokePlanOptions defaults;
  EXPECT_DOUBLE_EQ(plan.fn_min_n, defaults.fn_min_n);
  EXPECT_DOUBLE_EQ(plan.fn_max_n, defaults.fn_max_n);
  EXPECT_DOUBLE_EQ(plan.v_max_mm_s, defaults.v_max_mm_s);
  EXPECT_DOUBLE_EQ(plan.min_span_pct, defaults.min_span_pct);
  // v2 beside v1: the same plan plus the LuGre pair (default: at the middle
  // of the Fn span).
  ASSERT_TRUE(inbox_->WaitFor([&] { return !inbox_->requests_v2.empty(); }));
  const identification_request_v2& plan2 = inbox_->requests_v2.back();
  EXPECT_EQ(plan2.job_id, r.job_id);
  EXPECT_EQ(plan2.stroke, plan.stroke);
  EXPECT_DOUBLE_EQ(plan2.fn_max_n, defaults.fn_max_n);
  EXPECT_DOUBLE_EQ(plan2.max_duration_s, defaults.max_duration_s);
  EXPECT_TRUE(plan2.lugre_pair);
  EXPECT_DOUBLE_EQ(plan2.lugre_fn_n,
                   0.5 * (defaults.fn_min_n + defaults.fn_max_n));
  EXPECT_DOUBLE_EQ(plan2.lugre_slow_accel_mm_s2,
                   defaults.lugre_slow_accel_mm_s2);
  EXPECT_LE(plan2.lugre_slow_accel_mm_s2, 3.0);  // quasi-static step
  EXPECT_GE(plan2.lugre_fast_accel_mm_s2, 5.0);  // dynamic step
  EXPECT_EQ(plan2.lugre_fast_strokes, defaults.lugre_fast_strokes);
  EXPECT_DOUBLE_EQ(plan2.lugre_rest_s, defaults.lugre_rest_s);
  auto job = library_->store().GetJob(r.job_id);
  ASSERT_TRUE(job);
  EXPECT_EQ(job->state, "requested");
  EXPECT_EQ(job->requested_by, "lcm:test");
  // Asking again finds the same open job.
  EXPECT_EQ(Query("felt").job_id, r.job_id);
}

TEST_F(LcmEndpointTest, BadQueryIsRejectedNamingTheField) {
  const material_reply_v1 r = Query("no spaces allowed");
  EXPECT_EQ(r.status, +material_reply_v1::STATUS_ERROR);
  EXPECT_NE(r.reason.find("must match"), std::string::npos) << r.reason;
  ASSERT_TRUE(inbox_->WaitFor([&] { return !inbox_->errors.empty(); }));
  EXPECT_EQ(inbox_->errors.back().field, "material");
  EXPECT_EQ(inbox_->errors.back().message_type, "material_query_v1");
  EXPECT_TRUE(library_->store().ListJobs(false).empty());
}

TEST_F(LcmEndpointTest, ReplyV2CarriesTheRecognitionReasonAndCandidates) {
  // Beside every material_reply_v1, a material_reply_v2 on
  // FRICTIOND_REPLY_V2 with the same fields plus the recognition.
  auto v2_of = [&](const std::string& request_id) {
    material_reply_v2 out;
    out.status = -1;
    inbox_->WaitFor([&] {
      for (const auto& r : inbox_->replies_v2) {
        if (r.request_id == request_id) {
          out = r;
          return true;
        }
      }
      return false;
    });
    return out;
  };
  material_reply_v1 r = Query("new-mat", "an unknown picture");
  material_reply_v2 v2 = v2_of(r.request_id);
  ASSERT_EQ(v2.status, +material_reply_v2::STATUS_UNKNOWN) << v2.reason;
  EXPECT_EQ(v2.job_id, r.job_id);
  EXPECT_EQ(v2.material, "new-mat");
  EXPECT_TRUE(v2.recognition_unknown);
  EXPECT_EQ(v2.recognition_reason,
            "closest is felt at 0.31, below the 0.74 operating point");
  EXPECT_DOUBLE_EQ(v2.recognition_operating_point, 0.74);
  ASSERT_EQ(v2.n_candidates, 1);
  EXPECT_EQ(v2.candidate_material[0], "felt");
  EXPECT_DOUBLE_EQ(v2.candidate_score[0], 0.31);
  // Recognised: accepted, two candidates, best first.
  r = Query("proposed-id", "IMG:cork");
  v2 = v2_of(r.request_id);
  EXPECT_FALSE(v2.recognition_unknown);
  EXPECT_EQ(v2.material, "cork");
  ASSERT_EQ(v2.n_candidates, 2);
  EXPECT_EQ(v2.candidate_material[0], "cork");
  EXPECT_DOUBLE_EQ(v2.candidate_score[0], 0.87);
  EXPECT_DOUBLE_EQ(v2.recognition_score, 0.87);
  // No image: no recognition in the reply.
  r = Query("felt");
  v2 = v2_of(r.request_id);
  EXPECT_EQ(v2.status, r.status);
  EXPECT_TRUE(v2.recognition_unknown);
  EXPECT_EQ(v2.n_candidates, 0);
  EXPECT_EQ(v2.recognition_reason, "");
  // Rejected after recognition: the error reply still says what was seen.
  r = Query("", "an unknown picture");
  v2 = v2_of(r.request_id);
  EXPECT_EQ(v2.status, +material_reply_v2::STATUS_ERROR);
  EXPECT_EQ(v2.n_candidates, 1);
}

TEST_F(LcmEndpointTest, ImageQueriesUseTheRecognitionHook) {
  // Recognised: the candidate's material is looked up (unknown here, so a
  // job opens for it, not for the id the robot proposed).
  material_reply_v1 r = Query("proposed-id", "IMG:cork");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN) << r.reason;
  EXPECT_EQ(r.material, "cork");
  EXPECT_DOUBLE_EQ(r.recognition_score, 0.87);
  EXPECT_EQ(library_->store().GetJob(r.job_id)->material, "cork");
  // Not recognised: the proposed id names the new material.
  r = Query("new-mat", "an unknown picture");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN) << r.reason;
  EXPECT_EQ(library_->store().GetJob(r.job_id)->material, "new-mat");
  // Not recognised and no id: rejected naming the field.
  r = Query("", "an unknown picture");
  EXPECT_EQ(r.status, +material_reply_v1::STATUS_ERROR);
  EXPECT_EQ(r.reason.rfind("material: empty", 0), 0u) << r.reason;
  // An image that cannot be decoded.
  r = Query("x", "IMG-BAD");
  EXPECT_EQ(r.status, +material_reply_v1::STATUS_ERROR);
  EXPECT_EQ(r.reason.rfind("image: cannot decode", 0), 0u) << r.reason;
  EXPECT_EQ(library_->store().ListJobs(false).size(), 2u);
}

TEST_F(LcmEndpointTest, BadChunksAreRejectedNamingTheFieldAndStoreNothing) {
  const material_reply_v1 r = Query("felt");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN) << r.reason;
  const std::int64_t job = r.job_id;

  stroke_chunk_v1 c = MakeChunk(job + 1000, 0, 2, false);
  error_v1 e = ExpectRejected(c);
  EXPECT_EQ(e.field, "job_id") << e.reason;
  EXPECT_NE(e.reason.find("no such identification job"), std::string::npos);

  c = MakeChunk(job, 0, 2, false);
  c.fn_n[1] = std::numeric_limits<double>::quiet_NaN();
  e = ExpectRejected(c);
  EXPECT_EQ(e.field, "fn_n[1]") << e.reason;
  EXPECT_EQ(e.job_id, job);

  c = MakeChunk(job, 0, 2, false);
  c.fn_n[0] = -0.5;
  e = ExpectRejected(c);
  EXPECT_EQ(e.field, "fn_n[0]") << e.reason;
  EXPECT_NE(e.reason.find("must be finite and > 0"), std::string::npos);

  c = MakeChunk(job, 0, 2, false);
  c.v_mm_s[3] = -1;
  EXPECT_EQ(ExpectRejected(c).field, "v_mm_s[3]");

  c = MakeChunk(job, 3, 2, false);
  e = ExpectRejected(c);
  EXPECT_EQ(e.field, "seq") << e.reason;

  c = MakeChunk(job, 0, 0, false);
  c.n_samples = 0;
  c.t_s.clear();
  c.fn_n.clear();
  c.ft_n.clear();
  c.v_mm_s.clear();
  EXPECT_EQ(ExpectRejected(c).field, "n_samples");

  c = MakeChunk(job, 0, 2, false);
  c.material = "other";
  EXPECT_EQ(ExpectRejected(c).field, "material");

  // Wrong sizes on the wire: a truncated encoding.
  c = MakeChunk(job, 0, 2, false);
  std::vector<std::uint8_t> bytes(c.getEncodedSize());
  c.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const std::size_t before = inbox_->errors.size();
  inbox_->lcm().publish(
      kLcmStrokeChannel, bytes.data(), static_cast<unsigned>(bytes.size() - 9));
  ASSERT_TRUE(inbox_->WaitFor([&] { return inbox_->errors.size() > before; }));
  // The field that runs past the end is named (was "(encoding)").
  EXPECT_EQ(inbox_->errors[before].field, "n_samples");
  EXPECT_NE(inbox_->errors[before].reason.find("truncated"), std::string::npos);

  // Nothing from the rejected chunks was stored and the job did not move.
  ExpectNothingStored("felt");
  EXPECT_EQ(library_->store().GetJob(job)->state, "requested");
}

// Chunks that overlap in time are found only once the stroke is complete
// (chunk 1 may arrive before chunk 0). That is still the robot's error: it
// names t_s, the job and the stroke, as the other rejections do, not an
// internal error of the daemon; nothing is stored.
TEST_F(LcmEndpointTest, ChunksOverlappingInTimeAreRejectedNamingTs) {
  const material_reply_v1 r = Query("felt");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN) << r.reason;
  stroke_chunk_v1 second = MakeChunk(r.job_id, 1, 2, true);
  for (double& t : second.t_s) t -= 0.03;  // starts inside chunk 0
  inbox_->lcm().publish(kLcmStrokeChannel, &second);
  const error_v1 e = ExpectRejected(MakeChunk(r.job_id, 0, 2, false));
  EXPECT_EQ(e.field, "t_s") << e.reason;
  EXPECT_EQ(e.job_id, r.job_id);
  EXPECT_EQ(e.stroke, 0);
  EXPECT_NE(e.reason.find("before the previous chunk ends"), std::string::npos)
      << e.reason;
  ExpectNothingStored("felt");
}

TEST_F(LcmEndpointTest, TooLittleSpanGetsAFollowUpThenFails) {
  const material_reply_v1 r = Query("felt");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN);
  // A complete one-chunk stroke at one operating point: no span at all.
  stroke_chunk_v1 c = MakeChunk(r.job_id, 0, 1, true);
  inbox_->lcm().publish(kLcmStrokeChannel, &c);
  ASSERT_TRUE(WaitForFollowUp(1)) << "no follow-up request";
  const identification_request_v1& follow = inbox_->requests.back();
  EXPECT_EQ(follow.job_id, r.job_id);
  // Covered: only fn 2 N, v 20 mm/s. Missing: the larger uncovered end of
  // each axis (fn 2..4.5 N, v 20..80 mm/s).
  EXPECT_DOUBLE_EQ(follow.fn_min_n, 2.0);
  EXPECT_DOUBLE_EQ(follow.fn_max_n, StrokePlanOptions{}.fn_max_n);
  EXPECT_DOUBLE_EQ(follow.v_min_mm_s, 20.0);
  EXPECT_DOUBLE_EQ(follow.v_max_mm_s, StrokePlanOptions{}.v_max_mm_s);
  EXPECT_EQ(library_->store().GetJob(r.job_id)->state, "stroking");
  ExpectNothingStored("felt");  // no weak model
  // The second (last allowed) stroke covers nothing either: failed.
  c.stroke = 1;
  inbox_->lcm().publish(kLcmStrokeChannel, &c);
  ASSERT_TRUE(inbox_->WaitFor([&] {
    for (const auto& p : inbox_->progress)
      if (p.state == "failed") return true;
    return false;
  }));
  const auto job = library_->store().GetJob(r.job_id);
  EXPECT_EQ(job->state, "failed");
  EXPECT_NE(job->detail.find("too little span coverage"), std::string::npos)
      << job->detail;
  ExpectNothingStored("felt");
  // The failed LCM write is in the audit log, by the robot, for the pair.
  const auto audit = library_->store().ListAudit(0, 100, "felt");
  ASSERT_EQ(audit.size(), 1u);
  EXPECT_EQ(audit[0].actor, "lcm:test");
  EXPECT_EQ(audit[0].role, "");  // unsigned chunks
  EXPECT_EQ(audit[0].action, "LCM stroke_chunk_v1");
  const auto detail = nlohmann::json::parse(audit[0].detail);
  EXPECT_EQ(detail["status"], 422) << audit[0].detail;
  EXPECT_EQ(detail["job"], r.job_id) << audit[0].detail;
  EXPECT_EQ(detail["signed"], false) << audit[0].detail;
  // Chunks for the failed job are rejected.
  c.stroke = 0;
  EXPECT_EQ(ExpectRejected(c).field, "job_id");
}

// A complete stroke of an open job is kept in the store: an endpoint that
// starts again on the same store (a daemon restart) continues the job with
// it. Here the kept stroke 0 and the new stroke 1 together reach the job's
// limit of two strokes, so the job fails for too little span; an endpoint
// that had lost stroke 0 would ask for a third stroke instead.
TEST_F(LcmEndpointTest, KeptStrokeSurvivesARestart) {
  const material_reply_v1 r = Query("felt");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN);
  stroke_chunk_v1 c = MakeChunk(r.job_id, 0, 1, true);
  inbox_->lcm().publish(kLcmStrokeChannel, &c);
  ASSERT_TRUE(WaitForFollowUp(1)) << "no follow-up request";
  ASSERT_EQ(library_->store().ListJobStrokes(r.job_id).size(), 1u);
  // Restart: the endpoint's memory is gone, the store is not.
  endpoint_->Stop();
  endpoint_ = std::make_unique<LcmEndpoint>(*library_, endpoint_options_);
  endpoint_->Start();
  const std::size_t progress_before = inbox_->progress.size();
  c.stroke = 1;
  inbox_->lcm().publish(kLcmStrokeChannel, &c);
  ASSERT_TRUE(inbox_->WaitFor([&] {
    for (std::size_t i = progress_before; i < inbox_->progress.size(); ++i)
      if (inbox_->progress[i].state == "failed" ||
          inbox_->progress[i].state == "stroking")
        return true;
    return false;
  }));
  const auto job = library_->store().GetJob(r.job_id);
  EXPECT_EQ(job->state, "failed") << job->detail;
  EXPECT_NE(job->detail.find("in 2 stroke(s)"), std::string::npos)
      << job->detail;
  // Closed: its kept strokes are dropped.
  EXPECT_TRUE(library_->store().ListJobStrokes(r.job_id).empty());
}

TEST_F(LcmEndpointTest, MissingChunkIsAskedAgainThenDropped) {
  const material_reply_v1 r = Query("felt");
  ASSERT_EQ(r.status, +material_reply_v1::STATUS_UNKNOWN);
  const stroke_chunk_v1 first = MakeChunk(r.job_id, 0, 0, false);
  inbox_->lcm().publish(kLcmStrokeChannel, &first);
  const stroke_chunk_v1 last = MakeChunk(r.job_id, 2, 3, true);
  inbox_->lcm().publish(kLcmStrokeChannel, &last);
  // The resend request names exactly the missing seq.
  ASSERT_TRUE(inbox_->WaitFor(
      [&] {
        for (const auto& p : inbox_->progress)
          if (p.n_missing > 0) return true;
        return false;
      },
      3.0));
  for (const auto& p : inbox_->progress) {
    if (p.n_missing == 0) continue;
    EXPECT_EQ(p.job_id, r.job_id);
    ASSERT_EQ(p.missing_seqs.size(), 1u);
    EXPECT_EQ(p.missing_seqs[0], 1);
    EXPECT_EQ(p.chunks_expected, 3);
    break;
  }
  EXPECT_EQ(library_->store().GetJob(r.job_id)->state, "stroking");
  // Never resent: the stroke is dropped with a reason.
  ASSERT_TRUE(inbox_->WaitFor(
      [&] {
        for (const auto& e : inbox_->errors)
          if (e.reason.find("dropped") != std::string::npos) return true;
        return false;
      },
      4.0));
  ExpectNothingStored("felt");
}

}  // namespace
}  // namespace frictiond
