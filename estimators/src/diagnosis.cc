#include "frictiond/estimators/diagnosis.h"

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

#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/stats.h"

namespace frictiond {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPaperPeakMmS = 10.0;

std::string Num(double x, int digits = 3) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, x);
  return buf;
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

/// Canonical term: Parse(Name()) so that numbers carry the name's precision
/// and the stored term list reproduces the tested model exactly.
Term Canonical(TermKind kind,
               const std::string& input,
               double a = 0.0,
               double b = 0.0) {
  Term t;
  t.kind = kind;
  t.input = input;
  t.a = a;
  t.b = b;
  return Term::Parse(t.Name());
}

/// Rounds to the 6 significant digits term names keep.
double RoundForName(double x) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return std::strtod(buf, nullptr);
}

std::vector<std::string> Names(const std::vector<Term>& terms) {
  std::vector<std::string> out;
  out.reserve(terms.size());
  for (const Term& t : terms) out.push_back(t.Name());
  return out;
}

/// A candidate cause tried as one set of extra terms.
struct Expansion {
  std::string cause;
  std::string kind;
  std::string name;
  std::vector<Term> terms;  // fixed terms (empty for a window scan)
  std::vector<Term>
      scan;  // window scan: one of these is chosen on training data
};

/// Rows to fit, grouped by fold, and the stroke bookkeeping of the CV.
struct CvSetup {
  std::vector<std::size_t> rows;     // fit rows, ordered by fold
  std::vector<int> fold_begin;       // K + 1 offsets into rows
  std::vector<int> stroke_of_entry;  // dense stroke index per entry of rows
  std::map<int, int> dense_of_id;    // stroke id -> dense index (all strokes)
  std::vector<int> id_of_dense;
  std::vector<int> fold_of_dense;
  std::vector<int> fit_count;  // fit rows per dense stroke
  int strokes_with_fit = 0;
  double mean_per_stroke = 1.0;
  Eigen::VectorXd y;
  int folds = 0;
};

/// Coefficients fitted on each fold's training part (original scale).
struct FoldModels {
  bool ok = false;
  std::vector<Eigen::VectorXd> beta;
  std::vector<double> sigma;
};

/// Fits y ~ X on all folds but one, for each fold, from per-fold Gram
/// matrices of standardised columns (one pass over X). Column 0 must be the
/// intercept. A tiny ridge keeps collinear and empty columns at 0.
FoldModels FitFolds(const Eigen::MatrixXd& X,
                    const Eigen::VectorXd& y,
                    const std::vector<int>& fold_begin) {
  FoldModels out;
  const int n = static_cast<int>(X.rows());
  const int p = static_cast<int>(X.cols());
  const int K = static_cast<int>(fold_begin.size()) - 1;
  if (n == 0 || p == 0 || !X.allFinite()) return out;
  Eigen::VectorXd center = Eigen::VectorXd::Zero(p),
                  scale = Eigen::VectorXd::Ones(p);
  std::vector<bool> active(p, true);
  int p_active = 1;
  for (int j = 1; j < p; ++j) {
    center(j) = X.col(j).mean();
    const double sd = std::sqrt((X.col(j).array() - center(j)).square().mean());
    if (!(sd > 1e-12 * (std::fabs(center(j)) + sd)) || !(sd > 0)) {
      active[j] = false;
      scale(j) = 1.0;
    } else {
      scale(j) = sd;
      ++p_active;
    }
  }
  Eigen::MatrixXd Z(n, p);
  Z.col(0).setOnes();
  for (int j = 1; j < p; ++j) {
    if (active[j]) {
      Z.col(j) = (X.col(j).array() - center(j)) / scale(j);
    } else {
      Z.col(j).setZero();
    }
  }
  std::vector<Eigen::MatrixXd> G(K);
  std::vector<Eigen::VectorXd> g(K);
  std::vector<double> yy(K);
  Eigen::MatrixXd G_total = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd g_total = Eigen::VectorXd::Zero(p);
  double yy_total = 0.0;
  for (int k = 0; k < K; ++k) {
    const int b = fold_begin[k], m = fold_begin[k + 1] - fold_begin[k];
    const auto Zk = Z.middleRows(b, m);
    const auto yk = y.segment(b, m);
    G[k].noalias() = Zk.transpose() * Zk;
    g[k].noalias() = Zk.transpose() * yk;
    yy[k] = yk.squaredNorm();
    G_total += G[k];
    g_total += g[k];
    yy_total += yy[k];
  }
  out.beta.resize(K);
  out.sigma.resize(K);
  for (int k = 0; k < K; ++k) {
    const int n_train = n - (fold_begin[k + 1] - fold_begin[k]);
    Eigen::MatrixXd A = G_total - G[k];
    const Eigen::VectorXd rhs = g_total - g[k];
    const double ridge = 1e-9 * std::max(1, n_train);
    for (int j = 1; j < p; ++j) A(j, j) += ridge;
    if (n_train < p_active + 2) return out;
    Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
    if (ldlt.info() != Eigen::Success) return out;
    const Eigen::VectorXd bz = ldlt.solve(rhs);
    if (!bz.allFinite()) return out;
    const double rss = std::max(
        0.0,
        (yy_total - yy[k]) - 2.0 * bz.dot(rhs) + bz.dot((G_total - G[k]) * bz));
    out.sigma[k] = std::sqrt(rss / std::max(1, n_train - p_active));
    Eigen::VectorXd beta(p);
    beta(0) = bz(0);
    for (int j = 1; j < p; ++j) {
      beta(j) = active[j] ? bz(j) / scale(j) : 0.0;
      beta(0) -= beta(j) * center(j);
    }
    out.beta[k] = std::move(beta);
  }
  out.ok = true;
  return out;
}

