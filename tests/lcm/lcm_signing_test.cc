// Signed LCM writes (docs/lcm.md "Signed writes") on the in-process
// endpoint over a real udpm provider: a valid signed stroke chunk is
// accepted; a forged MAC, content changed after signing, another robot's
// key, an unknown robot, a replayed nonce, a stale or future timestamp and
// an unsigned chunk are each dropped, answered with error_v1 naming the
// field (a replay is only counted), counted in the metrics, and change
// nothing. Duplicated (replayed
// or re-signed) and reordered chunks still give exactly one stroke.
#include "frictiond/crypto/lcm_signing.h"

#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/crypto/hmac.h"
#include "frictiond/server/lcm_endpoint.h"
#include "frictiond/server/metrics.h"
#include "frictiond/stroke_chunk_v2.hpp"

#include "lcm_test_inbox.h"
#include "robot_simulator.h"

namespace frictiond {
namespace {

using testing::LcmInbox;

// The value of one counter series in the Prometheus text, -1 when absent.
long long CounterValue(const std::string& text, const std::string& series) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(series + " ", 0) == 0)
      return std::atoll(line.c_str() + series.size() + 1);
  }
  return -1;
}

std::string Dropped(const std::string& reason) {
  return "frictiond_lcm_dropped_total{reason=\"" + reason + "\"}";
}

class LcmSigningTest : public ::testing::Test {
 protected:
  void SetUp() override {
    url_ = testing::MakeTestLcmUrl(31);
    std::string why;
    if (!testing::CheckLcmLoopback(url_, &why)) GTEST_SKIP() << why;
    library_ = std::make_unique<FrictionLibrary>(OpenStore(":memory:"));
    key_a_ = RandomBytes(32);
    key_b_ = RandomBytes(32);
    LcmEndpointOptions o;
    o.url = url_;
    o.max_strokes_per_job = 2;
    o.security.keys = {{"robot-a", key_a_}, {"robot-b", key_b_}};
    o.security.max_skew_s = 30;
    o.security.send_unsigned = true;  // the inbox reads unsigned messages
    o.metrics = &metrics_;
    endpoint_ = std::make_unique<LcmEndpoint>(*library_, o);
    endpoint_->Start();
    inbox_ = std::make_unique<LcmInbox>(url_);
    ASSERT_TRUE(inbox_->good());
  }
  void TearDown() override {
    if (endpoint_) endpoint_->Stop();
  }

  std::int64_t OpenJob(const std::string& material) {
    material_query_v1 q;
    q.utime = 0;
    q.request_id = "q-" + material;
    q.robot = "robot-a";
    q.material = material;
    q.fingertip = "";
    q.image_size = 0;
    inbox_->lcm().publish(kLcmQueryChannel, &q);
    std::int64_t job = 0;
    inbox_->WaitFor([&] {
      for (const auto& r : inbox_->replies)
        if (r.request_id == q.request_id) job = r.job_id;
      return job != 0;
    });
    return job;
  }

  static stroke_chunk_v2 MakeChunk(const std::string& robot,
                                   const std::string& material,
                                   std::int64_t job_id,
                                   int seq,
                                   int total) {
    stroke_chunk_v2 c;
    c.utime = 0;
    std::fill(std::begin(c.nonce), std::end(c.nonce), std::uint8_t{0});
    std::fill(std::begin(c.hmac), std::end(c.hmac), std::uint8_t{0});
    c.job_id = job_id;
    c.stroke = 0;
    c.robot = robot;
    c.material = material;
    c.fingertip = "default";
    c.seq = seq;
    c.total_chunks = total;
    c.last = seq == total - 1;
    c.n_samples = 4;
    for (int i = 0; i < 4; ++i) {
      c.t_s.push_back(seq * 0.04 + i * 0.01);
      c.fn_n.push_back(2.0);
      c.ft_n.push_back(1.0);
      c.v_mm_s.push_back(20.0);
    }
    return c;
  }

