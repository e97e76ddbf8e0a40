#include "frictiond/estimators/span_variability.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>

#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/span_coverage.h"

namespace frictiond {

bool SpanVariabilityOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (subsets < 1 || subsets > 100000)
    return fail("subsets = " + std::to_string(subsets) +
                " (must be in 1..100000)");
  if (max_strokes < 1)
    return fail("max_strokes = " + std::to_string(max_strokes) +
                " (must be >= 1)");
  if (!(bin_pct > 0 && bin_pct <= 100))
    return fail("bin_pct = " + std::to_string(bin_pct) +
                " (must be in (0, 100])");
  if (min_samples < 4)
    return fail("min_samples = " + std::to_string(min_samples) +
                " (must be >= 4)");
  return true;
}

SpanVariability CalcSpanVariability(const std::vector<double>& fn_n,
                                    const std::vector<double>& v_mm_s,
                                    const std::vector<double>& mu,
                                    const std::vector<int>& stroke,
                                    const SpanVariabilityOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  if (fn_n.size() != mu.size() || v_mm_s.size() != mu.size() ||
      stroke.size() != mu.size()) {
    throw std::invalid_argument("fn_n, v_mm_s, mu and stroke differ in size");
  }
  SpanVariability out;
  // Samples per stroke (finite only).
  std::map<int, std::vector<std::size_t>> by_stroke;
  std::vector<std::pair<double, double>> all_points;
  for (std::size_t i = 0; i < mu.size(); ++i) {
    if (!std::isfinite(fn_n[i]) || !std::isfinite(v_mm_s[i]) ||
        !std::isfinite(mu[i]))
      continue;
    by_stroke[stroke[i]].push_back(i);
    all_points.emplace_back(fn_n[i], v_mm_s[i]);
  }
  out.strokes = static_cast<int>(by_stroke.size());
  out.full_hull_area = CalcConvexHullArea(all_points);
  if (!(out.full_hull_area > 0)) {
    out.why = "the slipping samples span no area in the Fn-v plane";
    return out;
  }
  std::vector<const std::vector<std::size_t>*> groups;
  for (const auto& kv : by_stroke) groups.push_back(&kv.second);
  std::mt19937_64 rng(options.seed);
  const int n_max = std::min(options.max_strokes, out.strokes);
  std::uniform_int_distribution<int> n_dist(1, n_max);
  std::vector<int> order(groups.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<std::size_t> rows;
  std::vector<std::pair<double, double>> points;
  for (int s = 0; s < options.subsets; ++s) {
    SpanSubset sub;
    sub.strokes = n_dist(rng);
    // Partial Fisher-Yates: the first sub.strokes entries are the subset.
    for (int k = 0; k < sub.strokes; ++k) {
      std::uniform_int_distribution<int> pick(
          k, static_cast<int>(order.size()) - 1);
      std::swap(order[k], order[pick(rng)]);
    }
    rows.clear();
    points.clear();
    for (int k = 0; k < sub.strokes; ++k) {
      for (std::size_t i : *groups[order[k]]) {
        rows.push_back(i);
        points.emplace_back(fn_n[i], v_mm_s[i]);
      }
    }
    sub.span_pct = std::min(
        100.0, 100.0 * CalcConvexHullArea(points) / out.full_hull_area);
    if (static_cast<int>(rows.size()) >= options.min_samples) {
      Eigen::MatrixXd X(rows.size(), 3);
      Eigen::VectorXd y(rows.size());
      for (std::size_t r = 0; r < rows.size(); ++r) {
        X(r, 0) = 1.0;
        X(r, 1) = v_mm_s[rows[r]];
        X(r, 2) = fn_n[rows[r]];
        y(r) = mu[rows[r]];
      }
      const OlsResult ols = FitOls(X, y);  // eq. (1)
      if (ols.status == FitStatus::kOk) {
        sub.identified = true;
        for (int j = 0; j < 3; ++j) sub.beta[j] = ols.beta(j);
      }
    }
    out.subsets.push_back(sub);
  }
  const int n_bins =
      static_cast<int>(std::ceil(100.0 / options.bin_pct - 1e-9));
  out.bins.resize(n_bins);
  for (int b = 0; b < n_bins; ++b) {
    out.bins[b].span_lo_pct = b * options.bin_pct;
    out.bins[b].span_hi_pct = std::min(100.0, (b + 1) * options.bin_pct);
  }
  // Welford per bin and coefficient.
  std::vector<std::array<double, 3>> m2(n_bins, {0, 0, 0});
  for (const SpanSubset& sub : out.subsets) {
    if (!sub.identified) continue;
    const int b =
        std::min(n_bins - 1, static_cast<int>(sub.span_pct / options.bin_pct));
    SpanBin& bin = out.bins[b];
    ++bin.subsets;
    for (int j = 0; j < 3; ++j) {
      const double d = sub.beta[j] - bin.beta_mean[j];
      bin.beta_mean[j] += d / bin.subsets;
      m2[b][j] += d * (sub.beta[j] - bin.beta_mean[j]);
    }
  }
  for (int b = 0; b < n_bins; ++b) {
    for (int j = 0; j < 3; ++j) {
      out.bins[b].beta_std[j] =
          out.bins[b].subsets > 1
              ? std::sqrt(m2[b][j] / (out.bins[b].subsets - 1))
              : 0.0;
    }
  }
  out.valid = true;
  return out;
}

}  // namespace frictiond
