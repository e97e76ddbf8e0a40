#pragma once
/// @file
/// Slip likelihood beyond the single sigmoid of stochastic_model.h
/// (paper 000, sections III-A and III-C-1):
///
/// - the binned slip ratio of Fig. 3 / Fig. 5 (slipping / all samples per
///   Ft/Fn bin), the raw data the sigmoid summarises;
/// - the conditional likelihood of eq. (2),
///     L(Fn, Ft/Fn) = 1 / (1 + exp(-f1(Fn) (Ft/Fn - f2(Fn))))     (eq. 2)
///   from sigmoids fitted by maximum likelihood in sliding Fn windows (paper:
///   every 0.2 N, 0.6 N wide), with c1 = f1(Fn), c2 = f2(Fn) interpolated
///   linearly between the window centres. Outside the centres of the fitted
///   windows the end values are held and the answer is flagged
///   `extrapolated`, never silently.
///
/// Departure: when the centres come from the data and its Fn range needs
/// more than `max_windows` of them at `step_n`, step and window grow by one
/// whole factor until they fit (the result's step_n / window_n say what was
/// used), instead of refusing the data.
///
/// Noise: samples are treated as independent Bernoulli draws (the fits'
/// covariances are the Fisher-information ones; samples within a slip
/// episode are correlated, so they are optimistic).
///
/// Usage:
/// @code
///   ConditionalSlipLikelihood L =
///       FitConditionalSlipLikelihood(fn_n, ratio, slip, {});
///   ConditionalSlipValue p = CalcConditionalSlipLikelihood(L, 2.0, 0.8);
///   if (p.extrapolated) { /* Fn outside the identified range */ }
/// @endcode

#include <limits>
#include <string>
#include <vector>

#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {

/// One bin of the binned slip ratio.
struct SlipRatioBin {
  double ratio_lo = 0.0;    ///< bin start (Ft/Fn), inclusive
  double ratio_hi = 0.0;    ///< bin end, exclusive
  int samples = 0;          ///< samples in the bin
  int slipping = 0;         ///< of which labelled slip
  double slip_ratio = 0.0;  ///< slipping / samples (0 when empty)
};

/// Bins (ratio, slip) pairs by ratio in bins of `bin_width` from
/// floor(min/bin_width)*bin_width up to the largest finite ratio. Empty bins
/// are kept. Non-finite ratios are skipped.
/// @throws std::invalid_argument when sizes differ or bin_width is not > 0,
/// or more than 100000 bins would result.
std::vector<SlipRatioBin> CalcBinnedSlipRatio(const std::vector<double>& ratio,
                                              const std::vector<int>& slip,
                                              double bin_width);

/// Options of FitConditionalSlipLikelihood.
struct ConditionalSlipOptions {
  double step_n = 0.2;    ///< distance between window centres [N]
  double window_n = 0.6;  ///< window width [N], centred
  /// Range of window centres [N]; NaN = from the data: lowest Fn + half a
  /// window to highest Fn - half a window, each rounded to the nearest
  /// multiple of step_n (a single centre when the data span less than a
  /// window).
  double fn_min_n = std::numeric_limits<double>::quiet_NaN();
  double fn_max_n = std::numeric_limits<double>::quiet_NaN();
  int min_samples = 40;        ///< fewest samples in a usable window
  int min_each_class = 5;      ///< fewest slip and fewest stick samples
  double never_level = 0.01;   ///< level of "never slips below"
  double always_level = 0.99;  ///< level of "always slips above"
  /// At most this many window centres: a data-derived range that needs
  /// more coarsens step and window (see the file comment); a range given
  /// in fn_min_n / fn_max_n that needs more is refused.
  int max_windows = 1000;

  /// True when usable; otherwise *why names the field, value and rule.
  bool IsValid(std::string* why) const;
};

/// One Fn window's fit.
struct SlipWindowFit {
  double fn_center_n = 0.0;
  double fn_lo_n = 0.0;
  double fn_hi_n = 0.0;
  int samples = 0;
  int slipping = 0;
  SlipLikelihoodFit fit;  ///< fit.valid false: window not usable (fit.why)
};

/// The conditional likelihood of eq. (2).
struct ConditionalSlipLikelihood {
  bool valid = false;  ///< at least one usable window
  std::string why;     ///< reason when not valid
  double step_n = 0.0;
  double window_n = 0.0;
  std::vector<SlipWindowFit> windows;  ///< every window tried, ascending
  /// Knots of the interpolation: centres of the usable windows, ascending,
  /// and their c1, c2.
  std::vector<double> knot_fn_n;
  std::vector<double> knot_c1;
  std::vector<double> knot_c2;
};

/// Fits eq. (2). `fn_n`, `ratio` (Ft/Fn) and `slip` (0/1) are per sample and
/// must have equal sizes; non-finite samples are skipped. `start`,
/// optional: an earlier fit of similar data (the daemon passes a pair's
/// previous refit's); each window whose centre matches one of its fitted
/// windows (same step_n) starts its Newton steps there (FitSlipLikelihood:
/// the same optimum in fewer passes).
/// @throws std::invalid_argument for invalid options or size mismatch.
ConditionalSlipLikelihood FitConditionalSlipLikelihood(
    const std::vector<double>& fn_n,
    const std::vector<double>& ratio,
    const std::vector<int>& slip,
    const ConditionalSlipOptions& options = {},
    const ConditionalSlipLikelihood* start = nullptr);

/// Value of eq. (2) at one point.
struct ConditionalSlipValue {
  double likelihood = 0.0;  ///< in [0, 1]
  double c1 = 0.0;          ///< f1(Fn) used
  double c2 = 0.0;          ///< f2(Fn) used
  /// fn_n lies outside [first knot, last knot]: the nearest knot's c1, c2
  /// were held, not interpolated.
  bool extrapolated = false;
};

/// Evaluates eq. (2) at (fn_n, ratio). Requires L.valid.
/// @throws std::invalid_argument when L is not valid or fn_n is not > 0 or
/// ratio is not finite.
ConditionalSlipValue CalcConditionalSlipLikelihood(
    const ConditionalSlipLikelihood& L, double fn_n, double ratio);

}  // namespace frictiond