/// Held-out performance of one model.
struct CvEval {
  bool ok = false;
  Eigen::VectorXd residuals;       // per entry of CvSetup::rows
  std::vector<double> stroke_sae;  // per dense stroke
  double mae = 0.0;
  double log_likelihood = 0.0;  // mean per sample
  FoldModels models;
};

CvEval Evaluate(const CvSetup& cv, const Eigen::MatrixXd& X) {
  CvEval ev;
  ev.models = FitFolds(X, cv.y, cv.fold_begin);
  if (!ev.models.ok) return ev;
  const int n = static_cast<int>(X.rows());
  ev.residuals.resize(n);
  ev.stroke_sae.assign(cv.id_of_dense.size(), 0.0);
  double sae = 0.0, ll = 0.0;
  for (int k = 0; k < cv.folds; ++k) {
    const Eigen::VectorXd& beta = ev.models.beta[k];
    const double s2 = std::max(1e-300, ev.models.sigma[k] * ev.models.sigma[k]);
    const double ll0 = -0.5 * std::log(2.0 * M_PI * s2);
    for (int i = cv.fold_begin[k]; i < cv.fold_begin[k + 1]; ++i) {
      const double r = cv.y(i) - X.row(i).dot(beta);
      ev.residuals(i) = r;
      ev.stroke_sae[cv.stroke_of_entry[i]] += std::fabs(r);
      sae += std::fabs(r);
      ll += ll0 - 0.5 * r * r / s2;
    }
  }
  ev.mae = sae / std::max(1, n);
  ev.log_likelihood = ll / std::max(1, n);
  ev.ok = ev.residuals.allFinite();
  return ev;
}

/// Picks the window whose indicator best explains residuals r (largest
/// (sum r)^2 / count over rows where `use`), among windows covering at least
/// 1 % of those rows. Returns -1 when none qualifies.
int PickWindow(const Eigen::MatrixXd& W,
               const Eigen::VectorXd& r,
               const std::vector<char>& use) {
  const int nw = static_cast<int>(W.cols());
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(nw),
                  cnt = Eigen::VectorXd::Zero(nw);
  int n_use = 0;
  for (int i = 0; i < W.rows(); ++i) {
    if (!use[i]) continue;
    ++n_use;
    sum.noalias() += r(i) * W.row(i).transpose();
    cnt.noalias() += W.row(i).transpose();
  }
  int best = -1;
  double best_score = 0.0;
  for (int w = 0; w < nw; ++w) {
    if (cnt(w) < 0.01 * n_use || cnt(w) > 0.99 * n_use) continue;
    // Reduction of the residual sum of squares by a mean shift inside the
    // window (against a mean shift outside it, which the intercept absorbs).
    const double inside = cnt(w), outside = n_use - cnt(w);
    const double score = sum(w) * sum(w) * n_use / (inside * outside);
    if (score > best_score) best_score = score, best = w;
  }
  return best;
}

/// Held-out evaluation of current model + one window chosen per fold on that
/// fold's training rows only (the choice is part of the fitted model, so the
/// held-out error is honest). *chosen_all is the window chosen on all rows.
CvEval EvaluateWindowScan(const CvSetup& cv,
                          const Eigen::MatrixXd& X_cur,
                          const CvEval& cur,
                          const Eigen::VectorXd& full_residuals,
                          const Eigen::MatrixXd& W,
                          int* chosen_all) {
  CvEval ev;
  const int n = static_cast<int>(X_cur.rows());
  const int p = static_cast<int>(X_cur.cols());
  std::vector<char> all(n, 1);
  *chosen_all = PickWindow(W, full_residuals, all);
  if (*chosen_all < 0 || !cur.models.ok) return ev;
  ev.residuals.resize(n);
  ev.stroke_sae.assign(cv.id_of_dense.size(), 0.0);
  ev.models.ok = true;
  ev.models.beta.resize(cv.folds);
  ev.models.sigma.resize(cv.folds);
  Eigen::MatrixXd X(n, p + 1);
  X.leftCols(p) = X_cur;
  double sae = 0.0, ll = 0.0;
  for (int k = 0; k < cv.folds; ++k) {
    std::vector<char> train(n, 1);
    Eigen::VectorXd r(n);
    for (int i = 0; i < n; ++i)
      r(i) = cv.y(i) - X_cur.row(i).dot(cur.models.beta[k]);
    for (int i = cv.fold_begin[k]; i < cv.fold_begin[k + 1]; ++i) train[i] = 0;
    const int w = PickWindow(W, r, train);
    X.col(p) = w >= 0 ? Eigen::VectorXd(W.col(w)) : Eigen::VectorXd::Zero(n);
    const FoldModels m = FitFolds(X, cv.y, cv.fold_begin);
    if (!m.ok) return CvEval();
    ev.models.beta[k] = m.beta[k];
    ev.models.sigma[k] = m.sigma[k];
    const double s2 = std::max(1e-300, m.sigma[k] * m.sigma[k]);
    const double ll0 = -0.5 * std::log(2.0 * M_PI * s2);
    for (int i = cv.fold_begin[k]; i < cv.fold_begin[k + 1]; ++i) {
      const double e = cv.y(i) - X.row(i).dot(m.beta[k]);
      ev.residuals(i) = e;
      ev.stroke_sae[cv.stroke_of_entry[i]] += std::fabs(e);
      sae += std::fabs(e);
      ll += ll0 - 0.5 * e * e / s2;
    }
  }
  ev.mae = sae / std::max(1, n);
  ev.log_likelihood = ll / std::max(1, n);
  ev.ok = ev.residuals.allFinite();
  return ev;
}