  void Send(const stroke_chunk_v2& c) {
    inbox_->lcm().publish(kLcmSignedStrokeChannel, &c);
  }

  // Sends and waits for the error_v1 it must cause.
  error_v1 ExpectDropped(const stroke_chunk_v2& c) {
    const std::size_t before = inbox_->errors.size();
    Send(c);
    error_v1 e;
    e.field = "(no error received)";
    if (inbox_->WaitFor([&] { return inbox_->errors.size() > before; }))
      e = inbox_->errors[before];
    return e;
  }

  long long Counter(const std::string& series) const {
    return CounterValue(metrics_.Render(), series);
  }

  std::string url_;
  std::string key_a_, key_b_;
  Metrics metrics_;
  std::unique_ptr<FrictionLibrary> library_;
  std::unique_ptr<LcmEndpoint> endpoint_;
  std::unique_ptr<LcmInbox> inbox_;
};

TEST_F(LcmSigningTest, BadWritesAreDroppedCountedAndChangeNothing) {
  const std::int64_t job = OpenJob("cork");
  ASSERT_GT(job, 0);
  for (const char* r :
       {"forged", "replayed", "stale", "unknown_robot", "unsigned"})
    EXPECT_EQ(Counter(Dropped(r)), 0) << r;

  // Forged MAC: one bit flipped.
  stroke_chunk_v2 c = MakeChunk("robot-a", "cork", job, 0, 2);
  SignLcmMessage(&c, key_a_);
  c.hmac[5] ^= 1;
  error_v1 e = ExpectDropped(c);
  EXPECT_EQ(e.field, "hmac") << e.reason;
  EXPECT_EQ(e.message_type, "stroke_chunk_v2");
  EXPECT_NE(e.reason.find("forged"), std::string::npos) << e.reason;
  EXPECT_EQ(Counter(Dropped("forged")), 1);

  // Content changed after signing (a sample), MAC left as it was.
  c = MakeChunk("robot-a", "cork", job, 0, 2);
  SignLcmMessage(&c, key_a_);
  c.fn_n[2] = 3.0;
  EXPECT_EQ(ExpectDropped(c).field, "hmac");
  EXPECT_EQ(Counter(Dropped("forged")), 2);

  // Signed with another robot's key (robot-b's key, claiming robot-a).
  c = MakeChunk("robot-a", "cork", job, 0, 2);
  SignLcmMessage(&c, key_b_);
  EXPECT_EQ(ExpectDropped(c).field, "hmac");
  EXPECT_EQ(Counter(Dropped("forged")), 3);

  // A robot without a key.
  c = MakeChunk("robot-z", "cork", job, 0, 2);
  SignLcmMessage(&c, key_a_);
  EXPECT_EQ(ExpectDropped(c).field, "robot");
  EXPECT_EQ(Counter(Dropped("unknown_robot")), 1);

  // Stale (31 s old) and from the future (31 s ahead), validly signed.
  c = MakeChunk("robot-a", "cork", job, 0, 2);
  SignLcmMessage(&c, key_a_, LcmSigningNowUs() - 31'000'000);
  EXPECT_EQ(ExpectDropped(c).field, "utime");
  SignLcmMessage(&c, key_a_, LcmSigningNowUs() + 31'000'000);
  EXPECT_EQ(ExpectDropped(c).field, "utime");
  EXPECT_EQ(Counter(Dropped("stale")), 2);

  // Unsigned stroke_chunk_v1 while unsigned writes are not allowed.
  stroke_chunk_v1 u;
  u.utime = 0;
  u.job_id = job;
  u.stroke = 0;
  u.robot = "robot-a";
  u.material = "cork";
  u.fingertip = "default";
  u.seq = 0;
  u.total_chunks = 1;
  u.last = true;
  u.n_samples = 1;
  u.t_s = {0.0};
  u.fn_n = {2.0};
  u.ft_n = {1.0};
  u.v_mm_s = {20.0};
  const std::size_t before = inbox_->errors.size();
  inbox_->lcm().publish(kLcmStrokeChannel, &u);
  ASSERT_TRUE(inbox_->WaitFor([&] { return inbox_->errors.size() > before; }));
  EXPECT_EQ(inbox_->errors[before].field, "(unsigned)");
  EXPECT_EQ(Counter(Dropped("unsigned")), 1);

  // Nothing of these reached the job.
  EXPECT_EQ(library_->store().GetJob(job)->state, "requested");
  EXPECT_TRUE(inbox_->progress.empty());
  EXPECT_EQ(Counter("frictiond_lcm_signed_accepted_total"), 0);

  // A valid one is accepted; the same bytes again are a replay.
  c = MakeChunk("robot-a", "cork", job, 0, 2);
  SignLcmMessage(&c, key_a_);
  Send(c);
  ASSERT_TRUE(inbox_->WaitFor([&] { return !inbox_->progress.empty(); }));
  EXPECT_EQ(inbox_->progress[0].chunks_received, 1);
  EXPECT_EQ(library_->store().GetJob(job)->state, "stroking");
  EXPECT_EQ(Counter("frictiond_lcm_signed_accepted_total"), 1);
  // Counted, not answered (the original got through).
  const std::size_t errors_before = inbox_->errors.size();
  Send(c);
  EXPECT_TRUE(
      inbox_->WaitFor([&] { return Counter(Dropped("replayed")) == 1; }, 2.0));
  EXPECT_EQ(inbox_->errors.size(), errors_before);
  EXPECT_EQ(inbox_->progress.size(), 1u);
  EXPECT_EQ(Counter("frictiond_lcm_signed_accepted_total"), 1);
}

