#include "frictiond/recognition/material_recognizer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include "image_features.h"

namespace frictiond {
namespace internal {
namespace {

/// Cells of a query kept for the partial match (of CellCount() = 16): an
/// occluder covering up to 6 of the 16 cells is left out. Tuning views,
/// accepted-and-right at 3 % false accepts: version 3 kept 8 / 10 / 12 / 14
/// at 0.77 / 0.80 / 0.83 / 0.81 and chose 12; with the version-4 features
/// the mean over 2-6 % false accepts (seeds 101 and 102) was 0.88 / 0.88 /
/// 0.86 / 0.81 for 8 / 10 / 12 / 14, and 10 has the better worst half of
/// the tuning materials (docs/recognition.md).
int KeptCells() { return CellCount() * 5 / 8; }

/// Two decimals, for the reasons ("0.62").
std::string Fixed(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f", value);
  return text;
}

}  // namespace

/// Registered references, stored as one contiguous feature array so that a
/// query is a single linear scan.
class RecognizerImpl {
 public:
  explicit RecognizerImpl(RecognizerOptions options) : options_(options) {}

  /// Platt scaling of the evidence into a probability.
  double Calibrate(double evidence) const {
    return 1.0 / (1.0 + std::exp(-options_.calibration_slope *
                                 (evidence - options_.calibration_midpoint)));
  }

  const RecognizerOptions& options() const { return options_; }

  void Add(const std::string& material_id, const std::vector<float>& features) {
    std::unique_lock lock(mutex_);
    materials_.push_back(material_id);
    features_.insert(features_.end(), features.begin(), features.end());
  }

  std::size_t Remove(const std::string& material_id) {
    std::unique_lock lock(mutex_);
    const std::size_t n = FeatureSize();
    std::size_t kept = 0;
    for (std::size_t i = 0; i < materials_.size(); ++i) {
      if (materials_[i] == material_id) continue;
      if (kept != i) {
        materials_[kept] = std::move(materials_[i]);
        std::copy_n(features_.begin() + i * n, n, features_.begin() + kept * n);
      }
      ++kept;
    }
    const std::size_t removed = materials_.size() - kept;
    materials_.resize(kept);
    features_.resize(kept * n);
    return removed;
  }

  void Clear() {
    std::unique_lock lock(mutex_);
    materials_.clear();
    features_.clear();
  }

