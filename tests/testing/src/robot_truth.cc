#include "frictiond/testing/robot_truth.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>

namespace frictiond::testing {

namespace {

// Noise of one stroke: eps weighted by w(v), plus sensor noise.
struct Noise {
  std::mt19937_64 rng;
  std::normal_distribution<double> normal{0.0, 1.0};
  double Draw(const RobotTruth& truth, double v_mm_s) {
    const double r = v_mm_s / truth.v0_mm_s;
    const double w = 1.0 - std::exp(-r * r);
    const double eps = truth.sigma_eps * normal(rng);
    return w * eps + truth.sensor_noise_mu * normal(rng);
  }
};

// Simulates one stroke at constant Fn from bristle state z0 over the
// speed profile v (at t0_s + k / rate) and appends the samples.
void AppendStroke(const RobotTruth& truth,
                  double fn_n,
                  const std::vector<double>& v,
                  double z0_mm,
                  double t0_s,
                  Noise* noise,
                  StrokeData* out) {
  const auto n = static_cast<Eigen::Index>(v.size());
  Eigen::VectorXd t(n), speed(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    t[k] = static_cast<double>(k) / truth.rate_hz;
    speed[k] = v[static_cast<std::size_t>(k)];
  }
  const VelocityDrivenResult r =
      SimulateVelocityDriven(truth.ThetaAt(fn_n), t, speed, z0_mm);
  if (r.status != SimulationStatus::kOk)
    throw std::runtime_error("robot truth: LuGre simulation failed: " + r.why);
  for (Eigen::Index k = 0; k < n; ++k) {
    const double mu = r.mu[k] + noise->Draw(truth, speed[k]);
    out->t_s.push_back(t0_s + t[k]);
    out->fn_n.push_back(fn_n);
    out->ft_n.push_back(std::abs(mu) * fn_n);
    out->v_mm_s.push_back(speed[k]);
  }
}

// Triangle 0 -> peak -> 0 at |dv/dt| = accel, sampled at rate, preceded by
// `before` and followed by `after` samples at rest.
std::vector<double> Triangle(
    double accel, double peak, double rate, int before, int after) {
  const double ramp_s = peak / accel;
  const int moving = static_cast<int>(std::ceil(2 * ramp_s * rate));
  std::vector<double> v(static_cast<std::size_t>(before), 0.0);
  for (int k = 0; k <= moving; ++k) {
    const double u = k / rate;  // time since the motion began
    const double up = accel * u, down = accel * (2 * ramp_s - u);
    v.push_back(std::max(0.0, std::min(up, down)));
  }
  v.insert(v.end(), static_cast<std::size_t>(after), 0.0);
  return v;
}

}  // namespace

LuGreTheta RobotTruth::ThetaAt(double fn_n) const {
  const double mu_c = b0 + b2 * fn_n;
  return MakeLuGreTheta(
      mu_c + static_excess, mu_c, v0_mm_s, b1, sigma0_per_mm, sigma1_s_mm);
}

StrokeData SimulateTruthSweep(const RobotTruth& truth,
                              double fn_min_n,
                              double fn_max_n,
                              double v_min_mm_s,
                              double v_max_mm_s,
                              std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unif(0.0, 1.0);
  Noise noise{std::mt19937_64(seed * 7919 + 13)};
  StrokeData d;
  const int n_rest = static_cast<int>(truth.rest_s * truth.rate_hz);
  const int n_slip = static_cast<int>(truth.slip_s * truth.rate_hz);
  double t0_s = 0.0;
  for (int s = 0; s < truth.strokes; ++s) {
    const double fn = fn_min_n + (fn_max_n - fn_min_n) * unif(rng);
    const double v_peak = v_min_mm_s + (v_max_mm_s - v_min_mm_s) * unif(rng);
    const LuGreTheta theta = truth.ThetaAt(fn);
    const double mu_c = theta[LuGreIndex::kMuCoulomb];
    const double mu_s = theta[LuGreIndex::kMuStatic];
    // Loading: mu = sigma0 z follows r(t) = (0.1 + 0.8 t / rest) mu_c; from
    // dz/dt = v (1 - sigma0 z / g(0)) (eq. 1 at creep speed, g ~ mu_s):
    // v = r'(t) / (sigma0 (1 - r / mu_s)).
    std::vector<double> v(static_cast<std::size_t>(n_rest + n_slip));
    for (int i = 0; i < n_rest; ++i) {
      const double r = (0.1 + 0.8 * i / n_rest) * mu_c;
      const double rate = 0.8 * mu_c / truth.rest_s;
      v[static_cast<std::size_t>(i)] =
          rate / (truth.sigma0_per_mm * (1.0 - r / mu_s));
    }
    for (int i = 0; i < n_slip; ++i) {
      const double phase = (i + 0.5) / n_slip;
      v[static_cast<std::size_t>(n_rest + i)] =
          std::max(v[static_cast<std::size_t>(n_rest - 1)],
                   v_peak * std::sin(M_PI * phase));
    }
    const double z0 = 0.1 * mu_c / truth.sigma0_per_mm;
    AppendStroke(truth, fn, v, z0, t0_s, &noise, &d);
    t0_s = d.t_s.back() + 1.0 / truth.rate_hz;
  }
  return d;
}

StrokeData SimulateTruthLuGrePair(const RobotTruth& truth,
                                  const LuGrePairShape& shape,
                                  std::uint64_t seed) {
  Noise noise{std::mt19937_64(seed * 104729 + 5)};
  StrokeData d;
  const int half = std::max(
      1, static_cast<int>(std::round(0.5 * shape.rest_s * truth.rate_hz)));
  // Each ramp: released rest (z = 0), the triangle, held rest.
  auto ramp = [&](double accel, double peak) {
    const std::vector<double> v =
        Triangle(accel, peak, truth.rate_hz, half, half);
    const double t0 = d.empty() ? 0.0 : d.t_s.back() + 1.0 / truth.rate_hz;
    AppendStroke(truth, shape.fn_n, v, 0.0, t0, &noise, &d);
  };
  ramp(shape.slow_accel_mm_s2, shape.slow_peak_mm_s);
  for (int k = 0; k < shape.fast_strokes; ++k)
    ramp(shape.fast_accel_mm_s2, shape.fast_peak_mm_s);
  return d;
}

std::string CompareLuGreToTruth(const LuGreTheta& estimate,
                                const LuGreTheta& truth,
                                const LuGreTolerances& tolerances) {
  static const char* const kNames[6] = {
      "mu_s", "mu_c", "v0_mm_s", "sigma2_s_mm", "sigma0_per_mm", "sigma1_s_mm"};
  const double tol[6] = {tolerances.mu_s,
                         tolerances.mu_c,
                         tolerances.v0,
                         tolerances.sigma2,
                         tolerances.sigma0,
                         tolerances.sigma1};
  std::string out;
  for (int i = 0; i < 6; ++i) {
    const double rel = std::abs(estimate[i] - truth[i]) / std::abs(truth[i]);
    if (rel <= tol[i]) continue;  // NaN fails
    char buf[200];
    std::snprintf(buf,
                  sizeof buf,
                  "%s = %.6g (truth %.6g, error %.1f %% > %.1f %%)",
                  kNames[i],
                  estimate[i],
                  truth[i],
                  100 * rel,
                  100 * tol[i]);
    out += (out.empty() ? "" : "; ") + std::string(buf);
  }
  return out;
}

}  // namespace frictiond::testing
