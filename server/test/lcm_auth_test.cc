// LcmAuthenticator (no network): order of the checks, the timestamp window,
// the bounded replay cache and the lcm_keys parser.
#include "frictiond/server/lcm_auth.h"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/crypto/hmac.h"

namespace frictiond {
namespace {

constexpr std::int64_t kNow = 1'800'000'000'000'000;  // us

struct Signed {
  std::string robot, data, nonce, mac;
  std::int64_t utime;
};

Signed Sign(const std::string& robot,
            const std::string& key,
            const std::string& data,
            const std::string& nonce,
            std::int64_t utime) {
  return {robot, data, nonce, HmacSha256(key, data + nonce), utime};
}

LcmAuthVerdict Check(LcmAuthenticator& a,
                     const Signed& s,
                     std::int64_t now = kNow) {
  return a.Check(
      s.robot,
      s.utime,
      s.nonce,
      s.mac,
      [&](const std::string& key) { return HmacSha256(key, s.data + s.nonce); },
      now);
}

LcmSecurityOptions Options() {
  LcmSecurityOptions o;
  o.keys = {{"r1", std::string(16, 'a')}, {"r2", std::string(32, 'b')}};
  return o;
}

TEST(LcmAuthenticator, AcceptsValidAndNamesEachReason) {
  LcmAuthenticator a(Options());
  const std::string k1(16, 'a');
  EXPECT_TRUE(Check(a, Sign("r1", k1, "m", "n1", kNow)).ok());
  LcmAuthVerdict v = Check(a, Sign("r1", k1, "m", "n1", kNow));
  EXPECT_EQ(v.reason, LcmDropReason::kReplayed);
  EXPECT_EQ(v.field, "nonce");
  v = Check(a, Sign("r9", k1, "m", "n2", kNow));
  EXPECT_EQ(v.reason, LcmDropReason::kUnknownRobot);
  EXPECT_EQ(v.field, "robot");
  v = Check(a, Sign("r2", k1, "m", "n3", kNow));  // r1's key, claims r2
  EXPECT_EQ(v.reason, LcmDropReason::kForged);
  EXPECT_EQ(v.field, "hmac");
  Signed s = Sign("r1", k1, "m", "n4", kNow);
  s.data = "M";  // content changed after signing
  EXPECT_EQ(Check(a, s).reason, LcmDropReason::kForged);
  EXPECT_EQ(Check(a, Sign("r1", k1, "m", "n5", kNow - 30'000'001)).reason,
            LcmDropReason::kStale);
  EXPECT_EQ(Check(a, Sign("r1", k1, "m", "n6", kNow + 30'000'001)).reason,
            LcmDropReason::kStale);
  EXPECT_TRUE(Check(a, Sign("r1", k1, "m", "n7", kNow - 29'000'000)).ok());
  // A forged message does not burn its nonce: the genuine one still passes.
  Signed f = Sign("r1", k1, "m", "n8", kNow);
  f.mac[0] ^= 1;
  EXPECT_EQ(Check(a, f).reason, LcmDropReason::kForged);
  EXPECT_TRUE(Check(a, Sign("r1", k1, "m", "n8", kNow)).ok());
  // Nonces are per robot.
  EXPECT_TRUE(Check(a, Sign("r2", std::string(32, 'b'), "m", "n1", kNow)).ok());
  EXPECT_STREQ(LcmDropReasonName(LcmDropReason::kUnknownRobot),
               "unknown_robot");
}

TEST(LcmAuthenticator, FullReplayCacheNeverForgetsIntoAHole) {
  LcmSecurityOptions o = Options();
  o.replay_cache_per_robot = 3;
  LcmAuthenticator a(o);
  const std::string k1(16, 'a');
  for (int i = 0; i < 5; ++i)
    EXPECT_TRUE(
        Check(a, Sign("r1", k1, "m", "n" + std::to_string(i), kNow + i)).ok());
  // n0 and n1 were forgotten; replaying them is still caught (not newer
  // than the newest forgotten timestamp).
  EXPECT_EQ(Check(a, Sign("r1", k1, "m", "n0", kNow)).reason,
            LcmDropReason::kReplayed);
  EXPECT_EQ(Check(a, Sign("r1", k1, "m", "n1", kNow + 1)).reason,
            LcmDropReason::kReplayed);
  EXPECT_EQ(Check(a, Sign("r1", k1, "m", "n4", kNow + 4)).reason,
            LcmDropReason::kReplayed);
  EXPECT_TRUE(Check(a, Sign("r1", k1, "m", "n9", kNow + 9)).ok());
}

TEST(LcmAuthenticator, OldNoncesLeaveWithTheWindow) {
  LcmAuthenticator a(Options());
  const std::string k1(16, 'a');
  EXPECT_TRUE(Check(a, Sign("r1", k1, "m", "n1", kNow)).ok());
  // 31 s later the same nonce with a fresh timestamp is new (the old
  // message itself would be stale by then).
  const std::int64_t later = kNow + 31'000'000;
  EXPECT_EQ(Check(a, Sign("r1", k1, "m", "n1", kNow), later).reason,
            LcmDropReason::kStale);
  EXPECT_TRUE(Check(a, Sign("r1", k1, "m", "n1", later), later).ok());
}

TEST(LcmAuthenticator, RejectsBadOptions) {
  LcmSecurityOptions o;
  o.keys = {{"r1", "short"}};
  EXPECT_THROW(LcmAuthenticator{o}, std::invalid_argument);
  o.keys = {{"", std::string(16, 'a')}};
  EXPECT_THROW(LcmAuthenticator{o}, std::invalid_argument);
  o = Options();
  o.max_skew_s = 0;
  EXPECT_THROW(LcmAuthenticator{o}, std::invalid_argument);
}

TEST(ParseLcmKeys, HexKeysAndErrorsNamingTheRobot) {
  const auto keys = ParseLcmKeys(
      R"({"arm-1": "000102030405060708090a0b0c0d0e0f"})", "keys.json");
  ASSERT_EQ(keys.size(), 1u);
  EXPECT_EQ(ToHex(keys.at("arm-1")), "000102030405060708090a0b0c0d0e0f");
  auto error_of = [](const std::string& text) {
    try {
      ParseLcmKeys(text, "keys.json");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_NE(error_of(R"({"arm-1": "00ff"})").find("arm-1: key of 2 bytes"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"arm-2": "xyz"})").find("arm-2: not a hex"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"arm-3": 5})").find("arm-3: expected a hex string"),
            std::string::npos);
  EXPECT_NE(error_of("[1]").find("keys.json: expected a JSON object"),
            std::string::npos);
}

}  // namespace
}  // namespace frictiond
