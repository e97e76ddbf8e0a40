// The bounds-checked LCM decoders (lcm_codec.h): each malformed form for
// every message type is rejected with the right reason and field, valid
// messages decode to what was encoded.
#include "frictiond/proto/lcm_codec.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

friction_model_v1 SampleModel() {
  friction_model_v1 m;
  m.material = "ptfe";
  m.fingertip = "default";
  m.version = 3;
  m.created_at = "2026-11-24T07:00:00Z";
  m.n_terms = 2;
  m.term_names = {"intercept", "v_mm_s"};
  m.coefficients = {0.2, 0.001};
  m.std_errors = {0.01, 0.0001};
  m.sigma_eps = 0.02;
  m.r2 = 0.9;
  m.samples = 1000;
  m.n_quantiles = 3;
  m.eps_levels = {0.05, 0.5, 0.95};
  m.eps_quantiles = {-0.03, 0, 0.03};
  m.mu_coulomb = 0.21;
  m.likelihood_c1 = 12;
  m.likelihood_c2 = 0.2;
  m.has_lugre = true;
  for (int i = 0; i < 6; ++i) m.lugre_theta[i] = 0.1 * (i + 1);
  return m;
}

template <class Message>
Message Sample();

template <>
material_query_v1 Sample() {
  material_query_v1 q{};
  q.utime = 1;
  q.request_id = "req-1";
  q.robot = "arm-7";
  q.material = "ptfe";
  q.fingertip = "";
  q.image_size = 3;
  q.image = {1, 2, 3};
  return q;
}
template <>
material_reply_v1 Sample() {
  material_reply_v1 r{};
  r.utime = 2;
  r.request_id = "req-1";
  r.robot = "arm-7";
  r.material = "ptfe";
  r.fingertip = "default";
  r.status = material_reply_v1::STATUS_KNOWN;
  r.reason = "";
  r.job_id = 0;
  r.recognition_score = 0;
  r.model = SampleModel();
  return r;
}
template <>
material_reply_v2 Sample() {
  LcmRecognition recognition;
  recognition.unknown = true;
  recognition.reason =
      "closest is ptfe at 0.62, below the 0.74 operating point";
  recognition.operating_point = 0.74;
  recognition.candidates = {{"ptfe", 0.62}, {"felt", 0.05}};
  material_reply_v1 v1 = Sample<material_reply_v1>();
  v1.status = material_reply_v1::STATUS_UNKNOWN;
  v1.reason = "no model";
  v1.job_id = 5;
  return MakeMaterialReplyV2(v1, &recognition);
}
template <class Request>
Request SampleRequest() {
  Request r{};
  r.utime = 3;
  r.job_id = 11;
  r.stroke = 0;
  r.request_id = "req-1";
  r.robot = "arm-7";
  r.material = "cork";
  r.fingertip = "default";
  r.fn_min_n = 1;
  r.fn_max_n = 5;
  r.v_min_mm_s = 2;
  r.v_max_mm_s = 40;
  r.max_duration_s = 120;
  r.min_span_pct = 50;
  r.follow_up = false;
  r.instructions = "slide";
  return r;
}
template <>
identification_request_v1 Sample() {
  return SampleRequest<identification_request_v1>();
}
template <>
identification_request_v2 Sample() {
  auto r = SampleRequest<identification_request_v2>();
  r.lugre_pair = true;
  r.lugre_fn_n = 3;
  r.lugre_slow_accel_mm_s2 = 2;
  r.lugre_slow_peak_mm_s = 4;
  r.lugre_fast_strokes = 3;
  r.lugre_fast_accel_mm_s2 = 50;
  r.lugre_fast_peak_mm_s = 30;
  r.lugre_rest_s = 0.5;
  return r;
}
template <class Chunk>
Chunk SampleChunk() {
  Chunk c{};
  c.utime = 4;
  c.job_id = 11;
  c.stroke = 0;
  c.robot = "arm-7";
  c.material = "cork";
  c.fingertip = "default";
  c.seq = 0;
  c.total_chunks = 1;
  c.last = true;
  c.n_samples = 2;
  c.t_s = {0, 0.01};
  c.fn_n = {2, 2};
  c.ft_n = {0.5, 0.6};
  c.v_mm_s = {0, 1};
  return c;
}
template <>
stroke_chunk_v1 Sample() {
  return SampleChunk<stroke_chunk_v1>();
}
template <>
stroke_chunk_v2 Sample() {
  auto c = SampleChunk<stroke_chunk_v2>();
  for (int i = 0; i < 16; ++i) c.nonce[i] = static_cast<std::uint8_t>(i);
  for (int i = 0; i < 32; ++i) c.hmac[i] = static_cast<std::uint8_t>(i * 7);
  return c;
}
template <>
coverage_progress_v1 Sample() {
  coverage_progress_v1 p{};
  p.utime = 5;
  p.job_id = 11;
  p.stroke = 0;
  p.material = "cork";
  p.fingertip = "default";
  p.robot = "arm-7";
  p.state = "stroking";
  p.chunks_received = 2;
  p.chunks_expected = 4;
  p.n_missing = 2;
  p.missing_seqs = {1, 3};
  p.samples = 200;
  p.span_pct = -1;
  p.min_span_pct = 50;
  p.model_version = 0;
  p.detail = "resend";
  return p;
}
template <>
model_update_v1 Sample() {
  model_update_v1 u{};
  u.utime = 6;
  u.job_id = 0;
  u.reason = "upload";
  u.model = SampleModel();
  return u;
}
template <>
error_v1 Sample() {
  error_v1 e{};
  e.utime = 7;
  e.message_type = "material_query_v1";
  e.request_id = "req-1";
  e.robot = "arm-7";
  e.job_id = 0;
  e.stroke = 0;
  e.seq = -1;
  e.field = "robot";
  e.reason = "robot: too long";
  return e;
}
template <>
signed_message_v1 Sample() {
  signed_message_v1 s{};
  s.utime = 8;
  for (int i = 0; i < 16; ++i) s.nonce[i] = static_cast<std::uint8_t>(i);
  s.key_id = "arm-7";
  s.channel = "FRICTIOND_REPLY_V1";
  const std::string payload = EncodeLcm(Sample<material_reply_v1>());
  s.payload_size = static_cast<int32_t>(payload.size());
  s.payload.assign(payload.begin(), payload.end());
  return s;
}