/// One-sided paired t-test over strokes that `cand` has lower held-out
/// absolute error than `cur`. Returns {t, p}.
std::pair<double, double> PairedStrokeTest(const CvSetup& cv,
                                           const CvEval& cur,
                                           const CvEval& cand) {
  std::vector<double> d;
  d.reserve(cv.id_of_dense.size());
  for (std::size_t s = 0; s < cv.id_of_dense.size(); ++s) {
    if (cv.fit_count[s] == 0) continue;
    d.push_back((cur.stroke_sae[s] - cand.stroke_sae[s]) / cv.mean_per_stroke);
  }
  const double S = static_cast<double>(d.size());
  if (S < 3) return {0.0, 1.0};
  double mean = 0.0;
  for (double x : d) mean += x;
  mean /= S;
  double var = 0.0;
  for (double x : d) var += (x - mean) * (x - mean);
  var /= (S - 1);
  if (!(var > 0))
    return {mean > 0 ? std::numeric_limits<double>::infinity() : 0.0,
            mean > 0 ? 0.0 : 1.0};
  const double t = mean / std::sqrt(var / S);
  const double two = StudentTTwoSidedP(t, S - 1);
  return {t, t > 0 ? 0.5 * two : 1.0 - 0.5 * two};
}

/// Holm's step-down adjustment.
std::vector<double> HolmAdjust(const std::vector<double>& p) {
  const std::size_t m = p.size();
  std::vector<std::size_t> order(m);
  for (std::size_t i = 0; i < m; ++i) order[i] = i;
  std::stable_sort(order.begin(),
                   order.end(),
                   [&](std::size_t a, std::size_t b) { return p[a] < p[b]; });
  std::vector<double> adj(m, 1.0);
  double running = 0.0;
  for (std::size_t r = 0; r < m; ++r) {
    const double v = std::min(1.0, static_cast<double>(m - r) * p[order[r]]);
    running = std::max(running, v);
    adj[order[r]] = running;
  }
  return adj;
}

// ---------------------------------------------------------------------------
// Candidate expansions

struct ColumnSummary {
  std::vector<double> sorted;  // values on fit rows, ascending
  int distinct = 0;            // capped at cap + 1
  std::vector<double> levels;  // distinct values when few
};

ColumnSummary Summarize(const std::vector<double>& col,
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
    const ColumnSummary s = Summarize(*col, rows, options.bins);
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
    const std::vector<double>& col = data.covariates[k];
    bool finite = true;
    for (std::size_t r : rows) finite = finite && std::isfinite(col[r]);
    if (!finite) {
      skipped->push_back(name +
                         ": missing or non-finite values on slipping samples");
      continue;
    }
    const ColumnSummary s = Summarize(col, rows, options.bins);
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
      std::vector<Term> bins = BinTerms(name, s, options.bins);
      if (!bins.empty())
        out.push_back({name, "covariate", "bins", std::move(bins), {}});
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
      }
    }
  }
  return out;
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
  if (e.name == "bins") {
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
    const double j_lo = c0 + c1 * d_lo, j_hi = c0 + c1 * d_hi;
    return "slip-onset transient growing with dwell: at onset mu changes by " +
           Num(j_lo, 2) + " after " + Num(d_lo, 2) + " s of dwell and by " +
           Num(j_hi, 2) + " after " + Num(d_hi, 2) +
           " s, decaying with time constant " + Num(tau) + " s";
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
  return std::string("mu is non-linear in ") + x + " (" + e.name +
         "): it changes by " + Num(f95 - f5) + " from " + x + " = " + Num(x5) +
         " to " + Num(x95) + " " + unit + ", and at the median (" + Num(x50) +
         ") lies " + Num(std::fabs(bend)) + (bend > 0 ? " above" : " below") +
         " the straight line between them";
}

// ---------------------------------------------------------------------------
// Replay

/// Peak measured Ft/Fn around a stroke's first slip onset: from 0.25 s
/// before to breakaway_window_s after (the window Replay uses); *onset gets
/// the onset row (j + 1 when the stroke [i, j] has no slip sample).
double MeasuredBreakaway(const StrokeData& data,
                         std::size_t i,
                         std::size_t j,
                         double window_s,
                         std::size_t* onset) {
  *onset = j + 1;
  for (std::size_t a = i; a <= j; ++a) {
    if (data.slip[a] == 1) {
      *onset = a;
      break;
    }
  }
  if (*onset > j) return kNaN;
  double peak = 0.0;
  for (std::size_t a = i; a <= j && data.t_s[a] <= data.t_s[*onset] + window_s;
       ++a) {
    if (data.t_s[a] >= data.t_s[*onset] - 0.25)
      peak = std::max(peak, data.mu(a));
  }
  return peak;
}

