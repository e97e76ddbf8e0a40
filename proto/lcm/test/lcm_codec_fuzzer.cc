// libFuzzer harness of the LCM decoders (lcm_codec.h), docs/fuzzing.md. The
// first byte picks the message type, the rest is the message. Every input
// must decode or fail with a reason (never crash, never allocate beyond the
// limits); what decodes must re-encode (lcm-gen's encoder) to exactly the
// bytes received, which is what the MAC checks of signed messages rely on.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "frictiond/proto/lcm_codec.h"

namespace {

template <class Message>
void Check(const std::uint8_t* data, std::size_t size) {
  frictiond::LcmDecodeLimits limits;
  limits.max_message_bytes = 1 << 20;
  Message m;
  const frictiond::LcmDecodeResult r =
      frictiond::DecodeLcm(data, size, &m, limits);
  if (!r.ok()) {
    if (r.field.empty() || r.detail.empty()) std::abort();
    return;
  }
  const std::string again = frictiond::EncodeLcm(m);
  if (again.size() != size || std::memcmp(again.data(), data, size) != 0)
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t* msg = data + 1;
  const std::size_t n = size - 1;
  switch (data[0] % 11) {
    case 0:
      Check<frictiond::material_query_v1>(msg, n);
      break;
    case 1:
      Check<frictiond::material_reply_v1>(msg, n);
      break;
    case 2:
      Check<frictiond::identification_request_v1>(msg, n);
      break;
    case 3:
      Check<frictiond::identification_request_v2>(msg, n);
      break;
    case 4:
      Check<frictiond::stroke_chunk_v1>(msg, n);
      break;
    case 5:
      Check<frictiond::stroke_chunk_v2>(msg, n);
      break;
    case 6:
      Check<frictiond::coverage_progress_v1>(msg, n);
      break;
    case 7:
      Check<frictiond::model_update_v1>(msg, n);
      break;
    case 8:
      Check<frictiond::error_v1>(msg, n);
      break;
    case 9:
      Check<frictiond::signed_message_v1>(msg, n);
      break;
    default:
      Check<frictiond::material_reply_v2>(msg, n);
      break;
  }
  return 0;
}
