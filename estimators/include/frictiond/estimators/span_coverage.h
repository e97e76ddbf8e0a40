#pragma once
/// @file
/// Span coverage of a test stroke (paper 000, section III-C-2 and Figs. 9
/// and 10): the area of the convex hull of the slipping samples in the Fn-v
/// plane as a percentage of a reference span.
///
/// The paper's definition, CalcHullSpanCoverage: the reference is the hull
/// of all of the material's slipping samples (the paper's "full handheld
/// dataset", Fig. 9), and >= 50 % of it identifies eq. (1) reliably (Fig.
/// 10). CalcSpanCoverage measures the same hull against the rectangle of
/// the stroke plan (StrokePlanOptions): that rectangle stays what the
/// library asks the robot to sweep (SpanCoverage::missing), but it is not
/// the paper's 100 %.
///
/// Usage:
/// @code
///   SpanRect plan{0.5, 4.5, 15.0, 80.0};
///   SpanCoverage c = CalcSpanCoverage(fn_slip, v_slip, plan);
///   if (c.span_pct < 50) { SpanRect next = c.missing; /* ask for it */ }
/// @endcode

#include <string>
#include <vector>

namespace frictiond {

struct IdentificationMemo;  // identification_memo.h

/// CalcMaterialHullCoverage's default max_strokes: the newest strokes
/// whose coverage is reported.
inline constexpr int kDefaultMaxHullStrokes = 1000;

/// An axis-aligned region of the Fn-v plane [N] x [mm/s].
struct SpanRect {
  double fn_min_n = 0.0;
  double fn_max_n = 0.0;
  double v_min_mm_s = 0.0;
  double v_max_mm_s = 0.0;

  /// True when both ranges are finite and non-empty.
  bool IsValid() const;
  double Area() const {
    return (fn_max_n - fn_min_n) * (v_max_mm_s - v_min_mm_s);
  }
};

/// Result of CalcSpanCoverage.
struct SpanCoverage {
  /// Hull area / reference area x 100, in [0, 100].
  double span_pct = 0.0;
  /// Extent of the (clamped) slipping samples; all zero when there are none.
  SpanRect covered;
  /// The part of the reference a follow-up stroke should sweep: along each
  /// axis whose covered extent is below half the reference, the larger
  /// uncovered end; along the other axes the whole reference range. Equal
  /// to the reference when nothing was covered.
  SpanRect missing;
  /// Slipping samples used.
  int samples = 0;
};

/// Coverage of `reference` by the points (fn_n[i], v_mm_s[i]) (the slipping
/// samples). Points outside the reference are clamped onto its border, so
/// the hull never leaves it. Non-finite points are ignored.
/// @throws std::invalid_argument when the reference is not valid or the
/// arrays differ in length.
SpanCoverage CalcSpanCoverage(const std::vector<double>& fn_n,
                              const std::vector<double>& v_mm_s,
                              const SpanRect& reference);

/// The same coverage, computed per stroke: `stroke[i]` is point i's stroke
/// id (empty: as above). The hull of the clamped points is the hull of the
/// strokes' clamped hulls, so the result is the one above (up to the
/// rounding of a vertex that is collinear with its neighbours); with a
/// `memo` (identification_memo.h) a stroke's clamped hull is kept for the
/// next call with the same points and reference, so a refit that repeats
/// its older strokes sorts only the new one (IdentifyMaterial; on a bounded
/// refit's 2,300 slipping samples of 17 strokes ~55 -> ~15 us).
/// @throws std::invalid_argument as above, or when `stroke` is not empty
/// and differs in length from fn_n.
SpanCoverage CalcSpanCoverage(const std::vector<double>& fn_n,
                              const std::vector<double>& v_mm_s,
                              const SpanRect& reference,
                              const std::vector<int>& stroke,
                              IdentificationMemo* memo);

/// Span coverage relative to a material's data (paper 000, III-C-2).
struct HullSpanCoverage {
  /// Hull area of the subset / hull area of the material's data (the
  /// subset included) x 100, in [0, 100]; 0 when the material's hull has
  /// no area.
  double span_pct = 0.0;
  double hull_area = 0.0;           ///< subset's hull [N mm/s]
  double material_hull_area = 0.0;  ///< the material's hull [N mm/s]
  /// span_pct >= 50: the paper's rule for a subset that identifies eq. (1)
  /// reliably.
  bool reliable = false;
  int samples = 0;           ///< finite subset points
  int material_samples = 0;  ///< finite material points (subset included)
};

/// Hull-relative span coverage: the subset (e.g. one stroke's slipping
/// samples) against all of a material's slipping samples. The subset's
/// points are added to the material's, so span_pct never exceeds 100.
/// Non-finite points are ignored.
/// @throws std::invalid_argument when paired arrays differ in length.
HullSpanCoverage CalcHullSpanCoverage(
    const std::vector<double>& fn_n,
    const std::vector<double>& v_mm_s,
    const std::vector<double>& material_fn_n,
    const std::vector<double>& material_v_mm_s);

/// One stroke's coverage within MaterialHullCoverage.
struct StrokeHullCoverage {
  int stroke = 0;             ///< stroke id
  HullSpanCoverage coverage;  ///< its hull against the material's hull
};

/// Hull-relative span coverage of every stroke of a material at once
/// (paper 000, III-C-2): the hull of all of the material's slipping
/// samples and each stroke's coverage of it, as the console route shows it.
struct MaterialHullCoverage {
  /// Hull of all finite points, counter-clockwise (CalcConvexHull).
  std::vector<std::pair<double, double>> hull;
  double hull_area = 0.0;  ///< [N mm/s]
  int samples = 0;         ///< finite points
  /// One entry per stroke id in ascending order (the newest `max_strokes`
  /// ids when there are more), each equal to CalcHullSpanCoverage(stroke's
  /// points, all points) except that material_samples counts every point
  /// once (the stroke's points are part of the material's).
  std::vector<StrokeHullCoverage> strokes;
};

/// Hull coverage for identification (IdentifyMaterial fills
/// MaterialIdentification::hull with it): pure, no I/O. `stroke` may be
/// empty (then `strokes` is empty); otherwise it pairs with fn_n. Each
/// stroke costs O(n_s log n_s) against the material hull computed once.
/// @throws std::invalid_argument when paired arrays differ in length or
/// max_strokes < 0.
/// `memo` (optional, identification_memo.h): a stroke's hull seen by an
/// earlier call with the same memo (same samples in the same order) is
/// looked up; the answer is the same with or without it.
MaterialHullCoverage CalcMaterialHullCoverage(
    const std::vector<double>& fn_n,
    const std::vector<double>& v_mm_s,
    const std::vector<int>& stroke,
    int max_strokes = kDefaultMaxHullStrokes,
    IdentificationMemo* memo = nullptr);

/// Convex hull of the points (Andrew's monotone chain), counter-clockwise
/// from the point with the smallest first coordinate, without collinear
/// points; fewer than three points when they are all collinear.
std::vector<std::pair<double, double>> CalcConvexHull(
    std::vector<std::pair<double, double>> points);

/// Area of the convex hull of the points (monotone chain); 0 for fewer than
/// three non-collinear points.
double CalcConvexHullArea(std::vector<std::pair<double, double>> points);

}  // namespace frictiond
