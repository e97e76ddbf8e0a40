// libFuzzer harness of the daemon config file (DaemonConfig::LoadFile,
// Validate and LoadLcmKeys), docs/fuzzing.md: any file loads or throws
// std::invalid_argument naming the key; a config that validates has sane
// values.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include <unistd.h>

#include "frictiond/server/daemon.h"

namespace {
// One scratch file per process (libFuzzer runs inputs one after another).
const std::string& ScratchPath() {
  static const std::string path =
      "/tmp/frictiond_config_fuzz_" + std::to_string(::getpid()) + ".json";
  return path;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  std::FILE* f = std::fopen(ScratchPath().c_str(), "wb");
  if (!f) return 0;
  std::fwrite(data, 1, size, f);
  std::fclose(f);
  frictiond::DaemonConfig config;
  config.lcm_keys_file.clear();
  try {
    config.LoadFile(ScratchPath());
    // A keys file named by the config is not followed (it could be any
    // path); the inline keys are.
    config.lcm_keys_file.clear();
    config.Validate();
    (void)config.LoadLcmKeys();
    if (!(config.max_body_mb > 0) || !(config.threads > 0)) std::abort();
  } catch (const std::invalid_argument&) {
    // rejected with a message: fine
  }
  return 0;
}
