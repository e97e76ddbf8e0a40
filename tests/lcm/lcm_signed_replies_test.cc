// Signed messages to robots (docs/lcm.md "Signed messages to robots",
// docs/security_lcm.md) on the in-process endpoint over a real udpm
// provider, with the unsigned forms off (the default): a query's reply and
// identification requests arrive only signed, with the asking robot's key;
// a new model version is broadcast signed once per robot key and with the
// fleet key. A forged reply, a forged model update, a replayed reply and a
// reply replayed on the model-update channel are dropped by the receiver.
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include "frictiond/crypto/hmac.h"
#include "frictiond/crypto/lcm_signing.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lcm_signed.h"
#include "frictiond/server/lcm_endpoint.h"
#include "frictiond/stroke_chunk_v2.hpp"
#include "frictiond/testing/stroke_simulator.h"

#include "lcm_test_inbox.h"
#include "robot_simulator.h"

namespace frictiond {
namespace {

using testing::LcmInbox;

// Records raw bytes of every "_SIGNED" message.
struct SignedInbox {
  struct Received {
    std::string channel;
    std::string bytes;
  };
  std::vector<Received> got;
  void On(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    got.push_back(
        {channel,
         std::string(static_cast<const char*>(rbuf->data), rbuf->data_size)});
  }
  std::vector<Received> On(const std::string& channel) const {
    std::vector<Received> out;
    for (const auto& r : got)
      if (r.channel == channel) out.push_back(r);
    return out;
  }
};

class LcmSignedRepliesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    url_ = testing::MakeTestLcmUrl(67);
    std::string why;
    if (!testing::CheckLcmLoopback(url_, &why)) GTEST_SKIP() << why;
    library_ = std::make_unique<FrictionLibrary>(OpenStore(":memory:"));
    key_a_ = RandomBytes(32);
    key_b_ = RandomBytes(32);
    fleet_key_ = RandomBytes(32);
    LcmEndpointOptions o;
    o.url = url_;
    o.security.keys = {
        {"robot-a", key_a_}, {"robot-b", key_b_}, {"fleet", fleet_key_}};
    ASSERT_FALSE(o.security.send_unsigned);  // the default
    endpoint_ = std::make_unique<LcmEndpoint>(*library_, o);
    endpoint_->Start();
    inbox_ = std::make_unique<LcmInbox>(url_);
    ASSERT_TRUE(inbox_->good());
    inbox_->lcm().subscribe("FRICTIOND_.*_SIGNED", &SignedInbox::On, &signed_);
  }
  void TearDown() override {
    if (endpoint_) endpoint_->Stop();
  }

  void Query(const std::string& robot, const std::string& material) {
    material_query_v1 q{};
    q.request_id = "q-" + material;
    q.robot = robot;
    q.material = material;
    q.fingertip = "";
    q.image_size = 0;
    inbox_->lcm().publish(kLcmQueryChannel, &q);
  }
  bool WaitSigned(const char* channel, std::size_t n = 1) {
    const std::string c = LcmSignedChannel(channel);
    return inbox_->WaitFor([&] { return signed_.On(c).size() >= n; });
  }

  std::string url_, key_a_, key_b_, fleet_key_;
  std::unique_ptr<FrictionLibrary> library_;
  std::unique_ptr<LcmEndpoint> endpoint_;
  std::unique_ptr<LcmInbox> inbox_;
  SignedInbox signed_;
};