  /// `query` holds the whole view and CellCount() cells (single-scale
  /// vectors of ScaleFeatureSize() floats). A reference's similarity is the
  /// larger of (a) the whole view against the reference's best scale and (b)
  /// the view without its least similar cells (an occluder) against the
  /// reference's scales.
  RecognitionResult Recognize(const float* query) const {
    std::vector<RecognitionCandidate> best;
    {
      std::shared_lock lock(mutex_);
      const std::size_t n = FeatureSize();
      const std::size_t per_scale = ScaleFeatureSize();
      const int scales = ScaleCount();
      const int cells = CellCount();
      const float* query_cells = query + per_scale;
      const int keep = KeptCells();
      std::vector<std::pair<double, int>> cell_similarity(cells);
      std::vector<int> kept(cells);
      std::vector<float> trimmed(per_scale);
      std::unordered_map<std::string_view, std::size_t> index;
      for (std::size_t i = 0; i < materials_.size(); ++i) {
        const float* reference = &features_[i * n];
        double whole = 0.0;
        int best_scale = 0;
        for (int k = 0; k < scales; ++k) {
          const double s = CalcSimilarity(query, reference + k * per_scale);
          if (s > whole) {
            whole = s;
            best_scale = k;
          }
        }
        double similarity = whole;
        {
          for (int c = 0; c < cells; ++c) {
            cell_similarity[c] = {
                CalcSimilarity(query_cells + c * per_scale,
                               reference + best_scale * per_scale),
                c};
          }
          std::sort(cell_similarity.begin(),
                    cell_similarity.end(),
                    [](const auto& a, const auto& b) {
                      return a.first > b.first ||
                             (a.first == b.first && a.second < b.second);
                    });
          for (int c = 0; c < keep; ++c) kept[c] = cell_similarity[c].second;
          AggregateCells(query_cells, kept.data(), keep, trimmed.data());
          double part = 0.0;
          for (int k = 0; k < scales; ++k) {
            part = std::max(
                part,
                CalcSimilarity(trimmed.data(), reference + k * per_scale));
          }
          similarity = std::max(whole, part);
        }
        const auto [it, inserted] = index.emplace(materials_[i], best.size());
        if (inserted) {
          best.push_back({materials_[i], 0.0, similarity});
        } else if (similarity > best[it->second].similarity) {
          best[it->second].similarity = similarity;
        }
      }
    }
    std::sort(best.begin(),
              best.end(),
              [](const RecognitionCandidate& a, const RecognitionCandidate& b) {
                if (a.similarity != b.similarity)
                  return a.similarity > b.similarity;
                return a.material < b.material;
              });
    // Evidence = similarity + margin over the best other material (a
    // ratio-test in difference form; with one material the margin is 0).
    for (std::size_t i = 0; i < best.size(); ++i) {
      const double other = best.size() == 1 ? best[i].similarity
                           : i == 0         ? best[1].similarity
                                            : best[0].similarity;
      best[i].score = Calibrate(2.0 * best[i].similarity - other);
    }
    RecognitionResult result;
    result.unknown = true;
    result.operating_point = options_.unknown_threshold;
    if (best.empty()) {
      result.reason = "no reference image is registered";
    } else {
      const RecognitionCandidate& top = best[0];
      const double margin =
          best.size() > 1 ? top.score - best[1].score : top.score;
      const std::string point =
          "the " + Fixed(options_.unknown_threshold) + " operating point";
      if (!(top.score >= options_.unknown_threshold)) {
        result.reason = "closest is " + top.material + " at " +
                        Fixed(top.score) + ", below " + point;
      } else if (options_.min_margin > 0.0 && margin < options_.min_margin) {
        result.reason = "closest is " + top.material + " at " +
                        Fixed(top.score) + " but " + best[1].material +
                        " is within " + Fixed(margin) + " (min_margin " +
                        Fixed(options_.min_margin) + ")";
      } else {
        result.unknown = false;
        result.reason =
            top.material + " at " + Fixed(top.score) + ", at or above " + point;
      }
    }
    if (best.size() > static_cast<std::size_t>(options_.max_candidates)) {
      best.resize(static_cast<std::size_t>(options_.max_candidates));
    }
    result.candidates = std::move(best);
    return result;
  }

  std::size_t reference_count() const {
    std::shared_lock lock(mutex_);
    return materials_.size();
  }

  std::size_t material_count() const {
    std::shared_lock lock(mutex_);
    std::vector<std::string_view> ids(materials_.begin(), materials_.end());
    std::sort(ids.begin(), ids.end());
    return static_cast<std::size_t>(std::unique(ids.begin(), ids.end()) -
                                    ids.begin());
  }

