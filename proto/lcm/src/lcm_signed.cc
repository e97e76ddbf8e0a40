// Signed messages to robots (lcm_signed.h).
#include "frictiond/proto/lcm_signed.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "frictiond/crypto/hmac.h"

namespace frictiond {

std::string LcmSignedChannel(const std::string& channel) {
  return channel + "_SIGNED";
}

signed_message_v1 SignLcmPayload(const std::string& payload_bytes,
                                 const std::string& channel,
                                 const std::string& key_id,
                                 const std::string& key,
                                 std::int64_t utime_us) {
  signed_message_v1 m{};
  m.key_id = key_id;
  m.channel = channel;
  m.payload_size = static_cast<std::int32_t>(payload_bytes.size());
  m.payload.assign(payload_bytes.begin(), payload_bytes.end());
  SignLcmMessage(&m, key, utime_us);
  return m;
}

const char* LcmVerifyFailureName(LcmVerifyFailure f) {
  switch (f) {
    case LcmVerifyFailure::kNone:
      return "";
    case LcmVerifyFailure::kUndecodable:
      return "undecodable";
    case LcmVerifyFailure::kUnknownKey:
      return "unknown_key";
    case LcmVerifyFailure::kForged:
      return "forged";
    case LcmVerifyFailure::kWrongChannel:
      return "wrong_channel";
    case LcmVerifyFailure::kStale:
      return "stale";
    case LcmVerifyFailure::kReplayed:
      return "replayed";
    case LcmVerifyFailure::kNotForMe:
      return "not_for_me";
  }
  return "undecodable";
}

LcmSignedReceiver::LcmSignedReceiver(std::map<std::string, std::string> keys,
                                     double max_skew_s,
                                     std::size_t replay_cache)
    : keys_(std::move(keys)),
      max_skew_s_(max_skew_s),
      replay_cache_(std::max<std::size_t>(replay_cache, 1)) {}

LcmVerifyResult LcmSignedReceiver::Verify(const void* data,
                                          std::size_t size,
                                          const std::string& channel,
                                          std::int64_t now_us,
                                          std::string* payload) {
  LcmVerifyResult v;
  auto fail = [&](LcmVerifyFailure f, std::string why) {
    v.failure = f;
    v.detail = std::move(why);
    return v;
  };
  signed_message_v1 m;
  if (const LcmDecodeResult r = DecodeLcm(data, size, &m); !r.ok())
    return fail(LcmVerifyFailure::kUndecodable, r.detail);
  v.key_id = m.key_id;
  const auto key = keys_.find(m.key_id);
  if (key == keys_.end())
    return fail(m.key_id == kLcmFleetKeyId ? LcmVerifyFailure::kUnknownKey
                                           : LcmVerifyFailure::kNotForMe,
                "key_id '" + m.key_id.substr(0, 64) + "' is not one of ours");
  if (!ConstantTimeEqual(CalcLcmMessageMac(m, key->second), LcmMessageMac(m)))
    return fail(LcmVerifyFailure::kForged,
                "hmac does not verify under key '" + m.key_id + "'");
  if (m.channel != channel)
    return fail(LcmVerifyFailure::kWrongChannel,
                "signed for channel '" + m.channel.substr(0, 64) +
                    "', received for '" + channel + "'");
  const double skew_s = std::fabs(static_cast<double>(now_us - m.utime) / 1e6);
  if (!(skew_s <= max_skew_s_))
    return fail(LcmVerifyFailure::kStale,
                "utime is " + std::to_string(skew_s) + " s from our clock");
  const std::string nonce = m.key_id + '\0' + LcmMessageNonce(m);
  std::lock_guard<std::mutex> lock(mu_);
  if (!seen_.insert(nonce).second)
    return fail(LcmVerifyFailure::kReplayed, "nonce seen before");
  order_.push_back(nonce);
  if (order_.size() > replay_cache_) {
    seen_.erase(order_.front());
    order_.pop_front();
  }
  payload->assign(m.payload.begin(), m.payload.end());
  return v;
}

}  // namespace frictiond