template <class T>
class LcmCodecTest : public ::testing::Test {};
using MessageTypes = ::testing::Types<material_query_v1,
                                      material_reply_v1,
                                      material_reply_v2,
                                      identification_request_v1,
                                      identification_request_v2,
                                      stroke_chunk_v1,
                                      stroke_chunk_v2,
                                      coverage_progress_v1,
                                      model_update_v1,
                                      error_v1,
                                      signed_message_v1>;
TYPED_TEST_SUITE(LcmCodecTest, MessageTypes);

template <class Message>
LcmDecodeResult DecodeBytes(const std::string& bytes, Message* out) {
  return DecodeLcm(bytes.data(), bytes.size(), out);
}

TYPED_TEST(LcmCodecTest, ValidMessageRoundTrips) {
  const std::string bytes = EncodeLcm(Sample<TypeParam>());
  TypeParam m;
  const LcmDecodeResult r = DecodeBytes(bytes, &m);
  ASSERT_TRUE(r.ok()) << r.detail;
  EXPECT_EQ(EncodeLcm(m), bytes);
}

TYPED_TEST(LcmCodecTest, EveryTruncationIsRejected) {
  const std::string bytes = EncodeLcm(Sample<TypeParam>());
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    TypeParam m;
    const LcmDecodeResult r = DecodeBytes(bytes.substr(0, n), &m);
    ASSERT_FALSE(r.ok()) << n;
    EXPECT_EQ(r.failure, LcmDecodeFailure::kTruncated) << n << ": " << r.detail;
    EXPECT_FALSE(r.field.empty());
  }
  TypeParam m;
  EXPECT_EQ(DecodeLcm(nullptr, 0, &m).failure, LcmDecodeFailure::kTruncated);
}

