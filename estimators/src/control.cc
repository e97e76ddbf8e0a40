#include "frictiond/estimators/control.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace frictiond {

namespace {

void CheckForce(const char* name, double x, bool allow_zero) {
  const bool ok = allow_zero ? (x >= 0) : (x > 0);
  if (!ok || !std::isfinite(x)) {
    throw std::invalid_argument(std::string(name) + " = " + std::to_string(x) +
                                (allow_zero ? " (must be finite and >= 0)"
                                            : " (must be finite and > 0)"));
  }
}

InputValues WithForces(const InputValues& covariates,
                       double fn_n,
                       double v_mm_s) {
  InputValues inputs{{"fn_n", fn_n}, {"v_mm_s", v_mm_s}};
  for (const auto& kv : covariates) {
    if (kv.first != "fn_n" && kv.first != "v_mm_s") inputs.push_back(kv);
  }
  return inputs;
}

bool IsOutside(const StochasticFrictionModel& model,
               const std::string& input,
               double value) {
  auto it = model.inputs.find(input);
  return it != model.inputs.end() &&
         (value < it->second.min || value > it->second.max);
}

}  // namespace

const char* ToString(SlidingSpeedStatus s) {
  switch (s) {
    case SlidingSpeedStatus::kOk:
      return "ok";
    case SlidingSpeedStatus::kNoSpeedTerm:
      return "no_speed_term";
    case SlidingSpeedStatus::kNonLinearInV:
      return "non_linear_in_v";
  }
  return "unknown";
}

TargetForce CalcTargetTangentialForce(const StochasticFrictionModel& model,
                                      double fn_n,
                                      double v_mm_s,
                                      const InputValues& covariates) {
  CheckForce("fn_n", fn_n, false);
  if (!(v_mm_s >= 0) || !std::isfinite(v_mm_s)) {
    throw std::invalid_argument("v_mm_s = " + std::to_string(v_mm_s) +
                                " (must be finite and >= 0)");
  }
  // Eq. (3): Ft = (b0 + b1 v_d + b2 Fn) Fn = mu_hat(Fn, v_d) Fn.
  const MuPrediction p = PredictMu(model, WithForces(covariates, fn_n, v_mm_s));
  TargetForce out;
  out.mu = p.mu;
  out.ft_n = p.mu * fn_n;
  out.ft_lo95_n = p.lo95 * fn_n;
  out.ft_hi95_n = p.hi95 * fn_n;
  out.extrapolated = p.extrapolated;
  out.extrapolated_inputs = p.extrapolated_inputs;
  return out;
}

SlidingSpeed PredictSlidingSpeed(const StochasticFrictionModel& model,
                                 double fn_n,
                                 double ft_n,
                                 const InputValues& covariates) {
  CheckForce("fn_n", fn_n, false);
  CheckForce("ft_n", ft_n, true);
  SlidingSpeed out;
  out.ratio = ft_n / fn_n;
  const RegressionModel& m = model.mu;
  int k_v = -1;
  for (std::size_t k = 0; k < m.terms.size(); ++k) {
    const Term& t = m.terms[k];
    if (t.input != "v_mm_s") continue;
    if (t.kind != TermKind::kLinear) {
      out.status = SlidingSpeedStatus::kNonLinearInV;
      out.why = "term " + t.Name() +
                " reads v_mm_s; eq. (4) needs mu linear in v_mm_s";
      return out;
    }
    k_v = static_cast<int>(k);
  }
  if (k_v < 0 || k_v >= m.beta.size() || m.beta(k_v) == 0.0 ||
      !std::isfinite(m.beta(k_v))) {
    out.status = SlidingSpeedStatus::kNoSpeedTerm;
    out.why =
        "the model has no identified v_mm_s slope (b1 = 0): the fitted "
        "strokes did not vary the sliding speed, so forces cannot tell it";
    return out;
  }
  out.b1 = m.beta(k_v);
  const double se =
      k_v < m.std_err.size() ? m.std_err(k_v) : 0.0;  // 0 when not stored
  out.b1_t = se > 0 ? out.b1 / se : 0.0;
  // mu_hat(Fn, v = 0) = b0 + b2 Fn (+ covariate terms at their values).
  const double mu0 = PredictMu(model, WithForces(covariates, fn_n, 0.0)).mu;
  // Eq. (4): v = (Ft/Fn - b0 - b2 Fn) / b1. With eps, Ft/Fn = mu0 + b1 v +
  // eps, so v = (ratio - mu0 - eps) / b1 at the eps quantiles.
  out.v_mm_s = (out.ratio - mu0) / out.b1;
  const double a = (out.ratio - mu0 - CalcEpsQuantile(m, 0.975)) / out.b1;
  const double b = (out.ratio - mu0 - CalcEpsQuantile(m, 0.025)) / out.b1;
  out.v_lo95_mm_s = std::min(a, b);
  out.v_hi95_mm_s = std::max(a, b);
  // No tangential force drives no sliding: Ft/Fn = 0 is not a sliding state
  // whatever speed the line gives (where b0 + b2 Fn < 0 it gives v > 0).
  out.below_model_range = out.v_mm_s < 0 || !(out.ratio > 0);
  out.extrapolated =
      IsOutside(model, "v_mm_s", out.v_mm_s) || IsOutside(model, "fn_n", fn_n);
  out.status = SlidingSpeedStatus::kOk;
  return out;
}

}  // namespace frictiond