ModelReplay Replay(const std::string& model_name,
                   const std::vector<Term>& terms,
                   const StrokeData& data,
                   const CvSetup& cv,
                   const CvEval& mu_eval,
                   const DiagnosisOptions& options) {
  ModelReplay out;
  out.model = model_name;
  out.terms = Names(terms);
  const std::size_t n = data.size();
  const std::size_t S = cv.id_of_dense.size();
  // Slip model: the mu model without motion inputs (knowing v implies
  // knowing slip; paper 000 III-C uses mu = b0 + b2 Fn + eps).
  std::vector<Term> slip_terms;
  for (const Term& t : terms) {
    if (t.input != "v_mm_s" && t.input != "accel_mm_s2")
      slip_terms.push_back(t);
  }
  const bool coulomb =
      model_name == "coulomb";  // binary: slip iff Ft/Fn >= mu_c
  const Eigen::MatrixXd X_slip_fit = BuildDesign(data, slip_terms, cv.rows);
  const FoldModels slip_models = FitFolds(X_slip_fit, cv.y, cv.fold_begin);
  std::vector<std::size_t> all(n);
  for (std::size_t i = 0; i < n; ++i) all[i] = i;
  const Eigen::MatrixXd X_slip_all = BuildDesign(data, slip_terms, all);

  std::vector<ReplayErrors> per(S);
  for (std::size_t s = 0; s < S; ++s) {
    per[s].stroke = cv.id_of_dense[s];
    per[s].breakaway_measured = kNaN;
    per[s].breakaway_predicted = kNaN;
  }
  for (std::size_t s = 0; s < S; ++s) {
    per[s].slip_samples = cv.fit_count[s];
    per[s].mu_mae =
        cv.fit_count[s] > 0 ? mu_eval.stroke_sae[s] / cv.fit_count[s] : kNaN;
  }
  // Slip probabilities per sample, events and Brier per stroke.
  std::vector<double> prob(n, 0.0);
  std::vector<int> dense(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const int s = cv.dense_of_id.at(data.stroke[i]);
    dense[i] = s;
    if (!slip_models.ok) {
      prob[i] = kNaN;
      continue;
    }
    const int k = cv.fold_of_dense[s];
    const double m = X_slip_all.row(i).dot(slip_models.beta[k]);
    const double ratio = data.mu(i);
    if (coulomb) {
      prob[i] = ratio >= m ? 1.0 : 0.0;
    } else {
      const double sigma = std::max(1e-12, slip_models.sigma[k]);
      prob[i] = NormalCdf((ratio - m) / sigma);
    }
  }
  std::vector<double> brier_sum(S, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    ReplayErrors& e = per[dense[i]];
    ++e.samples;
    const double d = prob[i] - data.slip[i];
    brier_sum[dense[i]] += d * d;
  }
  // Runs within a stroke: slip episodes and predicted-slip runs.
  std::vector<std::size_t> onset_rows;
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i;
    while (j + 1 < n && data.stroke[j + 1] == data.stroke[i]) ++j;
    ReplayErrors& e = per[dense[i]];
    for (std::size_t a = i; a <= j;) {  // episodes
      if (data.slip[a] != 1) {
        ++a;
        continue;
      }
      std::size_t b = a;
      double pmax = prob[a];
      while (b + 1 <= j && data.slip[b + 1] == 1)
        pmax = std::max(pmax, prob[++b]);
      ++e.slip_events;
      (pmax >= 0.5 ? e.hits : e.misses) += 1;
      a = b + 1;
    }
    for (std::size_t a = i; a <= j;) {  // predicted runs
      if (!(prob[a] >= 0.5)) {
        ++a;
        continue;
      }
      std::size_t b = a;
      bool any_slip = data.slip[a] == 1;
      while (b + 1 <= j && prob[b + 1] >= 0.5) {
        ++b;
        if (data.slip[b] == 1) any_slip = true;
      }
      if (!any_slip) ++e.false_alarms;
      a = b + 1;
    }
    // Break-away: peak ratio up to the window after the first onset.
    std::size_t onset = j + 1;
    const double peak =
        MeasuredBreakaway(data, i, j, options.breakaway_window_s, &onset);
    if (onset <= j) {
      e.breakaway_measured = peak;
      onset_rows.push_back(onset);
    }
    i = j + 1;
  }
  if (mu_eval.models.ok && !onset_rows.empty()) {
    const Eigen::MatrixXd x = BuildDesign(data, terms, onset_rows);
    for (std::size_t r = 0; r < onset_rows.size(); ++r) {
      const int s = dense[onset_rows[r]];
      const double pred =
          x.row(r).dot(mu_eval.models.beta[cv.fold_of_dense[s]]);
      if (std::isfinite(pred)) per[s].breakaway_predicted = pred;
    }
  }
  ReplayErrors& all_e = out.overall;
  double sae = 0.0, brier = 0.0, ba_abs = 0.0, ba_bias = 0.0;
  int fit = 0, ba_n = 0;
  for (std::size_t s = 0; s < S; ++s) {
    ReplayErrors& e = per[s];
    e.brier = e.samples > 0 ? brier_sum[s] / e.samples : kNaN;
    brier += brier_sum[s];
    sae += mu_eval.stroke_sae[s];
    fit += cv.fit_count[s];
    all_e.samples += e.samples;
    all_e.slip_samples += e.slip_samples;
    all_e.slip_events += e.slip_events;
    all_e.hits += e.hits;
    all_e.misses += e.misses;
    all_e.false_alarms += e.false_alarms;
    if (std::isfinite(e.breakaway_measured) &&
        std::isfinite(e.breakaway_predicted)) {
      e.breakaway_abs_error =
          std::fabs(e.breakaway_predicted - e.breakaway_measured);
      e.breakaway_bias = e.breakaway_predicted - e.breakaway_measured;
      ba_abs += e.breakaway_abs_error;
      ba_bias += e.breakaway_bias;
      ++ba_n;
    } else {
      e.breakaway_abs_error = e.breakaway_bias = kNaN;
    }
  }
  all_e.mu_mae = fit > 0 ? sae / fit : kNaN;
  all_e.brier = all_e.samples > 0 ? brier / all_e.samples : kNaN;
  all_e.breakaway_measured = all_e.breakaway_predicted = kNaN;
  all_e.breakaway_abs_error = ba_n > 0 ? ba_abs / ba_n : kNaN;
  all_e.breakaway_bias = ba_n > 0 ? ba_bias / ba_n : kNaN;
  out.strokes = std::move(per);
  return out;
}

