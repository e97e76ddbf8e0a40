// Model diagnosis: the search (greedy forward selection inside inner folds),
// its honest evaluation on outer folds the selection never saw, spread
// findings and alternatives (issue 18).
#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <thread>

#include <Eigen/Dense>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/stats.h"

#include "diagnosis_internal.h"

namespace frictiond {

namespace diagnosis_internal {
namespace {

/// One greedy step of a recorded selection (for alternatives).
struct StepRecord {
  std::vector<Expansion> exps;
  std::vector<CvEval> evals;
  std::vector<CandidateTest> tests;
  int best = -1;
};

/// Outcome of one run of the selection on one CV setup.
struct Selection {
  std::vector<Term> terms;           // baseline + chosen terms
  std::vector<Expansion> chosen;     // with the chosen terms filled in
  std::vector<double> chosen_gain;   // inner gain of each step [%]
  std::vector<CandidateTest> tests;  // every test of every step
  std::vector<StepRecord> steps;     // when recorded
  std::vector<std::string> candidates, skipped;
  CvEval base_eval, final_eval;
  bool ok = false;
};

bool IsNumericColumn(const StrokeData& data, const std::string& name) {
  return data.Column(name) != nullptr;
}

/// Greedy forward selection on `cv` (every choice made on cv's rows only):
/// Holm over all candidates x expansions of a step, the significant
/// expansion with the largest held-out gain joins, repeat.
Selection Select(const StrokeData& data,
                 const CvSetup& cv,
                 const std::vector<Term>& baseline,
                 const std::vector<std::string>& form_inputs,
                 const DiagnosisOptions& options,
                 bool record) {
  Selection out;
  out.base_eval = Evaluate(cv, BuildDesign(data, baseline, cv.rows));
  if (!out.base_eval.ok) return out;
  const std::vector<Expansion> expansions = BuildExpansions(
      data, cv.rows, form_inputs, options, &out.candidates, &out.skipped);
  std::vector<Term> current = baseline;
  CvEval cur_eval = out.base_eval;
  std::set<std::string> used;
  const double base_mae = out.base_eval.mae;
  for (int step = 0; step < options.max_findings; ++step) {
    std::vector<CandidateTest> tests;
    std::vector<Expansion> exps;
    std::vector<CvEval> evals;
    const Eigen::MatrixXd X_cur = BuildDesign(data, current, cv.rows);
    Eigen::VectorXd full_residuals;
    auto try_expansion = [&](const Expansion& candidate) {
      Expansion e = candidate;
      CvEval ev;
      if (!e.scan.empty()) {
        if (full_residuals.size() == 0)
          full_residuals = cv.y - X_cur * FitOls(X_cur, cv.y).beta;
        const WindowScan scan =
            MakeWindowScan(e.scan, *data.Column(e.cause), cv.rows);
        int chosen_window = -1;
        ev = EvaluateWindowScan(
            cv, X_cur, cur_eval, full_residuals, scan, &chosen_window);
        if (chosen_window < 0) return;
        e.terms = {e.scan[chosen_window]};
      } else {
        Eigen::MatrixXd X(X_cur.rows(), X_cur.cols() + e.terms.size());
        X.leftCols(X_cur.cols()) = X_cur;
        X.rightCols(e.terms.size()) = BuildDesign(data, e.terms, cv.rows);
        ev = Evaluate(cv, X);
      }
      // Reference: the current model, plus the main effects an interaction
      // brings along.
      const CvEval* ref = &cur_eval;
      CvEval ev_main;
      if (e.kind == "interaction" && e.terms.size() > 1) {
        const std::vector<Term> mains(e.terms.begin() + 1, e.terms.end());
        Eigen::MatrixXd X(X_cur.rows(), X_cur.cols() + mains.size());
        X.leftCols(X_cur.cols()) = X_cur;
        X.rightCols(mains.size()) = BuildDesign(data, mains, cv.rows);
        ev_main = Evaluate(cv, X);
        if (ev_main.ok) ref = &ev_main;
      }
      CandidateTest t;
      t.step = step;
      t.cause = e.cause;
      t.kind = e.kind;
      t.expansion = e.name;
      t.terms = Names(e.terms);
      if (ev.ok) {
        t.cv_mae = ev.mae;
        t.gain_pct = GainPct(ref->mae, ev.mae, base_mae);
        std::tie(t.t_stat, t.p_raw) = PairedStrokeTest(cv, *ref, ev);
      } else {
        t.cv_mae = kNaN;
      }
      tests.push_back(std::move(t));
      exps.push_back(std::move(e));
      evals.push_back(std::move(ev));
    };
    for (const Expansion& candidate : expansions) {
      if (!used.count(candidate.cause)) try_expansion(candidate);
    }
    if (options.interaction_candidates > 0) {
      // Pairwise interactions, by a rule that knows no effect: the model's
      // inputs with each other and with every numeric candidate column, and
      // the first interaction_candidates causes the selection chose with
      // each other. An interaction's gain is measured against the current
      // model plus its main effects, so that it wins only by the product.
      std::vector<std::pair<std::string, std::string>> pairs;
      auto add_pair = [&](const std::string& a, const std::string& b) {
        if (a == b) return;
        pairs.push_back({std::min(a, b), std::max(a, b)});
      };
      for (std::size_t a = 0; a < form_inputs.size(); ++a) {
        for (std::size_t b = a + 1; b < form_inputs.size(); ++b)
          add_pair(form_inputs[a], form_inputs[b]);
        for (const std::string& c : out.candidates) {
          if (std::find(form_inputs.begin(), form_inputs.end(), c) ==
              form_inputs.end())
            add_pair(form_inputs[a], c);
        }
      }
      std::vector<std::string> strongest;
      for (const Expansion& e : out.chosen) {
        if (static_cast<int>(strongest.size()) <
                options.interaction_candidates &&
            e.kind != "interaction" && IsNumericColumn(data, e.cause))
          strongest.push_back(e.cause);
      }
      for (std::size_t a = 0; a < strongest.size(); ++a) {
        for (std::size_t b = a + 1; b < strongest.size(); ++b)
          add_pair(strongest[a], strongest[b]);
      }
      std::sort(pairs.begin(), pairs.end());
      pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
      for (const auto& [x, y] : pairs) {
        if (used.count(x + "*" + y) || !data.Column(x + "*" + y)) continue;
        try_expansion(InteractionExpansion(x, y, current));
      }
    }
    if (tests.empty()) break;
    std::vector<double> p;
    for (const auto& t : tests) p.push_back(t.p_raw);
    const std::vector<double> adj = HolmAdjust(p);
    int best = -1;
    for (std::size_t i = 0; i < tests.size(); ++i) {
      tests[i].p_holm = adj[i];
      // Inside the selection a candidate needs raw p < selection_alpha
      // (uncorrected: false alarms are controlled by the outer test of
      // what the selection proposes, so here power matters more).
      tests[i].significant = evals[i].ok &&
                             tests[i].p_raw < options.selection_alpha &&
                             tests[i].gain_pct >= options.min_gain_pct;
      if (tests[i].significant &&
          (best < 0 || tests[i].gain_pct > tests[best].gain_pct))
        best = static_cast<int>(i);
    }
    out.tests.insert(out.tests.end(), tests.begin(), tests.end());
    if (best >= 0) {
      const Expansion& e = exps[best];
      out.chosen.push_back(e);
      out.chosen_gain.push_back(100.0 * (cur_eval.mae - evals[best].mae) /
                                base_mae);
      current.insert(current.end(), e.terms.begin(), e.terms.end());
      used.insert(e.cause);
    }
    CvEval next = best >= 0 ? evals[best] : CvEval();
    if (record) {
      StepRecord rec;
      rec.exps = std::move(exps);
      rec.evals = std::move(evals);
      rec.tests = std::move(tests);
      rec.best = best;
      out.steps.push_back(std::move(rec));
    }
    if (best < 0) break;
    cur_eval = std::move(next);
  }
  out.terms = std::move(current);
  out.final_eval = std::move(cur_eval);
  out.ok = true;
  return out;
}

double Correlation(const StrokeData& data,
                   const std::string& a,
                   const std::string& b,
                   const std::vector<std::size_t>& rows) {
  const std::vector<double>* x = data.Column(a);
  const std::vector<double>* y = data.Column(b);
  if (!x || !y || rows.size() < 3) return kNaN;
  double mx = 0, my = 0;
  for (std::size_t r : rows) mx += (*x)[r], my += (*y)[r];
  mx /= rows.size(), my /= rows.size();
  double sxy = 0, sxx = 0, syy = 0;
  for (std::size_t r : rows) {
    const double dx = (*x)[r] - mx, dy = (*y)[r] - my;
    sxy += dx * dy, sxx += dx * dx, syy += dy * dy;
  }
  return sxx > 0 && syy > 0 ? sxy / std::sqrt(sxx * syy) : kNaN;
}

/// Two-sided paired t-test over strokes of equal held-out error.
double TwoSidedStrokeP(const CvSetup& cv, const CvEval& a, const CvEval& b) {
  const auto [t, p_one] = PairedStrokeTest(cv, a, b);
  (void)t;
  return std::min(1.0, 2.0 * std::min(p_one, 1.0 - p_one));
}

/// Candidates of a recorded step whose gain the data cannot tell apart from
/// the winner's: best expansion per other cause, itself a raw-significant
/// gain >= min_gain_pct, within the winner's 95 % confidence interval of
/// the gain. (The two-sided paired test of equal errors is reported as
/// p_value; it is more sensitive than the interval because both models
/// share the strokes' noise.)
std::vector<Alternative> FindAlternatives(const StrokeData& data,
                                          const CvSetup& cv,
                                          const StepRecord& step,
                                          const DiagnosisOptions& options) {
  std::vector<Alternative> out;
  if (step.best < 0) return out;
  const std::string& winner = step.exps[step.best].cause;
  std::map<std::string, int> best_of;
  for (std::size_t i = 0; i < step.tests.size(); ++i) {
    const CandidateTest& t = step.tests[i];
    if (t.cause == winner || !step.evals[i].ok) continue;
    auto it = best_of.find(t.cause);
    if (it == best_of.end() || t.gain_pct > step.tests[it->second].gain_pct)
      best_of[t.cause] = static_cast<int>(i);
  }
  for (const auto& [cause, i] : best_of) {
    const CandidateTest& t = step.tests[i];
    if (!(t.p_raw < options.alpha) || t.gain_pct < options.min_gain_pct)
      continue;
    // Indistinguishable: its gain lies within the winner's 95 % confidence
    // interval (half-width ~2 standard errors, SE = gain / t).
    const CandidateTest& w = step.tests[step.best];
    const double half_width = w.t_stat > 0 && std::isfinite(w.t_stat)
                                  ? 2.0 * w.gain_pct / w.t_stat
                                  : 0.0;
    if (!(w.gain_pct - t.gain_pct <= half_width)) continue;
    const double p = TwoSidedStrokeP(cv, step.evals[step.best], step.evals[i]);
    Alternative a;
    a.cause = cause;
    a.kind = t.kind;
    a.expansion = t.expansion;
    a.cv_mae_gain_pct = t.gain_pct;
    a.p_value = p;
    a.correlation = Correlation(data, winner, cause, cv.rows);
    out.push_back(std::move(a));
  }
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) {
    return x.cv_mae_gain_pct > y.cv_mae_gain_pct;
  });
  return out;
}

/// Outer (held-out) evaluation of the findings chain: in outer fold o, model
/// i is the baseline plus the terms fold o's own inner selection chose for
/// causes[0..i] (nothing for a cause it did not choose); fitted on the outer
/// training strokes, scored on fold o.
struct OuterChain {
  std::vector<std::vector<double>> stroke_sae;     // [model i][dense stroke]
  std::vector<double> sae, ll;                     // totals per model
  std::vector<int> folds_selected;                 // per cause
  std::vector<Eigen::VectorXd> residuals;          // per model, per outer entry
  std::vector<std::vector<Eigen::VectorXd>> beta;  // [fold] final model
  std::vector<std::vector<Term>> terms;            // [fold] final model
  bool ok = true;
};

OuterChain EvaluateChain(const StrokeData& data,
                         const CvSetup& outer,
                         const std::vector<Term>& baseline,
                         const std::vector<std::string>& causes,
                         const std::vector<std::vector<std::string>>& stand_ins,
                         const std::vector<Selection>& fold_sel) {
  OuterChain c;
  const std::size_t m = causes.size();
  const std::size_t S = outer.id_of_dense.size();
  c.stroke_sae.assign(m + 1, std::vector<double>(S, 0.0));
  c.sae.assign(m + 1, 0.0);
  c.ll.assign(m + 1, 0.0);
  c.folds_selected.assign(m, 0);
  c.residuals.assign(m + 1, Eigen::VectorXd::Zero(outer.y.size()));
  c.terms.resize(outer.folds);
  for (int o = 0; o < outer.folds; ++o) {
    const Selection& sel = fold_sel[o];
    std::vector<Term> terms = baseline;
    std::set<std::string> used_stand_in;
    for (std::size_t i = 0; i <= m; ++i) {
      if (i > 0) {
        bool found = false;
        for (const Expansion& e : sel.chosen) {
          if (e.cause != causes[i - 1]) continue;
          terms.insert(terms.end(), e.terms.begin(), e.terms.end());
          ++c.folds_selected[i - 1];
          found = true;
        }
        // A fold that chose, instead, a candidate the data cannot tell
        // apart from this finding (its alternatives; not itself in the
        // chain, not used by this fold for an earlier finding) contributes
        // that choice: the fold's selection made the same step.
        for (std::size_t j = 0; !found && j < sel.chosen.size(); ++j) {
          const Expansion& e = sel.chosen[j];
          const auto& alt = stand_ins[i - 1];
          if (std::find(alt.begin(), alt.end(), e.cause) == alt.end() ||
              std::find(causes.begin(), causes.end(), e.cause) !=
                  causes.end() ||
              used_stand_in.count(e.cause))
            continue;
          terms.insert(terms.end(), e.terms.begin(), e.terms.end());
          used_stand_in.insert(e.cause);
          found = true;
        }
      }
      const Eigen::MatrixXd X = BuildDesign(data, terms, outer.rows);
      const FoldModels fm = FitFolds(X, outer.y, outer.fold_begin);
      if (!fm.ok) {
        c.ok = false;
        return c;
      }
      const double s2 = std::max(1e-300, fm.sigma[o] * fm.sigma[o]);
      const double ll0 = -0.5 * std::log(2.0 * M_PI * s2);
      for (int e = outer.fold_begin[o]; e < outer.fold_begin[o + 1]; ++e) {
        const double r = outer.y(e) - X.row(e).dot(fm.beta[o]);
        c.residuals[i](e) = r;
        c.stroke_sae[i][outer.stroke_of_entry[e]] += std::fabs(r);
        c.sae[i] += std::fabs(r);
        c.ll[i] += ll0 - 0.5 * r * r / s2;
      }
      if (i == m) {
        c.terms[o] = terms;
        c.beta.push_back({fm.beta[o]});
      }
    }
  }
  return c;
}

/// Per-stroke test of a chain step: d_s = (sae before - sae after) / mean
/// samples per stroke over the outer strokes.
std::pair<double, double> ChainTest(const CvSetup& outer,
                                    const std::vector<double>& before,
                                    const std::vector<double>& after) {
  std::vector<double> d;
  for (std::size_t s = 0; s < outer.id_of_dense.size(); ++s) {
    if (outer.fit_count[s] == 0) continue;
    d.push_back((before[s] - after[s]) / outer.mean_per_stroke);
  }
  return OneSidedT(d);
}

DiagnosedModel SummarizeModel(const std::string& name,
                              const std::vector<Term>& terms,
                              const StrokeData& data,
                              const CvSetup& cv,
                              double cv_mae,
                              double cv_ll,
                              Eigen::VectorXd* beta_out) {
  DiagnosedModel m;
  m.model = name;
  m.terms = Names(terms);
  m.cv_mae = cv_mae;
  m.cv_log_likelihood = cv_ll;
  const OlsResult ols = FitOls(BuildDesign(data, terms, cv.rows), cv.y);
  m.beta.assign(ols.beta.data(), ols.beta.data() + ols.beta.size());
  m.sigma_eps = ols.sigma_eps;
  if (beta_out) *beta_out = ols.beta;
  return m;
}

// ---------------------------------------------------------------------------
// Spread: does the scale of eps depend on an input or column?

/// log-linear scale fit (eps_scale.h); ok false when not identifiable.
struct ScaleFit {
  EpsScaleModel m;
  bool ok = false;
  double Sigma(double z) const { return m.Sigma(z); }
};

ScaleFit FitScale(const std::vector<double>& r, const std::vector<double>& z) {
  ScaleFit f;
  f.ok = FitEpsScaleModel(r, z, "", &f.m);
  return f;
}

double GaussLogPdf(double r, double sigma) {
  return -std::log(sigma) - 0.5 * std::log(2.0 * M_PI) -
         0.5 * r * r / (sigma * sigma);
}

void RemoveStrokeMeans(const CvSetup& cv, Eigen::VectorXd* r) {
  std::vector<double> sum(cv.id_of_dense.size(), 0.0);
  for (Eigen::Index e = 0; e < r->size(); ++e)
    sum[cv.stroke_of_entry[e]] += (*r)(e);
  for (Eigen::Index e = 0; e < r->size(); ++e) {
    const int s = cv.stroke_of_entry[e];
    (*r)(e) -= sum[s] / std::max(1, cv.fit_count[s]);
  }
}

struct SpreadCandidateEval {
  std::string cause;
  std::vector<double> stroke_ll_gain;  // per dense stroke (sum over samples)
  double ll_gain = 0.0;                // mean per sample
  double t = 0.0, p = 1.0, p_holm = 1.0;
};

/// Held-out log-likelihood gain of a scale model in each candidate column
/// over the constant scale, on the outer folds: scale fitted on the outer
/// training residuals of fold o's model, scored on fold o's residuals.
///
/// The scale is that of the first differences of the residuals between
/// consecutive fit samples of one stroke, (r_t - r_{t-1}) / sqrt(2), at
/// z = (z_t + z_{t-1}) / 2: a per-stroke offset cancels in a difference, and
/// so does a slow wander of eps (strongly autocorrelated noise) or a slow
/// unmodelled mean effect. (The earlier test used each stroke's residuals
/// minus their mean; with AR(1) noise of rho 0.995 those are largest at a
/// stroke's ends and in long strokes, a real but spurious dependence of the
/// within-stroke spread on anything that varies along or between strokes:
/// 5 of 50 null seeds reported it as a spread in v_mm_s, fn_rate_n_s or
/// dwell_s.) A scale effect on white noise keeps its shape in the
/// differences (variance s(z_t)^2 + s(z_{t-1})^2), and autocorrelated base
/// noise shrinks in them, so the test loses little power.
std::vector<SpreadCandidateEval> EvaluateSpread(
    const StrokeData& data,
    const CvSetup& outer,
    const OuterChain& chain,
    const std::vector<std::string>& names) {
  std::vector<SpreadCandidateEval> out;
  const std::size_t S = outer.id_of_dense.size();
  const Eigen::Index n = outer.y.size();
  // Consecutive pairs (e - 1, e) of fit samples of one stroke.
  std::vector<Eigen::Index> pair_end;
  for (Eigen::Index e = 1; e < n; ++e) {
    if (outer.stroke_of_entry[e] == outer.stroke_of_entry[e - 1] &&
        outer.rows[e] == outer.rows[e - 1] + 1)
      pair_end.push_back(e);
  }
  const Eigen::Index P = static_cast<Eigen::Index>(pair_end.size());
  // Differenced residuals of each fold's final model on all outer pairs
  // (held out on fold o, training residuals elsewhere).
  std::vector<Eigen::VectorXd> res(outer.folds);
  for (int o = 0; o < outer.folds; ++o) {
    const Eigen::MatrixXd X = BuildDesign(data, chain.terms[o], outer.rows);
    const Eigen::VectorXd r = outer.y - X * chain.beta[o][0];
    res[o].resize(P);
    for (Eigen::Index k = 0; k < P; ++k)
      res[o](k) = (r(pair_end[k]) - r(pair_end[k] - 1)) / std::sqrt(2.0);
  }
  for (const std::string& name : names) {
    const std::vector<double>* col = data.Column(name);
    if (!col) continue;
    SpreadCandidateEval ev;
    ev.cause = name;
    ev.stroke_ll_gain.assign(S, 0.0);
    bool ok = true;
    double total = 0.0;
    std::vector<double> zp(P);
    for (Eigen::Index k = 0; k < P; ++k) {
      const Eigen::Index e = pair_end[k];
      zp[k] = 0.5 * ((*col)[outer.rows[e]] + (*col)[outer.rows[e - 1]]);
    }
    for (int o = 0; o < outer.folds && ok; ++o) {
      auto held_out = [&](Eigen::Index k) {
        return pair_end[k] >= outer.fold_begin[o] &&
               pair_end[k] < outer.fold_begin[o + 1];
      };
      std::vector<double> r, z;
      r.reserve(P), z.reserve(P);
      for (Eigen::Index k = 0; k < P; ++k) {
        if (held_out(k)) continue;
        r.push_back(res[o](k));
        z.push_back(zp[k]);
      }
      const ScaleFit f = FitScale(r, z);
      if (!f.ok) {
        ok = false;
        break;
      }
      for (Eigen::Index k = 0; k < P; ++k) {
        if (!held_out(k)) continue;
        const double re = res[o](k);
        const double g =
            GaussLogPdf(re, f.Sigma(zp[k])) - GaussLogPdf(re, f.m.sigma_ref);
        ev.stroke_ll_gain[outer.stroke_of_entry[pair_end[k]]] += g;
        total += g;
      }
    }
    if (!ok) continue;
    ev.ll_gain = total / std::max<Eigen::Index>(1, P);
    std::vector<double> d;
    for (std::size_t s = 0; s < S; ++s) {
      if (outer.fit_count[s] > 0)
        d.push_back(ev.stroke_ll_gain[s] / outer.mean_per_stroke);
    }
    std::tie(ev.t, ev.p) = OneSidedT(d);
    out.push_back(std::move(ev));
  }
  std::vector<double> p;
  for (const auto& e : out) p.push_back(e.p);
  const std::vector<double> adj = HolmAdjust(p);
  for (std::size_t i = 0; i < out.size(); ++i) out[i].p_holm = adj[i];
  return out;
}

}  // namespace

