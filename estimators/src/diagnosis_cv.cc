// Model diagnosis: cross-validation, paired tests and multiple testing
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

namespace {

// Running sums of held-out absolute errors and Gaussian log-likelihoods.
struct HeldOutSums {
  double sae = 0.0;
  double ll = 0.0;
};

// Scores fold k's held-out rows of X with the model (beta, sigma) fitted
// without them: residuals and per-stroke absolute errors into ev, totals
// into sums.
void ScoreHeldOutFold(const CvSetup& cv,
                      const Eigen::MatrixXd& X,
                      int k,
                      const Eigen::VectorXd& beta,
                      double sigma,
                      CvEval* ev,
                      HeldOutSums* sums) {
  const double s2 = std::max(1e-300, sigma * sigma);
  const double ll0 = -0.5 * std::log(2.0 * M_PI * s2);
  for (int i = cv.fold_begin[k]; i < cv.fold_begin[k + 1]; ++i) {
    const double r = cv.y(i) - X.row(i).dot(beta);
    ev->residuals(i) = r;
    ev->stroke_sae[cv.stroke_of_entry[i]] += std::fabs(r);
    sums->sae += std::fabs(r);
    sums->ll += ll0 - 0.5 * r * r / s2;
  }
}

// Per-sample means of the sums over n rows, and whether every residual is
// finite.
void FinishEval(int n, const HeldOutSums& sums, CvEval* ev) {
  ev->mae = sums.sae / std::max(1, n);
  ev->log_likelihood = sums.ll / std::max(1, n);
  ev->ok = ev->residuals.allFinite();
}

}  // namespace

/// Held-out performance of one model.

CvEval Evaluate(const CvSetup& cv, const Eigen::MatrixXd& X) {
  CvEval ev;
  ev.models = FitFolds(X, cv.y, cv.fold_begin);
  if (!ev.models.ok) return ev;
  const int n = static_cast<int>(X.rows());
  ev.residuals.resize(n);
  ev.stroke_sae.assign(cv.id_of_dense.size(), 0.0);
  HeldOutSums sums;
  for (int k = 0; k < cv.folds; ++k)
    ScoreHeldOutFold(
        cv, X, k, ev.models.beta[k], ev.models.sigma[k], &ev, &sums);
  FinishEval(n, sums, &ev);
  return ev;
}

WindowScan MakeWindowScan(const std::vector<Term>& windows,
                          const std::vector<double>& column,
                          const std::vector<std::size_t>& rows) {
  WindowScan scan;
  for (const Term& t : windows)
    scan.edges.push_back(t.a), scan.edges.push_back(t.b);
  std::sort(scan.edges.begin(), scan.edges.end());
  scan.edges.erase(std::unique(scan.edges.begin(), scan.edges.end()),
                   scan.edges.end());
  auto index = [&](double e) {
    return static_cast<int>(
        std::lower_bound(scan.edges.begin(), scan.edges.end(), e) -
        scan.edges.begin());
  };
  for (const Term& t : windows)
    scan.windows.push_back({index(t.a), index(t.b)});
  scan.level.resize(rows.size());
  for (std::size_t e = 0; e < rows.size(); ++e) {
    const double x = column[rows[e]];
    // Level l: edges[l] <= x < edges[l + 1]; -1 outside all windows.
    const auto it = std::upper_bound(scan.edges.begin(), scan.edges.end(), x);
    const int l = static_cast<int>(it - scan.edges.begin()) - 1;
    scan.level[e] =
        (l < 0 || l + 1 >= static_cast<int>(scan.edges.size())) ? -1 : l;
  }
  return scan;
}

int PickWindow(const WindowScan& scan,
               const Eigen::VectorXd& r,
               const std::vector<char>& use) {
  const int L = static_cast<int>(scan.edges.size());
  std::vector<double> sum(L + 1, 0.0), cnt(L + 1, 0.0);
  int n_use = 0;
  for (std::size_t e = 0; e < scan.level.size(); ++e) {
    if (!use[e]) continue;
    ++n_use;
    const int l = scan.level[e];
    if (l < 0) continue;
    sum[l + 1] += r(static_cast<Eigen::Index>(e));
    cnt[l + 1] += 1.0;
  }
  for (int l = 1; l <= L; ++l) sum[l] += sum[l - 1], cnt[l] += cnt[l - 1];
  int best = -1;
  double best_score = 0.0;
  for (std::size_t w = 0; w < scan.windows.size(); ++w) {
    const auto [i, j] = scan.windows[w];
    const double inside = cnt[j] - cnt[i], s = sum[j] - sum[i];
    if (inside < 0.01 * n_use || inside > 0.99 * n_use) continue;
    // Reduction of the residual sum of squares by a mean shift inside the
    // window (against a mean shift outside it, which the intercept absorbs).
    const double outside = n_use - inside;
    const double score = s * s * n_use / (inside * outside);
    if (score > best_score) best_score = score, best = static_cast<int>(w);
  }
  return best;
}

