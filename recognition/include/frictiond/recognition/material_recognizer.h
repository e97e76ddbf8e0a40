#pragma once
/// @file
/// Material recognition from a photograph of a surface (CONTRACT.md, HTTP
/// API, "Recognition"): reference images are registered per material id, and
/// a query image is answered with the most similar materials, best first, or
/// flagged unknown.
///
/// Method (details and measured accuracy in docs/recognition.md): the image
/// is decoded (PNG or JPEG only), resized to a fixed working size, and
/// described by histograms chosen for what a robot's camera changes:
///   - light colour: a grey-world chromaticity histogram (each channel
///     divided by its mean, taken over the cells of a 4 x 4 grid within
///     1.2x of the median cell's brightness so that a dark occluder does not
///     tint it; a warmer or cooler lamp cancels), the texture computed on
///     the light-balanced grey, and the mean colour compared with a
///     tolerance as large as a lamp change along the warm-cool axis and
///     smaller across it;
///   - light intensity and falloff: grey divided by a wide Gaussian estimate
///     of the local light level before any texture histogram;
///   - noise: a 3 x 3 median filter before any histogram;
///   - in-plane rotation: rotation-invariant uniform LBP (riu2; 8 samples at
///     radius 1, 16 at radii 2 and 3) at radii 1, 2, 3 on the working image
///     and 1, 2 at half and quarter resolution;
///   - distance: every reference is described at nine magnifications
///     (0.5 .. 2, steps of 2^(1/4)), and a query is compared with each;
///   - partial occlusion: a query is also described per cell of a 4 x 4
///     grid; per reference, the 10 cells most like it are pooled into a
///     partial view, and the better of the whole and the partial view
///     counts.
/// Each histogram is compared by histogram intersection; the similarity of
/// two images is in [0, 1] (1 = identical histograms) and a material's
/// similarity is the best over its references, their scales and the query's
/// descriptions.
/// The reported score is a calibrated probability that the material is the
/// right one (logistic (Platt) fit of the similarity on held-out tuning
/// views, docs/recognition.md); a query is accepted when the best score
/// reaches the operating point RecognizerOptions::unknown_threshold, chosen
/// on the tuning views for a stated false-accept rate on materials not in the
/// library.
///
/// Usage:
/// @code
///   frictiond::MaterialRecognizer recognizer;
///   recognizer.AddReference("ptfe_sheet", png_bytes);
///   const frictiond::RecognitionResult r = recognizer.Recognize(query_jpeg);
///   if (!r.unknown) use(r.candidates.front().material);
/// @endcode
///
/// The header does not include OpenCV: the implementation is private
/// (internal::RecognizerImpl).

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace frictiond {

namespace internal {
class RecognizerImpl;
}  // namespace internal

/// One candidate material for a query image.
struct RecognitionCandidate {
  std::string material;  ///< material id given at registration
  /// Calibrated probability in [0, 1] that this is the right material:
  /// 1 / (1 + exp(-calibration_slope * (e - calibration_midpoint))) with the
  /// evidence e = similarity + (similarity - the best similarity of the
  /// other materials) (e = similarity when only one material is
  /// registered).
  double score = 0.0;
  /// Raw similarity in [0, 1] (1 = identical histograms), best over the
  /// material's references and scales.
  double similarity = 0.0;
};

/// Answer to MaterialRecognizer::Recognize.
struct RecognitionResult {
  /// True when no registered material is likely enough: the best score is
  /// below RecognizerOptions::unknown_threshold (the operating point), the
  /// margin over the second material is below RecognizerOptions::min_margin,
  /// or nothing is registered. The candidates are still reported (they are
  /// the closest materials, not matches).
  bool unknown = true;
  /// Up to RecognizerOptions::max_candidates distinct materials, best first
  /// (ties broken by material id).
  std::vector<RecognitionCandidate> candidates;
  /// Why, in one sentence, e.g. "closest is wood at 0.62, below the 0.80
  /// operating point" (unknown) or "wood at 0.97, at or above the 0.80
  /// operating point" (accepted).
  std::string reason;
  /// The operating point the decision used (RecognizerOptions).
  double operating_point = 0.0;
};

/// Matching options. Feature extraction itself has no options, so features
/// stored by one configuration stay valid in any other.
struct RecognizerOptions {
  /// Slope of the score calibration [1/similarity] (Platt scaling), fitted on
  /// the tuning views of recognition/test/recognition_calibration_test.cc.
  static constexpr double kCalibrationSlope = 49.48;
  /// Similarity at which the calibrated score is 0.5.
  static constexpr double kCalibrationMidpoint = 0.9569;
  /// Default operating point: the calibrated score at which at most 3 % of
  /// the tuning views of materials not in the library were accepted.
  static constexpr double kDefaultOperatingPoint = 0.49;

  /// The operating point: a query whose best calibrated score is below this
  /// is unknown. Must be in [0, 1].
  double unknown_threshold = kDefaultOperatingPoint;
  /// A query is also unknown when best - second best material score is below
  /// this (a ratio-style ambiguity test). 0 disables it. Must be in [0, 1].
  double min_margin = 0.0;
  /// Maximum number of candidates returned. Must be >= 1.
  int max_candidates = 5;
  /// Score calibration (see RecognitionCandidate::score). Must be > 0.
  double calibration_slope = kCalibrationSlope;
  /// Score calibration. Must be in [0, 1].
  double calibration_midpoint = kCalibrationMidpoint;

  /// Returns true when all fields satisfy their rules; otherwise returns
  /// false and, when `why` is not null, sets it to a message naming the
  /// field, its value and the rule.
  bool IsValid(std::string* why) const;
};

/// Registry of reference images per material and nearest-neighbour
/// recogniser.
///
/// Image input (every method taking `encoded_image`): PNG or JPEG bytes, at
/// least kMinImageSide pixels on each side and at most kMaxImagePixels
/// pixels in total (checked from the file header before decoding). Anything
/// else throws std::invalid_argument with a message starting with "image: ".
///
/// Thread safety: all methods are safe to call concurrently. An internal
/// reader-writer lock lets any number of Recognize / ExtractFeatures /
/// reference_count calls run in parallel; AddReference*, RemoveMaterial and
/// Clear take the lock exclusively (image decoding and feature extraction in
/// AddReference happen before the lock is taken).
///
/// Move-only (moves are noexcept). A moved-from recogniser may only be
/// destroyed or assigned to.
class MaterialRecognizer {
 public:
  /// Smallest accepted image side [px]: below this there is no texture to
  /// describe.
  static constexpr int kMinImageSide = 32;
  /// Largest accepted image size [px] (40 megapixels), to bound decoding
  /// memory and time.
  static constexpr long long kMaxImagePixels = 40'000'000;

  /// @throws std::invalid_argument when `options.IsValid()` fails (message
  /// from IsValid).
  explicit MaterialRecognizer(RecognizerOptions options = {});
  ~MaterialRecognizer();
  MaterialRecognizer(MaterialRecognizer&&) noexcept;
  MaterialRecognizer& operator=(MaterialRecognizer&&) noexcept;
  MaterialRecognizer(const MaterialRecognizer&) = delete;
  MaterialRecognizer& operator=(const MaterialRecognizer&) = delete;

  /// Number of floats in a feature vector returned by ExtractFeatures (the
  /// reference pyramid: nine scales; fixed by kFeatureVersion).
  static std::size_t feature_size();
  /// Version of the feature layout and extraction method. Persisted feature
  /// vectors must be discarded (and recomputed from the images) when it
  /// changes.
  static constexpr int kFeatureVersion = 4;

  /// Decodes `encoded_image` and registers it as a reference for
  /// `material_id`. A material may have any number of references; several
  /// photos (different spots, lighting) make recognition more robust.
  /// @throws std::invalid_argument "material_id: ..." for an empty id, or
  /// "image: ..." for an image that cannot be used (the message names the
  /// reason: empty, not PNG/JPEG, truncated, too small, too large). Nothing
  /// is registered when it throws.
  void AddReference(const std::string& material_id,
                    std::string_view encoded_image);

  /// Returns the feature vector of `encoded_image` (feature_size() floats),
  /// for persisting and re-registering with AddReferenceFeatures without
  /// decoding again.
  /// @throws std::invalid_argument "image: ..." as AddReference.
  std::vector<float> ExtractFeatures(std::string_view encoded_image) const;

  /// Registers a feature vector produced by ExtractFeatures (same
  /// kFeatureVersion).
  /// @throws std::invalid_argument "material_id: ..." for an empty id, or
  /// "features: ..." when the size is not feature_size(), a value is negative
  /// or not finite, or a histogram block is not unit-normalised.
  void AddReferenceFeatures(const std::string& material_id,
                            std::vector<float> features);

  /// Removes every reference of `material_id`; returns how many were
  /// removed (0 when the id is unknown).
  std::size_t RemoveMaterial(const std::string& material_id);

  /// Removes all references.
  void Clear();

  /// Ranks the registered materials by similarity to `encoded_image`.
  /// With nothing registered the answer is unknown with no candidates.
  /// @throws std::invalid_argument "image: ..." as AddReference.
  RecognitionResult Recognize(std::string_view encoded_image) const;

  /// Same as Recognize, from a vector returned by ExtractFeatures (its
  /// magnification-1 scale is the query).
  /// @throws std::invalid_argument "features: ..." as AddReferenceFeatures.
  RecognitionResult RecognizeFeatures(const std::vector<float>& features) const;

  /// Number of registered reference images (all materials).
  std::size_t reference_count() const;
  /// Number of distinct registered materials.
  std::size_t material_count() const;
  /// The options given at construction.
  const RecognizerOptions& options() const;

 private:
  std::unique_ptr<internal::RecognizerImpl> impl_;
};

}  // namespace frictiond
