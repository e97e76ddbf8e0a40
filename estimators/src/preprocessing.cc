#include "frictiond/estimators/preprocessing.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace frictiond {

SlipLabelOptions SlipLabelOptions::Paper000() {
  SlipLabelOptions o;
  o.peak_mm_s = 10.0;
  o.floor_mm_s = 5.0;
  o.median_window_s = 0.08;
  o.max_fn_n = 5.0;
  o.max_v_mm_s = 150.0;
  return o;
}

bool SlipLabelOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (!(peak_mm_s > 0) || !std::isfinite(peak_mm_s))
    return fail("slip_peak_mm_s = " + std::to_string(peak_mm_s) +
                " (must be finite and > 0)");
  if (!(floor_mm_s >= 0) || !(floor_mm_s <= peak_mm_s))
    return fail("slip_floor_mm_s = " + std::to_string(floor_mm_s) +
                " (must be in [0, slip_peak_mm_s])");
  if (!(median_window_s >= 0) || !(median_window_s <= 10))
    return fail("median_window_s = " + std::to_string(median_window_s) +
                " (must be in [0, 10])");
  if (!(max_fn_n > 0))
    return fail("max_fn_n = " + std::to_string(max_fn_n) + " (must be > 0)");
  if (!(max_v_mm_s > 0))
    return fail("max_v_mm_s = " + std::to_string(max_v_mm_s) +
                " (must be > 0)");
  if (!(gap_factor > 1))
    return fail("gap_factor = " + std::to_string(gap_factor) +
                " (must be > 1)");
  return true;
}

namespace {

// A NaN has no place in the order a median needs.
void RejectNan(const std::vector<double>& x, const char* who) {
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (std::isnan(x[i]))
      throw std::invalid_argument(std::string(who) + ": x[" +
                                  std::to_string(i) + "] is NaN");
  }
}

}  // namespace

std::vector<double> MedianFilter(const std::vector<double>& x, int kernel) {
  if (kernel <= 1 || x.size() < 3) return x;
  RejectNan(x, "MedianFilter");
  if (kernel % 2 == 0) ++kernel;
  const int half = kernel / 2;
  const int n = static_cast<int>(x.size());
  std::vector<double> out(x.size());
  // Sorted sliding window [lo, hi]: each step removes the sample leaving and
  // inserts the one entering (O(kernel) memmove, no per-sample selection).
  std::vector<double> win;
  win.reserve(kernel + 1);
  int lo = 0, hi = -1;
  auto insert = [&win](double v) {
    win.insert(std::upper_bound(win.begin(), win.end(), v), v);
  };
  auto erase = [&win](double v) {
    win.erase(std::lower_bound(win.begin(), win.end(), v));
  };
  for (int i = 0; i < n; ++i) {
    const int want_lo = std::max(0, i - half);
    const int want_hi = std::min(n - 1, i + half);
    while (hi < want_hi) insert(x[++hi]);
    while (lo < want_lo) erase(x[lo++]);
    out[i] = win[win.size() / 2];
  }
  return out;
}

