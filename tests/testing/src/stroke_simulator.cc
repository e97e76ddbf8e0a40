#include "frictiond/testing/stroke_simulator.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace frictiond::testing {

StrokeData SimulateStrokes(const SimulationSpec& spec, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unif(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  StrokeData d;
  for (const auto& c : spec.covariates) {
    d.covariate_names.push_back(c.name);
    d.covariates.emplace_back();
  }
  const double dt = 1.0 / spec.rate_hz;
  double t = 0.0;
  double distance = 0.0;
  std::vector<double> cov(spec.covariates.size());
  const double innov = std::sqrt(1.0 - spec.ar_rho * spec.ar_rho);
  for (int s = 0; s < spec.strokes; ++s) {
    const double fn_mean =
        spec.fn_min_n + (spec.fn_max_n - spec.fn_min_n) * unif(rng);
    const double fn_amp = 0.25 * std::min(fn_mean - 0.1, 1.0) * unif(rng);
    const double v_peak =
        spec.v_min_mm_s + (spec.v_max_mm_s - spec.v_min_mm_s) * unif(rng);
    const double offset = spec.stroke_offset_sd * normal(rng);
    const int n_rest = static_cast<int>(spec.rest_s * spec.rate_hz);
    const int n_slip = static_cast<int>(spec.slip_s * spec.rate_hz);
    double noise = spec.sigma_eps * normal(rng);
    const double rest_start = t;
    double dwell = 0.0;
    for (int i = 0; i < n_rest + n_slip; ++i) {
      const bool slipping = i >= n_rest;
      const double ts = i * dt;
      const double fn =
          fn_mean +
          fn_amp * std::sin(2 * M_PI * ts / (spec.rest_s + spec.slip_s));
      double v = 0.0;
      if (slipping) {
        const double phase = (i - n_rest + 0.5) / n_slip;
        v = v_peak * std::sin(M_PI * phase);
      }
      for (std::size_t k = 0; k < spec.covariates.size(); ++k)
        cov[k] = spec.covariates[k].value(s, ts, unif(rng));
      if (i == n_rest) dwell = t - rest_start;
      distance += v * dt;
      noise = spec.ar_rho * noise + innov * spec.sigma_eps * normal(rng);
      double mu = spec.b0 + spec.b1 * v + spec.b2 * fn + offset + noise;
      if (spec.extra_mu) {
        SimulationSpec::SampleView view{t,
                                        fn,
                                        v,
                                        distance,
                                        slipping ? dwell : t - rest_start,
                                        slipping ? (i - n_rest) * dt : 0.0,
                                        &cov};
        mu += spec.extra_mu(view);
      }
      double ft;
      if (slipping) {
        ft = mu * fn;
      } else {
        // Stick: the ratio ramps up towards (but below) the mean mu.
        const double frac = 0.1 + 0.8 * (double(i) / n_rest);
        ft = frac * (spec.b0 + spec.b2 * fn) * fn * (1.0 + 0.05 * normal(rng));
      }
      d.t_s.push_back(t);
      d.fn_n.push_back(fn);
      d.ft_n.push_back(std::max(0.0, ft));
      d.v_mm_s.push_back(v);
      if (spec.write_labels) {
        d.slip.push_back(slipping && v > 5.0 ? 1 : 0);
        d.stroke.push_back(s);
      }
      for (std::size_t k = 0; k < cov.size(); ++k)
        d.covariates[k].push_back(cov[k]);
      t += dt;
    }
  }
  return d;
}

}  // namespace frictiond::testing
