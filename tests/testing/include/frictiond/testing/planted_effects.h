#pragma once
/// @file
/// Synthetic strokes with one planted effect on mu, for known-truth tests of
/// model diagnosis (STYLE §10). Each stroke is a rest (stick: Ft/Fn ramps up
/// below mu) followed by a half-sine slip episode; mu follows paper 000
/// eq. (1) plus AR(1) noise within the stroke, a random per-stroke offset and
/// the planted effect. Deterministic for a given seed.
///
/// Every dataset carries the same covariate columns whatever is planted, so
/// each effect competes with all the other candidates:
/// - temp_c: ambient temperature, AR(1) across strokes plus a slow drift
///   within the stroke;
/// - dir_deg: stroke direction, uniform on [0, 360) per stroke;
/// - contact_x_mm: contact position, a random start per stroke plus 0.3 x
///   the distance slid in the stroke;
/// - noise_k (k < noise_columns): irrelevant columns; even k vary per sample
///   (AR(1)), odd k are constant within a stroke (confounded with the
///   per-stroke offsets).
/// The session alternates blocks of 25 fast strokes with short rests and 25
/// slow strokes with long rests, so that sliding distance is not a smooth
/// function of elapsed time (wear must be distinguishable from time drift).
/// Rests longer than recorded_rest_s are written as a time gap (unrecorded
/// rest), which keeps files small while dwell times vary widely.

#include <cstdint>
#include <string>

#include "frictiond/estimators/stroke_data.h"

namespace frictiond::testing {

/// The effect planted on mu (added during slip).
enum class PlantedEffect {
  kNone,            ///< nothing: eq. (1) is the truth
  kTemperature,     ///< mu += size * (temp_c - 25) / 10
  kDirection,       ///< mu += size * cos(dir_deg - 40 deg)
  kWear,            ///< mu -= size * distance_mm / 1000
  kOnsetTransient,  ///< mu += size * dwell_s * exp(-time since slip onset /
                    ///< 0.15 s)
  kNonlinearFn,     ///< mu += size * ((fn_n - 2.5) / 2)^2
  kPositionPatch,   ///< mu += size for contact_x_mm in [20, 26)
};

/// Name of the column (or derived feature) that carries the effect:
/// "" (kNone), "temp_c", "dir_deg", "distance_mm", "dwell_s", "fn_n",
/// "contact_x_mm".
std::string PlantedCause(PlantedEffect effect);
/// Short name for test output ("none", "temperature", ...).
std::string ToString(PlantedEffect effect);

/// Shape of the generated strokes.
struct PlantedSpec {
  PlantedEffect effect = PlantedEffect::kNone;
  double size =
      0.0;  ///< effect size (see PlantedEffect); 0 uses a default per effect
  int strokes = 100;
  double rate_hz = 100.0;
  double b0 = 0.9, b1 = 0.003, b2 = -0.06;  ///< eq. (1) truth (per mm/s, per N)
  double sigma_eps = 0.03;         ///< innovation std of the AR(1) noise of mu
  double ar_rho = 0.9;             ///< AR(1) coefficient within a stroke
  double stroke_offset_sd = 0.03;  ///< per-stroke random offset of mu
  double fn_min_n = 0.5, fn_max_n = 4.5;  ///< per-stroke mean Fn range [N]
  double v_min_mm_s = 10.0,
         v_max_mm_s = 100.0;  ///< peak speed, log-uniform [mm/s]
  double rest_min_s = 0.2,
         rest_max_s = 5.0;  ///< rest before a stroke, log-uniform [s]
  double slip_min_s = 0.4,
         slip_max_s = 1.2;  ///< slip episode length, uniform [s]
  double recorded_rest_s =
      0.3;  ///< at most this much of a rest is recorded; the rest is a gap
  int noise_columns = 2;      ///< irrelevant columns noise_0, noise_1, ...
  bool write_labels = false;  ///< emit slip and stroke columns
};

/// Generates the strokes (one "file": time starts at 0).
StrokeData GeneratePlantedStrokes(const PlantedSpec& spec, std::uint64_t seed);

/// Default effect size used when spec.size == 0.
double DefaultPlantedSize(PlantedEffect effect);

/// Planted cases drawn from families wider than the diagnosis' candidate
/// list (issue 18), for detection and false-alarm rates over many seeds.
/// Every case starts from GeneratePlantedStrokes(kNone) and adds one column
/// with a random, meaningless name (letters and digits, no unit suffix) and
/// an effect drawn at random within its family:
enum class WideKind {
  kSmoothCurve,      ///< mu += random smooth curve (3 random harmonics on the
                     ///< column's range) of a drifting column
  kInteraction,      ///< mu += size * (fn_n - 2.5) * z: the Fn slope depends on
                     ///< a per-stroke column z (no main effect of z)
  kSpread,           ///< eps gets white noise whose scale grows exp-linearly
                     ///< with a per-stroke column (mean unchanged)
  kCategorical,      ///< a per-stroke column with 3-5 integer levels (random
                     ///< codes), each level shifting mu by a random amount
  kNullHeavyTail,    ///< nothing planted; white Student-t(2.5) noise on mu
  kNullOffsets,      ///< nothing planted; per-stroke offsets sd 0.15 (5x)
  kNullArNoise,      ///< nothing planted; AR(1) noise with rho 0.995
  kNullManyColumns,  ///< nothing planted; 20 irrelevant columns
  /// As kCategorical (same seed: same levels, codes and pattern of shifts),
  /// but the shifts are rescaled so that their standard deviation over the
  /// strokes is drawn from 0.04-0.06 (bounded away from zero, as the other
  /// kinds' sizes are; kCategorical's Gaussian shifts can be arbitrarily
  /// small, e.g. seed 119: level means within 0.006 of each other).
  kCategoricalBounded,
};
/// Short name ("smooth_curve", ..., "null_many_columns").
std::string ToString(WideKind kind);
/// True for the null kinds.
bool IsNull(WideKind kind);

/// One generated case and what a correct diagnosis names first.
struct WideCase {
  StrokeData data;
  std::string cause;  ///< expected first cause ("" for nulls)
  std::string kind;   ///< expected finding kind ("covariate", "interaction",
                      ///< "spread"; "" for nulls)
  std::string truth;  ///< what was planted, for failure messages
  /// The categorical kinds: the realised size of the planted level shifts,
  /// their standard deviation over the strokes (each stroke weighted once),
  /// the statistic kCategoricalBounded draws from 0.04-0.06 and the other
  /// kinds' sizes compare with (smooth curve 0.05; interaction about
  /// 0.035-0.06). 0 for the other kinds.
  double effect_sd = 0.0;
};

/// Generates a case of `kind` with `strokes` strokes; deterministic per seed.
/// `categorical_sd` > 0 sets kCategoricalBounded's size to exactly that
/// standard deviation instead of a draw from 0.04-0.06 (a power curve;
/// every other draw unchanged); ignored by the other kinds.
WideCase GenerateWideCase(WideKind kind,
                          std::uint64_t seed,
                          int strokes = 100,
                          double categorical_sd = 0.0);

}  // namespace frictiond::testing