namespace {

// For each threshold t[j], whether the upper median of each (shrinking)
// window of x exceeds it: the upper median of a sorted window of m values
// (index m/2, as MedianFilter) exceeds t exactly when at least m - m/2 of
// them do. One sliding count per threshold, one pass.
template <std::size_t K>
void MedianAboveEach(const std::vector<double>& x,
                     int kernel,
                     const double (&t)[K],
                     std::vector<unsigned char> (&out)[K]) {
  const std::size_t n = x.size();
  RejectNan(x, "CalcMedianAbove");
  for (std::size_t j = 0; j < K; ++j) out[j].assign(n, 0);
  if (kernel <= 1 || n < 3) {
    for (std::size_t j = 0; j < K; ++j)
      for (std::size_t i = 0; i < n; ++i) out[j][i] = x[i] > t[j];
    return;
  }
  if (kernel % 2 == 0) ++kernel;
  const std::size_t half = static_cast<std::size_t>(kernel / 2);
  if (kernel <= 63 && n > static_cast<std::size_t>(kernel)) {
    // Short kernels: the window counts as sums of shifted 0/1 byte arrays
    // (vectorised), full windows in the interior, shrinking ones at the
    // ends counted directly.
    const std::size_t k = static_cast<std::size_t>(kernel);
    const unsigned char need = static_cast<unsigned char>(k - k / 2);
    std::vector<unsigned char> above(n), sum(n);
    for (std::size_t j = 0; j < K; ++j) {
      for (std::size_t i = 0; i < n; ++i) above[i] = x[i] > t[j];
      std::fill(sum.begin(), sum.end(), 0);
      for (std::size_t d = 0; d < k; ++d) {
        const unsigned char* src = above.data() + d;
        unsigned char* dst = sum.data() + half;
        for (std::size_t i = 0; i + k <= n; ++i) dst[i] += src[i];
      }
      for (std::size_t i = half; i + half < n; ++i) out[j][i] = sum[i] >= need;
      auto edge = [&](std::size_t i) {
        const std::size_t lo = i >= half ? i - half : 0;
        const std::size_t hi = std::min(n - 1, i + half);
        std::size_t count = 0;
        for (std::size_t a = lo; a <= hi; ++a) count += above[a];
        const std::size_t m = hi - lo + 1;
        out[j][i] = count >= m - m / 2;
      };
      for (std::size_t i = 0; i < half; ++i) edge(i);
      for (std::size_t i = n - half; i < n; ++i) edge(i);
    }
    return;
  }
  std::size_t count[K] = {};
  const std::size_t first_hi = std::min(n - 1, half);
  for (std::size_t i = 0; i <= first_hi; ++i)
    for (std::size_t j = 0; j < K; ++j) count[j] += x[i] > t[j];
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t lo = i >= half ? i - half : 0;
    const std::size_t hi = std::min(n - 1, i + half);
    const std::size_t m = hi - lo + 1;
    for (std::size_t j = 0; j < K; ++j) out[j][i] = count[j] >= m - m / 2;
    // Slide to i + 1: x[i + 1 + half] enters, x[i - half] leaves.
    if (i + 1 + half < n)
      for (std::size_t j = 0; j < K; ++j) count[j] += x[i + 1 + half] > t[j];
    if (i >= half)
      for (std::size_t j = 0; j < K; ++j) count[j] -= x[i - half] > t[j];
  }
}

}  // namespace

std::vector<unsigned char> CalcMedianAbove(const std::vector<double>& x,
                                           int kernel,
                                           double threshold) {
  const double t[1] = {threshold};
  std::vector<unsigned char> out[1];
  MedianAboveEach(x, kernel, t, out);
  return std::move(out[0]);
}

double CalcMedianDt(const std::vector<double>& t_s) {
  std::vector<double> dt;
  dt.reserve(t_s.size());
  for (std::size_t i = 1; i < t_s.size(); ++i) {
    const double d = t_s[i] - t_s[i - 1];
    if (d > 0) dt.push_back(d);
  }
  if (dt.empty()) return 0.0;
  const std::size_t k = dt.size() / 2;
  // Sampling intervals take few distinct values: guess the median from an
  // evenly strided sample and confirm it by counting (exact); select over
  // all intervals only when the guess is not the k-th smallest.
  if (dt.size() > 1024) {
    const std::size_t stride = dt.size() / 256;
    std::vector<double> sample;
    for (std::size_t i = 0; i < dt.size(); i += stride) sample.push_back(dt[i]);
    std::nth_element(
        sample.begin(), sample.begin() + sample.size() / 2, sample.end());
    const double guess = sample[sample.size() / 2];
    std::size_t below = 0, equal = 0;
    for (double d : dt) {
      below += d < guess;
      equal += d == guess;
    }
    if (below <= k && k < below + equal) return guess;
  }
  std::nth_element(dt.begin(), dt.begin() + k, dt.end());
  return dt[k];
}

