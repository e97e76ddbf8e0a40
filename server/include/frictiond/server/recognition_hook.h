#pragma once
/// @file
/// The recognition hook the transports share (HTTP /recognize registers it,
/// the LCM query with an image and LookUpModelForQuery call it), without
/// the HTTP routes.

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace frictiond {

/// Answer of the recognition hook: ranked candidates (material, score),
/// best first, or unknown (below the confidence threshold, or nothing
/// registered).
struct ImageRecognition {
  bool unknown = true;
  /// (material, calibrated score in [0, 1]), best first.
  std::vector<std::pair<std::string, double>> candidates;
  /// Why accepted or unknown, e.g. "closest is wood at 0.62, below the 0.84
  /// operating point" (docs/recognition.md).
  std::string reason;
  /// The operating point (score threshold) the decision used.
  double operating_point = 0.0;
};
/// The recognition hook: image bytes (PNG or JPEG) -> ImageRecognition.
/// @throws std::invalid_argument for an image that cannot be decoded.
using RecognizeImageFn =
    std::function<ImageRecognition(const std::string& image)>;

}  // namespace frictiond
