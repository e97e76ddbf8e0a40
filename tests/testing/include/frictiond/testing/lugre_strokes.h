#pragma once
/// @file
/// Strokes simulated from a known LuGre parameter set (paper 001), for
/// known-truth tests of the LuGre replay in diagnosis (STYLE §10):
/// velocity-driven, each stroke a rest, a trapezoid speed profile and a
/// rest, with per-stroke normal force, peak speed and acceleration, and
/// Gaussian sensor noise on mu. Deterministic for a given seed.

#include <cstdint>

#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond::testing {

/// Shape and noise of LuGre strokes.
struct LuGreStrokeSpec {
  /// Truth (docs/lugre.md): mu_s 0.9, mu_c 0.6, v0 5 mm/s, sigma2 0.004
  /// s/mm, sigma0 50 /mm, sigma1 0.1 s/mm.
  LuGreTheta theta = MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1);
  int strokes = 8;
  double rate_hz = 200.0;
  double rest_s = 0.5;                          ///< rest before and after
  double hold_s = 0.8;                          ///< time at peak speed
  double v_min_mm_s = 15.0, v_max_mm_s = 35.0;  ///< per-stroke peak speed
  double accel_min_mm_s2 = 20.0, accel_max_mm_s2 = 200.0;  ///< per stroke
  double fn_min_n = 2.0, fn_max_n = 5.0;  ///< per-stroke normal force
  double noise_mu = 0.005;                ///< std of Gaussian noise on mu
  double gap_s = 2.0;                     ///< unrecorded time between strokes
};

/// Simulates the strokes (z = 0 at each stroke's start) and returns them
/// with slip (v_mm_s >= 5 mm/s) and stroke columns. Ft is |mu| Fn.
/// @throws std::runtime_error when a simulation fails.
StrokeData SimulateLuGreStrokes(const LuGreStrokeSpec& spec,
                                std::uint64_t seed);

}  // namespace frictiond::testing
