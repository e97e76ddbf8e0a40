#include "frictiond/estimators/mu_windows.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace frictiond {

std::vector<MuWindowStd> CalcMuStdByWindow(
    const std::vector<double>& fn_n,
    const std::vector<double>& v_mm_s,
    const std::vector<double>& mu,
    double fn_center_n,
    double v_center_mm_s,
    const std::vector<double>& fn_widths_n,
    const std::vector<double>& v_widths_mm_s) {
  if (fn_n.size() != mu.size() || v_mm_s.size() != mu.size()) {
    throw std::invalid_argument(
        "fn_n, v_mm_s and mu have " + std::to_string(fn_n.size()) + ", " +
        std::to_string(v_mm_s.size()) + " and " + std::to_string(mu.size()) +
        " entries (must be equal)");
  }
  if (fn_widths_n.size() != v_widths_mm_s.size()) {
    throw std::invalid_argument(
        "fn_widths_n has " + std::to_string(fn_widths_n.size()) +
        " entries, v_widths_mm_s " + std::to_string(v_widths_mm_s.size()) +
        " (must be equal)");
  }
  for (std::size_t k = 0; k < fn_widths_n.size(); ++k) {
    if (!(fn_widths_n[k] > 0))
      throw std::invalid_argument("fn_widths_n[" + std::to_string(k) +
                                  "] = " + std::to_string(fn_widths_n[k]) +
                                  " (must be > 0)");
    if (!(v_widths_mm_s[k] > 0))
      throw std::invalid_argument("v_widths_mm_s[" + std::to_string(k) +
                                  "] = " + std::to_string(v_widths_mm_s[k]) +
                                  " (must be > 0)");
  }
  std::vector<MuWindowStd> out(fn_widths_n.size());
  for (std::size_t k = 0; k < out.size(); ++k) {
    MuWindowStd& w = out[k];
    w.fn_width_n = fn_widths_n[k];
    w.v_width_mm_s = v_widths_mm_s[k];
    const double hf = 0.5 * w.fn_width_n, hv = 0.5 * w.v_width_mm_s;
    // Welford's running mean and variance.
    double mean = 0, m2 = 0;
    int n = 0;
    for (std::size_t i = 0; i < mu.size(); ++i) {
      if (!std::isfinite(fn_n[i]) || !std::isfinite(v_mm_s[i]) ||
          !std::isfinite(mu[i]))
        continue;
      if (std::fabs(fn_n[i] - fn_center_n) > hf ||
          std::fabs(v_mm_s[i] - v_center_mm_s) > hv)
        continue;
      ++n;
      const double d = mu[i] - mean;
      mean += d / n;
      m2 += d * (mu[i] - mean);
    }
    w.samples = n;
    w.mean_mu = n > 0 ? mean : 0.0;
    w.std_mu = n > 1 ? std::sqrt(m2 / (n - 1)) : 0.0;
  }
  return out;
}

}  // namespace frictiond