TYPED_TEST(LcmCodecTest, WrongFingerprintIsRejected) {
  std::string bytes = EncodeLcm(Sample<TypeParam>());
  bytes[3] ^= 0x10;
  TypeParam m;
  const LcmDecodeResult r = DecodeBytes(bytes, &m);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kWrongHash) << r.detail;
  EXPECT_EQ(r.field, "(fingerprint)");
}

TYPED_TEST(LcmCodecTest, TrailingBytesAreRejected) {
  const std::string bytes = EncodeLcm(Sample<TypeParam>()) + "x";
  TypeParam m;
  const LcmDecodeResult r = DecodeBytes(bytes, &m);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kMalformed) << r.detail;
  EXPECT_EQ(r.field, "(message)");
}

TYPED_TEST(LcmCodecTest, OversizedMessageIsRejected) {
  const std::string bytes = EncodeLcm(Sample<TypeParam>());
  LcmDecodeLimits limits;
  limits.max_message_bytes = bytes.size() - 1;
  TypeParam m;
  const LcmDecodeResult r = DecodeLcm(bytes.data(), bytes.size(), &m, limits);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kOversized) << r.detail;
}

// Every 4-byte big-endian word that is a string length or an array count in
// the sample is set to 0, -1, a huge value and 0x7fffffff in turn (and every
// byte of every field to 0xff): the decoder must fail with a reason or
// decode, never crash or allocate beyond the buffer (ASan runs this).
TYPED_TEST(LcmCodecTest, CorruptedWordsNeverCrash) {
  const std::string bytes = EncodeLcm(Sample<TypeParam>());
  int rejected = 0;
  for (std::size_t at = 8; at + 4 <= bytes.size(); ++at) {
    for (std::uint32_t v : {0u, 0xffffffffu, 0x7fffffffu, 0x10000000u}) {
      std::string b = bytes;
      for (int k = 0; k < 4; ++k)
        b[at + k] = static_cast<char>((v >> (24 - 8 * k)) & 0xff);
      TypeParam m;
      const LcmDecodeResult r = DecodeBytes(b, &m);
      if (!r.ok()) {
        ++rejected;
        EXPECT_FALSE(r.field.empty());
        EXPECT_NE(r.detail.find(r.field), std::string::npos) << r.detail;
      }
    }
  }
  EXPECT_GT(rejected, 0);
}

// The forms the issue names, on a query: the ~30-byte query whose string
// length is 0 (threw inside liblcm with lcm-gen's decoder), a negative and a
// huge array count, invalid UTF-8, a NUL inside a string.
std::string QueryWith(const std::string& request_id_field) {
  std::string b = EncodeLcm(Sample<material_query_v1>());
  // Replace request_id (length 6 incl. NUL, at offset 16) with raw bytes.
  return b.substr(0, 16) + request_id_field + b.substr(16 + 4 + 6);
}

TEST(LcmCodecQuery, ZeroStringLengthIsMalformed) {
  material_query_v1 q;
  const LcmDecodeResult r =
      DecodeBytes(QueryWith(std::string("\0\0\0\0", 4)), &q);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kMalformed);
  EXPECT_EQ(r.field, "request_id");
  EXPECT_NE(r.detail.find("string length 0"), std::string::npos) << r.detail;
}

TEST(LcmCodecQuery, StringWithoutNulIsMalformed) {
  material_query_v1 q;
  const LcmDecodeResult r =
      DecodeBytes(QueryWith(std::string("\0\0\0\3abc", 7)), &q);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kMalformed);
  EXPECT_EQ(r.field, "request_id");
}

TEST(LcmCodecQuery, NulInsideStringIsMalformed) {
  material_query_v1 q;
  const LcmDecodeResult r =
      DecodeBytes(QueryWith(std::string("\0\0\0\4a\0b\0", 8)), &q);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kMalformed);
  EXPECT_NE(r.detail.find("NUL"), std::string::npos);
}