 private:
  const RecognizerOptions options_;
  mutable std::shared_mutex mutex_;
  std::vector<std::string> materials_;  ///< material id of reference i
  std::vector<float> features_;         ///< reference i at [i * FeatureSize()]
};

}  // namespace internal

namespace {

void CheckMaterialId(const std::string& material_id) {
  if (material_id.empty()) {
    throw std::invalid_argument("material_id: empty (must be non-empty)");
  }
}

std::vector<float> DecodeAndExtractQuery(std::string_view encoded_image) {
  return internal::ComputeFeatures(
      internal::DecodeImage(encoded_image,
                            MaterialRecognizer::kMinImageSide,
                            MaterialRecognizer::kMaxImagePixels));
}

std::vector<float> DecodeAndExtract(std::string_view encoded_image) {
  return internal::ComputeReferenceFeatures(
      internal::DecodeImage(encoded_image,
                            MaterialRecognizer::kMinImageSide,
                            MaterialRecognizer::kMaxImagePixels));
}

std::string Number(double value) {
  // std::to_string prints fixed 6 decimals; enough for options in [0, 1].
  return std::to_string(value);
}

}  // namespace

bool RecognizerOptions::IsValid(std::string* why) const {
  std::string message;
  if (!(unknown_threshold >= 0.0 && unknown_threshold <= 1.0)) {
    message = "unknown_threshold = " + Number(unknown_threshold) +
              " (must be in [0, 1])";
  } else if (!(min_margin >= 0.0 && min_margin <= 1.0)) {
    message = "min_margin = " + Number(min_margin) + " (must be in [0, 1])";
  } else if (!(calibration_slope > 0.0 && calibration_slope <= 1e4)) {
    message = "calibration_slope = " + Number(calibration_slope) +
              " (must be in (0, 10000])";
  } else if (!(calibration_midpoint >= 0.0 && calibration_midpoint <= 1.0)) {
    message = "calibration_midpoint = " + Number(calibration_midpoint) +
              " (must be in [0, 1])";
  } else if (!(max_candidates >= 1)) {
    message = "max_candidates = " + std::to_string(max_candidates) +
              " (must be >= 1)";
  }
  if (message.empty()) return true;
  if (why != nullptr) *why = std::move(message);
  return false;
}

MaterialRecognizer::MaterialRecognizer(RecognizerOptions options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  impl_ = std::make_unique<internal::RecognizerImpl>(options);
}

MaterialRecognizer::~MaterialRecognizer() = default;
MaterialRecognizer::MaterialRecognizer(MaterialRecognizer&&) noexcept = default;
MaterialRecognizer& MaterialRecognizer::operator=(
    MaterialRecognizer&&) noexcept = default;

std::size_t MaterialRecognizer::feature_size() {
  return internal::FeatureSize();
}

void MaterialRecognizer::AddReference(const std::string& material_id,
                                      std::string_view encoded_image) {
  CheckMaterialId(material_id);
  impl_->Add(material_id, DecodeAndExtract(encoded_image));
}

std::vector<float> MaterialRecognizer::ExtractFeatures(
    std::string_view encoded_image) const {
  return DecodeAndExtract(encoded_image);
}

void MaterialRecognizer::AddReferenceFeatures(const std::string& material_id,
                                              std::vector<float> features) {
  CheckMaterialId(material_id);
  internal::CheckFeatures(features);
  impl_->Add(material_id, features);
}

std::size_t MaterialRecognizer::RemoveMaterial(const std::string& material_id) {
  return impl_->Remove(material_id);
}

void MaterialRecognizer::Clear() { impl_->Clear(); }

RecognitionResult MaterialRecognizer::Recognize(
    std::string_view encoded_image) const {
  return impl_->Recognize(DecodeAndExtractQuery(encoded_image).data());
}

RecognitionResult MaterialRecognizer::RecognizeFeatures(
    const std::vector<float>& features) const {
  internal::CheckFeatures(features);
  // The query: the whole view (unit scale), then the cells stored after
  // the pyramid.
  const std::size_t n = internal::ScaleFeatureSize();
  const std::size_t unit = internal::UnitScaleIndex() * n;
  std::vector<float> query(features.begin() + unit,
                           features.begin() + unit + n);
  query.insert(query.end(),
               features.begin() + internal::ScaleCount() * n,
               features.end());
  return impl_->Recognize(query.data());
}

std::size_t MaterialRecognizer::reference_count() const {
  return impl_->reference_count();
}

std::size_t MaterialRecognizer::material_count() const {
  return impl_->material_count();
}

const RecognizerOptions& MaterialRecognizer::options() const {
  return impl_->options();
}

}  // namespace frictiond