/// LuGre replay (paper 001): each stroke velocity-driven by its measured
/// v(t) (signed by dir_sign when present) from z0 = min(mu_0, mu_s) / sigma0,
/// compared as |mu_sim| with the measured Ft/Fn on the fitted (slipping)
/// samples of `cv`, and on the peak ratio in the break-away window.
ModelReplay ReplayLuGre(const LuGreTheta& theta,
                        const StrokeData& data,
                        const CvSetup& cv,
                        const DiagnosisOptions& options) {
  static const char* const kNames[6] = {
      "mu_s", "mu_c", "v0_mm_s", "sigma2_s_mm", "sigma0_per_mm", "sigma1_s_mm"};
  ModelReplay out;
  out.model = "lugre";
  for (int k = 0; k < 6; ++k)
    out.terms.push_back(std::string(kNames[k]) + "=" + Num(theta[k], 4));
  out.predicts_slip = false;
  out.note =
      "given parameters (not fitted to these strokes); velocity-driven "
      "replay of each stroke from z0 = min(mu_0, mu_s)/sigma0";
  const std::size_t n = data.size();
  const std::size_t S = cv.id_of_dense.size();
  const std::optional<std::size_t> dir = data.FindCovariate("dir_sign");
  std::vector<double> mu_sim(n, kNaN);
  std::vector<ReplayErrors> per(S);
  for (std::size_t s = 0; s < S; ++s) {
    per[s].stroke = cv.id_of_dense[s];
    per[s].slip_samples = cv.fit_count[s];
    per[s].brier = kNaN;
    per[s].breakaway_measured = per[s].breakaway_predicted = kNaN;
  }
  int failed = 0;
  std::string first_failure;
  Eigen::VectorXd t, v;
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i;
    while (j + 1 < n && data.stroke[j + 1] == data.stroke[i]) ++j;
    ReplayErrors& e = per[cv.dense_of_id.at(data.stroke[i])];
    const Eigen::Index m = static_cast<Eigen::Index>(j - i + 1);
    e.samples += static_cast<int>(m);
    t.resize(m);
    v.resize(m);
    double first_sign = 0.0;
    for (Eigen::Index k = 0; k < m; ++k) {
      const std::size_t row = i + static_cast<std::size_t>(k);
      // Strictly increasing times for the integrator (duplicates nudged).
      t[k] = data.t_s[row] - data.t_s[i];
      if (k > 0 && !(t[k] > t[k - 1])) t[k] = t[k - 1] + 1e-9;
      const double sign = dir && data.covariates[*dir][row] < 0 ? -1.0 : 1.0;
      v[k] = sign * data.v_mm_s[row];
      if (first_sign == 0.0 && data.v_mm_s[row] > 0) first_sign = sign;
    }
    if (first_sign == 0.0) first_sign = 1.0;
    const double z0_mm = first_sign *
                         std::min(data.mu(i), theta[LuGreIndex::kMuStatic]) /
                         theta[LuGreIndex::kStiffness];
    VelocityDrivenResult r;
    if (m >= 2) {
      try {
        r = SimulateVelocityDriven(theta, t, v, z0_mm);
      } catch (const std::invalid_argument& e) {  // e.g. non-finite input
        r.status = SimulationStatus::kNonFinite;
        r.why = e.what();
        r.mu = Eigen::VectorXd::Constant(m, kNaN);
      }
    } else {
      r.status = SimulationStatus::kOk;
      r.mu =
          Eigen::VectorXd::Constant(1, theta[LuGreIndex::kStiffness] * z0_mm);
    }
    if (r.status != SimulationStatus::kOk) {
      if (failed++ == 0)
        first_failure =
            "stroke " + std::to_string(data.stroke[i]) + ": " + r.why;
    }
    for (Eigen::Index k = 0; k < m; ++k)
      mu_sim[i + static_cast<std::size_t>(k)] = std::fabs(r.mu[k]);
    std::size_t onset = j + 1;
    e.breakaway_measured =
        MeasuredBreakaway(data, i, j, options.breakaway_window_s, &onset);
    if (onset <= j) {
      double peak = kNaN;
      for (std::size_t a = i;
           a <= j &&
           data.t_s[a] <= data.t_s[onset] + options.breakaway_window_s;
           ++a) {
        if (data.t_s[a] >= data.t_s[onset] - 0.25 && std::isfinite(mu_sim[a]))
          peak = std::isfinite(peak) ? std::max(peak, mu_sim[a]) : mu_sim[a];
      }
      e.breakaway_predicted = peak;
    }
    for (std::size_t a = i; a <= j;) {  // labelled slip episodes
      if (data.slip[a] != 1) {
        ++a;
        continue;
      }
      while (a + 1 <= j && data.slip[a + 1] == 1) ++a;
      ++e.slip_events;
      ++a;
    }
    i = j + 1;
  }
  if (failed > 0) {
    out.note += "; " + std::to_string(failed) +
                " stroke(s) not fully simulated (first: " + first_failure + ")";
  }
  // mu errors on the fitted samples (the rows of the other replays).
  std::vector<double> sae(S, 0.0);
  std::vector<int> used(S, 0);
  for (std::size_t r = 0; r < cv.rows.size(); ++r) {
    const std::size_t row = cv.rows[r];
    if (!std::isfinite(mu_sim[row])) continue;
    const int s = cv.stroke_of_entry[r];
    sae[s] += std::fabs(data.mu(row) - mu_sim[row]);
    ++used[s];
  }
  ReplayErrors& all_e = out.overall;
  all_e.brier = kNaN;
  double sae_all = 0.0, ba_abs = 0.0, ba_bias = 0.0;
  int used_all = 0, ba_n = 0;
  for (std::size_t s = 0; s < S; ++s) {
    ReplayErrors& e = per[s];
    e.mu_mae = used[s] > 0 ? sae[s] / used[s] : kNaN;
    sae_all += sae[s];
    used_all += used[s];
    all_e.samples += e.samples;
    all_e.slip_samples += e.slip_samples;
    all_e.slip_events += e.slip_events;
    if (std::isfinite(e.breakaway_measured) &&
        std::isfinite(e.breakaway_predicted)) {
      e.breakaway_bias = e.breakaway_predicted - e.breakaway_measured;
      e.breakaway_abs_error = std::fabs(e.breakaway_bias);
      ba_abs += e.breakaway_abs_error;
      ba_bias += e.breakaway_bias;
      ++ba_n;
    } else {
      e.breakaway_abs_error = e.breakaway_bias = kNaN;
    }
  }
  all_e.mu_mae = used_all > 0 ? sae_all / used_all : kNaN;
  all_e.breakaway_measured = all_e.breakaway_predicted = kNaN;
  all_e.breakaway_abs_error = ba_n > 0 ? ba_abs / ba_n : kNaN;
  all_e.breakaway_bias = ba_n > 0 ? ba_bias / ba_n : kNaN;
  out.strokes = std::move(per);
  return out;
}

