#include "frictiond/server/lcm_auth.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "frictiond/crypto/hmac.h"
#include "frictiond/proto/json_parse.h"

namespace frictiond {

namespace {
constexpr std::size_t kMinKeyBytes = 16;
constexpr std::size_t kMaxRobotId = 128;
}  // namespace

const char* LcmDropReasonName(LcmDropReason r) {
  switch (r) {
    case LcmDropReason::kNone:
      return "none";
    case LcmDropReason::kUnknownRobot:
      return "unknown_robot";
    case LcmDropReason::kForged:
      return "forged";
    case LcmDropReason::kStale:
      return "stale";
    case LcmDropReason::kReplayed:
      return "replayed";
    case LcmDropReason::kUnsigned:
      return "unsigned";
    case LcmDropReason::kMalformed:
      return "malformed";
    case LcmDropReason::kTruncated:
      return "truncated";
    case LcmDropReason::kWrongHash:
      return "wrong_hash";
    case LcmDropReason::kOversized:
      return "oversized";
    case LcmDropReason::kInternal:
      return "internal";
    case LcmDropReason::kUnavailable:
      return "unavailable";
    case LcmDropReason::kReceiveBufferFull:
      return "receive_buffer_full";
  }
  return "unknown";
}

LcmAuthenticator::LcmAuthenticator(LcmSecurityOptions options)
    : options_(std::move(options)) {
  for (const auto& [robot, key] : options_.keys) {
    if (robot.empty() || robot.size() > kMaxRobotId)
      throw std::invalid_argument("lcm_keys: robot id '" + robot.substr(0, 64) +
                                  "' must have 1..128 characters");
    if (key.size() < kMinKeyBytes)
      throw std::invalid_argument("lcm_keys: " + robot + ": key of " +
                                  std::to_string(key.size()) +
                                  " bytes (at least 16 bytes = 32 hex digits)");
  }
  if (!(options_.max_skew_s > 0 && std::isfinite(options_.max_skew_s)))
    throw std::invalid_argument("lcm_max_skew_s: must be > 0");
  if (options_.replay_cache_per_robot < 1)
    throw std::invalid_argument("lcm replay cache: must hold >= 1 nonce");
}

const std::string* LcmAuthenticator::KeyOf(const std::string& robot) const {
  auto it = options_.keys.find(robot);
  return it == options_.keys.end() ? nullptr : &it->second;
}

LcmAuthVerdict LcmAuthenticator::Check(
    const std::string& robot,
    std::int64_t utime_us,
    const std::string& nonce,
    const std::string& mac,
    const std::function<std::string(const std::string& key)>& expected_mac,
    std::int64_t now_us) {
  LcmAuthVerdict v;
  const std::string* key = KeyOf(robot);
  if (!key) {
    v.reason = LcmDropReason::kUnknownRobot;
    v.field = "robot";
    v.detail = "robot = '" + robot.substr(0, 64) +
               "' (no LCM key configured for this robot; see lcm_keys)";
    return v;
  }
  if (!ConstantTimeEqual(expected_mac(*key), mac)) {
    v.reason = LcmDropReason::kForged;
    v.field = "hmac";
    v.detail = "hmac: does not verify under the key of robot '" + robot +
               "' (forged, corrupted or signed with another key)";
    return v;
  }
  const double skew_s = static_cast<double>(now_us - utime_us) * 1e-6;
  if (!(std::fabs(skew_s) <= options_.max_skew_s)) {
    v.reason = LcmDropReason::kStale;
    v.field = "utime";
    v.detail = "utime: " + std::to_string(skew_s) +
               " s from the daemon's clock (allowed +-" +
               std::to_string(options_.max_skew_s) +
               " s; check the robot's clock)";
    return v;
  }
  std::lock_guard<std::mutex> lock(mu_);
  Seen& s = seen_[robot];
  // Forget nonces whose timestamps left the window: a message that old is
  // stale anyway.
  const auto window_us =
      static_cast<std::int64_t>(options_.max_skew_s * 1e6) + 1;
  while (!s.order.empty() && s.order.front().first < now_us - window_us) {
    s.nonces.erase(s.order.front().second);
    s.order.pop_front();
  }
  if (utime_us <= s.floor_us || s.nonces.count(nonce)) {
    v.reason = LcmDropReason::kReplayed;
    v.field = "nonce";
    v.detail = "nonce: already seen from robot '" + robot +
               "' (a replayed or duplicated message; sign every send anew)";
    return v;
  }
  s.nonces.insert(nonce);
  s.order.emplace_back(utime_us, nonce);
  if (s.order.size() > options_.replay_cache_per_robot) {
    // Full: forget the oldest inserted; nothing at or before its time is
    // accepted any more, so no forgotten nonce can be replayed.
    s.floor_us = std::max(s.floor_us, s.order.front().first);
    s.nonces.erase(s.order.front().second);
    s.order.pop_front();
  }
  return v;
}

std::map<std::string, std::string> ParseLcmKeys(const std::string& json_text,
                                                const std::string& where) {
  const nlohmann::json j = ParseJsonOrDiscarded(json_text);
  if (j.is_discarded() || !j.is_object())
    throw std::invalid_argument(
        where + ": expected a JSON object {\"robot-id\": \"hex key\", ...}");
  std::map<std::string, std::string> keys;
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!it.value().is_string())
      throw std::invalid_argument(where + ": " + it.key() +
                                  ": expected a hex string");
    const auto key = FromHex(it.value().get<std::string>());
    if (!key)
      throw std::invalid_argument(where + ": " + it.key() +
                                  ": not a hex string");
    if (it.key().empty() || it.key().size() > kMaxRobotId)
      throw std::invalid_argument(where + ": robot id '" +
                                  it.key().substr(0, 64) +
                                  "' must have 1..128 characters");
    if (key->size() < kMinKeyBytes)
      throw std::invalid_argument(where + ": " + it.key() + ": key of " +
                                  std::to_string(key->size()) +
                                  " bytes (at least 16 bytes = 32 hex digits)");
    keys[it.key()] = *key;
  }
  return keys;
}

}  // namespace frictiond
