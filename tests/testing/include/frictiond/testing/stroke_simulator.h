#pragma once
/// @file
/// Synthetic fingertip strokes from a known stochastic friction model, for
/// known-truth tests (STYLE §10). Deterministic for a given seed.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "frictiond/estimators/stroke_data.h"

namespace frictiond::testing {

/// Truth and shape of simulated strokes.
struct SimulationSpec {
  double b0 = 0.9;          ///< intercept of mu
  double b1 = 0.004;        ///< per mm/s
  double b2 = -0.06;        ///< per N
  double sigma_eps = 0.05;  ///< white noise std of mu
  double ar_rho =
      0.0;  ///< AR(1) coefficient of the noise within a stroke (0: white)
  double stroke_offset_sd = 0.0;  ///< per-stroke random offset of mu
  int strokes = 20;
  double rate_hz = 300.0;
  double fn_min_n = 0.5, fn_max_n = 4.5;        ///< per-stroke mean Fn range
  double v_min_mm_s = 15.0, v_max_mm_s = 80.0;  ///< per-stroke peak speed range
  double slip_s = 0.6;                          ///< duration of a slip episode
  double rest_s = 0.4;                          ///< rest before each episode
  bool write_labels = false;  ///< emit slip and stroke columns
  /// Extra covariate columns: name -> generator(stroke, t_in_stroke_s,
  /// rng-uniform u in [0,1)).
  struct Covariate {
    std::string name;
    std::function<double(int stroke, double t_s, double u)> value;
  };
  std::vector<Covariate> covariates;
  /// Extra additive effect on mu during slip: f(sample features) where the
  /// sample view gives access to fn, v, covariates by index, distance and
  /// dwell.
  struct SampleView {
    double t_s, fn_n, v_mm_s, distance_mm, dwell_s, t_in_slip_s;
    const std::vector<double>*
        covariates;  ///< values of spec.covariates at this sample
  };
  std::function<double(const SampleView&)> extra_mu;
};

/// Simulates strokes: each is a rest (Ft/Fn well below mu) followed by a
/// half-sine speed profile; mu follows eq. (1) + noise (+ extra_mu) during
/// slip.
StrokeData SimulateStrokes(const SimulationSpec& spec, std::uint64_t seed);

}  // namespace frictiond::testing