DiagnosedModel Summarize(const std::string& name,
                         const std::vector<Term>& terms,
                         const StrokeData& data,
                         const CvSetup& cv,
                         const CvEval& ev,
                         Eigen::VectorXd* beta_out) {
  DiagnosedModel m;
  m.model = name;
  m.terms = Names(terms);
  m.cv_mae = ev.mae;
  m.cv_log_likelihood = ev.log_likelihood;
  const OlsResult ols = FitOls(BuildDesign(data, terms, cv.rows), cv.y);
  m.beta.assign(ols.beta.data(), ols.beta.data() + ols.beta.size());
  m.sigma_eps = ols.sigma_eps;
  if (beta_out) *beta_out = ols.beta;
  return m;
}

}  // namespace

bool DiagnosisOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (!labelling.IsValid(why)) return false;
  if (!(folds >= 2))
    return fail("folds = " + std::to_string(folds) + " (must be >= 2)");
  if (!(alpha > 0 && alpha < 1))
    return fail("alpha = " + Num(alpha) + " (must be in (0, 1))");
  if (!(min_gain_pct >= 0) || !std::isfinite(min_gain_pct)) {
    return fail("min_gain_pct = " + Num(min_gain_pct) +
                " (must be finite and >= 0)");
  }
  if (max_findings < 0)
    return fail("max_findings = " + std::to_string(max_findings) +
                " (must be >= 0)");
  if (baseline_terms.empty() || baseline_terms.front() != "intercept") {
    return fail("baseline_terms must start with \"intercept\"");
  }
  for (const std::string& t : baseline_terms) {
    try {
      Term::Parse(t);
    } catch (const std::invalid_argument& e) {
      return fail(std::string("baseline_terms: ") + e.what());
    }
  }
  if (!(min_relative_span >= 0))
    return fail("min_relative_span = " + Num(min_relative_span) +
                " (must be >= 0)");
  if (bins < 2)
    return fail("bins = " + std::to_string(bins) + " (must be >= 2)");
  for (double tau : onset_decay_s) {
    if (!(tau > 0) || !std::isfinite(tau))
      return fail("onset_decay_s = " + Num(tau) + " (must be finite and > 0)");
  }
  if (!(breakaway_window_s >= 0)) {
    return fail("breakaway_window_s = " + Num(breakaway_window_s) +
                " (must be >= 0)");
  }
  std::string lugre_why;
  if (lugre && !IsValidLuGreTheta(*lugre, &lugre_why))
    return fail("lugre: " + lugre_why);
  return true;
}

