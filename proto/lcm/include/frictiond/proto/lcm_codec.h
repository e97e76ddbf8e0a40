#pragma once
/// @file
/// Bounds-checked decoders of frictiond's LCM message types (proto/*.lcm),
/// the codec half of the LCM endpoint (docs/lcm.md "Hostile input",
/// docs/security_lcm.md). lcm-gen's generated decode() allocates before it
/// checks a length against the buffer and throws from std::string on a
/// string length of 0; these decoders never throw and never allocate more
/// than the bytes they were given justify:
/// - the 8-byte type fingerprint must be the type's (else kWrongHash);
/// - every string length and array count is checked against the bytes left
///   (else kTruncated) and against LcmDecodeLimits (else kOversized) before
///   anything is allocated;
/// - a string must end in its NUL, contain no other NUL and be valid UTF-8;
///   a boolean must be 0 or 1; no bytes may follow the message (else
///   kMalformed).
/// A message that decodes re-encodes (generated encode()) to the same bytes,
/// so a MAC over the re-encoding verifies the bytes that were received.
/// The generated types are used as the decoded values; encoding stays
/// lcm-gen's (only what the daemon itself produced is encoded).
///
/// @code
///   frictiond::material_query_v1 q;
///   const frictiond::LcmDecodeResult r = frictiond::DecodeLcm(data, size, &q);
///   if (!r.ok()) drop(r.failure, r.field, r.detail);  // q holds the fields
///                                                    // decoded before it
/// @endcode

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/coverage_progress_v1.hpp"
#include "frictiond/error_v1.hpp"
#include "frictiond/friction_model_v1.hpp"
#include "frictiond/identification_request_v1.hpp"
#include "frictiond/identification_request_v2.hpp"
#include "frictiond/material_query_v1.hpp"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/material_reply_v2.hpp"
#include "frictiond/model_update_v1.hpp"
#include "frictiond/signed_message_v1.hpp"
#include "frictiond/stroke_chunk_v1.hpp"
#include "frictiond/stroke_chunk_v2.hpp"

namespace frictiond {

/// Why a message did not decode.
enum class LcmDecodeFailure {
  kNone,       ///< decoded
  kMalformed,  ///< bytes present but not a valid value (negative count,
               ///< string without its NUL, invalid UTF-8, trailing bytes, ..)
  kTruncated,  ///< a field runs past the end of the message
  kWrongHash,  ///< the type fingerprint is not this type's
  kOversized,  ///< the message, a string or an array exceeds LcmDecodeLimits
};

/// "malformed", "truncated", "wrong_hash", "oversized" (the /metrics label
/// of frictiond_lcm_dropped_total); "" for kNone.
const char* LcmDecodeFailureName(LcmDecodeFailure f);

/// Size limits checked while decoding (before anything is allocated).
struct LcmDecodeLimits {
  /// Whole message [bytes].
  std::size_t max_message_bytes = 32u << 20;
  /// One string field [bytes] (ids and names are further limited by the
  /// endpoint, which answers such messages with a field error).
  std::size_t max_string_bytes = 4096;
  /// Image of a material_query_v1 [bytes].
  std::size_t max_image_bytes = 16u << 20;
  /// Samples of a stroke chunk (n_samples).
  std::int32_t max_samples = 10000;
  /// Terms and quantiles of a friction_model_v1, missing seqs of a
  /// coverage_progress_v1.
  std::int32_t max_terms = 256;
  std::int32_t max_quantiles = 4096;
  std::int32_t max_missing = 65536;
  /// Candidates of a material_reply_v2.
  std::int32_t max_candidates = 64;
  /// Payload of a signed_message_v1 [bytes].
  std::size_t max_payload_bytes = 16u << 20;
};

/// Outcome of a decode.
struct LcmDecodeResult {
  LcmDecodeFailure failure = LcmDecodeFailure::kNone;
  /// The offending field ("request_id", "fn_n", "image_size"; "(fingerprint)"
  /// for a wrong hash, "(message)" for the whole message or trailing bytes).
  std::string field;
  /// Field, value and rule, e.g. "robot: string length 0 (must be >= 1:
  /// the NUL terminator)".
  std::string detail;
  bool ok() const { return failure == LcmDecodeFailure::kNone; }
};

/// Decoders, one per type. `*out` holds every field decoded before a
/// failure (the rest default-initialised), so a caller can name the sender.
/// Never throw (std::bad_alloc aside).
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          material_query_v1* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          material_reply_v1* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          material_reply_v2* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          identification_request_v1* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          identification_request_v2* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          stroke_chunk_v1* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          stroke_chunk_v2* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          coverage_progress_v1* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          model_update_v1* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          error_v1* out,
                          const LcmDecodeLimits& limits = {});
LcmDecodeResult DecodeLcm(const void* data,
                          std::size_t size,
                          signed_message_v1* out,
                          const LcmDecodeLimits& limits = {});

/// What the recogniser made of a query's image, for material_reply_v2.
struct LcmRecognition {
  bool unknown = true;
  std::string reason;
  double operating_point = 0.0;
  /// (material, calibrated score), best first.
  std::vector<std::pair<std::string, double>> candidates;
};

/// material_reply_v2 from the material_reply_v1 sent for the same query and
/// the recognition of its image (null: the query carried no image, or it was
/// rejected before recognition: unknown, no reason, no candidates). At most
/// `max_candidates` candidates are copied.
material_reply_v2 MakeMaterialReplyV2(const material_reply_v1& v1,
                                      const LcmRecognition* recognition,
                                      std::int32_t max_candidates = 64);

/// Encodes a message with lcm-gen's encoder into a byte string (fingerprint
/// included). @throws std::runtime_error when encoding fails.
template <class Message>
std::string EncodeLcm(const Message& m) {
  const int size = m.getEncodedSize();
  std::string buf(static_cast<std::size_t>(size), '\0');
  if (m.encode(buf.data(), 0, size) != size)
    throw std::runtime_error("cannot encode the LCM message");
  return buf;
}

}  // namespace frictiond