TEST(LcmCodecQuery, InvalidUtf8IsMalformed) {
  for (const std::string& bad : {std::string("\xc3", 1),
                                 std::string("\xc0\xaf", 2),
                                 std::string("\xed\xa0\x80", 3),
                                 std::string("\xf4\x90\x80\x80", 4)}) {
    std::string field(4, '\0');
    field[3] = static_cast<char>(bad.size() + 1);
    material_query_v1 q;
    const LcmDecodeResult r = DecodeBytes(QueryWith(field + bad + '\0'), &q);
    EXPECT_EQ(r.failure, LcmDecodeFailure::kMalformed);
    EXPECT_NE(r.detail.find("UTF-8"), std::string::npos) << r.detail;
  }
  std::string field(4, '\0');
  field[3] = 3;
  material_query_v1 q;
  EXPECT_TRUE(DecodeBytes(QueryWith(field + "\xc3\xa9" + '\0'), &q).ok());
  EXPECT_EQ(q.request_id, "\xc3\xa9");
}

TEST(LcmCodecQuery, LongStringIsOversized) {
  const std::string big(5000, 'a');
  std::string field(4, '\0');
  const std::uint32_t n = 5001;
  for (int k = 0; k < 4; ++k) field[k] = static_cast<char>(n >> (24 - 8 * k));
  material_query_v1 q;
  const LcmDecodeResult r = DecodeBytes(QueryWith(field + big + '\0'), &q);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kOversized);
  EXPECT_EQ(r.field, "request_id");
}

TEST(LcmCodecQuery, ArrayCountsAreCheckedBeforeAllocating) {
  material_query_v1 s = Sample<material_query_v1>();
  std::string b = EncodeLcm(s);
  const std::size_t at = b.size() - 3 - 4;  // image_size
  auto with_count = [&](std::uint32_t v) {
    std::string c = b;
    for (int k = 0; k < 4; ++k)
      c[at + k] = static_cast<char>(v >> (24 - 8 * k));
    material_query_v1 q;
    return DecodeBytes(c, &q);
  };
  EXPECT_EQ(with_count(0xffffffffu).failure, LcmDecodeFailure::kMalformed);
  EXPECT_EQ(with_count(0xffffffffu).field, "image_size");
  EXPECT_EQ(with_count(0x7fffffffu).failure, LcmDecodeFailure::kOversized);
  EXPECT_EQ(with_count(1000).failure, LcmDecodeFailure::kTruncated);
  EXPECT_EQ(with_count(2).failure, LcmDecodeFailure::kMalformed);  // trailing
  EXPECT_TRUE(with_count(3).ok());
}

TEST(LcmCodecChunk, SampleCountOverLimitIsOversizedAndNamesTheSender) {
  stroke_chunk_v1 c = Sample<stroke_chunk_v1>();
  LcmDecodeLimits limits;
  limits.max_samples = 1;
  const std::string b = EncodeLcm(c);
  stroke_chunk_v1 m;
  const LcmDecodeResult r = DecodeLcm(b.data(), b.size(), &m, limits);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kOversized);
  EXPECT_EQ(r.field, "n_samples");
  EXPECT_EQ(m.robot, "arm-7");  // decoded before the failure
  EXPECT_EQ(m.job_id, 11);
}

TEST(LcmCodecChunk, BooleanOtherThanZeroOrOneIsMalformed) {
  stroke_chunk_v1 c = Sample<stroke_chunk_v1>();
  std::string b = EncodeLcm(c);
  // `last` is the byte before n_samples (4 bytes) and 4 arrays of 2 doubles.
  const std::size_t at = b.size() - 4 * 2 * 8 - 4 - 1;
  ASSERT_EQ(b[at], 1);
  b[at] = 2;
  stroke_chunk_v1 m;
  const LcmDecodeResult r = DecodeBytes(b, &m);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kMalformed);
  EXPECT_EQ(r.field, "last");
}

