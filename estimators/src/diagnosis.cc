#include "frictiond/estimators/diagnosis.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>

#include <Eigen/Dense>

#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/stats.h"

#include "diagnosis_internal.h"

namespace frictiond {

namespace {
constexpr double kPaperPeakMmS = 10.0;
}  // namespace

using diagnosis_internal::Num;
using diagnosis_internal::RoundForName;

bool DiagnosisOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (!labelling.IsValid(why)) return false;
  if (!(folds >= 2))
    return fail("folds = " + std::to_string(folds) + " (must be >= 2)");
  if (!(inner_folds >= 2))
    return fail("inner_folds = " + std::to_string(inner_folds) +
                " (must be >= 2)");
  if (interaction_candidates < 0)
    return fail("interaction_candidates = " +
                std::to_string(interaction_candidates) + " (must be >= 0)");
  if (!(alpha > 0 && alpha < 1))
    return fail("alpha = " + Num(alpha) + " (must be in (0, 1))");
  if (!(selection_alpha > 0 && selection_alpha < 1))
    return fail("selection_alpha = " + Num(selection_alpha) +
                " (must be in (0, 1))");
  if (!(min_gain_pct >= 0) || !std::isfinite(min_gain_pct)) {
    return fail("min_gain_pct = " + Num(min_gain_pct) +
                " (must be finite and >= 0)");
  }
  if (max_findings < 0)
    return fail("max_findings = " + std::to_string(max_findings) +
                " (must be >= 0)");
  if (baseline_terms.empty() || baseline_terms.front() != "intercept") {
    return fail("baseline_terms must start with \"intercept\"");
  }
  for (const std::string& t : baseline_terms) {
    try {
      Term::Parse(t);
    } catch (const std::invalid_argument& e) {
      return fail(std::string("baseline_terms: ") + e.what());
    }
  }
  if (!(min_relative_span >= 0))
    return fail("min_relative_span = " + Num(min_relative_span) +
                " (must be >= 0)");
  if (bins < 2)
    return fail("bins = " + std::to_string(bins) + " (must be >= 2)");
  for (double tau : onset_decay_s) {
    if (!(tau > 0) || !std::isfinite(tau))
      return fail("onset_decay_s = " + Num(tau) + " (must be finite and > 0)");
  }
  if (!(breakaway_window_s >= 0)) {
    return fail("breakaway_window_s = " + Num(breakaway_window_s) +
                " (must be >= 0)");
  }
  std::string lugre_why;
  if (lugre && !IsValidLuGreTheta(*lugre, &lugre_why))
    return fail("lugre: " + lugre_why);
  return true;
}