CvEval EvaluateWindowScan(const CvSetup& cv,
                          const Eigen::MatrixXd& X_cur,
                          const CvEval& cur,
                          const Eigen::VectorXd& full_residuals,
                          const WindowScan& scan,
                          int* chosen_all) {
  CvEval ev;
  const int n = static_cast<int>(X_cur.rows());
  const int p = static_cast<int>(X_cur.cols());
  std::vector<char> all(n, 1);
  *chosen_all = PickWindow(scan, full_residuals, all);
  if (*chosen_all < 0 || !cur.models.ok) return ev;
  ev.residuals.resize(n);
  ev.stroke_sae.assign(cv.id_of_dense.size(), 0.0);
  ev.models.ok = true;
  ev.models.beta.resize(cv.folds);
  ev.models.sigma.resize(cv.folds);
  Eigen::MatrixXd X(n, p + 1);
  X.leftCols(p) = X_cur;
  HeldOutSums sums;
  std::vector<char> train(n, 1);
  Eigen::VectorXd r(n);
  for (int k = 0; k < cv.folds; ++k) {
    r.noalias() = cv.y - X_cur * cur.models.beta[k];
    std::fill(train.begin(), train.end(), 1);
    for (int i = cv.fold_begin[k]; i < cv.fold_begin[k + 1]; ++i) train[i] = 0;
    const int w = PickWindow(scan, r, train);
    if (w >= 0) {
      const auto [lo, hi] = scan.windows[w];
      for (int i = 0; i < n; ++i)
        X(i, p) = scan.level[i] >= lo && scan.level[i] < hi ? 1.0 : 0.0;
    } else {
      X.col(p).setZero();
    }
    const FoldModels m = FitFolds(X, cv.y, cv.fold_begin);
    if (!m.ok) return CvEval();
    ev.models.beta[k] = m.beta[k];
    ev.models.sigma[k] = m.sigma[k];
    ScoreHeldOutFold(cv, X, k, m.beta[k], m.sigma[k], &ev, &sums);
  }
  FinishEval(n, sums, &ev);
  return ev;
}

std::pair<double, double> OneSidedT(const std::vector<double>& d) {
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

std::pair<double, double> PairedStrokeTest(const CvSetup& cv,
                                           const CvEval& cur,
                                           const CvEval& cand) {
  std::vector<double> d;
  d.reserve(cv.id_of_dense.size());
  for (std::size_t s = 0; s < cv.id_of_dense.size(); ++s) {
    if (cv.fit_count[s] == 0) continue;
    d.push_back((cur.stroke_sae[s] - cand.stroke_sae[s]) / cv.mean_per_stroke);
  }
  return OneSidedT(d);
}

CvSetup BuildCv(const StrokeData& data,
                const std::vector<bool>& use,
                int folds,
                bool shuffle,
                std::uint64_t seed) {
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
    if (use[i]) ++cv.fit_count[cv.dense_of_id[data.stroke[i]]], ++fit_total;
  }
  std::vector<int> fit_strokes;  // in order of appearance (recording order)
  for (std::size_t s = 0; s < S; ++s) {
    if (cv.fit_count[s] > 0) fit_strokes.push_back(static_cast<int>(s));
  }
  cv.strokes_with_fit = static_cast<int>(fit_strokes.size());
  cv.folds = std::max(1, std::min(folds, cv.strokes_with_fit));
  cv.fold_of_dense.assign(S, 0);
  for (std::size_t s = 0; s < S; ++s)  // strokes without fit rows (replay)
    cv.fold_of_dense[s] = static_cast<int>(s % cv.folds);
  const std::size_t F = fit_strokes.size();
  if (shuffle) {
    std::mt19937_64 rng(seed);
    for (std::size_t i = F; i > 1; --i)
      std::swap(fit_strokes[i - 1], fit_strokes[rng() % i]);
    for (std::size_t r = 0; r < F; ++r)
      cv.fold_of_dense[fit_strokes[r]] = static_cast<int>(r % cv.folds);
  } else {
    // Contiguous blocks of strokes in time: drifting offsets and neighbouring
    // episodes of one contact stay on one side of the split.
    for (std::size_t r = 0; r < F; ++r)
      cv.fold_of_dense[fit_strokes[r]] =
          static_cast<int>(r * static_cast<std::size_t>(cv.folds) / F);
  }
  std::vector<std::vector<std::size_t>> by_fold(cv.folds);
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (use[i])
      by_fold[cv.fold_of_dense[cv.dense_of_id[data.stroke[i]]]].push_back(i);
  }
  cv.fold_begin.push_back(0);
  for (const auto& f : by_fold) {
    cv.rows.insert(cv.rows.end(), f.begin(), f.end());
    cv.fold_begin.push_back(static_cast<int>(cv.rows.size()));
  }
  cv.y.resize(static_cast<Eigen::Index>(cv.rows.size()));
  cv.stroke_of_entry.resize(cv.rows.size());
  for (std::size_t e = 0; e < cv.rows.size(); ++e) {
    cv.y(static_cast<Eigen::Index>(e)) = data.mu(cv.rows[e]);
    cv.stroke_of_entry[e] = cv.dense_of_id[data.stroke[cv.rows[e]]];
  }
  cv.mean_per_stroke =
      static_cast<double>(fit_total) / std::max(1, cv.strokes_with_fit);
  return cv;
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

}  // namespace frictiond::diagnosis_internal
