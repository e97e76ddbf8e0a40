#include "frictiond/testing/planted_effects.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace frictiond::testing {

std::string PlantedCause(PlantedEffect effect) {
  switch (effect) {
    case PlantedEffect::kNone:
      return "";
    case PlantedEffect::kTemperature:
      return "temp_c";
    case PlantedEffect::kDirection:
      return "dir_deg";
    case PlantedEffect::kWear:
      return "distance_mm";
    case PlantedEffect::kOnsetTransient:
      return "dwell_s";
    case PlantedEffect::kNonlinearFn:
      return "fn_n";
    case PlantedEffect::kPositionPatch:
      return "contact_x_mm";
  }
  return "";
}

std::string ToString(PlantedEffect effect) {
  switch (effect) {
    case PlantedEffect::kNone:
      return "none";
    case PlantedEffect::kTemperature:
      return "temperature";
    case PlantedEffect::kDirection:
      return "direction";
    case PlantedEffect::kWear:
      return "wear";
    case PlantedEffect::kOnsetTransient:
      return "onset_transient";
    case PlantedEffect::kNonlinearFn:
      return "nonlinear_fn";
    case PlantedEffect::kPositionPatch:
      return "position_patch";
  }
  return "?";
}

double DefaultPlantedSize(PlantedEffect effect) {
  switch (effect) {
    case PlantedEffect::kNone:
      return 0.0;
    case PlantedEffect::kTemperature:
      return 0.1;
    case PlantedEffect::kDirection:
      return 0.06;
    case PlantedEffect::kWear:
      return 0.1;
    case PlantedEffect::kOnsetTransient:
      return 0.1;
    case PlantedEffect::kNonlinearFn:
      return 0.15;
    case PlantedEffect::kPositionPatch:
      return 0.1;
  }
  return 0.0;
}

