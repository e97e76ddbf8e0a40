#pragma once
/// @file
/// The span-percentage experiment of paper 000, section III-C-2 and
/// Fig. 10: draw random subsets of n strokes (n uniform in 1..max_strokes),
/// measure each subset's span percentage (convex hull area of its slipping
/// (Fn, v) samples over that of all strokes), fit eq. (1)
///   mu = b0 + b1*v + b2*Fn + eps
/// to the subset, and report how the spread of the estimates b0, b1, b2
/// falls as the span grows. The paper finds the spread close to its steady
/// state above ~50 % span.
///
/// Deterministic for a given seed (std::mt19937_64).
///
/// Usage:
/// @code
///   SpanVariability r = CalcSpanVariability(fn, v, mu, stroke, {});
///   for (const SpanBin& b : r.bins) { /* b.span_lo_pct, b.beta_std */ }
/// @endcode

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace frictiond {

/// Options of CalcSpanVariability.
struct SpanVariabilityOptions {
  int subsets = 500;      ///< random subsets drawn (paper: 500)
  int max_strokes = 40;   ///< n is drawn from 1..min(max_strokes, strokes)
  double bin_pct = 10.0;  ///< width of the span-percentage bins
  int min_samples = 10;   ///< a subset needs this many samples to be fitted
  std::uint64_t seed = 1;
  /// True when usable; otherwise *why names the field, value and rule.
  bool IsValid(std::string* why) const;
};

/// One random subset.
struct SpanSubset {
  int strokes = 0;
  double span_pct = 0.0;
  bool identified = false;       ///< all three coefficients identified
  std::array<double, 3> beta{};  ///< b0, b1, b2 (when identified)
};

/// Spread of the estimates among subsets whose span lies in one bin.
struct SpanBin {
  double span_lo_pct = 0.0;
  double span_hi_pct = 0.0;
  int subsets = 0;                    ///< identified subsets in the bin
  std::array<double, 3> beta_mean{};  ///< mean of b0, b1, b2
  std::array<double, 3> beta_std{};   ///< std of b0, b1, b2 (0 for < 2)
};

/// Result of the experiment.
struct SpanVariability {
  bool valid = false;  ///< false: no stroke with >= 3 non-collinear points
  std::string why;
  double full_hull_area = 0.0;  ///< [N mm/s]
  int strokes = 0;
  std::vector<SpanSubset> subsets;
  std::vector<SpanBin> bins;  ///< 0..100 % in bin_pct steps
};

/// Runs the experiment on slipping samples (fn_n, v_mm_s, mu) grouped by
/// stroke id.
/// @throws std::invalid_argument when sizes differ or options are invalid.
SpanVariability CalcSpanVariability(const std::vector<double>& fn_n,
                                    const std::vector<double>& v_mm_s,
                                    const std::vector<double>& mu,
                                    const std::vector<int>& stroke,
                                    const SpanVariabilityOptions& options = {});

}  // namespace frictiond
