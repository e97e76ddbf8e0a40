// Model diagnosis: replay of the models over the strokes
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

}  // namespace frictiond::diagnosis_internal