const char* ToString(DiagnosisStatus status) {
  switch (status) {
    case DiagnosisStatus::kOk:
      return "ok";
    case DiagnosisStatus::kTooFewSamples:
      return "too_few_samples";
    case DiagnosisStatus::kTooFewStrokes:
      return "too_few_strokes";
    case DiagnosisStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

StrokeData PrepareDiagnosisData(StrokeData data,
                                const SlipLabelOptions& labelling) {
  EnsureLabels(&data, labelling);
  AddDerivedFeatures(&data, labelling);
  return data;
}

SlipLabelOptions CalcAutoSlipLabelOptions(const std::vector<double>& v_mm_s,
                                          const SlipLabelOptions& base,
                                          std::string* rule) {
  SlipLabelOptions o = base;
  std::vector<double> v = v_mm_s;
  std::sort(v.begin(), v.end());
  const double v99 = v.empty() ? 0.0 : SortedQuantile(v, 0.99);
  if (v99 >= kPaperPeakMmS || !(v99 > 0)) {
    o.peak_mm_s = kPaperPeakMmS;
    o.floor_mm_s = 5.0;
    if (rule)
      *rule = "paper 000 thresholds (99th percentile speed " + Num(v99) +
              " mm/s >= 10 mm/s)";
    return o;
  }
  o.peak_mm_s = RoundForName(0.25 * v99);
  o.floor_mm_s = RoundForName(0.08 * v99);
  if (rule) {
    *rule = "automatic: 99th percentile speed " + Num(v99) +
            " mm/s is below the paper's 10 mm/s peak, so peak = 0.25 x " +
            Num(v99) + " = " + Num(o.peak_mm_s) + " mm/s, floor = 0.08 x " +
            Num(v99) + " = " + Num(o.floor_mm_s) + " mm/s";
  }
  return o;
}

namespace {

/// Adds product columns "x*y" (x < y) for the interaction candidates: pairs
/// among the baseline's inputs and the numeric covariates with finite values
/// on the fit rows. When all pairs would exceed kMaxProductValues values,
/// only pairs with a baseline input are added, and at most as many of
/// those as fit in that bound.
void AddProductColumns(StrokeData* data,
                       const std::vector<bool>& mask,
                       const DiagnosisOptions& options) {
  constexpr double kMaxProductValues = 16e6;
  std::vector<std::string> inputs, covariates;
  for (const std::string& name : options.baseline_terms) {
    const Term t = Term::Parse(name);
    if (t.kind == TermKind::kLinear && data->Column(t.input))
      inputs.push_back(t.input);
  }
  for (std::size_t k = 0; k < data->covariate_names.size(); ++k) {
    const std::string& name = data->covariate_names[k];
    if (name.find('*') != std::string::npos) continue;
    if (std::find(options.exclude_candidates.begin(),
                  options.exclude_candidates.end(),
                  name) != options.exclude_candidates.end())
      continue;
    bool finite = true;
    for (std::size_t i = 0; i < data->size() && finite; ++i)
      finite = !mask[i] || std::isfinite(data->covariates[k][i]);
    if (finite) covariates.push_back(name);
  }
  std::vector<std::pair<std::string, std::string>> pairs;
  std::vector<std::string> all = inputs;
  all.insert(all.end(), covariates.begin(), covariates.end());
  const bool all_pairs =
      0.5 * all.size() * (all.size() - 1) * data->size() <= kMaxProductValues;
  for (std::size_t a = 0; a < all.size(); ++a) {
    for (std::size_t b = a + 1; b < all.size(); ++b) {
      if (!all_pairs && a >= inputs.size()) continue;
      pairs.push_back({std::min(all[a], all[b]), std::max(all[a], all[b])});
    }
  }
  // Bounded memory: at most kMaxProductValues values in product columns
  // (pairs among the inputs come first, then input x covariate pairs).
  const std::size_t max_pairs = static_cast<std::size_t>(
      kMaxProductValues / std::max<double>(1.0, data->size()));
  if (pairs.size() > max_pairs) pairs.resize(max_pairs);
  for (const auto& [x, y] : pairs) {
    // The one rule for computed columns (eps_scale.h).
    AddComputedColumn(data, x + "*" + y);
  }
}

}  // namespace

DiagnosisResult Diagnose(const StrokeData& input,
                         const DiagnosisOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  // Labels, derived features and product columns, on a copy.
  StrokeData data = input;
  bool has_derived = true;
  for (const std::string& name : DerivedFeatureNames())
    has_derived = has_derived && input.FindCovariate(name);
  if (input.slip.size() != input.size() || input.stroke.size() != input.size())
    EnsureLabels(&data, options.labelling);
  if (!has_derived) AddDerivedFeatures(&data, options.labelling);

  DiagnosisResult result;
  result.samples = static_cast<int>(data.size());
  const std::vector<bool> mask = CalcFitMask(data, options.labelling);
  std::set<int> fit_strokes;
  int fit_total = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (mask[i]) fit_strokes.insert(data.stroke[i]), ++fit_total;
  }
  result.fit_samples = fit_total;
  result.strokes = static_cast<int>(fit_strokes.size());
  if (fit_total < 20) {
    result.status = DiagnosisStatus::kTooFewSamples;
    result.why = std::to_string(fit_total) +
                 " slipping samples within the bounds (need at least 20); "
                 "check the slip thresholds";
    return result;
  }
  if (result.strokes < 3) {
    result.status = DiagnosisStatus::kTooFewStrokes;
    result.why = std::to_string(result.strokes) +
                 " strokes with slipping samples (need at least 3 for "
                 "stroke-level cross-validation)";
    return result;
  }
  if (options.interaction_candidates > 0)
    AddProductColumns(&data, mask, options);
  return diagnosis_internal::RunDiagnosis(
      data, options, mask, std::move(result));
}

}  // namespace frictiond
