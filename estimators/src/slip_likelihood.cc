#include "frictiond/estimators/slip_likelihood.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "frictiond/estimators/number_text.h"

namespace frictiond {

namespace {

std::string Num(double x) { return std::to_string(x); }

}  // namespace

std::vector<SlipRatioBin> CalcBinnedSlipRatio(const std::vector<double>& ratio,
                                              const std::vector<int>& slip,
                                              double bin_width) {
  if (ratio.size() != slip.size()) {
    throw std::invalid_argument(
        "slip has " + std::to_string(slip.size()) + " entries, ratio " +
        std::to_string(ratio.size()) + " (must be equal)");
  }
  if (!(bin_width > 0) || !std::isfinite(bin_width)) {
    throw std::invalid_argument("bin_width = " + Num(bin_width) +
                                " (must be finite and > 0)");
  }
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (double r : ratio) {
    if (!std::isfinite(r)) continue;
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  std::vector<SlipRatioBin> bins;
  if (!(lo <= hi)) return bins;
  const double start = std::floor(lo / bin_width) * bin_width;
  const double count = std::floor((hi - start) / bin_width) + 1;
  if (!(count <= 100000)) {
    throw std::invalid_argument("bin_width = " + Num(bin_width) +
                                " gives more than 100000 bins over the "
                                "ratio range");
  }
  bins.resize(static_cast<std::size_t>(count));
  for (std::size_t b = 0; b < bins.size(); ++b) {
    bins[b].ratio_lo = start + b * bin_width;
    bins[b].ratio_hi = start + (b + 1) * bin_width;
  }
  for (std::size_t i = 0; i < ratio.size(); ++i) {
    if (!std::isfinite(ratio[i])) continue;
    std::size_t b =
        static_cast<std::size_t>(std::floor((ratio[i] - start) / bin_width));
    b = std::min(b, bins.size() - 1);
    ++bins[b].samples;
    bins[b].slipping += slip[i] != 0;
  }
  for (SlipRatioBin& b : bins) {
    b.slip_ratio =
        b.samples > 0 ? static_cast<double>(b.slipping) / b.samples : 0.0;
  }
  return bins;
}

bool ConditionalSlipOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (!(step_n > 0) || !std::isfinite(step_n))
    return fail("step_n = " + Num(step_n) + " (must be finite and > 0)");
  if (!(window_n > 0) || !std::isfinite(window_n))
    return fail("window_n = " + Num(window_n) + " (must be finite and > 0)");
  if (std::isnan(fn_min_n) != std::isnan(fn_max_n))
    return fail("fn_min_n and fn_max_n must both be given or both be NaN");
  if (!std::isnan(fn_min_n) &&
      (!(fn_min_n <= fn_max_n) || !std::isfinite(fn_min_n) ||
       !std::isfinite(fn_max_n)))
    return fail("fn_min_n = " + Num(fn_min_n) + ", fn_max_n = " +
                Num(fn_max_n) + " (must be finite with fn_min_n <= fn_max_n)");
  if (min_samples < 2)
    return fail("min_samples = " + std::to_string(min_samples) +
                " (must be >= 2)");
  if (min_each_class < 1)
    return fail("min_each_class = " + std::to_string(min_each_class) +
                " (must be >= 1)");
  if (!(never_level > 0 && never_level < always_level && always_level < 1))
    return fail("never_level = " + Num(never_level) + ", always_level = " +
                Num(always_level) + " (must satisfy 0 < never < always < 1)");
  if (max_windows < 1)
    return fail("max_windows = " + std::to_string(max_windows) +
                " (must be >= 1)");
  return true;
}

ConditionalSlipLikelihood FitConditionalSlipLikelihood(
    const std::vector<double>& fn_n,
    const std::vector<double>& ratio,
    const std::vector<int>& slip,
    const ConditionalSlipOptions& options,
    const ConditionalSlipLikelihood* start) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  if (fn_n.size() != ratio.size() || slip.size() != ratio.size()) {
    throw std::invalid_argument(
        "fn_n, ratio and slip have " + std::to_string(fn_n.size()) + ", " +
        std::to_string(ratio.size()) + " and " + std::to_string(slip.size()) +
        " entries (must be equal)");
  }
  ConditionalSlipLikelihood out;
  out.step_n = options.step_n;
  out.window_n = options.window_n;
  // Fn range of the finite samples.
  double fn_lo = std::numeric_limits<double>::infinity(), fn_hi = -fn_lo;
  for (std::size_t i = 0; i < fn_n.size(); ++i) {
    if (!std::isfinite(fn_n[i]) || !std::isfinite(ratio[i])) continue;
    fn_lo = std::min(fn_lo, fn_n[i]);
    fn_hi = std::max(fn_hi, fn_n[i]);
  }
  if (!(fn_lo <= fn_hi)) {
    out.why = "no finite samples";
    return out;
  }
  double half = 0.5 * options.window_n;
  double step = options.step_n;
  double first = options.fn_min_n, last = options.fn_max_n;
  if (std::isnan(first)) {
    // Centres on the grid of multiples of step_n, half a window inside the
    // data's Fn range (rounded to the nearest grid point).
    auto place = [&] {
      first = step * std::round((fn_lo + half) / step);
      last = step * std::round((fn_hi - half) / step);
      if (last < first)
        first = last = step * std::round(0.5 * (fn_lo + fn_hi) / step);
    };
    place();
    // Departure from the paper (its 0.2 / 0.6 N suit its 0-10 N gripper):
    // when the data's Fn range needs more than max_windows centres (a
    // 0.5-250 N gripper needs 1,245), step and window grow by the same
    // whole factor k until they fit; the result reports the step and
    // window used. A range given in the options is never widened.
    if (!((last - first) / step < options.max_windows)) {
      const double k0 = std::ceil((fn_hi - fn_lo) / options.step_n /
                                  std::max(1, options.max_windows - 2));
      for (double k = std::max(2.0, k0);; k *= 2.0) {
        step = k * options.step_n;
        half = 0.5 * k * options.window_n;
        place();
        if ((last - first) / step < options.max_windows || !std::isfinite(step))
          break;
      }
      out.step_n = step;
      out.window_n = 2.0 * half;
    }
    // A hostile or broken sample (e.g. fn_n = 1e308) makes the range too
    // wide for any finite grid: say so, not "from -nan to -nan".
    if (!std::isfinite(step) || !std::isfinite(first) || !std::isfinite(last))
      throw std::invalid_argument("the data's Fn range " + NumberText(fn_lo) +
                                  " to " + NumberText(fn_hi) +
                                  " N is too wide for Fn windows (their step "
                                  "overflows)");
  }
  const double span = (last - first) / step;
  if (!(span < options.max_windows)) {
    throw std::invalid_argument(
        "window centres from " + Num(first) + " to " + Num(last) +
        " N every step_n = " + Num(step) +
        " N exceed max_windows = " + std::to_string(options.max_windows));
  }
  const int n_windows = static_cast<int>(std::floor(span + 1e-9)) + 1;
  std::vector<SlipWindowFit> windows(n_windows);
  for (int w = 0; w < n_windows; ++w) {
    windows[w].fn_center_n = first + w * step;
    windows[w].fn_lo_n = windows[w].fn_center_n - half;
    windows[w].fn_hi_n = windows[w].fn_center_n + half;
  }
  // Each sample goes straight to the few windows that hold it (lo <= Fn <
  // hi), found from its Fn on the centre grid: no sort by Fn. The windows
  // holding one Fn are consecutive (both bounds rise with w), so a sample
  // belongs to one range [lo, hi] of windows; consecutive samples with the
  // same range form a run (loads change slowly), and each run is copied
  // into each of its windows as one block.
  const std::size_t n = fn_n.size();
  std::vector<double> win_lo(n_windows), win_hi(n_windows);
  for (int w = 0; w < n_windows; ++w) {
    win_lo[w] = windows[w].fn_lo_n;
    win_hi[w] = windows[w].fn_hi_n;
  }
  const double inv_step = 1.0 / step;  // rounding is absorbed by the margin
  struct Run {
    std::size_t begin, end;  // samples [begin, end)
    int lo, hi;              // windows [lo, hi]
  };
  std::vector<Run> runs;
  std::vector<std::size_t> offset(n_windows + 1, 0);  // counts, then offsets
  auto close_run = [&](Run* run, std::size_t end) {
    if (run->lo <= run->hi && end > run->begin) {
      run->end = end;
      runs.push_back(*run);
      for (int w = run->lo; w <= run->hi; ++w)
        offset[w + 1] += end - run->begin;
    }
  };
  Run run{0, 0, 0, -1};
  // Fn interval in which a sample has exactly the current run's windows.
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double keep_lo = kInf, keep_hi = -kInf;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = fn_n[i];
    if (x >= keep_lo && x < keep_hi && std::isfinite(ratio[i])) continue;
    int lo = 0, hi = -1;  // no window
    if (std::isfinite(x) && std::isfinite(ratio[i])) {
      // Candidates: the windows whose [lo, hi) can hold x, plus one on each
      // side against rounding; both bounds rise with w, so the candidates
      // ending at or below x come first and those starting at or below x
      // form a prefix (branch-free).
      const double lo_cell = std::clamp((x - half - first) * inv_step,
                                        -2.0,
                                        static_cast<double>(n_windows) + 2);
      const double hi_cell = std::clamp((x + half - first) * inv_step,
                                        -2.0,
                                        static_cast<double>(n_windows) + 2);
      const int a = std::max(0, static_cast<int>(lo_cell + 2.0) - 2);
      const int b =
          std::min(n_windows - 1, static_cast<int>(hi_cell + 2.0) - 1);
      lo = a;
      hi = a - 1;
      for (int w = a; w <= b; ++w) {
        lo += win_hi[w] <= x;
        hi += win_lo[w] <= x;
      }
      if (lo > hi) {
        lo = 0;
        hi = -1;
      }
    }
    if (lo != run.lo || hi != run.hi) {
      close_run(&run, i);
      run = Run{i, i, lo, hi};
      if (lo <= hi) {
        // In windows lo..hi exactly: inside the last one's start and the
        // first one's end, outside the neighbours.
        keep_lo = std::max(win_lo[hi], lo > 0 ? win_hi[lo - 1] : -kInf);
        keep_hi =
            std::min(win_hi[lo], hi + 1 < n_windows ? win_lo[hi + 1] : kInf);
      } else {
        keep_lo = kInf;
        keep_hi = -kInf;
      }
    }
  }
  close_run(&run, n);
  for (int w = 0; w < n_windows; ++w) offset[w + 1] += offset[w];
  std::vector<double> r(offset[n_windows]);
  std::vector<int> s(offset[n_windows]);
  {
    std::vector<std::size_t> next(offset.begin(), offset.end() - 1);
    for (const Run& u : runs) {
      for (int w = u.lo; w <= u.hi; ++w) {
        std::copy(ratio.begin() + u.begin,
                  ratio.begin() + u.end,
                  r.begin() + next[w]);
        for (std::size_t i = u.begin; i < u.end; ++i)
          s[next[w] + (i - u.begin)] = slip[i] != 0;
        next[w] += u.end - u.begin;
      }
    }
  }
  for (int w = 0; w < n_windows; ++w) {
    windows[w].slipping = static_cast<int>(
        std::count(s.begin() + offset[w], s.begin() + offset[w + 1], 1));
  }
  // The start's window with this centre (the centres lie on one grid of
  // step_n, so a refit's windows meet the previous fit's), when it was fitted.
  auto start_of = [start, step](double centre) -> const SlipLikelihoodFit* {
    if (start == nullptr || !(start->step_n == step)) return nullptr;
    const auto& sw = start->windows;
    auto it = std::lower_bound(
        sw.begin(),
        sw.end(),
        centre - 0.5 * step,
        [](const SlipWindowFit& a, double c) { return a.fn_center_n < c; });
    if (it == sw.end() || !(std::fabs(it->fn_center_n - centre) < 0.5 * step) ||
        !it->fit.valid)
      return nullptr;
    return &it->fit;
  };
  for (int w = 0; w < n_windows; ++w) {
    SlipWindowFit& win = windows[w];
    win.samples = static_cast<int>(offset[w + 1] - offset[w]);
    const int stick = win.samples - win.slipping;
    if (win.samples < options.min_samples) {
      win.fit.why = std::to_string(win.samples) + " samples (fewer than " +
                    std::to_string(options.min_samples) + ")";
    } else if (win.slipping < options.min_each_class ||
               stick < options.min_each_class) {
      win.fit.why = std::to_string(win.slipping) + " slip and " +
                    std::to_string(stick) + " stick samples (each must be >= " +
                    std::to_string(options.min_each_class) + ")";
    } else {
      win.fit = FitSlipLikelihood(r.data() + offset[w],
                                  s.data() + offset[w],
                                  static_cast<std::size_t>(win.samples),
                                  options.never_level,
                                  options.always_level,
                                  start_of(win.fn_center_n));
    }
    if (win.fit.valid) {
      out.knot_fn_n.push_back(win.fn_center_n);
      out.knot_c1.push_back(win.fit.c1);
      out.knot_c2.push_back(win.fit.c2);
    }
    out.windows.push_back(std::move(win));
  }
  out.valid = !out.knot_fn_n.empty();
  if (!out.valid) {
    out.why = "no Fn window had enough slip and stick samples (" +
              std::to_string(n_windows) + " windows of " +
              Num(options.window_n) + " N tried)";
  }
  return out;
}

