// libFuzzer harness of the image header check (ReadImageHeader: PNG IHDR /
// JPEG start-of-frame before any decoding), docs/fuzzing.md: any input gives
// a header or throws std::invalid_argument "image: ...".
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string_view>

#include "../src/image_features.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    const frictiond::internal::ImageHeader h =
        frictiond::internal::ReadImageHeader(bytes);
    if (!(h.width > 0) || !(h.height > 0)) std::abort();
  } catch (const std::invalid_argument& e) {
    if (std::string_view(e.what()).rfind("image: ", 0) != 0) std::abort();
  }
  return 0;
}
