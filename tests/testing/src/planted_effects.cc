#include "frictiond/testing/planted_effects.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>

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

std::string ToString(WideKind kind) {
  switch (kind) {
    case WideKind::kSmoothCurve:
      return "smooth_curve";
    case WideKind::kInteraction:
      return "interaction";
    case WideKind::kSpread:
      return "spread";
    case WideKind::kCategorical:
      return "categorical";
    case WideKind::kNullHeavyTail:
      return "null_heavy_tail";
    case WideKind::kNullOffsets:
      return "null_offsets";
    case WideKind::kNullArNoise:
      return "null_ar_noise";
    case WideKind::kNullManyColumns:
      return "null_many_columns";
    case WideKind::kCategoricalBounded:
      return "categorical_bounded";
  }
  return "unknown";
}

bool IsNull(WideKind kind) {
  return kind == WideKind::kNullHeavyTail || kind == WideKind::kNullOffsets ||
         kind == WideKind::kNullArNoise || kind == WideKind::kNullManyColumns;
}

WideCase GenerateWideCase(WideKind kind,
                          std::uint64_t seed,
                          int strokes,
                          double categorical_sd) {
  // kCategoricalBounded draws what kCategorical draws (same stream).
  const WideKind stream =
      kind == WideKind::kCategoricalBounded ? WideKind::kCategorical : kind;
  std::mt19937_64 rng(seed * 7919 + static_cast<std::uint64_t>(stream));
  std::uniform_real_distribution<double> unif(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  PlantedSpec spec;
  spec.strokes = strokes;
  spec.write_labels = true;  // to know the slipping samples; removed below
  if (kind == WideKind::kNullOffsets) spec.stroke_offset_sd = 0.15;
  if (kind == WideKind::kNullArNoise) spec.ar_rho = 0.995;
  if (kind == WideKind::kNullManyColumns) spec.noise_columns = 20;
  WideCase out;
  out.data = GeneratePlantedStrokes(spec, seed);
  StrokeData& d = out.data;
  const std::size_t n = d.size();
  // A meaningless column name: 2-4 letters and 1-2 digits.
  std::string name;
  const int letters = 2 + static_cast<int>(unif(rng) * 3);
  for (int k = 0; k < letters; ++k)
    name += static_cast<char>('a' + static_cast<int>(unif(rng) * 26) % 26);
  name += std::to_string(static_cast<int>(unif(rng) * 90) + 1);
  // Per-stroke values of the new column (and a slow drift within strokes).
  std::vector<double> per_stroke(strokes);
  for (double& v : per_stroke) v = normal(rng);
  std::vector<double> z(n);
  double t0 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (i == 0 || d.stroke[i] != d.stroke[i - 1]) t0 = d.t_s[i];
    z[i] = per_stroke[d.stroke[i]];
    if (kind == WideKind::kSmoothCurve) z[i] += 0.3 * (d.t_s[i] - t0);
  }
  auto add_mu = [&](std::size_t i, double dmu) {
    if (d.slip[i] == 1) d.ft_n[i] = std::max(0.0, d.ft_n[i] + dmu * d.fn_n[i]);
  };
  switch (kind) {
    case WideKind::kSmoothCurve: {
      // Random smooth curve: 3 harmonics, random amplitudes and phases,
      // scaled to a standard deviation of 0.05 over the column's values.
      const double lo = -2.5, hi = 2.5;
      double a[3], ph[3];
      for (int k = 0; k < 3; ++k)
        a[k] = normal(rng) / (k + 1), ph[k] = 2 * M_PI * unif(rng);
      auto f = [&](double x) {
        const double u = (std::min(std::max(x, lo), hi) - lo) / (hi - lo);
        double s = 0.0;
        for (int k = 0; k < 3; ++k)
          s += a[k] * std::sin(M_PI * (k + 1) * u + ph[k]);
        return s;
      };
      double m = 0.0, ss = 0.0;
      for (double v : per_stroke) m += f(v);
      m /= strokes;
      for (double v : per_stroke) ss += (f(v) - m) * (f(v) - m);
      const double scale = 0.05 / std::max(1e-9, std::sqrt(ss / strokes));
      for (std::size_t i = 0; i < n; ++i) add_mu(i, scale * (f(z[i]) - m));
      out.cause = name;
      out.kind = "covariate";
      out.truth = "random smooth curve of " + name;
      break;
    }
    case WideKind::kInteraction: {
      const double size =
          (unif(rng) < 0.5 ? -1.0 : 1.0) * (0.03 + 0.02 * unif(rng));
      for (std::size_t i = 0; i < n; ++i)
        add_mu(i, size * (d.fn_n[i] - 2.5) * z[i]);
      out.cause = std::min(name, std::string("fn_n")) + "*" +
                  std::max(name, std::string("fn_n"));
      out.kind = "interaction";
      out.truth = "Fn slope changes by " + std::to_string(size) +
                  " per unit of " + name;
      break;
    }
    case WideKind::kSpread: {
      const double growth = 0.6 + 0.4 * unif(rng);
      for (std::size_t i = 0; i < n; ++i)
        add_mu(i, 0.03 * std::exp(growth * z[i]) * normal(rng));
      out.cause = name;
      out.kind = "spread";
      out.truth =
          "eps scale x exp(" + std::to_string(growth) + " " + name + ")";
      break;
    }
    case WideKind::kCategorical:
    case WideKind::kCategoricalBounded: {
      const int levels = 3 + static_cast<int>(unif(rng) * 3) % 3;
      std::vector<double> code(levels), shift(levels);
      for (int l = 0; l < levels; ++l) {
        code[l] = 10.0 * (l + 1) + static_cast<int>(unif(rng) * 9);
        shift[l] = 0.06 * normal(rng);
      }
      std::vector<int> level(strokes);
      for (int& l : level) l = static_cast<int>(unif(rng) * levels) % levels;
      // Mean and standard deviation of the shifts over the strokes (each
      // stroke weighted once).
      auto stroke_mean_sd = [&] {
        double m = 0.0, ss = 0.0;
        for (int l : level) m += shift[l];
        m /= strokes;
        for (int l : level) ss += (shift[l] - m) * (shift[l] - m);
        return std::pair<double, double>(m, std::sqrt(ss / strokes));
      };
      if (kind == WideKind::kCategoricalBounded) {
        // The same pattern of shifts, centred and scaled to a standard
        // deviation over the strokes drawn from 0.04-0.06 (drawn last, so
        // everything above matches kCategorical's draws).
        const auto [m, sd] = stroke_mean_sd();
        const double drawn = 0.04 + 0.02 * unif(rng);
        const double target = categorical_sd > 0 ? categorical_sd : drawn;
        const double scale = target / std::max(1e-12, sd);
        for (double& s : shift) s = (s - m) * scale;
      }
      out.effect_sd = stroke_mean_sd().second;
      for (std::size_t i = 0; i < n; ++i) {
        const int l = level[d.stroke[i]];
        z[i] = code[l];
        add_mu(i, shift[l]);
      }
      out.cause = name;
      out.kind = "covariate";
      out.truth = std::to_string(levels) + " levels of " + name + ", shifts";
      for (double s : shift) out.truth += " " + std::to_string(s);
      break;
    }
    case WideKind::kNullHeavyTail: {
      std::student_t_distribution<double> t(2.5);
      for (std::size_t i = 0; i < n; ++i) add_mu(i, 0.02 * t(rng));
      out.truth = "null, Student-t noise";
      break;
    }
    case WideKind::kNullOffsets:
      out.truth = "null, large stroke offsets";
      break;
    case WideKind::kNullArNoise:
      out.truth = "null, AR(1) rho 0.995";
      break;
    case WideKind::kNullManyColumns:
      out.truth = "null, 20 irrelevant columns";
      break;
  }
  d.covariate_names.push_back(name);
  d.covariates.push_back(std::move(z));
  d.slip.clear();
  d.stroke.clear();
  return out;
}

}  // namespace frictiond::testing
