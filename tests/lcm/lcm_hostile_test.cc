// Hostile LCM input (issue 16, docs/security_lcm.md): every malformed form
// of every message type the daemon receives (material_query_v1,
// stroke_chunk_v1, stroke_chunk_v2) — truncated, wrong fingerprint (every
// other frictiond type on the channel), string length 0 (the ~30-byte query
// that used to abort the daemon), a string without its NUL, invalid UTF-8,
// negative and huge array counts, a bad boolean, trailing bytes, an
// oversized string — is dropped, counted in frictiond_lcm_dropped_total by
// reason and answered with error_v1 naming the field; afterwards a valid
// query is still answered, and nothing was stored.
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include "frictiond/crypto/hmac.h"
#include "frictiond/crypto/lcm_signing.h"
#include "frictiond/proto/lcm_codec.h"
#include "frictiond/server/lcm_endpoint.h"
#include "frictiond/server/metrics.h"

#include "lcm_test_inbox.h"
#include "robot_simulator.h"

namespace frictiond {
namespace {

using testing::LcmInbox;

long long CounterValue(const std::string& text, const std::string& series) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(series + " ", 0) == 0)
      return std::atoll(line.c_str() + series.size() + 1);
  return -1;
}

std::string Word(std::uint32_t v) {
  std::string w(4, '\0');
  for (int k = 0; k < 4; ++k) w[k] = static_cast<char>(v >> (24 - 8 * k));
  return w;
}

// `bytes` with the 4 bytes at `at` replaced by `v`.
std::string WithWord(std::string bytes, std::size_t at, std::uint32_t v) {
  bytes.replace(at, 4, Word(v));
  return bytes;
}

// `bytes` with the string whose length word is at `at` (old length
// `old_len` incl. NUL) replaced by the raw field `field`.
std::string WithString(const std::string& bytes,
                       std::size_t at,
                       std::size_t old_len,
                       const std::string& field) {
  return bytes.substr(0, at) + field + bytes.substr(at + 4 + old_len);
}

struct Form {
  std::string name;
  std::string bytes;
  std::string reason;  // drop counter label
  std::string field;   // error_v1.field
};

// The malformed forms of one message: `first_string` is the offset of the
// length word of its first string (`first_len` bytes incl. NUL), `count_at`
// the offset of its array count, `bool_at` of a boolean (0: none).
std::vector<Form> MalformedForms(const std::string& valid,
                                 std::size_t first_string,
                                 std::size_t first_len,
                                 const std::string& string_field,
                                 std::size_t count_at,
                                 const std::string& count_field,
                                 std::size_t bool_at,
                                 const std::string& bool_field) {
  std::vector<Form> f;
  f.push_back({"empty", "", "truncated", "(fingerprint)"});
  f.push_back({"fingerprint only", valid.substr(0, 8), "truncated", ""});
  f.push_back({"half", valid.substr(0, valid.size() / 2), "truncated", ""});
  f.push_back(
      {"one byte short", valid.substr(0, valid.size() - 1), "truncated", ""});
  f.push_back({"trailing byte", valid + "x", "malformed", "(message)"});
  f.push_back({"string length 0",
               WithString(valid, first_string, first_len, Word(0)),
               "malformed",
               string_field});
  f.push_back({"negative string length",
               WithWord(valid, first_string, 0xfffffff0u),
               "malformed",
               string_field});
  f.push_back({"huge string length",
               WithWord(valid, first_string, 0x7fffffffu),
               "oversized",
               string_field});
  f.push_back({"string without NUL",
               WithString(valid, first_string, first_len, Word(2) + "ab"),
               "malformed",
               string_field});
  f.push_back({"invalid UTF-8",
               WithString(valid,
                          first_string,
                          first_len,
                          Word(3) + std::string("\xc3\x28\0", 3)),
               "malformed",
               string_field});
  f.push_back({"oversized string",
               WithString(valid,
                          first_string,
                          first_len,
                          Word(10001) + std::string(10000, 'a') + '\0'),
               "oversized",
               string_field});
  f.push_back({"negative count",
               WithWord(valid, count_at, 0xffffffffu),
               "malformed",
               count_field});
  f.push_back({"huge count",
               WithWord(valid, count_at, 0x7fffffffu),
               "oversized",
               count_field});
  f.push_back({"count past the end",
               WithWord(valid, count_at, 5000),
               "truncated",
               count_field});
  if (bool_at) {
    std::string b = valid;
    b[bool_at] = 7;
    f.push_back({"boolean 7", b, "malformed", bool_field});
  }
  return f;
}

class LcmHostileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    url_ = testing::MakeTestLcmUrl(53);
    std::string why;
    if (!testing::CheckLcmLoopback(url_, &why)) GTEST_SKIP() << why;
    library_ = std::make_unique<FrictionLibrary>(OpenStore(":memory:"));
    key_ = RandomBytes(32);
    LcmEndpointOptions o;
    o.url = url_;
    o.security.keys = {{"robot-a", key_}};
    o.security.allow_unsigned = true;
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

  long long Dropped(const std::string& reason) {
    return CounterValue(
        metrics_.Render(),
        "frictiond_lcm_dropped_total{reason=\"" + reason + "\"}");
  }

  // Publishes raw bytes; returns the error_v1 they caused.
  error_v1 Send(const char* channel, const std::string& bytes) {
    const std::size_t before = inbox_->errors.size();
    inbox_->lcm().publish(
        channel, bytes.data(), static_cast<unsigned>(bytes.size()));
    error_v1 e;
    e.field = "(no error received)";
    if (inbox_->WaitFor([&] { return inbox_->errors.size() > before; }))
      e = inbox_->errors[before];
    return e;
  }

  void ExpectAllDropped(const char* channel,
                        const char* type,
                        const std::vector<Form>& forms) {
    for (const Form& f : forms) {
      SCOPED_TRACE(std::string(type) + ": " + f.name);
      const long long before = Dropped(f.reason);
      const error_v1 e = Send(channel, f.bytes);
      EXPECT_EQ(e.message_type, type) << e.reason;
      if (!f.field.empty()) {
        EXPECT_EQ(e.field, f.field) << e.reason;
      }
      EXPECT_NE(e.reason.find(f.reason), std::string::npos) << e.reason;
      EXPECT_EQ(Dropped(f.reason), before + 1) << e.reason;
    }
  }

  // A valid query gets its reply (the endpoint still serves).
  void ExpectQueryAnswered(const std::string& id) {
    material_query_v1 q{};
    q.request_id = id;
    q.robot = "robot-a";
    q.material = "hostile-check";
    q.fingertip = "";
    q.image_size = 0;
    inbox_->lcm().publish(kLcmQueryChannel, &q);
    EXPECT_TRUE(inbox_->WaitFor([&] {
      for (const auto& r : inbox_->replies)
        if (r.request_id == id) return true;
      return false;
    })) << "no reply to "
        << id;
  }

  std::string url_;
  std::string key_;
  Metrics metrics_;
  std::unique_ptr<FrictionLibrary> library_;
  std::unique_ptr<LcmEndpoint> endpoint_;
  std::unique_ptr<LcmInbox> inbox_;
};

material_query_v1 ValidQuery() {
  material_query_v1 q{};
  q.utime = 1;
  q.request_id = "req-1";  // 6 bytes incl. NUL, length word at 16
  q.robot = "robot-a";
  q.material = "ptfe";
  q.fingertip = "";
  q.image = {1, 2, 3};
  q.image_size = 3;
  return q;
}

template <class Chunk>
Chunk ValidChunk() {
  Chunk c{};
  c.utime = 1;
  c.job_id = 1;
  c.stroke = 0;
  c.robot = "robot-a";  // 8 bytes incl. NUL
  c.material = "ptfe";
  c.fingertip = "default";
  c.seq = 0;
  c.total_chunks = 1;
  c.last = true;
  c.n_samples = 2;
  c.t_s = {0, 0.01};
  c.fn_n = {1, 1};
  c.ft_n = {0.2, 0.2};
  c.v_mm_s = {1, 1};
  return c;
}