TEST_F(LcmSignedRepliesTest, ReplyAndRequestsGoSignedWithTheRobotsKeyOnly) {
  Query("robot-a", "cork");
  ASSERT_TRUE(WaitSigned(kLcmReplyChannel));
  ASSERT_TRUE(WaitSigned(kLcmIdentRequestChannel));
  ASSERT_TRUE(WaitSigned(kLcmIdentRequestV2Channel));
  LcmSignedReceiver robot_a({{"robot-a", key_a_}});
  LcmSignedReceiver robot_b({{"robot-b", key_b_}});
  const auto replies = signed_.On(LcmSignedChannel(kLcmReplyChannel));
  ASSERT_EQ(replies.size(), 1u);  // one copy: robot-a's key
  material_reply_v1 reply;
  const LcmVerifyResult v = robot_a.Open(replies[0].bytes.data(),
                                         replies[0].bytes.size(),
                                         kLcmReplyChannel,
                                         &reply);
  ASSERT_TRUE(v.ok()) << v.detail;
  EXPECT_EQ(reply.status, +material_reply_v1::STATUS_UNKNOWN);
  EXPECT_EQ(reply.request_id, "q-cork");
  EXPECT_GT(reply.job_id, 0);
  EXPECT_EQ(robot_b
                .Open(replies[0].bytes.data(),
                      replies[0].bytes.size(),
                      kLcmReplyChannel,
                      &reply)
                .failure,
            LcmVerifyFailure::kNotForMe);
  identification_request_v2 r2;
  const auto req = signed_.On(LcmSignedChannel(kLcmIdentRequestV2Channel));
  ASSERT_TRUE(robot_a
                  .Open(req[0].bytes.data(),
                        req[0].bytes.size(),
                        kLcmIdentRequestV2Channel,
                        &r2)
                  .ok());
  EXPECT_EQ(r2.job_id, reply.job_id);
  // Nothing went unsigned.
  inbox_->WaitFor([] { return false; }, 0.3);
  EXPECT_TRUE(inbox_->replies.empty());
  EXPECT_TRUE(inbox_->requests.empty());
  EXPECT_TRUE(inbox_->requests_v2.empty());
}

TEST_F(LcmSignedRepliesTest, ModelUpdatesAreSignedPerRobotAndFleet) {
  testing::SimulationSpec spec;
  spec.strokes = 4;
  IngestOptions io;
  library_->IngestStrokes(
      "felt", FormatStrokeCsv(testing::SimulateStrokes(spec, 5)), io);
  ASSERT_TRUE(WaitSigned(kLcmModelUpdateChannel, 3));
  inbox_->WaitFor([] { return false; }, 0.2);
  const auto updates = signed_.On(LcmSignedChannel(kLcmModelUpdateChannel));
  EXPECT_EQ(updates.size(), 3u);  // robot-a, robot-b, fleet
  LcmSignedReceiver robot_a({{"robot-a", key_a_}});
  LcmSignedReceiver fleet_robot({{kLcmFleetKeyId, fleet_key_}});
  int for_a = 0, for_fleet = 0;
  for (const auto& u : updates) {
    model_update_v1 m;
    if (robot_a.Open(u.bytes.data(), u.bytes.size(), kLcmModelUpdateChannel, &m)
            .ok()) {
      ++for_a;
      EXPECT_EQ(m.model.material, "felt");
      EXPECT_EQ(m.model.version, 1);
    }
    if (fleet_robot
            .Open(u.bytes.data(), u.bytes.size(), kLcmModelUpdateChannel, &m)
            .ok())
      ++for_fleet;
  }
  EXPECT_EQ(for_a, 1);
  EXPECT_EQ(for_fleet, 1);
  EXPECT_TRUE(inbox_->updates.empty());  // no unsigned update
}