DiagnosisResult RunDiagnosis(const StrokeData& data,
                             const DiagnosisOptions& options,
                             const std::vector<bool>& mask,
                             DiagnosisResult result) {
  // Outer folds: the reported figures.
  const CvSetup outer =
      BuildCv(data, mask, options.folds, options.shuffle_folds, options.seed);
  result.folds = outer.folds;
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
      v.reserve(outer.rows.size());
      for (std::size_t r : outer.rows) v.push_back((*col)[r]);
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
  const CvEval base_eval =
      Evaluate(outer, BuildDesign(data, baseline, outer.rows));
  if (!base_eval.ok) {
    result.status = DiagnosisStatus::kFailed;
    result.why =
        "the baseline model could not be fitted on the cross-validation folds";
    return result;
  }
  result.fit_rows = outer.rows;
  result.baseline_residuals.assign(
      base_eval.residuals.data(),
      base_eval.residuals.data() + base_eval.residuals.size());

  // The reported model: the selection on all strokes (inner folds).
  const CvSetup inner_all = BuildCv(
      data, mask, options.inner_folds, options.shuffle_folds, options.seed + 1);
  result.inner_folds = inner_all.folds;
  Selection sel =
      Select(data, inner_all, baseline, form_inputs, options, /*record=*/true);
  if (!sel.ok) {
    result.status = DiagnosisStatus::kFailed;
    result.why = "the baseline model could not be fitted on the inner folds";
    return result;
  }
  result.candidates = sel.candidates;
  result.skipped = sel.skipped;
  result.tests = sel.tests;

  // The same selection on each outer training part (in parallel).
  std::vector<Selection> fold_sel(outer.folds);
  if (!sel.chosen.empty()) {
    std::vector<std::exception_ptr> errors(outer.folds);
    auto run_fold = [&](int o) {
      try {
        std::vector<bool> use = mask;
        for (std::size_t i = 0; i < data.size(); ++i) {
          if (use[i] &&
              outer.fold_of_dense[outer.dense_of_id.at(data.stroke[i])] == o)
            use[i] = false;
        }
        const CvSetup inner = BuildCv(data,
                                      use,
                                      options.inner_folds,
                                      options.shuffle_folds,
                                      options.seed + 2 + o);
        fold_sel[o] = Select(data,
                             inner,
                             baseline,
                             form_inputs,
                             options,
                             /*record=*/false);
      } catch (...) {
        errors[o] = std::current_exception();
      }
    };
    const int threads = std::max(
        1,
        std::min<int>(outer.folds,
                      static_cast<int>(std::thread::hardware_concurrency())));
    for (int o0 = 0; o0 < outer.folds; o0 += threads) {
      std::vector<std::thread> pool;
      for (int o = o0 + 1; o < std::min(outer.folds, o0 + threads); ++o)
        pool.emplace_back(run_fold, o);
      run_fold(o0);
      for (std::thread& t : pool) t.join();
    }
    for (const auto& e : errors) {
      if (e) std::rethrow_exception(e);
    }
  }

  // Outer test of the findings as a fixed sequence: in selection order,
  // each at level alpha, stopping at the first one that fails (its p-value
  // or its gain); the adjusted p-value of finding k is the largest raw
  // p-value of findings 1..k. (Holm over every proposal, used before,
  // let a weak late proposal double the threshold of a strong first one:
  // see docs/diagnosis.md, "Outer test".) The chain is refitted on the
  // survivors; model i depends only on findings 1..i, so one more pass
  // settles it.
  std::vector<int> kept;
  for (std::size_t i = 0; i < sel.chosen.size(); ++i)
    kept.push_back(static_cast<int>(i));
  // Each proposal's alternatives (candidates of its step the data cannot
  // tell apart from it): an outer fold whose selection chose one of them
  // instead is scored with that choice (see EvaluateChain).
  std::vector<std::vector<Alternative>> alternatives(sel.chosen.size());
  for (std::size_t i = 0; i < sel.chosen.size() && i < sel.steps.size(); ++i)
    alternatives[i] = FindAlternatives(data, inner_all, sel.steps[i], options);
  const std::size_t m_tested = sel.chosen.size();
  OuterChain chain;
  std::vector<double> p_holm;
  // Each pass that does not settle drops at least one finding, so at most
  // m_tested + 1 passes; the last one evaluates the final list.
  for (std::size_t pass = 0; pass <= m_tested + 1; ++pass) {
    std::vector<std::string> causes;
    std::vector<std::vector<std::string>> stand_ins;
    for (int i : kept) {
      causes.push_back(sel.chosen[i].cause);
      stand_ins.emplace_back();
      if (options.outer_alternatives) {
        for (const Alternative& a : alternatives[i])
          stand_ins.back().push_back(a.cause);
      }
    }
    chain = EvaluateChain(data, outer, baseline, causes, stand_ins, fold_sel);
    if (!chain.ok) {
      result.status = DiagnosisStatus::kFailed;
      result.why = "an outer-fold model could not be fitted";
      return result;
    }
    std::vector<int> next;
    p_holm.clear();
    double p_seq = 0.0;
    for (std::size_t k = 0; k < kept.size(); ++k) {
      const double p =
          ChainTest(outer, chain.stroke_sae[k], chain.stroke_sae[k + 1]).second;
      p_seq = std::max(p_seq, p);
      const double gain = GainPct(chain.sae[k], chain.sae[k + 1], chain.sae[0]);
      if (!(p_seq < options.alpha) || gain < options.min_gain_pct) break;
      next.push_back(kept[k]);
      p_holm.push_back(p_seq);
    }
    if (next == kept) break;
    kept = next;
  }
  const double n_outer = static_cast<double>(outer.y.size());
  const double base_mae = chain.sae[0] / n_outer;
  std::vector<Term> current = baseline;
  std::vector<Expansion> chosen;
  for (std::size_t k = 0; k < kept.size(); ++k) {
    const Expansion& e = sel.chosen[kept[k]];
    Finding f;
    f.cause = e.cause;
    f.kind = e.kind;
    f.expansion = e.name;
    f.terms = Names(e.terms);
    f.p_value = p_holm[k];
    f.cv_mae_gain_pct = GainPct(chain.sae[k], chain.sae[k + 1], chain.sae[0]);
    f.cv_mae = chain.sae[k + 1] / n_outer;
    f.log_likelihood_gain = (chain.ll[k + 1] - chain.ll[k]) / n_outer;
    f.selection_bias_pct = sel.chosen_gain[kept[k]] - f.cv_mae_gain_pct;
    f.folds_selected = chain.folds_selected[k];
    f.alternatives = alternatives[kept[k]];
    result.findings.push_back(std::move(f));
    current.insert(current.end(), e.terms.begin(), e.terms.end());
    chosen.push_back(e);
  }
  const double ext_mae = chain.sae.back() / n_outer;
  result.baseline = SummarizeModel("linear",
                                   baseline,
                                   data,
                                   outer,
                                   base_mae,
                                   chain.ll[0] / n_outer,
                                   nullptr);
  std::string name = "linear";
  for (const Finding& f : result.findings) name += "+" + f.cause;
  Eigen::VectorXd beta_ext;
  result.extended = SummarizeModel(name,
                                   current,
                                   data,
                                   outer,
                                   ext_mae,
                                   chain.ll.back() / n_outer,
                                   &beta_ext);
  result.gain_pct = GainPct(base_mae, ext_mae, base_mae);
  result.log_likelihood_gain = (chain.ll.back() - chain.ll[0]) / n_outer;
  // What the selection saw for the kept findings (the old, optimistic
  // figure) minus the outer gain.
  double inner_gain = 0.0;
  for (int i : kept) inner_gain += sel.chosen_gain[i];
  result.selection_bias_pct = inner_gain - result.gain_pct;
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    Finding& f = result.findings[i];
    f.effect = DescribeEffect(chosen[i], current, beta_ext, data, outer.rows);
    for (const Alternative& a : f.alternatives) {
      f.effect += "; the data cannot tell this apart from " + a.cause +
                  " (gain " + Num(a.cv_mae_gain_pct, 3) + " %, correlation " +
                  Num(a.correlation, 2) + ")";
    }
  }

  // Spread of eps: scale models in each input and numeric column.
  if (options.spread) {
    std::vector<std::string> names = form_inputs;
    for (const std::string& c : result.candidates) {
      if (c.find('*') == std::string::npos &&
          std::find(names.begin(), names.end(), c) == names.end() &&
          std::find(options.exclude_candidates.begin(),
                    options.exclude_candidates.end(),
                    c) == options.exclude_candidates.end())
        names.push_back(c);
    }
    std::vector<SpreadCandidateEval> spread =
        EvaluateSpread(data, outer, chain, names);
    int best = -1;
    for (std::size_t i = 0; i < spread.size(); ++i) {
      if (spread[i].p_holm < options.alpha && spread[i].ll_gain > 0 &&
          (best < 0 || spread[i].ll_gain > spread[best].ll_gain))
        best = static_cast<int>(i);
    }
    if (best >= 0) {
      const SpreadCandidateEval& s = spread[best];
      // Scale model of the extended model's residuals on all fit rows.
      Eigen::VectorXd r =
          outer.y - BuildDesign(data, current, outer.rows) * beta_ext;
      const double total_ss = r.squaredNorm();
      RemoveStrokeMeans(outer, &r);
      // The scale model describes the within-stroke spread; its level is
      // raised to the total residual variance (offsets included) so that
      // Sigma(x) replaces sigma_eps and ScaleFactor is the relative change.
      const double level =
          0.5 * std::log(total_ss / std::max(1e-300, r.squaredNorm()));
      const std::vector<double>& col = *data.Column(s.cause);
      std::vector<double> rv(r.data(), r.data() + r.size()), z;
      for (std::size_t e : outer.rows) z.push_back(col[e]);
      const ScaleFit fit = FitScale(rv, z);
      Finding f;
      f.cause = s.cause;
      f.kind = "spread";
      f.expansion = "log-linear scale";
      f.terms = {"scale(" + s.cause + ")"};
      f.p_value = s.p_holm;
      f.cv_mae_gain_pct = 0.0;
      f.cv_mae = ext_mae;
      f.log_likelihood_gain = s.ll_gain;
      f.folds_selected = outer.folds;
      for (std::size_t i = 0; i < spread.size(); ++i) {
        if (static_cast<int>(i) == best || !(spread[i].p < options.alpha))
          continue;
        std::vector<double> d;
        for (std::size_t k = 0; k < outer.id_of_dense.size(); ++k) {
          if (outer.fit_count[k] > 0)
            d.push_back((s.stroke_ll_gain[k] - spread[i].stroke_ll_gain[k]) /
                        outer.mean_per_stroke);
        }
        // As for mean findings: within the winner's 95 % interval.
        const double half_width =
            s.t > 0 && std::isfinite(s.t) ? 2.0 * s.ll_gain / s.t : 0.0;
        if (!(s.ll_gain - spread[i].ll_gain <= half_width) ||
            !(spread[i].ll_gain > 0))
          continue;
        const double p_one = OneSidedT(d).second;
        const double p_two = std::min(1.0, 2.0 * std::min(p_one, 1.0 - p_one));
        Alternative a;
        a.cause = spread[i].cause;
        a.kind = "spread";
        a.expansion = "log-linear scale";
        a.p_value = p_two;
        a.correlation = Correlation(data, s.cause, a.cause, outer.rows);
        f.alternatives.push_back(std::move(a));
      }
      if (fit.ok) {
        EpsScaleModel scale = fit.m;
        scale.input = s.cause;
        scale.log_sigma_intercept += level;
        scale.sigma_ref = result.extended.sigma_eps;
        const double s_lo = scale.Sigma(fit.m.x_min),
                     s_hi = scale.Sigma(fit.m.x_max);
        f.effect =
            "the spread of eps " +
            std::string(fit.m.log_sigma_slope > 0 ? "grows" : "shrinks") +
            " with " + s.cause + ": sigma_eps " + Num(s_lo) + " at " + s.cause +
            " = " + Num(fit.m.x_min) + " and " + Num(s_hi) + " at " +
            Num(fit.m.x_max) + " " + UnitOf(s.cause) +
            " (constant model: " + Num(result.extended.sigma_eps) +
            "); held-out log-likelihood +" + Num(s.ll_gain) + " nats/sample";
        result.extended.eps_scale = scale;
      } else {
        f.effect = "the spread of eps depends on " + s.cause;
      }
      for (const Alternative& a : f.alternatives) {
        f.effect += "; the data cannot tell this apart from " + a.cause +
                    " (correlation " + Num(a.correlation, 2) + ")";
      }
      result.log_likelihood_gain += s.ll_gain;
      result.extended.cv_log_likelihood += s.ll_gain;
      result.extended.model += "+scale(" + s.cause + ")";
      result.findings.push_back(std::move(f));
    }
  }

  if (options.replay) {
    const std::vector<Term> coulomb = {Term::Intercept()};
    const CvEval coulomb_eval =
        Evaluate(outer, BuildDesign(data, coulomb, outer.rows));
    result.replay.push_back(
        Replay("coulomb", coulomb, data, outer, coulomb_eval, options));
    result.replay.push_back(
        Replay("linear", baseline, data, outer, base_eval, options));
    if (current.size() > baseline.size()) {
      const CvEval ext_eval =
          Evaluate(outer, BuildDesign(data, current, outer.rows));
      result.replay.push_back(
          Replay("extended", current, data, outer, ext_eval, options));
    }
    if (options.lugre)
      result.replay.push_back(
          ReplayLuGre(*options.lugre, data, outer, options));
  }
  result.status = DiagnosisStatus::kOk;
  return result;
}

}  // namespace diagnosis_internal
}  // namespace frictiond
