#pragma once
/// @file
/// Private helpers of the recogniser: safe image decoding and the colour +
/// texture feature vector. OpenCV appears only here and in the .cc files.

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>

namespace frictiond {
namespace internal {

/// Width and height read from a PNG or JPEG header.
struct ImageHeader {
  enum class Format { kPng, kJpeg };
  Format format = Format::kPng;
  int width = 0;
  int height = 0;
};

/// Parses the PNG IHDR or the JPEG start-of-frame without decoding pixels.
/// @throws std::invalid_argument "image: ..." when the bytes are empty, not
/// PNG/JPEG, truncated before the size is known, or the JPEG has no
/// end-of-image marker (truncated file).
ImageHeader ReadImageHeader(std::string_view bytes);

/// Checks the header size limits, then decodes to 8-bit BGR. Large JPEGs are
/// decoded at 1/2 or 1/4 resolution (libjpeg DCT scaling), which is faster
/// and loses nothing at the working size.
/// @throws std::invalid_argument "image: ..." naming the reason.
cv::Mat DecodeImage(std::string_view bytes, int min_side, long long max_pixels);

/// Histogram blocks of the feature vector, in order. Each block holds the
/// square roots of an L1-normalised histogram, so its Euclidean norm is 1 and
/// the dot product of two blocks is the Bhattacharyya coefficient.
struct FeatureBlock {
  const char* name;
  int size;
  double weight;  ///< contribution to the score; weights sum to 1
};

/// The layout: hue-saturation, LBP riu2 at 5 (scale, radius) pairs, relative
/// intensity.
const std::vector<FeatureBlock>& FeatureLayout();

/// Total number of floats (sum of the block sizes).
std::size_t FeatureSize();

/// Computes the feature vector of a decoded 8-bit BGR image of any size.
std::vector<float> ComputeFeatures(const cv::Mat& bgr);

/// Validates a vector given by a caller (size, finite, non-negative, unit
/// norm per block).
/// @throws std::invalid_argument "features: ..." naming the rule.
void CheckFeatures(const std::vector<float>& features);

/// score = 1 - sum_b w_b * H_b with the Hellinger distance
/// H_b = sqrt(1 - BC_b) = ||a_b - b_b|| / sqrt(2), in [0, 1].
double CalcSimilarity(const float* a, const float* b);

}  // namespace internal
}  // namespace frictiond