StrokeData GeneratePlantedStrokes(const PlantedSpec& spec, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unif(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double size =
      spec.size != 0.0 ? spec.size : DefaultPlantedSize(spec.effect);
  StrokeData d;
  d.covariate_names = {"temp_c", "dir_deg", "contact_x_mm"};
  for (int k = 0; k < spec.noise_columns; ++k)
    d.covariate_names.push_back("noise_" + std::to_string(k));
  d.covariates.resize(d.covariate_names.size());
  const double dt = 1.0 / spec.rate_hz;
  const double innov = std::sqrt(1.0 - spec.ar_rho * spec.ar_rho);
  auto log_uniform = [&](double lo, double hi) {
    return lo * std::exp(std::log(hi / lo) * unif(rng));
  };
  double t = 0.0;
  double distance = 0.0;
  double temp = 25.0;
  std::vector<double> noise_state(spec.noise_columns, 0.0);
  for (int s = 0; s < spec.strokes; ++s) {
    const double fn_mean =
        spec.fn_min_n + (spec.fn_max_n - spec.fn_min_n) * unif(rng);
    const double fn_amp = 0.25 * std::min(fn_mean - 0.1, 1.0) * unif(rng);
    // The session alternates blocks of 25 fast strokes with short rests and
    // 25 slow strokes with long rests, so that sliding distance is not a
    // smooth function of elapsed time (otherwise wear with distance could not
    // be told from a drift in time).
    const bool fast_block = (s / 25) % 2 == 0;
    const double v_peak =
        std::max(0.5 * spec.v_min_mm_s,
                 (fast_block ? 1.5 : 0.5) *
                     log_uniform(spec.v_min_mm_s, spec.v_max_mm_s));
    const double rest = (fast_block ? 0.5 : 3.0) *
                        log_uniform(spec.rest_min_s, spec.rest_max_s);
    const double slip =
        spec.slip_min_s + (spec.slip_max_s - spec.slip_min_s) * unif(rng);
    const double offset = spec.stroke_offset_sd * normal(rng);
    temp = 25.0 + 0.6 * (temp - 25.0) + 4.0 * normal(rng);
    const double dir = 360.0 * unif(rng);
    const double x0 = 5.0 + 30.0 * unif(rng);
    std::vector<double> stroke_noise(spec.noise_columns);
    for (double& v : stroke_noise) v = normal(rng);
    // The unrecorded part of the rest is a time gap before the recorded part.
    const double recorded_rest = std::min(rest, spec.recorded_rest_s);
    if (s > 0) t += rest - recorded_rest;
    const int n_rest = std::max(
        1, static_cast<int>(std::lround(recorded_rest * spec.rate_hz)));
    const int n_slip = static_cast<int>(std::lround(slip * spec.rate_hz));
    const double dwell = s > 0 ? rest : recorded_rest;
    double eps = spec.sigma_eps * normal(rng);
    double stroke_distance = 0.0;
    for (int i = 0; i < n_rest + n_slip; ++i) {
      const bool slipping = i >= n_rest;
      const double ts = i * dt;
      const double fn =
          fn_mean + fn_amp * std::sin(2 * M_PI * ts / (recorded_rest + slip));
      double v = 0.0;
      double since_onset = 0.0;
      if (slipping) {
        const double phase = (i - n_rest + 0.5) / n_slip;
        v = v_peak * std::sqrt(std::sin(M_PI * phase));
        since_onset = (i - n_rest) * dt;
      }
      distance += v * dt;
      stroke_distance += v * dt;
      eps = spec.ar_rho * eps + innov * spec.sigma_eps * normal(rng);
      const double temp_now = temp + 0.2 * ts + 0.05 * normal(rng);
      const double x_now = x0 + 0.3 * stroke_distance;
      double mu = spec.b0 + spec.b1 * v + spec.b2 * fn + offset + eps;
      switch (spec.effect) {
        case PlantedEffect::kNone:
          break;
        case PlantedEffect::kTemperature:
          mu += size * (temp_now - 25.0) / 10.0;
          break;
        case PlantedEffect::kDirection:
          mu += size * std::cos((dir - 40.0) * M_PI / 180.0);
          break;
        case PlantedEffect::kWear:
          mu -= size * distance / 1000.0;
          break;
        case PlantedEffect::kOnsetTransient:
          if (slipping) mu += size * dwell * std::exp(-since_onset / 0.15);
          break;
        case PlantedEffect::kNonlinearFn: {
          const double u = (fn - 2.5) / 2.0;
          mu += size * u * u;
          break;
        }
        case PlantedEffect::kPositionPatch:
          if (x_now >= 20.0 && x_now < 26.0) mu += size;
          break;
      }
      double ft;
      if (slipping) {
        ft = mu * fn;
      } else {
        const double frac = 0.1 + 0.75 * (static_cast<double>(i) / n_rest);
        ft = frac * (spec.b0 + spec.b2 * fn) * fn * (1.0 + 0.03 * normal(rng));
      }
      const double v_measured = std::max(0.0, v + 0.3 * normal(rng));
      d.t_s.push_back(t);
      d.fn_n.push_back(fn);
      d.ft_n.push_back(std::max(0.0, ft));
      d.v_mm_s.push_back(v_measured);
      if (spec.write_labels) {
        d.slip.push_back(slipping && v > 5.0 ? 1 : 0);
        d.stroke.push_back(s);
      }
      d.covariates[0].push_back(temp_now);
      d.covariates[1].push_back(dir);
      d.covariates[2].push_back(x_now);
      for (int k = 0; k < spec.noise_columns; ++k) {
        if (k % 2 == 0) {
          noise_state[k] =
              0.98 * noise_state[k] + std::sqrt(1 - 0.98 * 0.98) * normal(rng);
          d.covariates[3 + k].push_back(noise_state[k]);
        } else {
          d.covariates[3 + k].push_back(stroke_noise[k]);
        }
      }
      t += dt;
    }
  }
  return d;
}

}  // namespace frictiond::testing
