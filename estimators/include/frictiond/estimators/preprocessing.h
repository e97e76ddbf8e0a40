#pragma once
/// @file
/// Slip labelling, stroke segmentation and the derived per-sample features of
/// CONTRACT.md (paper 000, sections II-B and II-C).

#include <limits>
#include <string>
#include <vector>

#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

/// Options of the slip-labelling rule of paper 000, section II-C: "for slip
/// episodes whose peak velocity is above 10 mm/s, we label the peak and any
/// neighbouring samples with a velocity value above 5 mm/s as slip".
/// Defaults are the paper's fingertip values; the bundled micro-tribometer
/// data needs far lower thresholds (its PROVENANCE suggests ~0.02 mm/s).
struct SlipLabelOptions {
  /// An episode is slip when its peak speed exceeds this [mm/s].
  double peak_mm_s = 10.0;
  /// Samples around the peak with speed above this belong to the episode
  /// [mm/s].
  double floor_mm_s = 5.0;
  /// Median-filter kernel applied to the speed before labelling [s]
  /// (paper II-B: 80 ms). The kernel length in samples is derived from the
  /// median sample interval (rate-aware); 0 disables filtering.
  double median_window_s = 0.08;
  /// Samples with fn_n at or above this are excluded from fitting [N]
  /// (paper: 5 N; default: no bound).
  double max_fn_n = std::numeric_limits<double>::infinity();
  /// Samples with speed at or above this are excluded from fitting [mm/s]
  /// (paper: 150 mm/s; default: no bound).
  double max_v_mm_s = std::numeric_limits<double>::infinity();
  /// A time step longer than this many median sample intervals is a gap
  /// (unrecorded rest): it ends an episode and starts a new stroke.
  double gap_factor = 10.0;

  /// The paper's handheld-experiment settings (10/5 mm/s, 80 ms, 5 N, 150
  /// mm/s).
  static SlipLabelOptions Paper000();

  /// True when the options are usable; otherwise *why names the field,
  /// value and rule.
  bool IsValid(std::string* why) const;
};

/// Median filter of `x` with an odd kernel of `kernel` samples (shrinking at
/// the ends). kernel <= 1 returns x unchanged. Throws std::invalid_argument
/// when x holds a NaN (it has no place in the order).
std::vector<double> MedianFilter(const std::vector<double>& x, int kernel);

/// For each sample, whether MedianFilter(x, kernel) exceeds `threshold`
/// there (1) or not (0), computed from counts of samples above the
/// threshold in each window (O(n), no sorting). Throws
/// std::invalid_argument when x holds a NaN.
std::vector<unsigned char> CalcMedianAbove(const std::vector<double>& x,
                                           int kernel,
                                           double threshold);

/// Median of the positive sample intervals of t (0 when there are fewer
/// than two samples).
double CalcMedianDt(const std::vector<double>& t_s);

/// Labels slip per the episode rule (paper II-C) on the median-filtered
/// speed. Returns 0/1 per sample.
/// @throws std::invalid_argument when options are invalid.
std::vector<int> LabelSlip(const StrokeData& data,
                           const SlipLabelOptions& options);

/// Segments samples into strokes: a stroke is a slip episode together with
/// the rest that precedes it; a time gap always starts a new stroke.
/// `slip` is the 0/1 label per sample. Stroke ids start at 0.
std::vector<int> SegmentStrokes(const StrokeData& data,
                                const std::vector<int>& slip,
                                double gap_factor = 10.0);

/// Fills data.slip (when absent) and data.stroke (when absent) per the rules
/// above. Given labels are kept.
void EnsureLabels(StrokeData* data, const SlipLabelOptions& options);

/// True for samples usable for fitting mu: labelled slip, fn_n below
/// max_fn_n and speed below max_v_mm_s. Requires data.slip to be filled.
std::vector<bool> CalcFitMask(const StrokeData& data,
                              const SlipLabelOptions& options);

/// Names of the derived per-sample features of CONTRACT.md, in this order:
/// distance_mm, dwell_s, time_s, accel_mm_s2, fn_rate_n_s.
const std::vector<std::string>& DerivedFeatureNames();

/// Computes the derived features and appends them as covariates (replacing
/// same-named columns that were computed before):
/// - distance_mm: cumulative sliding distance, trapezoidal integral of v
///   (no sliding is assumed across time gaps);
/// - dwell_s: length of the rest before the current slip episode began
///   (inside rest: the rest elapsed so far; gaps count as rest). With
///   `labelling`, rest ends also at motion without slip: samples whose
///   median-filtered speed exceeds labelling.floor_mm_s (a run above the
///   floor that never reaches the peak, which LabelSlip leaves unlabelled);
///   without it, at slip labels only;
/// - time_s: time since the first sample;
/// - accel_mm_s2, fn_rate_n_s: central differences of v and fn (one-sided at
///   ends and gaps).
/// Requires data.slip to be filled (EnsureLabels).
void AddDerivedFeatures(StrokeData* data, double gap_factor = 10.0);
void AddDerivedFeatures(StrokeData* data, const SlipLabelOptions& labelling);

}  // namespace frictiond