TEST(LcmCodecReplyV2, CarriesTheRecognitionBesideV1sFields) {
  const material_reply_v2 m = Sample<material_reply_v2>();
  EXPECT_EQ(m.request_id, "req-1");
  EXPECT_EQ(m.status, +material_reply_v2::STATUS_UNKNOWN);
  EXPECT_EQ(m.job_id, 5);
  EXPECT_TRUE(m.recognition_unknown);
  EXPECT_EQ(m.recognition_reason,
            "closest is ptfe at 0.62, below the 0.74 operating point");
  EXPECT_DOUBLE_EQ(m.recognition_operating_point, 0.74);
  ASSERT_EQ(m.n_candidates, 2);
  EXPECT_EQ(m.candidate_material[1], "felt");
  EXPECT_DOUBLE_EQ(m.candidate_score[0], 0.62);
  // Without an image: unknown, no reason, no candidates.
  const material_reply_v2 none =
      MakeMaterialReplyV2(Sample<material_reply_v1>(), nullptr);
  EXPECT_TRUE(none.recognition_unknown);
  EXPECT_EQ(none.n_candidates, 0);
  EXPECT_EQ(none.model.n_terms, Sample<material_reply_v1>().model.n_terms);
  // The candidate list is capped.
  LcmRecognition many;
  many.candidates.assign(100, {"x", 0.1});
  EXPECT_EQ(
      MakeMaterialReplyV2(Sample<material_reply_v1>(), &many, 64).n_candidates,
      64);
}

TEST(LcmCodecReplyV2, CandidateCountIsCheckedBeforeAllocating) {
  material_reply_v2 m = Sample<material_reply_v2>();
  LcmDecodeLimits limits;
  limits.max_candidates = 1;
  const std::string bytes = EncodeLcm(m);
  material_reply_v2 out;
  LcmDecodeResult r = DecodeLcm(bytes.data(), bytes.size(), &out, limits);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kOversized);
  EXPECT_EQ(r.field, "n_candidates");
  EXPECT_NE(r.detail.find("at most 1"), std::string::npos) << r.detail;
  // A count that the bytes left cannot hold: truncated, nothing allocated.
  m.n_candidates = 0;
  m.candidate_material.clear();
  m.candidate_score.clear();
  std::string b = EncodeLcm(m);
  // n_candidates is the last 4 bytes of a message without candidates.
  b[b.size() - 4] = 0x00;
  b[b.size() - 3] = 0x00;
  b[b.size() - 2] = 0x00;
  b[b.size() - 1] = 0x30;  // 48 candidates, 0 bytes left
  r = DecodeLcm(b.data(), b.size(), &out);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kTruncated);
  EXPECT_EQ(r.field, "n_candidates");
  b[b.size() - 4] = static_cast<char>(0xFF);  // negative
  r = DecodeLcm(b.data(), b.size(), &out);
  EXPECT_EQ(r.failure, LcmDecodeFailure::kMalformed);
  EXPECT_EQ(r.field, "n_candidates");
}

// Writes the seed corpus of lcm_codec_fuzzer (one file per type: the type
// byte, then the sample) when FRICTIOND_WRITE_LCM_SEEDS names a directory.
template <class Message>
void WriteSeed(const std::string& dir, int type, const char* name) {
  std::ofstream f(dir + "/" + name + ".bin", std::ios::binary);
  f << static_cast<char>(type) << EncodeLcm(Sample<Message>());
}
TEST(LcmCodecSeeds, WriteWhenAsked) {
  const char* dir = std::getenv("FRICTIOND_WRITE_LCM_SEEDS");
  if (!dir) GTEST_SKIP() << "FRICTIOND_WRITE_LCM_SEEDS not set";
  WriteSeed<material_query_v1>(dir, 0, "material_query_v1");
  WriteSeed<material_reply_v1>(dir, 1, "material_reply_v1");
  WriteSeed<identification_request_v1>(dir, 2, "identification_request_v1");
  WriteSeed<identification_request_v2>(dir, 3, "identification_request_v2");
  WriteSeed<stroke_chunk_v1>(dir, 4, "stroke_chunk_v1");
  WriteSeed<stroke_chunk_v2>(dir, 5, "stroke_chunk_v2");
  WriteSeed<coverage_progress_v1>(dir, 6, "coverage_progress_v1");
  WriteSeed<model_update_v1>(dir, 7, "model_update_v1");
  WriteSeed<error_v1>(dir, 8, "error_v1");
  WriteSeed<signed_message_v1>(dir, 9, "signed_message_v1");
  WriteSeed<material_reply_v2>(dir, 10, "material_reply_v2");
}

}  // namespace
}  // namespace frictiond
