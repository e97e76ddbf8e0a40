// libFuzzer harness of query-parameter parsing (docs/fuzzing.md): the first
// byte picks a read route, the rest is split at '&' and '=' into query
// parameters as httplib hands them over after percent-decoding (so any
// bytes), dispatched without sockets. Any query must be answered below 500.
#include <cstddef>
#include <cstdint>
#include <string>

#include "http_fuzz_world.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  static frictiond::fuzz::HttpWorld world;
  if (size == 0) return 0;
  static const char* const kPaths[] = {
      "/v1/materials/fz-known/predict",
      "/v1/materials/fz-known/slip-likelihood",
      "/v1/materials/fz-known/grip-force",
      "/v1/materials/fz-known/model",
      "/v1/materials/fz-unknown/model",
      "/v1/identifications",
      "/v1/materials",
      "/v1/materials/fz-known/export",
      "/v1/pairs/default/fz-known/friction",
      "/v1/materials/fz-known/strokes",
  };
  frictiond::HttpRequest r;
  r.method = "GET";
  r.path = kPaths[data[0] % (sizeof kPaths / sizeof kPaths[0])];
  r.remote_addr = "127.0.0.1";
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  std::size_t i = 0;
  while (i <= text.size()) {
    std::size_t amp = text.find('&', i);
    if (amp == std::string::npos) amp = text.size();
    const std::string pair = text.substr(i, amp - i);
    const std::size_t eq = pair.find('=');
    if (!pair.empty())
      r.query.emplace(pair.substr(0, eq),
                      eq == std::string::npos ? "" : pair.substr(eq + 1));
    i = amp + 1;
  }
  world.Check(r);
  return 0;
}
