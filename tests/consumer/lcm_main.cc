// Consumer of the installed package, LCM component: a robot verifying the
// daemon's signed messages with frictiond::lcm_codec (LcmSignedReceiver),
// the way its LCM handler would. No socket: the daemon's side is played by
// SignLcmPayload with the same key.
#include <cstdio>
#include <string>

#include "frictiond/error_v1.hpp"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lcm_codec.h"
#include "frictiond/proto/lcm_signed.h"

namespace {

// The bytes the robot's LCM handler gets on "<channel>_SIGNED".
template <class Message>
std::string SignedBytes(const Message& m,
                        const char* channel,
                        const std::string& key_id,
                        const std::string& key) {
  return frictiond::EncodeLcm(
      frictiond::SignLcmPayload(frictiond::EncodeLcm(m), channel, key_id, key));
}

int failures = 0;
void Check(bool ok, const char* what) {
  if (!ok) {
    std::printf("FAILED: %s\n", what);
    ++failures;
  }
}

}  // namespace

int main() {
  const std::string key(32, '\x5a');
  frictiond::LcmSignedReceiver rx({{"arm-7", key}});

  frictiond::material_reply_v1 reply{};
  reply.request_id = "q-1";
  reply.robot = "arm-7";
  reply.material = "felt";
  reply.fingertip = "default";
  reply.status = frictiond::material_reply_v1::STATUS_KNOWN;
  reply.model.material = "felt";
  reply.model.version = 3;
  const std::string bytes =
      SignedBytes(reply, frictiond::kLcmReplyChannel, "arm-7", key);

  frictiond::material_reply_v1 got;
  auto v =
      rx.Open(bytes.data(), bytes.size(), frictiond::kLcmReplyChannel, &got);
  Check(v.ok() && got.request_id == "q-1" && got.model.version == 3,
        "a signed reply verifies and decodes");
  v = rx.Open(bytes.data(), bytes.size(), frictiond::kLcmReplyChannel, &got);
  Check(v.failure == frictiond::LcmVerifyFailure::kReplayed,
        "the same message again is a replay");

  std::string forged =
      SignedBytes(reply, frictiond::kLcmReplyChannel, "arm-7", key);
  forged[forged.size() - 1] ^= 1;  // a payload byte
  v = rx.Open(forged.data(), forged.size(), frictiond::kLcmReplyChannel, &got);
  Check(v.failure == frictiond::LcmVerifyFailure::kForged,
        "a changed byte is a forgery");

  const std::string other_key(32, '\x11');
  const std::string wrong =
      SignedBytes(reply, frictiond::kLcmReplyChannel, "arm-7", other_key);
  v = rx.Open(wrong.data(), wrong.size(), frictiond::kLcmReplyChannel, &got);
  Check(v.failure == frictiond::LcmVerifyFailure::kForged,
        "another key's MAC is a forgery");

  // Errors are signed too (FRICTIOND_ERROR_V1_SIGNED).
  frictiond::error_v1 e{};
  e.message_type = "stroke_chunk_v2";
  e.robot = "arm-7";
  e.field = "seq";
  e.reason = "seq = 9 (total_chunks = 4)";
  const std::string err =
      SignedBytes(e, frictiond::kLcmErrorChannel, "arm-7", key);
  frictiond::error_v1 got_e;
  v = rx.Open(err.data(), err.size(), frictiond::kLcmErrorChannel, &got_e);
  Check(v.ok() && got_e.field == "seq", "a signed error verifies");
  v = rx.Open(err.data(), err.size(), frictiond::kLcmReplyChannel, &got);
  Check(!v.ok(), "an error cannot pass as a reply");

  std::printf("lcm_codec consumer: %d failure(s)\n", failures);
  return failures == 0 ? 0 : 1;
}