const char* ToString(DiagnosisStatus status) {
  switch (status) {
    case DiagnosisStatus::kOk:
      return "ok";
    case DiagnosisStatus::kTooFewSamples:
      return "too_few_samples";
    case DiagnosisStatus::kTooFewStrokes:
      return "too_few_strokes";
    case DiagnosisStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

StrokeData PrepareDiagnosisData(StrokeData data,
                                const SlipLabelOptions& labelling) {
  EnsureLabels(&data, labelling);
  AddDerivedFeatures(&data, labelling.gap_factor);
  return data;
}

SlipLabelOptions CalcAutoSlipLabelOptions(const std::vector<double>& v_mm_s,
                                          const SlipLabelOptions& base,
                                          std::string* rule) {
  SlipLabelOptions o = base;
  std::vector<double> v = v_mm_s;
  std::sort(v.begin(), v.end());
  const double v99 = v.empty() ? 0.0 : SortedQuantile(v, 0.99);
  if (v99 >= kPaperPeakMmS || !(v99 > 0)) {
    o.peak_mm_s = kPaperPeakMmS;
    o.floor_mm_s = 5.0;
    if (rule)
      *rule = "paper 000 thresholds (99th percentile speed " + Num(v99) +
              " mm/s >= 10 mm/s)";
    return o;
  }
  o.peak_mm_s = RoundForName(0.25 * v99);
  o.floor_mm_s = RoundForName(0.08 * v99);
  if (rule) {
    *rule = "automatic: 99th percentile speed " + Num(v99) +
            " mm/s is below the paper's 10 mm/s peak, so peak = 0.25 x " +
            Num(v99) + " = " + Num(o.peak_mm_s) + " mm/s, floor = 0.08 x " +
            Num(v99) + " = " + Num(o.floor_mm_s) + " mm/s";
  }
  return o;
}

DiagnosisResult Diagnose(const StrokeData& input,
                         const DiagnosisOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  // Labels and derived features (on a copy when missing).
  const StrokeData* data_ptr = &input;
  StrokeData prepared;
  bool has_derived = true;
  for (const std::string& name : DerivedFeatureNames())
    has_derived = has_derived && input.FindCovariate(name);
  if (input.slip.size() != input.size() ||
      input.stroke.size() != input.size() || !has_derived) {
    prepared = input;
    EnsureLabels(&prepared, options.labelling);
    if (!has_derived)
      AddDerivedFeatures(&prepared, options.labelling.gap_factor);
    data_ptr = &prepared;
  }
  const StrokeData& data = *data_ptr;

  DiagnosisResult result;
  result.samples = static_cast<int>(data.size());
  const std::vector<bool> mask = CalcFitMask(data, options.labelling);

  // Strokes (dense indices over all strokes) and folds.
  CvSetup cv;
  for (int id : data.stroke) {
    if (cv.dense_of_id.emplace(id, static_cast<int>(cv.id_of_dense.size()))
            .second)
      cv.id_of_dense.push_back(id);
  }
  const std::size_t S = cv.id_of_dense.size();
  cv.fit_count.assign(S, 0);
  int fit_total = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (mask[i]) ++cv.fit_count[cv.dense_of_id[data.stroke[i]]], ++fit_total;
  }
  std::vector<int> fit_strokes;
  for (std::size_t s = 0; s < S; ++s) {
    if (cv.fit_count[s] > 0) fit_strokes.push_back(static_cast<int>(s));
  }
  cv.strokes_with_fit = static_cast<int>(fit_strokes.size());
  result.fit_samples = fit_total;
  result.strokes = cv.strokes_with_fit;
  if (fit_total < 20) {
    result.status = DiagnosisStatus::kTooFewSamples;
    result.why = std::to_string(fit_total) +
                 " slipping samples within the bounds (need at least 20); "
                 "check the slip thresholds";
    return result;
  }
  if (cv.strokes_with_fit < 3) {
    result.status = DiagnosisStatus::kTooFewStrokes;
    result.why = std::to_string(cv.strokes_with_fit) +
                 " strokes with slipping samples (need at least 3 for "
                 "stroke-level cross-validation)";
    return result;
  }
  cv.folds = std::min(options.folds, cv.strokes_with_fit);
  result.folds = cv.folds;
  // Deterministic Fisher-Yates shuffle of the fitted strokes, then round robin.
  std::mt19937_64 rng(options.seed);
  for (std::size_t i = fit_strokes.size(); i > 1; --i)
    std::swap(fit_strokes[i - 1], fit_strokes[rng() % i]);
  cv.fold_of_dense.assign(S, 0);
  for (std::size_t s = 0; s < S; ++s)
    cv.fold_of_dense[s] = static_cast<int>(s % cv.folds);
  for (std::size_t r = 0; r < fit_strokes.size(); ++r)
    cv.fold_of_dense[fit_strokes[r]] = static_cast<int>(r % cv.folds);
  std::vector<std::vector<std::size_t>> by_fold(cv.folds);
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (mask[i])
      by_fold[cv.fold_of_dense[cv.dense_of_id[data.stroke[i]]]].push_back(i);
  }
  cv.fold_begin.push_back(0);
  for (const auto& f : by_fold) {
    cv.rows.insert(cv.rows.end(), f.begin(), f.end());
    cv.fold_begin.push_back(static_cast<int>(cv.rows.size()));
  }
  cv.y.resize(cv.rows.size());
  cv.stroke_of_entry.resize(cv.rows.size());
  for (std::size_t e = 0; e < cv.rows.size(); ++e) {
    cv.y(e) = data.mu(cv.rows[e]);
    cv.stroke_of_entry[e] = cv.dense_of_id[data.stroke[cv.rows[e]]];
  }
  cv.mean_per_stroke = static_cast<double>(fit_total) / cv.strokes_with_fit;

  // Baseline: eq. (1) without inputs that have no span.
  std::vector<Term> baseline;
  std::vector<std::string> form_inputs;
  for (const std::string& name : options.baseline_terms) {
    const Term t = Term::Parse(name);
    if (t.kind != TermKind::kIntercept) {
      const std::vector<double>* col = data.Column(t.input);
      if (!col)
        throw std::invalid_argument("baseline term '" + name +
                                    "': no column '" + t.input +
                                    "' in the data");
      std::vector<double> v;
      v.reserve(cv.rows.size());
      for (std::size_t r : cv.rows) v.push_back((*col)[r]);
      std::sort(v.begin(), v.end());
      const double span = SortedQuantile(v, 0.95) - SortedQuantile(v, 0.05);
      const double med = std::fabs(SortedQuantile(v, 0.5));
      if (!(span > options.min_relative_span * med) || !(span > 0)) {
        result.dropped_baseline_terms.push_back(name);
        continue;
      }
      if (t.kind == TermKind::kLinear) form_inputs.push_back(t.input);
    }
    baseline.push_back(t);
  }
  const CvEval base_eval = Evaluate(cv, BuildDesign(data, baseline, cv.rows));
  if (!base_eval.ok) {
    result.status = DiagnosisStatus::kFailed;
    result.why =
        "the baseline model could not be fitted on the cross-validation folds";
    return result;
  }
  Eigen::VectorXd beta;
  result.baseline = Summarize("linear", baseline, data, cv, base_eval, &beta);
  result.fit_rows = cv.rows;
  result.baseline_residuals.assign(
      base_eval.residuals.data(),
      base_eval.residuals.data() + base_eval.residuals.size());

  // Greedy forward selection.
  const std::vector<Expansion> expansions = BuildExpansions(
      data, cv.rows, form_inputs, options, &result.candidates, &result.skipped);
  std::vector<Term> current = baseline;
  CvEval cur_eval = base_eval;
  std::set<std::string> used;
  std::vector<Expansion> chosen;
  const double base_mae = base_eval.mae;
  for (int step = 0; step < options.max_findings; ++step) {
    std::vector<CandidateTest> tests;
    std::vector<Expansion> exps;
    std::vector<CvEval> evals;
    const Eigen::MatrixXd X_cur = BuildDesign(data, current, cv.rows);
    Eigen::VectorXd full_residuals;
    for (const Expansion& candidate : expansions) {
      if (used.count(candidate.cause)) continue;
      Expansion e = candidate;
      CvEval ev;
      if (!e.scan.empty()) {
        if (full_residuals.size() == 0) {
          full_residuals = cv.y - X_cur * FitOls(X_cur, cv.y).beta;
        }
        const Eigen::MatrixXd W = BuildDesign(data, e.scan, cv.rows);
        int chosen_window = -1;
        ev = EvaluateWindowScan(
            cv, X_cur, cur_eval, full_residuals, W, &chosen_window);
        if (chosen_window < 0) continue;
        e.terms = {e.scan[chosen_window]};
      } else {
        std::vector<Term> terms = current;
        terms.insert(terms.end(), e.terms.begin(), e.terms.end());
        ev = Evaluate(cv, BuildDesign(data, terms, cv.rows));
      }
      CandidateTest t;
      t.step = step;
      t.cause = e.cause;
      t.kind = e.kind;
      t.expansion = e.name;
      t.terms = Names(e.terms);
      if (ev.ok) {
        t.cv_mae = ev.mae;
        t.gain_pct = 100.0 * (cur_eval.mae - ev.mae) / base_mae;
        std::tie(t.t_stat, t.p_raw) = PairedStrokeTest(cv, cur_eval, ev);
      } else {
        t.cv_mae = kNaN;
      }
      tests.push_back(std::move(t));
      exps.push_back(std::move(e));
      evals.push_back(std::move(ev));
    }
    if (tests.empty()) break;
    std::vector<double> p;
    for (const auto& t : tests) p.push_back(t.p_raw);
    const std::vector<double> adj = HolmAdjust(p);
    int best = -1;
    for (std::size_t i = 0; i < tests.size(); ++i) {
      tests[i].p_holm = adj[i];
      tests[i].significant = evals[i].ok && adj[i] < options.alpha &&
                             tests[i].gain_pct >= options.min_gain_pct;
      if (tests[i].significant &&
          (best < 0 || tests[i].gain_pct > tests[best].gain_pct))
        best = static_cast<int>(i);
    }
    result.tests.insert(result.tests.end(), tests.begin(), tests.end());
    if (best < 0) break;
    const Expansion& e = exps[best];
    Finding f;
    f.cause = e.cause;
    f.kind = e.kind;
    f.expansion = e.name;
    f.terms = Names(e.terms);
    f.p_value = tests[best].p_holm;
    f.cv_mae_gain_pct = tests[best].gain_pct;
    f.cv_mae = evals[best].mae;
    f.log_likelihood_gain =
        evals[best].log_likelihood - cur_eval.log_likelihood;
    result.findings.push_back(std::move(f));
    current.insert(current.end(), e.terms.begin(), e.terms.end());
    cur_eval = std::move(evals[best]);
    used.insert(e.cause);
    chosen.push_back(e);
  }

  std::string name = "linear";
  for (const Finding& f : result.findings) name += "+" + f.cause;
  Eigen::VectorXd beta_ext;
  result.extended = Summarize(name, current, data, cv, cur_eval, &beta_ext);
  result.gain_pct = 100.0 * (base_mae - cur_eval.mae) / base_mae;
  result.log_likelihood_gain =
      cur_eval.log_likelihood - base_eval.log_likelihood;
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    result.findings[i].effect =
        DescribeEffect(chosen[i], current, beta_ext, data, cv.rows);
  }

  if (options.replay) {
    const std::vector<Term> coulomb = {Term::Intercept()};
    const CvEval coulomb_eval =
        Evaluate(cv, BuildDesign(data, coulomb, cv.rows));
    result.replay.push_back(
        Replay("coulomb", coulomb, data, cv, coulomb_eval, options));
    result.replay.push_back(
        Replay("linear", baseline, data, cv, base_eval, options));
    if (!result.findings.empty())
      result.replay.push_back(
          Replay("extended", current, data, cv, cur_eval, options));
    if (options.lugre)
      result.replay.push_back(ReplayLuGre(*options.lugre, data, cv, options));
  }
  result.status = DiagnosisStatus::kOk;
  return result;
}

}  // namespace frictiond