ConditionalSlipValue CalcConditionalSlipLikelihood(
    const ConditionalSlipLikelihood& L, double fn_n, double ratio) {
  if (!L.valid || L.knot_fn_n.empty() ||
      L.knot_c1.size() != L.knot_fn_n.size() ||
      L.knot_c2.size() != L.knot_fn_n.size()) {
    throw std::invalid_argument("conditional slip likelihood is not fitted: " +
                                L.why);
  }
  if (!(fn_n > 0) || !std::isfinite(fn_n))
    throw std::invalid_argument("fn_n = " + Num(fn_n) +
                                " (must be finite and > 0)");
  if (!std::isfinite(ratio))
    throw std::invalid_argument("ratio = " + Num(ratio) + " (must be finite)");
  ConditionalSlipValue out;
  const std::vector<double>& x = L.knot_fn_n;
  if (fn_n <= x.front()) {
    out.c1 = L.knot_c1.front();
    out.c2 = L.knot_c2.front();
    out.extrapolated = fn_n < x.front();
  } else if (fn_n >= x.back()) {
    out.c1 = L.knot_c1.back();
    out.c2 = L.knot_c2.back();
    out.extrapolated = fn_n > x.back();
  } else {
    const std::size_t k = static_cast<std::size_t>(
        std::upper_bound(x.begin(), x.end(), fn_n) - x.begin());
    const double w = (fn_n - x[k - 1]) / (x[k] - x[k - 1]);
    out.c1 = (1 - w) * L.knot_c1[k - 1] + w * L.knot_c1[k];
    out.c2 = (1 - w) * L.knot_c2[k - 1] + w * L.knot_c2[k];
  }
  // Eq. (2).
  out.likelihood = 1.0 / (1.0 + std::exp(-out.c1 * (ratio - out.c2)));
  return out;
}

}  // namespace frictiond
