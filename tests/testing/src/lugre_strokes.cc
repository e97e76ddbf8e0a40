#include "frictiond/testing/lugre_strokes.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace frictiond::testing {

StrokeData SimulateLuGreStrokes(const LuGreStrokeSpec& spec,
                                std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, spec.noise_mu);
  StrokeData d;
  d.slip.clear();
  d.stroke.clear();
  double t0_s = 0.0;
  for (int s = 0; s < spec.strokes; ++s) {
    const double vp =
        spec.v_min_mm_s + (spec.v_max_mm_s - spec.v_min_mm_s) * unit(rng);
    const double a = spec.accel_min_mm_s2 +
                     (spec.accel_max_mm_s2 - spec.accel_min_mm_s2) * unit(rng);
    const double fn =
        spec.fn_min_n + (spec.fn_max_n - spec.fn_min_n) * unit(rng);
    const double ramp_s = vp / a;
    const double duration_s = 2 * spec.rest_s + 2 * ramp_s + spec.hold_s;
    const int n = static_cast<int>(std::round(duration_s * spec.rate_hz)) + 1;
    Eigen::VectorXd t(n), v(n);
    for (int k = 0; k < n; ++k) {
      t[k] = k / spec.rate_hz;
      const double u = t[k] - spec.rest_s;  // time since motion began
      double speed = 0.0;
      if (u > 0 && u < ramp_s) {
        speed = a * u;
      } else if (u >= ramp_s && u <= ramp_s + spec.hold_s) {
        speed = vp;
      } else if (u > ramp_s + spec.hold_s && u < 2 * ramp_s + spec.hold_s) {
        speed = vp - a * (u - ramp_s - spec.hold_s);
      }
      v[k] = std::max(0.0, speed);
    }
    const VelocityDrivenResult r =
        SimulateVelocityDriven(spec.theta, t, v, 0.0);
    if (r.status != SimulationStatus::kOk)
      throw std::runtime_error("SimulateLuGreStrokes: stroke " +
                               std::to_string(s) + ": " + r.why);
    for (int k = 0; k < n; ++k) {
      d.t_s.push_back(t0_s + t[k]);
      d.fn_n.push_back(fn);
      d.ft_n.push_back(std::abs(r.mu[k] + noise(rng)) * fn);
      d.v_mm_s.push_back(v[k]);
      d.slip.push_back(v[k] >= 5.0 ? 1 : 0);
      d.stroke.push_back(s);
    }
    t0_s += duration_s + spec.gap_s;
  }
  return d;
}

}  // namespace frictiond::testing