namespace {

// True where the step from i-1 to i is a gap (unrecorded rest); dt is the
// median sampling interval (CalcMedianDt).
std::vector<unsigned char> CalcGaps(const std::vector<double>& t_s,
                                    double dt,
                                    double gap_factor) {
  std::vector<unsigned char> gap(t_s.size(), 0);
  if (dt <= 0) return gap;
  for (std::size_t i = 1; i < t_s.size(); ++i)
    gap[i] = (t_s[i] - t_s[i - 1]) > gap_factor * dt;
  return gap;
}

std::vector<unsigned char> CalcGaps(const std::vector<double>& t_s,
                                    double gap_factor) {
  return CalcGaps(t_s, CalcMedianDt(t_s), gap_factor);
}

// Samples in the labeller's median filter of the speed (at least 1); dt is
// the median sampling interval.
int MedianKernel(double dt, const SlipLabelOptions& options) {
  if (dt > 0 && options.median_window_s > 0)
    return static_cast<int>(std::lround(options.median_window_s / dt));
  return 1;
}

// LabelSlip with the median interval and the gaps already known.
std::vector<int> LabelSlip(const StrokeData& data,
                           const SlipLabelOptions& options,
                           double dt,
                           const std::vector<unsigned char>& gap) {
  const std::size_t n = data.size();
  std::vector<int> slip(n, 0);
  if (n == 0) return slip;
  const int kernel = MedianKernel(dt, options);
  // The rule only compares the filtered speed with the two thresholds:
  // counts replace the filter (CalcMedianAbove).
  const double thresholds[2] = {options.floor_mm_s, options.peak_mm_s};
  std::vector<unsigned char> above[2];
  MedianAboveEach(data.v_mm_s, kernel, thresholds, above);
  const std::vector<unsigned char>& above_floor = above[0];
  const std::vector<unsigned char>& above_peak = above[1];
  // Episodes: maximal runs with v > floor, not crossing gaps (paper II-C),
  // slipping when their peak exceeds peak_mm_s.
  std::size_t i = 0;
  while (i < n) {
    if (!above_floor[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    bool peaked = above_peak[i];
    while (j + 1 < n && above_floor[j + 1] && !gap[j + 1]) {
      ++j;
      peaked = peaked || above_peak[j];
    }
    if (peaked) std::fill(slip.begin() + i, slip.begin() + j + 1, 1);
    i = j + 1;
  }
  return slip;
}

// SegmentStrokes with the gaps already known.
std::vector<int> SegmentStrokes(const std::vector<int>& slip,
                                const std::vector<unsigned char>& gap) {
  const std::size_t n = slip.size();
  std::vector<int> stroke(n, 0);
  int id = 0;
  bool seen_slip = false;  // the current stroke already had a slip episode
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) {
      const bool slip_ended = slip[i - 1] == 1 && slip[i] == 0;
      if (gap[i]) {
        // A gap ends the stroke, unless it had no slip yet (the rest goes on).
        if (seen_slip) ++id;
        seen_slip = false;
      } else if (slip_ended) {
        ++id;  // rest after a slip episode belongs to the next stroke
        seen_slip = false;
      }
    }
    if (slip[i]) seen_slip = true;
    stroke[i] = id;
  }
  return stroke;
}

}  // namespace

std::vector<int> LabelSlip(const StrokeData& data,
                           const SlipLabelOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  const double dt = CalcMedianDt(data.t_s);
  return LabelSlip(
      data, options, dt, CalcGaps(data.t_s, dt, options.gap_factor));
}

std::vector<int> SegmentStrokes(const StrokeData& data,
                                const std::vector<int>& slip,
                                double gap_factor) {
  if (slip.size() != data.size())
    throw std::invalid_argument("slip has " + std::to_string(slip.size()) +
                                " entries for " + std::to_string(data.size()) +
                                " samples");
  return SegmentStrokes(slip, CalcGaps(data.t_s, gap_factor));
}

void EnsureLabels(StrokeData* data, const SlipLabelOptions& options) {
  const bool need_slip = data->slip.size() != data->size();
  const bool need_stroke = data->stroke.size() != data->size();
  if (!need_slip && !need_stroke) return;
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  // One median interval and one gap vector for both steps.
  const double dt = CalcMedianDt(data->t_s);
  const std::vector<unsigned char> gap =
      CalcGaps(data->t_s, dt, options.gap_factor);
  if (need_slip) data->slip = LabelSlip(*data, options, dt, gap);
  if (need_stroke) data->stroke = SegmentStrokes(data->slip, gap);
}