// An attacker on the group: forged replies and model updates, replays.
TEST_F(LcmSignedRepliesTest, ForgedAndReplayedMessagesAreDroppedByTheRobot) {
  Query("robot-a", "cork");
  ASSERT_TRUE(WaitSigned(kLcmReplyChannel));
  const std::string genuine =
      signed_.On(LcmSignedChannel(kLcmReplyChannel))[0].bytes;
  LcmSignedReceiver robot_a({{"robot-a", key_a_}, {"fleet", fleet_key_}});
  material_reply_v1 reply;
  ASSERT_TRUE(
      robot_a.Open(genuine.data(), genuine.size(), kLcmReplyChannel, &reply)
          .ok());

  // A forged reply: a known model with a made-up mu, under robot-a's name
  // but without its key.
  material_reply_v1 evil = reply;
  evil.status = material_reply_v1::STATUS_KNOWN;
  evil.model.mu_coulomb = 1.5;
  const std::string forged_reply = EncodeLcm(SignLcmPayload(
      EncodeLcm(evil), kLcmReplyChannel, "robot-a", RandomBytes(32)));
  // A forged model update under the fleet key id.
  model_update_v1 u{};
  u.reason = "upload";
  u.model.material = "cork";
  u.model.version = 99;
  u.model.n_terms = u.model.n_quantiles = 0;
  u.model.mu_coulomb = 1.5;
  const std::string forged_update = EncodeLcm(SignLcmPayload(
      EncodeLcm(u), kLcmModelUpdateChannel, "fleet", RandomBytes(32)));
  // Sent over the wire as an attacker would.
  inbox_->lcm().publish(LcmSignedChannel(kLcmReplyChannel),
                        forged_reply.data(),
                        static_cast<unsigned>(forged_reply.size()));
  inbox_->lcm().publish(LcmSignedChannel(kLcmModelUpdateChannel),
                        forged_update.data(),
                        static_cast<unsigned>(forged_update.size()));
  inbox_->lcm().publish(LcmSignedChannel(kLcmReplyChannel),
                        genuine.data(),
                        static_cast<unsigned>(genuine.size()));
  ASSERT_TRUE(WaitSigned(kLcmReplyChannel, 3));
  ASSERT_TRUE(WaitSigned(kLcmModelUpdateChannel, 1));
  const auto replies = signed_.On(LcmSignedChannel(kLcmReplyChannel));
  material_reply_v1 got;
  EXPECT_EQ(robot_a
                .Open(replies[1].bytes.data(),
                      replies[1].bytes.size(),
                      kLcmReplyChannel,
                      &got)
                .failure,
            LcmVerifyFailure::kForged);
  EXPECT_EQ(robot_a
                .Open(replies[2].bytes.data(),
                      replies[2].bytes.size(),
                      kLcmReplyChannel,
                      &got)
                .failure,
            LcmVerifyFailure::kReplayed);
  const auto updates = signed_.On(LcmSignedChannel(kLcmModelUpdateChannel));
  model_update_v1 m;
  EXPECT_EQ(robot_a
                .Open(updates[0].bytes.data(),
                      updates[0].bytes.size(),
                      kLcmModelUpdateChannel,
                      &m)
                .failure,
            LcmVerifyFailure::kForged);
  // The genuine reply replayed on the model-update channel.
  EXPECT_EQ(
      robot_a.Open(genuine.data(), genuine.size(), kLcmModelUpdateChannel, &m)
          .failure,
      LcmVerifyFailure::kWrongChannel);
}

// The fleet key is not a robot: a chunk signed as robot "fleet" is dropped.
TEST_F(LcmSignedRepliesTest, FleetKeyCannotWrite) {
  EXPECT_EQ(endpoint_ != nullptr, true);
  stroke_chunk_v2 c{};
  c.robot = "fleet";
  c.material = "cork";
  c.fingertip = "default";
  c.job_id = 1;
  c.n_samples = 1;
  c.t_s = {0};
  c.fn_n = {1};
  c.ft_n = {0.1};
  c.v_mm_s = {1};
  c.last = true;
  c.total_chunks = 1;
  SignLcmMessage(&c, fleet_key_);
  inbox_->lcm().publish(kLcmSignedStrokeChannel, &c);
  ASSERT_TRUE(WaitSigned(kLcmErrorChannel));
  // "fleet" has no robot key: the error goes signed with the fleet key.
  const auto errors = signed_.On(LcmSignedChannel(kLcmErrorChannel));
  LcmSignedReceiver fleet({{"fleet", fleet_key_}});
  error_v1 e;
  const LcmVerifyResult v = fleet.Open(
      errors[0].bytes.data(), errors[0].bytes.size(), kLcmErrorChannel, &e);
  ASSERT_TRUE(v.ok()) << v.detail;
  EXPECT_EQ(e.field, "robot") << e.reason;
}

