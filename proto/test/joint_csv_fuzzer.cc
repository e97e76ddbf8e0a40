// libFuzzer harness of the joint CSV parser (ParseJointCsv), docs/fuzzing.md:
// any input parses or throws std::invalid_argument; at most max_rows rows.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "frictiond/proto/joint_json.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const frictiond::JointData parsed =
        frictiond::ParseJointCsv(text, frictiond::Lubricant{}, 5000);
    if (parsed.size() > 5000) std::abort();
  } catch (const std::invalid_argument&) {
    // rejected with a message: fine
  }
  return 0;
}
