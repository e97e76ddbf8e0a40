#pragma once
/// @file
/// Signed messages from the daemon to robots (docs/lcm.md "Signed messages
/// to robots", docs/security_lcm.md): material_reply_v1,
/// identification_request_v1/_v2, coverage_progress_v1, model_update_v1
/// and error_v1 wrapped in signed_message_v1 on "<channel>_SIGNED":
///
///   hmac = HMAC-SHA256(key of key_id, LCM encoding of the signed_message_v1
///                      with every hmac byte 0)
///
/// key_id is the robot whose key signed (the same per-robot key the robot
/// signs its stroke chunks with) or "fleet" (a key every robot holds). The
/// payload is the inner message's LCM encoding; `channel` names the
/// unsigned channel, so a signed message cannot be replayed on another
/// channel. A receiver (LcmSignedReceiver) checks the key, the MAC
/// (constant time), the channel, the timestamp window and a nonce replay
/// cache, then decodes the payload with the bounds-checked codec.
///
/// @code
///   // robot side
///   frictiond::LcmSignedReceiver rx({{"arm-7", key}});
///   frictiond::material_reply_v1 reply;
///   const auto v = rx.Open(rbuf->data, rbuf->data_size,
///                          frictiond::kLcmReplyChannel, &reply);
///   if (!v.ok()) return;  // forged, stale, replayed, malformed: dropped
/// @endcode

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <string>

#include "frictiond/crypto/lcm_signing.h"
#include "frictiond/proto/lcm_codec.h"

namespace frictiond {

/// key_id of the fleet key.
inline constexpr const char* kLcmFleetKeyId = "fleet";

/// The signed channel of an unsigned one: "<channel>_SIGNED".
std::string LcmSignedChannel(const std::string& channel);

/// Wraps the LCM encoding of `payload_bytes` (a message meant for
/// `channel`) into a signed_message_v1 signed with `key` under `key_id`:
/// utime = `utime_us`, a fresh random nonce, the MAC.
signed_message_v1 SignLcmPayload(const std::string& payload_bytes,
                                 const std::string& channel,
                                 const std::string& key_id,
                                 const std::string& key,
                                 std::int64_t utime_us = LcmSigningNowUs());

/// Why a signed message was not accepted.
enum class LcmVerifyFailure {
  kNone,
  kUndecodable,   ///< the wrapper or the payload does not decode
  kUnknownKey,    ///< no key for key_id
  kForged,        ///< the MAC does not verify
  kWrongChannel,  ///< signed for another channel
  kStale,         ///< utime outside the window
  kReplayed,      ///< nonce seen before
  kNotForMe,      ///< signed for another robot (key_id not ours)
};

/// "undecodable", "unknown_key", "forged", "wrong_channel", "stale",
/// "replayed", "not_for_me"; "" for kNone.
const char* LcmVerifyFailureName(LcmVerifyFailure f);

struct LcmVerifyResult {
  LcmVerifyFailure failure = LcmVerifyFailure::kNone;
  std::string detail;
  std::string key_id;  ///< of the accepted message
  bool ok() const { return failure == LcmVerifyFailure::kNone; }
};

/// Verifies signed messages from the daemon. Thread-safe.
class LcmSignedReceiver {
 public:
  /// `keys`: key_id -> raw key (the robot's own id and key, and "fleet"
  /// when the fleet key is used). Messages signed under another key_id are
  /// "not for me" (a copy for another robot), not forgeries.
  explicit LcmSignedReceiver(std::map<std::string, std::string> keys,
                             double max_skew_s = 30.0,
                             std::size_t replay_cache = 4096);

  /// Checks a received signed_message_v1 (raw bytes) that arrived on
  /// LcmSignedChannel(`channel`) and decodes its payload into *out.
  template <class Message>
  LcmVerifyResult Open(const void* data,
                       std::size_t size,
                       const std::string& channel,
                       Message* out,
                       std::int64_t now_us = LcmSigningNowUs()) {
    std::string payload;
    LcmVerifyResult v = Verify(data, size, channel, now_us, &payload);
    if (!v.ok()) return v;
    const LcmDecodeResult r = DecodeLcm(payload.data(), payload.size(), out);
    if (!r.ok()) {
      v.failure = LcmVerifyFailure::kUndecodable;
      v.detail = "payload: " + r.detail;
    }
    return v;
  }

  /// The checks without decoding the payload; *payload gets its bytes.
  LcmVerifyResult Verify(const void* data,
                         std::size_t size,
                         const std::string& channel,
                         std::int64_t now_us,
                         std::string* payload);

 private:
  std::map<std::string, std::string> keys_;
  double max_skew_s_;
  std::size_t replay_cache_;
  std::mutex mu_;
  std::set<std::string> seen_;
  std::deque<std::string> order_;
};

}  // namespace frictiond
