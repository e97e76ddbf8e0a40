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

/// Blocks of the feature vector of one scale, in order. A histogram block
/// holds the square roots of an L1-normalised histogram, so its Euclidean
/// norm is 1 and the dot product of two blocks is the Bhattacharyya
/// coefficient; the one non-histogram block holds the mean log
/// chromaticities (log(R/G), log(B/G)).
struct FeatureBlock {
  const char* name;
  int size;
  double weight;   ///< contribution to the score; weights sum to 1
  bool histogram;  ///< false: mean log chromaticities
};

/// The layout of one scale: grey-world chromaticity, LBP riu2 at 7 (scale,
/// radius) pairs, relative intensity, mean log chromaticity.
const std::vector<FeatureBlock>& FeatureLayout();

/// Floats per scale (sum of the block sizes).
std::size_t ScaleFeatureSize();
/// Number of scales in a reference vector (the magnification pyramid).
int ScaleCount();
/// Index of magnification 1 in a reference vector.
int UnitScaleIndex();
/// Total number of floats of a reference vector: ScaleCount() scales (the
/// whole view at each magnification), then CellCount() cells of the view at
/// magnification 1.
std::size_t FeatureSize();

/// Number of cells (a 4 x 4 grid) a view at magnification 1 is also
/// described by, so that the matcher can leave out an occluded part.
int CellCount();

/// Query features of a decoded 8-bit BGR image of any size at magnification
/// 1: the whole view, then CellCount() cells (1 + CellCount() single-scale
/// vectors of ScaleFeatureSize() floats).
std::vector<float> ComputeFeatures(const cv::Mat& bgr);

/// Reference features: ScaleCount() scales, the image as a camera at
/// magnifications 0.5 .. 2 (steps of 2^(1/4)) would see it (scale
/// UnitScaleIndex() is the whole view of ComputeFeatures(bgr)), then the
/// cells of ComputeFeatures(bgr).
std::vector<float> ComputeReferenceFeatures(const cv::Mat& bgr);

/// Single-scale vector of the union of the cells `kept[0..kept_count)` of
/// `cells` (CellCount() single-scale vectors): each histogram block the
/// normalised sum of the cells' histograms (cells weigh equally), the mean
/// log chromaticities averaged. Written to `out` (ScaleFeatureSize()).
void AggregateCells(const float* cells,
                    const int* kept,
                    int kept_count,
                    float* out);

/// Validates a reference vector given by a caller (size, finite, histogram
/// blocks non-negative with unit norm, chromaticities bounded).
/// @throws std::invalid_argument "features: ..." naming the rule.
void CheckFeatures(const std::vector<float>& features);

/// Tolerances of the mean-colour block's distance: the log chromaticity
/// difference is free within an ellipse about the lamp (warm-cool) axis,
/// `along` it and `across` it; beyond, D grows with the excess (in units of
/// `along`) and saturates `range` further on. The defaults are the
/// recogniser's (how they were chosen: image_features.cc).
struct ColourTolerance {
  double along = 0.35;
  double across = 0.15;
  double range = 0.5;
};

/// D_b of one block (CalcSimilarity): `a` and `b` point at the block's first
/// value in two single-scale vectors. In [0, 1].
double CalcBlockDistance(const FeatureBlock& block,
                         const float* a,
                         const float* b,
                         const ColourTolerance& colour = ColourTolerance{});

/// Similarity of two single-scale vectors, in [0, 1]:
/// score = 1 - sum_b w_b * D_b, with D_b = 1 - sum_i min(h_a,i, h_b,i) the
/// histogram intersection distance of the histograms h = (stored value)^2,
/// and for the mean colour clamp(excess / range, 0, 1), with excess the
/// distance of the log chromaticity difference beyond an ellipse around the
/// lamp (warm-cool) axis (image_features.cc).
double CalcSimilarity(const float* a, const float* b);

}  // namespace internal
}  // namespace frictiond
