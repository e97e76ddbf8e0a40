#pragma once
/// @file
/// Checks of signed LCM writes (docs/lcm.md "Signed writes"): the robot's
/// key, the HMAC-SHA256 (constant-time compare), the timestamp window and a
/// bounded replay cache of nonces. No LCM dependency: the caller passes the
/// MAC the message should carry (computed with the robot's key) and the one
/// it carries.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <unordered_set>

namespace frictiond {

/// Security settings of the LCM endpoint.
struct LcmSecurityOptions {
  /// Robot id -> raw key bytes (at least 16). Robots not listed cannot
  /// write.
  std::map<std::string, std::string> keys;
  /// Accept unsigned stroke_chunk_v1 on FRICTIOND_STROKE_V1 (off by
  /// default: unsigned writes are dropped and counted as "unsigned").
  bool allow_unsigned = false;
  /// Also publish the unsigned forms of the messages to robots (replies,
  /// identification requests, progress, model updates). Off: they go only
  /// signed (signed_message_v1 on "<channel>_SIGNED", lcm_signed.h), with
  /// the robot's key, or for a robot without a key and for model updates
  /// with every robot key and the fleet key (the keys entry "fleet").
  /// Risk when on: anyone on the group can forge them.
  bool send_unsigned = false;
  /// Largest |daemon clock - message utime| accepted [s].
  double max_skew_s = 30.0;
  /// Nonces remembered per robot (bounds memory). When full, the oldest is
  /// forgotten and messages not newer than it are dropped as replayed.
  std::size_t replay_cache_per_robot = 100000;
};

/// Why a signed write was dropped.
enum class LcmDropReason {
  kNone,          ///< accepted
  kUnknownRobot,  ///< no key for the robot
  kForged,        ///< MAC does not verify
  kStale,         ///< timestamp outside the window
  kReplayed,      ///< nonce already seen (or older than the cache remembers)
  kUnsigned,      ///< unsigned write while allow_unsigned is off
  // Messages that do not decode (lcm_codec.h, LcmDecodeFailure):
  kMalformed,  ///< an invalid value (negative count, bad string, ...)
  kTruncated,  ///< a field runs past the end of the message
  kWrongHash,  ///< another type's fingerprint on this channel
  kOversized,  ///< the message, a string or an array beyond the limits
  /// The handler failed (e.g. the store is unavailable): answered with an
  /// error, nothing stored, the endpoint keeps serving.
  kInternal,
  /// The store is unavailable (e.g. PostgreSQL away): answered with an
  /// error_v1 whose field is "(store)", nothing stored; send it again later.
  kUnavailable,
  /// Dropped by the kernel before the endpoint read it: the LCM receive
  /// socket's buffer was full (udp_drops.h). Counted, never answered (the
  /// sender is unknown).
  kReceiveBufferFull,
};

/// "unknown_robot", "forged", ... (the /metrics label).
const char* LcmDropReasonName(LcmDropReason r);

/// Verdict on one message.
struct LcmAuthVerdict {
  LcmDropReason reason = LcmDropReason::kNone;
  std::string field;   ///< field to name in error_v1 ("robot", "hmac", ...)
  std::string detail;  ///< human-readable why
  bool ok() const { return reason == LcmDropReason::kNone; }
};

/// The checks. Thread-safe.
class LcmAuthenticator {
 public:
  /// @throws std::invalid_argument for a key shorter than 16 bytes, an
  /// empty or too long robot id, or a non-positive skew/cache size.
  explicit LcmAuthenticator(LcmSecurityOptions options);

  /// The key of a robot, or nullptr.
  const std::string* KeyOf(const std::string& robot) const;

  /// Checks a signed message in order: robot known, MAC (computed by
  /// `expected_mac(key)`), timestamp within the window, nonce unseen. The
  /// nonce is remembered only when everything else passed.
  LcmAuthVerdict Check(
      const std::string& robot,
      std::int64_t utime_us,
      const std::string& nonce,
      const std::string& mac,
      const std::function<std::string(const std::string& key)>& expected_mac,
      std::int64_t now_us);

  const LcmSecurityOptions& options() const { return options_; }

 private:
  struct Seen {
    std::unordered_set<std::string> nonces;
    std::deque<std::pair<std::int64_t, std::string>> order;  // utime, nonce
    std::int64_t floor_us = INT64_MIN;  // newest forgotten entry's utime
  };
  LcmSecurityOptions options_;
  std::mutex mu_;
  std::map<std::string, Seen> seen_;
};

/// Parses an lcm_keys JSON object {"robot-id": "hex key", ...} into raw
/// keys. `where` prefixes error messages (e.g. "--lcm-keys keys.json").
/// @throws std::invalid_argument naming the robot and the rule.
std::map<std::string, std::string> ParseLcmKeys(const std::string& json_text,
                                                const std::string& where);

}  // namespace frictiond
