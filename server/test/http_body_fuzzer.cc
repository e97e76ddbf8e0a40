// libFuzzer harness of the JSON request bodies (docs/fuzzing.md): the
// first byte picks the write route (material, fingertip, robot, token), the
// rest is its body, dispatched without sockets. Any body must be answered
// below 500.
#include <cstddef>
#include <cstdint>
#include <string>

#include "http_fuzz_world.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  static frictiond::fuzz::HttpWorld world;
  if (size == 0) return 0;
  static const char* const kRoutes[][2] = {
      {"PUT", "/v1/materials/fz-body"},
      {"PUT", "/v1/fingertips/fz-tip"},
      {"PUT", "/v1/robots/fz-robot"},
      {"POST", "/v1/tokens"},
  };
  const auto& route = kRoutes[data[0] % 4];
  frictiond::HttpRequest r;
  r.method = route[0];
  r.path = route[1];
  r.body.assign(reinterpret_cast<const char*>(data + 1), size - 1);
  r.remote_addr = "127.0.0.1";
  r.headers.emplace("Content-Type", "application/json");
  world.Check(r);
  return 0;
}
