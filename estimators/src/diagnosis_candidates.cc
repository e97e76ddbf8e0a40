// Model diagnosis: candidate causes, their expansions and effect texts
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>

#include <Eigen/Dense>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/stats.h"

#include "diagnosis_internal.h"

namespace frictiond::diagnosis_internal {

// ---------------------------------------------------------------------------
// Candidate expansions

ColumnSummary SummarizeColumn(const std::vector<double>& col,
                              const std::vector<std::size_t>& rows,
                              int cap) {
  ColumnSummary s;
  s.sorted.reserve(rows.size());
  for (std::size_t r : rows) s.sorted.push_back(col[r]);
  std::sort(s.sorted.begin(), s.sorted.end());
  for (std::size_t i = 0; i < s.sorted.size(); ++i) {
    if (i == 0 || s.sorted[i] != s.sorted[i - 1]) {
      ++s.distinct;
      if (s.distinct <= cap) s.levels.push_back(s.sorted[i]);
      if (s.distinct > cap) break;
    }
  }
  return s;
}

bool IsAngleDegrees(const std::string& name, const ColumnSummary& s) {
  if (EndsWith(name, "_deg")) return true;
  static const char* kUnits[] = {"_mm",
                                 "_s",
                                 "_n",
                                 "_c",
                                 "_pct",
                                 "_k",
                                 "_rad",
                                 "_sign",
                                 "_mm_s",
                                 "_mm_s2",
                                 "_n_s"};
  for (const char* u : kUnits) {
    if (EndsWith(name, u)) return false;
  }
  const double lo = s.sorted.front(), hi = s.sorted.back();
  return hi - lo >= 300 && hi - lo <= 400 && lo >= -360 && hi <= 720 &&
         s.distinct > 8;
}

/// Step basis: indicator windows of all bins but the first (the reference).
std::vector<Term> BinTerms(const std::string& name,
                           const ColumnSummary& s,
                           int bins) {
  std::vector<Term> terms;
  std::vector<double> edges;
  if (s.distinct <= bins) {
    const auto& l = s.levels;
    if (l.size() < 3)
      return terms;  // two levels: the step equals the linear term
    for (std::size_t j = 1; j < l.size(); ++j) {
      const double lo = 0.5 * (l[j - 1] + l[j]);
      const double hi = j + 1 < l.size() ? 0.5 * (l[j] + l[j + 1])
                                         : l[j] + 0.5 * (l[j] - l[j - 1]);
      edges.push_back(RoundForName(lo));
      if (j + 1 == l.size()) edges.push_back(RoundForName(hi));
    }
  } else {
    std::vector<double> u;
    for (int j = 0; j <= bins; ++j) {
      const double q =
          RoundForName(SortedQuantile(s.sorted, static_cast<double>(j) / bins));
      if (u.empty() || q > u.back()) u.push_back(q);
    }
    if (u.size() < 3) return terms;
    const double range = u.back() - u.front();
    u.back() = RoundForName(u.back() + 0.01 * range);
    edges.assign(u.begin() + 1, u.end());
  }
  for (std::size_t j = 0; j + 1 < edges.size(); ++j) {
    if (edges[j] < edges[j + 1])
      terms.push_back(
          Canonical(TermKind::kWindow, name, edges[j], edges[j + 1]));
  }
  return terms;
}

/// Candidate windows of a localized patch: [u_i, u_j) between quantiles
/// u of 2 x bins levels, 1 to bins / 2 levels wide.
std::vector<Term> ScanWindows(const std::string& name,
                              const ColumnSummary& s,
                              int bins) {
  std::vector<Term> out;
  if (s.distinct <= bins) return out;
  const int levels = 2 * bins;
  std::vector<double> u;
  for (int j = 0; j <= levels; ++j) {
    const double q =
        RoundForName(SortedQuantile(s.sorted, static_cast<double>(j) / levels));
    if (u.empty() || q > u.back()) u.push_back(q);
  }
  if (u.size() < 4) return out;
  u.back() = RoundForName(u.back() + 0.01 * (u.back() - u.front()));
  const int m = static_cast<int>(u.size());
  for (int i = 0; i + 1 < m; ++i) {
    for (int j = i + 1; j < m && j - i <= std::max(1, bins / 2); ++j) {
      if (i == 0 && j == m - 1) continue;
      out.push_back(Canonical(TermKind::kWindow, name, u[i], u[j]));
    }
  }
  return out;
}

std::vector<Expansion> BuildExpansions(
    const StrokeData& data,
    const std::vector<std::size_t>& rows,
    const std::vector<std::string>& form_inputs,
    const DiagnosisOptions& options,
    std::vector<std::string>* candidates,
    std::vector<std::string>* skipped) {
  std::vector<Expansion> out;
  auto excluded = [&](const std::string& name) {
    return std::find(options.exclude_candidates.begin(),
                     options.exclude_candidates.end(),
                     name) != options.exclude_candidates.end();
  };
  // Form of the model's own inputs.
  for (const std::string& name : form_inputs) {
    if (excluded(name)) continue;
    const std::vector<double>* col = data.Column(name);
    if (!col) continue;
    const ColumnSummary s = SummarizeColumn(*col, rows, options.bins);
    if (s.distinct < 4) {
      skipped->push_back(name + ": too few distinct values for a form test");
      continue;
    }
    candidates->push_back(name);
    out.push_back({name,
                   "form",
                   "quadratic",
                   {Canonical(TermKind::kPower, name, 2.0)},
                   {}});
    if (s.sorted.front() > 0)
      out.push_back(
          {name, "form", "log", {Canonical(TermKind::kLog, name)}, {}});
    const double q1 = RoundForName(SortedQuantile(s.sorted, 1.0 / 3)),
                 q2 = RoundForName(SortedQuantile(s.sorted, 2.0 / 3));
    if (q1 < q2) {
      out.push_back({name,
                     "form",
                     "hinge",
                     {Canonical(TermKind::kHinge, name, q1),
                      Canonical(TermKind::kHinge, name, q2)},
                     {}});
    }
  }
  // Covariates: extra columns and derived features.
  for (std::size_t k = 0; k < data.covariate_names.size(); ++k) {
    const std::string& name = data.covariate_names[k];
    if (excluded(name)) continue;
    // Product columns x*y are interaction candidates (InteractionExpansion).
    if (name.find('*') != std::string::npos) continue;
    const std::vector<double>& col = data.covariates[k];
    bool finite = true;
    for (std::size_t r : rows) finite = finite && std::isfinite(col[r]);
    if (!finite) {
      skipped->push_back(name +
                         ": missing or non-finite values on slipping samples");
      continue;
    }
    const ColumnSummary s = SummarizeColumn(col, rows, options.bins);
    const bool is_dwell = name == "dwell_s";
    const bool constant = s.distinct < 2;
    if (constant && !is_dwell) {
      skipped->push_back(name + ": constant on slipping samples");
      continue;
    }
    candidates->push_back(name);
    if (!constant) {
      out.push_back({name,
                     "covariate",
                     "linear",
                     {Canonical(TermKind::kLinear, name)},
                     {}});
      const double lo = s.sorted.front(), hi = s.sorted.back();
      const double mid = SortedQuantile(s.sorted, 0.5);
      const double sd_proxy =
          SortedQuantile(s.sorted, 0.84) - SortedQuantile(s.sorted, 0.16);
      if (IsAngleDegrees(name, s)) {
        out.push_back({name,
                       "covariate",
                       "periodic",
                       {Canonical(TermKind::kSinDeg, name),
                        Canonical(TermKind::kCosDeg, name)},
                       {}});
      } else if (EndsWith(name, "_rad") && hi - lo > 5.0) {
        out.push_back(
            {name,
             "covariate",
             "periodic",
             {Canonical(TermKind::kSin, name), Canonical(TermKind::kCos, name)},
             {}});
      }
      if (s.distinct > 3 && std::fabs(mid) < 100.0 * sd_proxy) {
        out.push_back({name,
                       "covariate",
                       "quadratic",
                       {Canonical(TermKind::kLinear, name),
                        Canonical(TermKind::kPower, name, 2.0)},
                       {}});
      }
      // Smooth monotone or not: a piecewise-linear spline with knots at the
      // quartiles (any shape the data bend into, not one planted curve).
      if (s.distinct > options.bins) {
        std::vector<Term> spline = {Canonical(TermKind::kLinear, name)};
        for (double q : {0.25, 0.5, 0.75}) {
          const double knot = RoundForName(SortedQuantile(s.sorted, q));
          if (knot > s.sorted.front() && knot < s.sorted.back() &&
              !(spline.back().kind == TermKind::kHinge &&
                spline.back().a == knot))
            spline.push_back(Canonical(TermKind::kHinge, name, knot));
        }
        if (spline.size() > 2)
          out.push_back({name, "covariate", "spline", std::move(spline), {}});
      }
      // Few distinct values: a categorical column, one level per value.
      std::vector<Term> bins = BinTerms(name, s, options.bins);
      if (!bins.empty())
        out.push_back({name,
                       "covariate",
                       s.distinct <= options.bins ? "levels" : "bins",
                       std::move(bins),
                       {}});
      std::vector<Term> windows = ScanWindows(name, s, options.bins);
      if (!windows.empty())
        out.push_back({name, "covariate", "window", {}, std::move(windows)});
    }
    if (is_dwell) {
      for (double tau : options.onset_decay_s) {
        std::vector<Term> terms = {
            Canonical(TermKind::kOnsetDecay, name, tau, 0.0)};
        if (!constant)
          terms.push_back(Canonical(TermKind::kOnsetDecay, name, tau, 1.0));
        out.push_back({name,
                       "regime",
                       "onset(" + Num(tau, 3) + " s)",
                       std::move(terms),
                       {}});
        // A transient growing concavely with the dwell (x^0.5): contact
        // ageing grows sub-linearly with the time at rest (static friction
        // ~ log of the dwell), and a concave weight does not let the few
        // strokes after the longest rests dominate the fit (a linear weight
        // over- or under-shoots them when the measured dwell or the
        // labelled onset is off for those strokes).
        if (!constant) {
          out.push_back({name,
                         "regime",
                         "onset(" + Num(tau, 3) + " s, sqrt)",
                         {Canonical(TermKind::kOnsetDecay, name, tau, 0.0),
                          Canonical(TermKind::kOnsetDecay, name, tau, 0.5)},
                         {}});
        }
      }
    }
  }
  return out;
}

Expansion InteractionExpansion(const std::string& x,
                               const std::string& y,
                               const std::vector<Term>& current) {
  Expansion e;
  e.cause = x + "*" + y;
  e.kind = "interaction";
  e.name = "product";
  e.terms.push_back(Canonical(TermKind::kLinear, e.cause));
  for (const std::string& main : {x, y}) {
    const Term t = Canonical(TermKind::kLinear, main);
    if (std::find(current.begin(), current.end(), t) == current.end())
      e.terms.push_back(t);
  }
  return e;
}

// ---------------------------------------------------------------------------
// Effect descriptions

std::string UnitOf(const std::string& name) {
  static const std::vector<std::pair<std::string, std::string>> kUnits = {
      {"_mm_s2", "mm/s^2"},
      {"_n_s", "N/s"},
      {"_mm_s", "mm/s"},
      {"_deg", "degree"},
      {"_rad", "rad"},
      {"_pct", "%"},
      {"_mm", "mm"},
      {"_s", "s"},
      {"_n", "N"},
      {"_c", "degC"},
      {"_k", "K"}};
  for (const auto& [suffix, unit] : kUnits) {
    if (EndsWith(name, suffix)) return unit;
  }
  return "unit";
}

double Beta(const std::vector<Term>& terms,
            const Eigen::VectorXd& beta,
            const Term& t) {
  for (std::size_t k = 0; k < terms.size(); ++k) {
    if (terms[k] == t) return beta(k);
  }
  return 0.0;
}

std::string DescribeEffect(const Expansion& e,
                           const std::vector<Term>& terms,
                           const Eigen::VectorXd& beta,
                           const StrokeData& data,
                           const std::vector<std::size_t>& rows) {
  const std::string& x = e.cause;
  const std::vector<double>* col = data.Column(x);
  std::vector<double> sorted;
  if (col) {
    for (std::size_t r : rows) sorted.push_back((*col)[r]);
    std::sort(sorted.begin(), sorted.end());
  }
  const std::string unit = UnitOf(x);
  if (e.name == "linear") {
    const double b = Beta(terms, beta, e.terms[0]);
    return std::string("mu ") + (b < 0 ? "falls " : "rises ") +
           Num(std::fabs(b)) + " per " + unit + " of " + x;
  }
  if (e.name == "periodic") {
    const double bs = Beta(terms, beta, e.terms[0]),
                 bc = Beta(terms, beta, e.terms[1]);
    const double amp = std::hypot(bs, bc);
    double phase = std::atan2(bs, bc) *
                   (e.terms[0].kind == TermKind::kSinDeg ? 180.0 / M_PI : 1.0);
    if (e.terms[0].kind == TermKind::kSinDeg && phase < 0) phase += 360.0;
    return "mu varies by +-" + Num(amp) + " with " + x +
           " (periodic, highest at " + x + " = " + Num(phase) + ")";
  }
  if (e.kind == "interaction") {
    const double b = Beta(terms, beta, e.terms[0]);
    const std::size_t star = x.find('*');
    const std::string a = x.substr(0, star), c = x.substr(star + 1);
    return "the slope of mu in " + a + " changes by " + Num(b) + " per " +
           UnitOf(c) + " of " + c + " (interaction " + x + ")";
  }
  if (e.name == "bins" || e.name == "levels") {
    // Bin effects relative to the sample-weighted mean.
    std::vector<double> effect = {0.0};
    std::vector<std::pair<double, double>> range = {
        {sorted.empty() ? 0 : sorted.front(), e.terms[0].a}};
    for (const Term& t : e.terms) {
      effect.push_back(Beta(terms, beta, t));
      range.push_back({t.a, t.b});
    }
    std::vector<double> weight(effect.size(), 0.0);
    for (double v : sorted) {
      std::size_t bin = 0;
      for (std::size_t j = 0; j < e.terms.size(); ++j) {
        if (v >= e.terms[j].a && v < e.terms[j].b) bin = j + 1;
      }
      weight[bin] += 1.0;
    }
    double mean = 0.0, total = 0.0;
    for (std::size_t j = 0; j < effect.size(); ++j)
      mean += weight[j] * effect[j], total += weight[j];
    mean /= std::max(1.0, total);
    std::size_t best = 0;
    for (std::size_t j = 0; j < effect.size(); ++j) {
      if (weight[j] > 0 &&
          std::fabs(effect[j] - mean) > std::fabs(effect[best] - mean))
        best = j;
    }
    const double d = effect[best] - mean;
    return "mu is " + Num(std::fabs(d)) + (d > 0 ? " higher" : " lower") +
           " than average for " + x + " in [" + Num(range[best].first, 5) +
           ", " + Num(range[best].second, 5) + ") " + unit + " (step basis, " +
           std::to_string(effect.size()) + " bins)";
  }
  if (e.name == "window") {
    const double b = Beta(terms, beta, e.terms[0]);
    return "mu is " + Num(std::fabs(b)) + (b > 0 ? " higher" : " lower") +
           " for " + x + " in [" + Num(e.terms[0].a, 5) + ", " +
           Num(e.terms[0].b, 5) + ") " + unit +
           " than elsewhere (localized patch)";
  }
  if (e.kind == "regime") {
    const double tau = e.terms[0].a;
    const double c0 = Beta(terms, beta, e.terms[0]);
    const double c1 = e.terms.size() > 1 ? Beta(terms, beta, e.terms[1]) : 0.0;
    if (e.terms.size() == 1 || sorted.empty()) {
      return "slip-onset transient: mu is " + Num(std::fabs(c0)) +
             (c0 > 0 ? " higher" : " lower") +
             " at slip onset, decaying with time constant " + Num(tau) + " s";
    }
    const double d_lo = SortedQuantile(sorted, 0.1),
                 d_hi = SortedQuantile(sorted, 0.9);
    const double power = e.terms[1].b;
    const double j_lo = c0 + c1 * std::pow(std::max(0.0, d_lo), power),
                 j_hi = c0 + c1 * std::pow(std::max(0.0, d_hi), power);
    return std::string("slip-onset transient growing with ") +
           (power == 1.0 ? "dwell" : "the square root of dwell") +
           ": at onset mu changes by " + Num(j_lo, 2) + " after " +
           Num(d_lo, 2) + " s of dwell and by " + Num(j_hi, 2) + " after " +
           Num(d_hi, 2) + " s, decaying with time constant " + Num(tau) + " s";
  }
  // Quadratic, log, hinge (form or covariate): the model's whole dependence
  // on x (its linear term included) at the 5th, 50th and 95th percentiles.
  if (sorted.empty()) return "non-linear in " + x;
  auto f = [&](double v) {
    double s = 0.0;
    for (std::size_t k = 0; k < terms.size(); ++k) {
      if (terms[k].input == x && !terms[k].NeedsSlipOnset())
        s += beta(k) * terms[k].Eval(v);
    }
    return s;
  };
  const double x5 = SortedQuantile(sorted, 0.05),
               x50 = SortedQuantile(sorted, 0.5),
               x95 = SortedQuantile(sorted, 0.95);
  const double f5 = f(x5), f50 = f(x50), f95 = f(x95);
  const double line50 =
      x95 > x5 ? f5 + (f95 - f5) * (x50 - x5) / (x95 - x5) : f50;
  const double bend = f50 - line50;
  // Enough digits to tell the quantiles apart (e.g. positions -109.97 and
  // -109.79 mm).
  const double mag = std::max(std::fabs(x5), std::fabs(x95));
  const int digits =
      x95 > x5 && mag > 0
          ? std::min(10,
                     3 + std::max(0,
                                  static_cast<int>(
                                      std::ceil(std::log10(mag / (x95 - x5))))))
          : 3;
  return std::string("mu is non-linear in ") + x + " (" + e.name +
         "): it changes by " + Num(f95 - f5) + " from " + x + " = " +
         Num(x5, digits) + " to " + Num(x95, digits) + " " + unit +
         ", and at the median (" + Num(x50, digits) + ") lies " +
         Num(std::fabs(bend)) + (bend > 0 ? " above" : " below") +
         " the straight line between them";
}

}  // namespace frictiond::diagnosis_internal
