// libFuzzer harness of the LCM endpoint's handlers (LcmEndpoint over an
// in-memory library, provider memq:// so no socket is opened), driven with
// LcmEndpoint::HandleMessage. docs/fuzzing.md. The first byte picks the
// channel (query, unsigned chunk, signed chunk), the rest is the message.
// A query for "fz" opened identification job 1, so mutated seeds of valid
// chunks for it reach reassembly, coverage and ingest. Nothing may crash
// or throw; the endpoint is rebuilt every 2000 inputs to bound its state.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "frictiond/server/lcm_endpoint.h"
#include "frictiond/storage/store.h"

#ifdef FRICTIOND_HAVE_LCM
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lcm_codec.h"

namespace {

struct Harness {
  frictiond::Metrics metrics;
  std::unique_ptr<frictiond::FrictionLibrary> library;
  std::unique_ptr<frictiond::LcmEndpoint> endpoint;
  int inputs = 0;

  void Reset() {
    endpoint.reset();
    library = std::make_unique<frictiond::FrictionLibrary>(
        frictiond::OpenStore(":memory:"));
    frictiond::LcmEndpointOptions o;
    o.url = "memq://";
    o.security.allow_unsigned = true;
    o.security.keys = {{"robot-a", std::string(32, 'k')}};
    o.metrics = &metrics;
    o.reassembly.max_samples = 20000;
    o.reassembly.max_open_strokes = 8;
    endpoint = std::make_unique<frictiond::LcmEndpoint>(*library, o);
    frictiond::material_query_v1 q{};
    q.request_id = "fuzz";
    q.robot = "robot-a";
    q.material = "fz";
    q.fingertip = "";
    q.image_size = 0;
    const std::string bytes = frictiond::EncodeLcm(q);
    endpoint->HandleMessage(
        frictiond::kLcmQueryChannel, bytes.data(), bytes.size());
    inputs = 0;
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  static Harness* h = [] {
    auto* x = new Harness;
    x->Reset();
    return x;
  }();
  if (size < 1) return 0;
  if (++h->inputs > 2000) h->Reset();
  static const char* const kChannels[] = {frictiond::kLcmQueryChannel,
                                          frictiond::kLcmStrokeChannel,
                                          frictiond::kLcmSignedStrokeChannel};
  h->endpoint->HandleMessage(kChannels[data[0] % 3], data + 1, size - 1);
  return 0;
}

#else

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t*, std::size_t) {
  return 0;  // built without LCM
}

#endif