TEST_F(LcmSigningTest, DuplicatedAndReorderedChunksGiveExactlyOneStroke) {
  const std::int64_t job = OpenJob("felt");
  ASSERT_GT(job, 0);
  std::vector<stroke_chunk_v2> chunks;
  for (int seq = 0; seq < 3; ++seq)
    chunks.push_back(MakeChunk("robot-b", "felt", job, seq, 3));
  auto signed_copy = [&](int seq) {
    stroke_chunk_v2 c = chunks[seq];
    SignLcmMessage(&c, key_b_);
    return c;
  };
  // Order 2, 0, 0 (the same bytes: replay), 0 (re-signed duplicate), 1,
  // then 1 again re-signed after the stroke is complete.
  const stroke_chunk_v2 last = signed_copy(2);
  Send(last);
  const stroke_chunk_v2 first = signed_copy(0);
  Send(first);
  Send(first);
  Send(signed_copy(0));
  Send(signed_copy(1));
  auto complete = [&] {
    int n = 0;
    for (const auto& p : inbox_->progress)
      if (p.job_id == job && p.stroke == 0 && p.span_pct >= 0) ++n;
    return n;
  };
  ASSERT_TRUE(inbox_->WaitFor([&] { return complete() >= 1; }));
  Send(signed_copy(1));
  inbox_->WaitFor([] { return false; }, 0.5);  // let late messages arrive
  EXPECT_EQ(complete(), 1);
  for (const auto& p : inbox_->progress) {
    if (p.span_pct < 0) continue;
    EXPECT_EQ(p.chunks_received, 3);
    EXPECT_EQ(p.samples, 12);  // three chunks of four, none twice
  }
  int follow_ups = 0;
  for (const auto& r : inbox_->requests)
    if (r.job_id == job && r.follow_up) ++follow_ups;
  EXPECT_EQ(follow_ups, 1);  // one stroke, too little span: one follow-up
  EXPECT_EQ(Counter(Dropped("replayed")), 1);
  EXPECT_EQ(Counter(Dropped("forged")), 0);
  EXPECT_EQ(Counter("frictiond_lcm_signed_accepted_total"), 5);
  for (const auto& e : inbox_->errors)
    ADD_FAILURE() << "unexpected error_v1 " << e.field << ": " << e.reason;
}

}  // namespace
}  // namespace frictiond
