#include "frictiond/estimators/mu_admissibility.h"

#include <algorithm>
#include <cmath>

#include "frictiond/estimators/number_text.h"

namespace frictiond {

namespace {

bool Finite(const MuPrediction& p) {
  return std::isfinite(p.mu) && std::isfinite(p.sigma) &&
         std::isfinite(p.lo95) && std::isfinite(p.hi95);
}

// The rule for an answer with mean `mean` whose numbers are all finite or
// not (`finite`).
MeanMuCheck Check(const StochasticFrictionModel& model,
                  const InputValues& inputs,
                  double mean,
                  bool finite) {
  MeanMuCheck out;
  if (finite && mean >= 0) return out;
  out.admissible = false;
  // The given input whose move to its fitted mean (PredictMu's value for an
  // input not given) raises mu the most; when the answer is not finite, the
  // first whose move makes it finite.
  double best_gain = 0.0, best_value = 0.0, best_mu = 0.0;
  for (std::size_t k = 0; k < inputs.size(); ++k) {
    InputValues without;
    for (std::size_t j = 0; j < inputs.size(); ++j)
      if (j != k) without.push_back(inputs[j]);
    const MuPrediction moved = PredictMu(model, without);
    if (!Finite(moved)) continue;
    const double gain = finite ? moved.mu - mean : 0.0;
    if (!finite ? out.field.empty() : gain > best_gain) {
      best_gain = gain;
      out.field = inputs[k].first;
      best_value = inputs[k].second;
      best_mu = moved.mu;
    }
  }
  out.why = finite
                ? "the model's mean mu at these inputs is " + NumberText(mean) +
                      " (< 0): mu = |Ft|/Fn cannot be negative, so the "
                      "model is not valid here (its terms carry a trend "
                      "past where the data hold it)"
                : "the model's mu at these inputs is not finite (mean " +
                      NumberText(mean) + "): its terms overflow there";
  if (!out.field.empty()) {
    out.why += "; " + out.field + " = " + NumberText(best_value) +
               " moves it there most (at its fitted mean mu is " +
               NumberText(best_mu) + ")";
  }
  return out;
}

}  // namespace

MeanMuCheck CheckServableMu(const StochasticFrictionModel& model,
                            const InputValues& inputs,
                            const MuPrediction& p) {
  return Check(model, inputs, p.mu, Finite(p));
}

MeanMuCheck CheckServableMu(const StochasticFrictionModel& model,
                            const InputValues& inputs,
                            const MuDistribution& d) {
  bool finite = std::isfinite(d.mean) && std::isfinite(d.sigma);
  for (double q : d.quantiles) finite = finite && std::isfinite(q);
  return Check(model, inputs, d.mean, finite);
}

MeanMuCheck CheckServableMu(const StochasticFrictionModel& model,
                            const InputValues& inputs,
                            const TargetForce& f) {
  const bool finite = std::isfinite(f.mu) && std::isfinite(f.ft_n) &&
                      std::isfinite(f.ft_lo95_n) && std::isfinite(f.ft_hi95_n);
  return Check(model, inputs, f.mu, finite);
}

bool FloorAtZero(MuPrediction* p) {
  const bool floored = p->lo95 < 0 || p->hi95 < 0;
  p->lo95 = std::max(0.0, p->lo95);
  p->hi95 = std::max(0.0, p->hi95);
  return floored;
}

bool FloorAtZero(TargetForce* f) {
  const bool floored = f->ft_lo95_n < 0 || f->ft_hi95_n < 0;
  f->ft_lo95_n = std::max(0.0, f->ft_lo95_n);
  f->ft_hi95_n = std::max(0.0, f->ft_hi95_n);
  return floored;
}

bool FloorAtZero(MuDistribution* d) {
  bool floored = false;
  for (double& q : d->quantiles) {
    if (q < 0) {
      q = 0.0;
      floored = true;
    }
  }
  return floored;
}

ServedHoldSlip CalcServedHoldSlip(const StochasticFrictionModel& model,
                                  double fn_n,
                                  double load_n,
                                  const GripForceOptions& options) {
  ServedHoldSlip out;
  out.inputs = {{"fn_n", fn_n}, {"v_mm_s", options.v_mm_s}};
  out.at = PredictMu(model, out.inputs);
  out.check = CheckServableMu(model, out.inputs, out.at);
  if (out.check.admissible)
    out.probability = CalcHoldSlipProbability(model, fn_n, load_n, options);
  return out;
}

}  // namespace frictiond
