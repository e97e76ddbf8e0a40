#pragma once
/// @file
/// Narrowing of the mu distribution with priors on Fn and v (paper 000,
/// section III-B, Fig. 5 and Fig. 6): the standard deviation of mu among
/// samples inside a window of Fn and/or v around a centre, as a function of
/// the window width. Under eq. (1), mu = b0 + b1 v + b2 Fn + eps, the std
/// inside a window falls from that of all data towards sigma_eps as both
/// windows shrink (only towards sqrt(sigma_eps^2 + b1^2 Var(v)) when only Fn
/// is windowed).
///
/// Usage:
/// @code
///   std::vector<MuWindowStd> curve = CalcMuStdByWindow(
///       fn, v, mu, /*fn_center_n=*/2.0, /*v_center_mm_s=*/20.0,
///       /*fn_widths_n=*/{4, 2, 1, 0.5}, /*v_widths_mm_s=*/{80, 40, 20, 10});
/// @endcode

#include <vector>

namespace frictiond {

/// mu statistics in one window.
struct MuWindowStd {
  double fn_width_n = 0.0;    ///< full width of the Fn window (inf: none)
  double v_width_mm_s = 0.0;  ///< full width of the v window (inf: none)
  int samples = 0;            ///< samples inside
  double mean_mu = 0.0;       ///< mean mu inside (0 when empty)
  double std_mu = 0.0;        ///< sample std of mu inside (0 for < 2)
};

/// For each k, the samples with |fn - fn_center| <= fn_widths[k]/2 and
/// |v - v_center| <= v_widths[k]/2 (an infinite width means no window on
/// that input) and their mean and std of mu. Non-finite samples are skipped.
/// @throws std::invalid_argument when array sizes differ, or a width is NaN
/// or not > 0.
std::vector<MuWindowStd> CalcMuStdByWindow(
    const std::vector<double>& fn_n,
    const std::vector<double>& v_mm_s,
    const std::vector<double>& mu,
    double fn_center_n,
    double v_center_mm_s,
    const std::vector<double>& fn_widths_n,
    const std::vector<double>& v_widths_mm_s);

}  // namespace frictiond