// A flood the endpoint cannot read in time overflows its socket's receive
// buffer; the kernel drops datagrams, which LCM does not report. They are
// counted (udp_drops.h) and the endpoint serves on.
TEST_F(LcmHostileTest, DatagramsTheKernelDroppedAreCounted) {
  EXPECT_EQ(Dropped("receive_buffer_full"), 0);
  endpoint_->Stop();  // its socket stays open, and nobody reads it
  const std::string junk(1000, 'x');
  for (int i = 0; i < 5000; ++i)
    inbox_->lcm().publish(
        "FRICTIOND_FLOOD", junk.data(), static_cast<unsigned>(junk.size()));
  endpoint_->Start();
  // Counted at most a second after the endpoint runs again.
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (Dropped("receive_buffer_full") == 0 &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const long long dropped = Dropped("receive_buffer_full");
  EXPECT_GT(dropped, 0);
  EXPECT_LT(dropped, 5000);  // the buffer held some
  ExpectQueryAnswered("after-flood");
}

// The issue's ~30-byte query: fingerprint, utime, request_id of length 0.
TEST_F(LcmHostileTest, ThirtyByteQueryWithZeroLengthStringIsDropped) {
  const std::string valid = EncodeLcm(ValidQuery());
  const std::string attack =
      valid.substr(0, 16) + Word(0) + std::string(10, 'A');
  const error_v1 e = Send(kLcmQueryChannel, attack);
  EXPECT_EQ(e.field, "request_id") << e.reason;
  EXPECT_EQ(Dropped("malformed"), 1);
  // Twice: the second one used to hit liblcm's assertion and abort.
  EXPECT_EQ(Send(kLcmQueryChannel, attack).field, "request_id");
  ExpectQueryAnswered("after-attack");
}

TEST_F(LcmHostileTest, EveryMalformedQueryIsDroppedThenAValidOneIsAnswered) {
  const std::string valid = EncodeLcm(ValidQuery());
  const std::size_t image_size_at = valid.size() - 3 - 4;
  ExpectAllDropped(
      kLcmQueryChannel,
      "material_query_v1",
      MalformedForms(
          valid, 16, 6, "request_id", image_size_at, "image_size", 0, ""));
  ExpectQueryAnswered("after-malformed-queries");
}

TEST_F(LcmHostileTest, EveryMalformedChunkIsDroppedThenAQueryIsAnswered) {
  const std::string v1 = EncodeLcm(ValidChunk<stroke_chunk_v1>());
  const std::size_t v1_count = v1.size() - 4 * 2 * 8 - 4;
  ExpectAllDropped(
      kLcmStrokeChannel,
      "stroke_chunk_v1",
      MalformedForms(
          v1, 28, 8, "robot", v1_count, "n_samples", v1_count - 1, "last"));
  stroke_chunk_v2 c2 = ValidChunk<stroke_chunk_v2>();
  SignLcmMessage(&c2, key_);
  const std::string v2 = EncodeLcm(c2);
  const std::size_t v2_count = v2.size() - 4 * 2 * 8 - 4;
  ExpectAllDropped(
      kLcmSignedStrokeChannel,
      "stroke_chunk_v2",
      MalformedForms(
          v2, 76, 8, "robot", v2_count, "n_samples", v2_count - 1, "last"));
  ExpectQueryAnswered("after-malformed-chunks");
  // Nothing of them reached the store.
  EXPECT_TRUE(library_->store().ListJobs(false).size() <= 1u);
  EXPECT_TRUE(library_->store().ListStrokes("ptfe", "default").empty());
}

// Every other frictiond type on each receiving channel: wrong fingerprint.
TEST_F(LcmHostileTest, OtherTypesOnAChannelAreWrongHash) {
  model_update_v1 u{};
  u.reason = "x";
  u.model.n_terms = u.model.n_quantiles = 0;
  error_v1 err{};
  coverage_progress_v1 p{};
  p.n_missing = 0;
  identification_request_v1 r1{};
  identification_request_v2 r2{};
  material_reply_v1 reply{};
  reply.model.n_terms = reply.model.n_quantiles = 0;
  signed_message_v1 s{};
  s.payload_size = 0;
  const std::vector<std::pair<const char*, std::string>> others = {
      {"model_update_v1", EncodeLcm(u)},
      {"error_v1", EncodeLcm(err)},
      {"coverage_progress_v1", EncodeLcm(p)},
      {"identification_request_v1", EncodeLcm(r1)},
      {"identification_request_v2", EncodeLcm(r2)},
      {"material_reply_v1", EncodeLcm(reply)},
      {"signed_message_v1", EncodeLcm(s)},
      {"stroke_chunk_v1", EncodeLcm(ValidChunk<stroke_chunk_v1>())},
      {"material_query_v1", EncodeLcm(ValidQuery())}};
  long long expected = 0;
  for (const auto& [channel, type] :
       std::vector<std::pair<const char*, const char*>>{
           {kLcmQueryChannel, "material_query_v1"},
           {kLcmStrokeChannel, "stroke_chunk_v1"},
           {kLcmSignedStrokeChannel, "stroke_chunk_v2"}}) {
    for (const auto& [name, bytes] : others) {
      if (std::string(name) == type) continue;
      SCOPED_TRACE(std::string(name) + " on " + channel);
      const error_v1 e = Send(channel, bytes);
      EXPECT_EQ(e.field, "(fingerprint)") << e.reason;
      EXPECT_EQ(Dropped("wrong_hash"), ++expected);
    }
  }
  ExpectQueryAnswered("after-wrong-types");
}

// The store fails inside a handler (another process holds the SQLite
// database's write lock, as a PostgreSQL outage would fail every write): the
// query is answered with STATUS_ERROR, counted as "internal", and once the
// store is back the next query is answered normally.
TEST(LcmStoreOutageTest, StoreErrorInAHandlerIsAnsweredAndTheEndpointServesOn) {
  const std::string url = testing::MakeTestLcmUrl(59);
  std::string why;
  if (!testing::CheckLcmLoopback(url, &why)) GTEST_SKIP() << why;
  const std::filesystem::path db =
      std::filesystem::temp_directory_path() /
      ("frictiond_lcm_outage_" + std::to_string(::getpid()) + ".db");
  std::filesystem::remove(db);
  Metrics metrics;
  {
    FrictionLibrary library(OpenStore(db.string()));
    LcmEndpointOptions o;
    o.url = url;
    o.security.send_unsigned = true;
    o.metrics = &metrics;
    LcmEndpoint endpoint(library, o);
    endpoint.Start();
    LcmInbox inbox(url);
    ASSERT_TRUE(inbox.good());
    // Take the write lock from another connection.
    sqlite3* other = nullptr;
    ASSERT_EQ(sqlite3_open(db.string().c_str(), &other), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(other, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr),
              SQLITE_OK);
    auto query = [&](const std::string& id, const std::string& material) {
      material_query_v1 q{};
      q.request_id = id;
      q.robot = "robot-a";
      q.material = material;
      q.fingertip = "";
      q.image_size = 0;
      inbox.lcm().publish(kLcmQueryChannel, &q);
      material_reply_v1 out{};
      out.status = -1;
      inbox.WaitFor(
          [&] {
            for (const auto& r : inbox.replies)
              if (r.request_id == id) {
                out = r;
                return true;
              }
            return false;
          },
          20.0);
      return out;
    };
    const material_reply_v1 during = query("during-outage", "cork");
    EXPECT_EQ(during.status, +material_reply_v1::STATUS_ERROR) << during.reason;
    EXPECT_FALSE(during.reason.empty());
    sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr);
    sqlite3_close(other);
    const material_reply_v1 after = query("after-outage", "cork");
    EXPECT_EQ(after.status, +material_reply_v1::STATUS_UNKNOWN) << after.reason;
    endpoint.Stop();
  }
  std::filesystem::remove(db);
  std::filesystem::remove(db.string() + "-wal");
  std::filesystem::remove(db.string() + "-shm");
}

}  // namespace
}  // namespace frictiond
