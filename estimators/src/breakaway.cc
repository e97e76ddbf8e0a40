#include "frictiond/estimators/breakaway.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "frictiond/estimators/number_text.h"

namespace frictiond {

ForceDrivenResult PredictBreakawayRatio(const LuGreTheta& theta,
                                        double rho_per_s,
                                        double fn_n,
                                        const ForceDrivenOptions& options) {
  return SimulateForceDriven(theta, rho_per_s, fn_n, options, nullptr);
}

double CalcHeldBristleDeflection(const LuGreTheta& theta,
                                 double mu_applied,
                                 double v_mm_s) {
  ValidateLuGreTheta(theta);
  if (!std::isfinite(mu_applied))
    throw std::invalid_argument("mu_applied = " + std::to_string(mu_applied) +
                                " (must be finite)");
  if (!std::isfinite(v_mm_s))
    throw std::invalid_argument("v_mm_s = " + std::to_string(v_mm_s) +
                                " (must be finite)");
  const double sigma0 = theta[LuGreIndex::kStiffness];
  const double sigma1 = theta[LuGreIndex::kDamping];
  const double sigma2 = theta[LuGreIndex::kViscous];
  // Eq. 9 with eq. 8 for dz/dt, solved for z at mu_f = mu_e (eq. 17, dv/dt
  // = 0).
  const double damping =
      1.0 - sigma1 * std::abs(v_mm_s) / CalcStribeckRatio(theta, v_mm_s);
  if (!(damping > 0))
    throw std::invalid_argument(
        "v_mm_s = " + std::to_string(v_mm_s) +
        " (sigma1 |v| / g(v) must be < 1 for a held state)");
  const double z =
      (mu_applied - (sigma1 + sigma2) * v_mm_s) / (sigma0 * damping);
  // LuGre keeps |z| <= max_v g(v) / sigma0 = max(mu_s, mu_c) / sigma0 for
  // every history that starts inside that bound (Canudas de Wit et al.
  // 1995, Property 1): a deflection beyond it is no state a contact can
  // reach. Held (v = 0) this says mu_applied <= mu_s: a larger Ft/Fn has
  // already broken away.
  const double g_max =
      std::max(theta[LuGreIndex::kMuStatic], theta[LuGreIndex::kMuCoulomb]);
  if (sigma0 * std::abs(z) > g_max * (1 + 1e-12))
    throw std::invalid_argument(
        "mu_applied = " + NumberText(mu_applied) +
        " implies a bristle deflection with sigma0 |z| = " +
        NumberText(sigma0 * std::abs(z)) +
        " above the static ratio mu_s = " + NumberText(g_max) +
        " (the LuGre bound |z| <= max g / sigma0): no contact holds it, it "
        "has broken away already");
  return z;
}

ForceDrivenResult PredictBreakawayRatioFromState(
    const LuGreTheta& theta,
    double mu_applied,
    double v_mm_s,
    double rho_per_s,
    double fn_n,
    const ForceDrivenOptions& options) {
  if (!(mu_applied >= 0) || !std::isfinite(mu_applied))
    throw std::invalid_argument("mu_applied = " + std::to_string(mu_applied) +
                                " (must be finite and >= 0)");
  ForceDrivenOptions o = options;
  o.mu_applied0 = mu_applied;  // eq. 16: mu_e(t0), the measured Ft/Fn
  o.initial_v_mm_s = v_mm_s;
  o.initial_z_mm = CalcHeldBristleDeflection(theta, mu_applied, v_mm_s);
  return SimulateForceDriven(theta, rho_per_s, fn_n, o, nullptr);
}

ForceDrivenResult PredictLiftBreakawayRatio(const LuGreTheta& theta,
                                            double jerk_m_s3,
                                            double fn_n,
                                            const ForceDrivenOptions& options,
                                            double accel0_m_s2) {
  if (!(jerk_m_s3 > 0) || !std::isfinite(jerk_m_s3))
    throw std::invalid_argument("jerk_m_s3 = " + std::to_string(jerk_m_s3) +
                                " (must be finite and > 0)");
  if (!(accel0_m_s2 + kGravityM_S2 >= 0) || !std::isfinite(accel0_m_s2))
    throw std::invalid_argument("accel0_m_s2 = " + std::to_string(accel0_m_s2) +
                                " (must be finite and >= -g)");
  if (!(fn_n > 0) || !std::isfinite(fn_n))
    throw std::invalid_argument("fn_n = " + std::to_string(fn_n) +
                                " (must be finite and > 0)");
  std::string why;
  if (!options.IsValid(&why))
    throw std::invalid_argument("ForceDrivenOptions." + why);
  // Section II.B: a_of = a + g - Ft/m, i.e. eq. 17 with mu_e = m (g + a)/Fn.
  const double m = options.mass_kg;
  const double mu_e0 = m * (kGravityM_S2 + accel0_m_s2) / fn_n;
  const double rho = m * jerk_m_s3 / fn_n;
  return PredictBreakawayRatioFromState(theta, mu_e0, 0.0, rho, fn_n, options);
}

bool BreakawayMonitorOptions::IsValid(std::string* why) const {
  std::string sub;
  if (!simulation.IsValid(&sub)) {
    if (why) *why = "simulation." + sub;
    return false;
  }
  auto fail = [why](const char* field, double value, const char* rule) {
    if (why)
      *why = std::string(field) + " = " + std::to_string(value) + " (must be " +
             rule + ")";
    return false;
  };
  if (!(fn_n > 0) || !std::isfinite(fn_n))
    return fail("fn_n", fn_n, "finite and > 0");
  if (!(min_rho_per_s > 0) || !std::isfinite(min_rho_per_s))
    return fail("min_rho_per_s", min_rho_per_s, "finite and > 0");
  if (!(rho_rel_change >= 0) || !std::isfinite(rho_rel_change))
    return fail("rho_rel_change", rho_rel_change, "finite and >= 0");
  return true;
}

BreakawayMonitor::BreakawayMonitor(const LuGreTheta& theta,
                                   const BreakawayMonitorOptions& options)
    : theta_(theta), options_(options) {
  ValidateLuGreTheta(theta_);
  std::string why;
  if (!options_.IsValid(&why))
    throw std::invalid_argument("BreakawayMonitorOptions." + why);
}

BreakawayEstimate BreakawayMonitor::Update(double mu_applied,
                                           double rho_per_s,
                                           double v_mm_s) {
  if (!std::isfinite(mu_applied))
    throw std::invalid_argument("mu_applied = " + std::to_string(mu_applied) +
                                " (must be finite)");
  if (!std::isfinite(rho_per_s))
    throw std::invalid_argument("rho_per_s = " + std::to_string(rho_per_s) +
                                " (must be finite)");
  const double rho =
      rho_per_s < options_.min_rho_per_s ? options_.min_rho_per_s : rho_per_s;
  if (!std::isfinite(v_mm_s))
    throw std::invalid_argument("v_mm_s = " + std::to_string(v_mm_s) +
                                " (must be finite)");
  const bool reuse =
      !options_.from_measured_state && simulations_ > 0 &&
      std::abs(rho - last_rho_) <= options_.rho_rel_change * last_rho_;
  if (!reuse) {
    const ForceDrivenResult p =
        options_.from_measured_state
            ? PredictBreakawayRatioFromState(theta_,
                                             mu_applied,
                                             v_mm_s,
                                             rho,
                                             options_.fn_n,
                                             options_.simulation)
            : SimulateForceDriven(
                  theta_, rho, options_.fn_n, options_.simulation);
    ++simulations_;
    last_rho_ = rho;
    last_bf_ = p.bf_ratio;
    last_t_breakaway_s_ = p.t_breakaway_s;
    last_status_ = p.status;
  }
  BreakawayEstimate e;
  e.status = last_status_;
  e.bf_ratio = last_bf_;
  e.mu_applied = mu_applied;
  e.rho_per_s = last_rho_;
  if (e.status == SimulationStatus::kOk) {
    e.margin = (e.bf_ratio - mu_applied) / e.bf_ratio;
    e.slip_predicted = mu_applied >= e.bf_ratio;
    e.t_breakaway_s = last_t_breakaway_s_;
  } else {
    e.margin = std::numeric_limits<double>::quiet_NaN();
    e.t_breakaway_s = std::numeric_limits<double>::quiet_NaN();
    e.slip_predicted = false;
  }
  last_ = e;
  return e;
}

}  // namespace frictiond
