#include "frictiond/estimators/breakaway.h"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace frictiond {

ForceDrivenResult PredictBreakawayRatio(const LuGreTheta& theta,
                                        double rho_per_s,
                                        double fn_n,
                                        const ForceDrivenOptions& options) {
  return SimulateForceDriven(theta, rho_per_s, fn_n, options, nullptr);
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
                                           double rho_per_s) {
  if (!std::isfinite(mu_applied))
    throw std::invalid_argument("mu_applied = " + std::to_string(mu_applied) +
                                " (must be finite)");
  if (!std::isfinite(rho_per_s))
    throw std::invalid_argument("rho_per_s = " + std::to_string(rho_per_s) +
                                " (must be finite)");
  const double rho =
      rho_per_s < options_.min_rho_per_s ? options_.min_rho_per_s : rho_per_s;
  const bool reuse =
      simulations_ > 0 &&
      std::abs(rho - last_rho_) <= options_.rho_rel_change * last_rho_;
  if (!reuse) {
    const ForceDrivenResult p =
        SimulateForceDriven(theta_, rho, options_.fn_n, options_.simulation);
    ++simulations_;
    last_rho_ = rho;
    last_bf_ = p.bf_ratio;
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
  } else {
    e.margin = std::numeric_limits<double>::quiet_NaN();
    e.slip_predicted = false;
  }
  last_ = e;
  return e;
}

}  // namespace frictiond
