#include "frictiond/estimators/identification.h"

#include <future>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/estimators/preprocessing.h"

namespace frictiond {

namespace {

// Eq. (2) on every sample, the hull of the slipping ones and the LuGre
// family: the steps that do not need the regressions.
void FitConditionalAndCoverage(const StrokeData& data,
                               const MaterialIdentificationOptions& options,
                               MaterialIdentification* out) {
  const std::size_t n = data.size();
  std::vector<double> ratio(n);
  for (std::size_t i = 0; i < n; ++i) ratio[i] = data.ft_n[i] / data.fn_n[i];
  out->conditional = FitConditionalSlipLikelihood(
      data.fn_n, ratio, data.slip, options.conditional);
  std::vector<double> fn, v;
  std::vector<int> stroke;
  fn.reserve(n);
  v.reserve(n);
  const bool has_stroke = data.stroke.size() == n;
  for (std::size_t i = 0; i < n; ++i) {
    if (data.slip[i]) {
      fn.push_back(data.fn_n[i]);
      v.push_back(data.v_mm_s[i]);
      if (has_stroke) stroke.push_back(data.stroke[i]);
    }
  }
  out->coverage = CalcSpanCoverage(fn, v, options.reference);
  out->hull = CalcMaterialHullCoverage(fn, v, stroke);
  if (options.lugre) {
    // A family that cannot be identified is a status, never an exception
    // (the other families stand).
    try {
      out->lugre = IdentifyLuGreFromStrokes(data);
    } catch (const std::exception& e) {
      out->lugre = LuGreIdentification{};
      out->lugre.why = std::string("identification failed: ") + e.what();
    }
  } else {
    out->lugre.why = "not requested";
  }
}

}  // namespace

MaterialIdentification IdentifyMaterial(
    StrokeData data, const MaterialIdentificationOptions& options) {
  std::string why;
  if (!options.fit.IsValid(&why)) throw std::invalid_argument(why);
  if (!options.conditional.IsValid(&why))
    throw std::invalid_argument("conditional: " + why);
  if (!options.reference.IsValid())
    throw std::invalid_argument(
        "reference: fn and v ranges must be finite and non-empty");
  if (options.threads < 1)
    throw std::invalid_argument("threads = " + std::to_string(options.threads) +
                                " (must be >= 1)");
  EnsureLabels(&data, options.fit.labelling);
  MaterialIdentification out;
  if (options.threads == 1) {
    out.fit = FitStochasticModel(data, options.fit);
    FitConditionalAndCoverage(data, options, &out);
    return out;
  }
  // Both read `data` only and write disjoint members of `out`.
  std::future<void> side = std::async(std::launch::async, [&] {
    FitConditionalAndCoverage(data, options, &out);
  });
  try {
    out.fit = FitStochasticModel(data, options.fit);
  } catch (...) {
    side.wait();
    throw;
  }
  side.get();  // rethrows the side's exception, if any
  return out;
}

}  // namespace frictiond