std::vector<bool> CalcFitMask(const StrokeData& data,
                              const SlipLabelOptions& options) {
  std::vector<bool> mask(data.size(), false);
  for (std::size_t i = 0; i < data.size(); ++i) {
    mask[i] = data.slip[i] == 1 && data.fn_n[i] < options.max_fn_n &&
              data.v_mm_s[i] < options.max_v_mm_s;
  }
  return mask;
}

const std::vector<std::string>& DerivedFeatureNames() {
  static const std::vector<std::string> kNames = {
      "distance_mm", "dwell_s", "time_s", "accel_mm_s2", "fn_rate_n_s"};
  return kNames;
}

namespace {

// AddDerivedFeatures; `moving` (optional, one flag per sample) marks
// samples that are not rest although they are not labelled slip.
void AddDerivedFeaturesImpl(StrokeData* data,
                            double gap_factor,
                            const std::vector<unsigned char>* moving) {
  const std::size_t n = data->size();
  const auto& t = data->t_s;
  const auto& v = data->v_mm_s;
  const auto& fn = data->fn_n;
  const std::vector<unsigned char> gap = CalcGaps(t, gap_factor);
  std::vector<double> distance(n, 0.0), dwell(n, 0.0), time(n, 0.0),
      accel(n, 0.0), fn_rate(n, 0.0);
  const std::vector<int>& slip = data->slip;
  const bool have_slip = slip.size() == n;
  double rest_start = n ? t[0] : 0.0;
  double current_dwell = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    time[i] = t[i] - t[0];
    if (i > 0)
      distance[i] =
          distance[i - 1] +
          (gap[i] ? 0.0 : 0.5 * (v[i] + v[i - 1]) * (t[i] - t[i - 1]));
    const bool s = have_slip && slip[i] == 1;
    const bool prev_s = have_slip && i > 0 && slip[i - 1] == 1;
    if (s && !prev_s) current_dwell = t[i] - rest_start;  // episode begins
    if (!s && prev_s) rest_start = t[i];                  // rest begins
    // Motion without slip (a run above the floor that never reached the
    // peak): the rest begins after it.
    if (!s && moving && (*moving)[i]) rest_start = t[i];
    dwell[i] = s ? current_dwell : t[i] - rest_start;
    // Derivatives: central, one-sided across gaps and at ends.
    const bool has_prev = i > 0 && !gap[i];
    const bool has_next = i + 1 < n && !gap[i + 1];
    std::size_t a = has_prev ? i - 1 : i;
    std::size_t b = has_next ? i + 1 : i;
    const double dt = t[b] - t[a];
    if (dt > 0) {
      accel[i] = (v[b] - v[a]) / dt;
      fn_rate[i] = (fn[b] - fn[a]) / dt;
    }
  }
  std::vector<std::vector<double>> cols = {std::move(distance),
                                           std::move(dwell),
                                           std::move(time),
                                           std::move(accel),
                                           std::move(fn_rate)};
  const auto& names = DerivedFeatureNames();
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (auto j = data->FindCovariate(names[k])) {
      data->covariates[*j] = std::move(cols[k]);
    } else {
      data->covariate_names.push_back(names[k]);
      data->covariates.push_back(std::move(cols[k]));
    }
  }
}

}  // namespace

void AddDerivedFeatures(StrokeData* data, double gap_factor) {
  AddDerivedFeaturesImpl(data, gap_factor, nullptr);
}

void AddDerivedFeatures(StrokeData* data, const SlipLabelOptions& labelling) {
  std::vector<unsigned char> moving;
  if (labelling.floor_mm_s > 0 && data->size() > 0) {
    // The labeller's test of motion: median-filtered speed above the floor.
    moving = CalcMedianAbove(data->v_mm_s,
                             MedianKernel(CalcMedianDt(data->t_s), labelling),
                             labelling.floor_mm_s);
  }
  AddDerivedFeaturesImpl(
      data, labelling.gap_factor, moving.empty() ? nullptr : &moving);
}

}  // namespace frictiond
