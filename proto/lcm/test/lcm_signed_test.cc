// Signed messages to robots (lcm_signed.h): a signed reply verifies and
// decodes; a forged MAC, a changed payload, another key, a stale or
// replayed message, another channel and a copy for another robot are
// dropped with their reason.
#include "frictiond/proto/lcm_signed.h"

#include <string>

#include <gtest/gtest.h>

#include "frictiond/crypto/hmac.h"
#include "frictiond/proto/lcm_channels.h"

namespace frictiond {
namespace {

material_reply_v1 Reply() {
  material_reply_v1 r{};
  r.request_id = "q1";
  r.robot = "arm-7";
  r.material = "ptfe";
  r.fingertip = "default";
  r.status = material_reply_v1::STATUS_KNOWN;
  r.model.material = "ptfe";
  r.model.version = 2;
  r.model.n_terms = 0;
  r.model.n_quantiles = 0;
  r.model.mu_coulomb = 0.2;
  return r;
}

class LcmSignedTest : public ::testing::Test {
 protected:
  const std::string key_ = std::string(32, 'a');
  const std::string other_key_ = std::string(32, 'b');
  const std::int64_t now_us_ = 1'800'000'000'000'000;
  LcmSignedReceiver rx_{{{"arm-7", key_}, {kLcmFleetKeyId, other_key_}}};

  std::string Signed(const std::string& channel,
                     const std::string& key_id,
                     const std::string& key,
                     std::int64_t utime) {
    return EncodeLcm(
        SignLcmPayload(EncodeLcm(Reply()), channel, key_id, key, utime));
  }
  LcmVerifyResult Open(const std::string& bytes,
                       const std::string& channel = kLcmReplyChannel) {
    material_reply_v1 r;
    return rx_.Open(bytes.data(), bytes.size(), channel, &r, now_us_);
  }
};

TEST_F(LcmSignedTest, ValidReplyVerifiesAndDecodes) {
  const std::string b = Signed(kLcmReplyChannel, "arm-7", key_, now_us_);
  material_reply_v1 r;
  const LcmVerifyResult v =
      rx_.Open(b.data(), b.size(), kLcmReplyChannel, &r, now_us_);
  ASSERT_TRUE(v.ok()) << v.detail;
  EXPECT_EQ(v.key_id, "arm-7");
  EXPECT_EQ(r.model.version, 2);
  EXPECT_DOUBLE_EQ(r.model.mu_coulomb, 0.2);
  EXPECT_EQ(LcmSignedChannel(kLcmReplyChannel), "FRICTIOND_REPLY_V1_SIGNED");
}

TEST_F(LcmSignedTest, FleetKeyVerifies) {
  EXPECT_TRUE(
      Open(Signed(kLcmReplyChannel, kLcmFleetKeyId, other_key_, now_us_)).ok());
}

TEST_F(LcmSignedTest, ForgeriesAreDropped) {
  // Signed with a key the sender guessed.
  EXPECT_EQ(
      Open(Signed(kLcmReplyChannel, "arm-7", other_key_, now_us_)).failure,
      LcmVerifyFailure::kForged);
  // A valid message whose model was changed afterwards (a forged model).
  signed_message_v1 m = SignLcmPayload(
      EncodeLcm(Reply()), kLcmReplyChannel, "arm-7", key_, now_us_);
  material_reply_v1 evil = Reply();
  evil.model.mu_coulomb = 0.9;
  const std::string evil_bytes = EncodeLcm(evil);
  m.payload.assign(evil_bytes.begin(), evil_bytes.end());
  m.payload_size = static_cast<int32_t>(m.payload.size());
  EXPECT_EQ(Open(EncodeLcm(m)).failure, LcmVerifyFailure::kForged);
  // A flipped MAC bit.
  m = SignLcmPayload(
      EncodeLcm(Reply()), kLcmReplyChannel, "arm-7", key_, now_us_);
  m.hmac[0] ^= 1;
  EXPECT_EQ(Open(EncodeLcm(m)).failure, LcmVerifyFailure::kForged);
}

TEST_F(LcmSignedTest, ReplayStaleWrongChannelAndOthersAreDropped) {
  const std::string b = Signed(kLcmReplyChannel, "arm-7", key_, now_us_);
  EXPECT_TRUE(Open(b).ok());
  EXPECT_EQ(Open(b).failure, LcmVerifyFailure::kReplayed);
  EXPECT_EQ(Open(Signed(kLcmReplyChannel, "arm-7", key_, now_us_ - 31'000'000))
                .failure,
            LcmVerifyFailure::kStale);
  EXPECT_EQ(Open(Signed(kLcmReplyChannel, "arm-7", key_, now_us_),
                 kLcmModelUpdateChannel)
                .failure,
            LcmVerifyFailure::kWrongChannel);
  EXPECT_EQ(
      Open(Signed(kLcmReplyChannel, "arm-8", other_key_, now_us_)).failure,
      LcmVerifyFailure::kNotForMe);
  const std::string junk = "\x01\x02\x03";
  EXPECT_EQ(Open(junk).failure, LcmVerifyFailure::kUndecodable);
  // A payload of another type under a valid signature.
  model_update_v1 u{};
  u.model.n_terms = u.model.n_quantiles = 0;
  const std::string wrong = EncodeLcm(
      SignLcmPayload(EncodeLcm(u), kLcmReplyChannel, "arm-7", key_, now_us_));
  EXPECT_EQ(Open(wrong).failure, LcmVerifyFailure::kUndecodable);
}

}  // namespace
}  // namespace frictiond