// error_v1 goes signed (FRICTIOND_ERROR_V1_SIGNED) with the named robot's
// key only, and not unsigned (lcm_send_unsigned is off); a robot without a
// key gets it under the fleet key; a forged error is dropped.
TEST_F(LcmSignedRepliesTest, ErrorsAreSignedWithTheRobotsKey) {
  stroke_chunk_v2 c{};
  c.robot = "robot-a";
  c.material = "cork";
  c.fingertip = "default";
  c.job_id = 12345;  // no such job
  c.n_samples = 1;
  c.t_s = {0};
  c.fn_n = {1};
  c.ft_n = {0.1};
  c.v_mm_s = {1};
  c.last = true;
  c.total_chunks = 1;
  SignLcmMessage(&c, key_a_);
  inbox_->lcm().publish(kLcmSignedStrokeChannel, &c);
  ASSERT_TRUE(WaitSigned(kLcmErrorChannel));
  inbox_->WaitFor([] { return false; }, 0.3);  // any second copy arrives
  const auto errors = signed_.On(LcmSignedChannel(kLcmErrorChannel));
  ASSERT_EQ(errors.size(), 1u);  // one copy: robot-a's key
  LcmSignedReceiver robot_a({{"robot-a", key_a_}});
  LcmSignedReceiver robot_b({{"robot-b", key_b_}});
  error_v1 e;
  LcmVerifyResult v = robot_a.Open(
      errors[0].bytes.data(), errors[0].bytes.size(), kLcmErrorChannel, &e);
  ASSERT_TRUE(v.ok()) << v.detail;
  EXPECT_EQ(e.robot, "robot-a");
  EXPECT_EQ(e.job_id, 12345);
  EXPECT_EQ(e.field, "job_id") << e.reason;
  EXPECT_EQ(robot_b
                .Open(errors[0].bytes.data(),
                      errors[0].bytes.size(),
                      kLcmErrorChannel,
                      &e)
                .failure,
            LcmVerifyFailure::kNotForMe);
  EXPECT_TRUE(inbox_->errors.empty()) << "an error went unsigned";

  // A forged error (another key under robot-a's name) is dropped.
  error_v1 fake{};
  fake.robot = "robot-a";
  fake.field = "job_id";
  fake.reason = "forged";
  const signed_message_v1 forged = SignLcmPayload(
      EncodeLcm(fake), kLcmErrorChannel, "robot-a", RandomBytes(32));
  const std::string bytes = EncodeLcm(forged);
  EXPECT_EQ(
      robot_a.Open(bytes.data(), bytes.size(), kLcmErrorChannel, &e).failure,
      LcmVerifyFailure::kForged);

  // A malformed query naming no robot: signed with the fleet key.
  const std::string junk = "\x01\x02\x03";
  inbox_->lcm().publish(kLcmQueryChannel, junk.data(), junk.size());
  ASSERT_TRUE(WaitSigned(kLcmErrorChannel, 2));
  const auto all = signed_.On(LcmSignedChannel(kLcmErrorChannel));
  LcmSignedReceiver fleet({{"fleet", fleet_key_}});
  v = fleet.Open(
      all[1].bytes.data(), all[1].bytes.size(), kLcmErrorChannel, &e);
  ASSERT_TRUE(v.ok()) << v.detail;
  EXPECT_EQ(e.message_type, "material_query_v1");
  EXPECT_TRUE(inbox_->errors.empty()) << "an error went unsigned";
}

}  // namespace
}  // namespace frictiond
