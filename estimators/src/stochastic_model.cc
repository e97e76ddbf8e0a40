#include "frictiond/estimators/stochastic_model.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>

#include "frictiond/estimators/logistic_sums.h"
#include "frictiond/estimators/robust_covariance.h"
#include "frictiond/estimators/stats.h"

namespace frictiond {

const std::vector<double>& EpsQuantileLevels() {
  static const std::vector<double> kLevels = [] {
    std::vector<double> l = {0.001, 0.0025, 0.005, 0.0075};
    for (int k = 1; k <= 99; ++k) l.push_back(k / 100.0);
    for (double x : {0.9925, 0.995, 0.9975, 0.999}) l.push_back(x);
    return l;
  }();
  return kLevels;
}

int RegressionModel::FindTerm(const std::string& name) const {
  for (std::size_t k = 0; k < terms.size(); ++k) {
    if (terms[k].Name() == name) return static_cast<int>(k);
  }
  return -1;
}

bool StochasticFitOptions::IsValid(std::string* why) const {
  if (!labelling.IsValid(why)) return false;
  auto fail = [&](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (terms.empty()) return fail("terms: empty (need at least one term)");
  for (const auto& t : terms) {
    try {
      Term::Parse(t);
    } catch (const std::invalid_argument& e) {
      return fail(std::string("terms: ") + e.what());
    }
  }
  if (!(min_relative_span >= 0 && min_relative_span < 1))
    return fail("min_relative_span = " + std::to_string(min_relative_span) +
                " (must be in [0, 1))");
  if (min_slip_samples < 3)
    return fail("min_slip_samples = " + std::to_string(min_slip_samples) +
                " (must be >= 3)");
  if (!(never_level > 0 && never_level < 0.5))
    return fail("never_level = " + std::to_string(never_level) +
                " (must be in (0, 0.5))");
  if (!(always_level > 0.5 && always_level < 1))
    return fail("always_level = " + std::to_string(always_level) +
                " (must be in (0.5, 1))");
  if (!eps_scale_input.empty()) {
    try {
      const Term t = Term::Parse(eps_scale_input);
      if (t.kind != TermKind::kLinear) throw std::invalid_argument("");
    } catch (const std::invalid_argument&) {
      return fail("eps_scale_input = '" + eps_scale_input.substr(0, 64) +
                  "' (must be a column name)");
    }
  }
  return true;
}

namespace {

void FillQuantiles(RegressionModel* m, const Eigen::VectorXd& residuals) {
  m->eps_quantiles.clear();
  if (residuals.size() == 0) return;
  std::vector<double> e(static_cast<std::size_t>(residuals.size()));
  Eigen::Map<Eigen::VectorXd>(e.data(), residuals.size()) = residuals;
  std::vector<double> q = SelectQuantiles(&e, EpsQuantileLevels());
  m->eps_quantiles.swap(q);
  m->mae = residuals.cwiseAbs().mean();
}

// Fits mu on `rows` with `terms`, fixing slopes of inputs without span.
// mu[i] is data.mu(i); `has_span` remembers the span check per input
// across calls.
FitStatus FitRegression(const StrokeData& data,
                        const std::vector<double>& mu,
                        const std::vector<std::size_t>& rows,
                        std::vector<Term> terms,
                        double min_relative_span,
                        std::map<std::string, bool>* has_span,
                        RegressionModel* out,
                        std::string* why,
                        std::string* field) {
  // Inputs without span: drop their terms (reported as unidentified).
  std::vector<Term> kept;
  std::vector<std::string> unidentified;
  for (const Term& t : terms) {
    if (t.kind == TermKind::kIntercept || t.kind == TermKind::kWindow) {
      kept.push_back(t);
      continue;
    }
    const std::vector<double>* col = data.Column(t.input);
    if (!col)
      throw std::invalid_argument("term '" + t.Name() + "': no column '" +
                                  t.input + "' in the data");
    auto known = has_span->find(t.input);
    if (known == has_span->end()) {
      std::vector<double> x;
      x.reserve(rows.size());
      for (std::size_t r : rows) x.push_back((*col)[r]);
      const std::vector<double> q = SelectQuantiles(&x, {0.05, 0.5, 0.95});
      const double span = q[2] - q[0];
      const double mag = std::fabs(q[1]);
      known =
          has_span->emplace(t.input, span > min_relative_span * mag && span > 0)
              .first;
    }
    if (known->second) {
      kept.push_back(t);
    } else {
      unidentified.push_back(t.Name());
    }
  }
  const Eigen::MatrixXd X = BuildDesign(data, kept, rows);
  Eigen::VectorXd y(rows.size());
  for (std::size_t r = 0; r < rows.size(); ++r) y(r) = mu[rows[r]];
  const OlsResult ols = FitOls(X, y);
  if (ols.status == FitStatus::kTooFewSamples ||
      ols.status == FitStatus::kFailed) {
    *why = ols.why;
    const int bad = ols.nonfinite_column;
    if (bad >= 0 && bad < static_cast<int>(kept.size())) {
      // The input the term reads (a product "x*y": its first factor).
      const std::string& input = kept[static_cast<std::size_t>(bad)].input;
      *field = input.substr(0, input.find('*'));
      *why = "term " + kept[static_cast<std::size_t>(bad)].Name() +
             ": values not finite or too large to fit (their squares "
             "overflow)";
    } else if (bad >= 0) {
      *field = "ft_n";
      *why =
          "mu = ft_n / fn_n: values not finite or too large to fit "
          "(their squares overflow)";
    }
    return ols.status;
  }
  // Expand back to the full term list (unidentified terms at 0).
  const int p = static_cast<int>(terms.size());
  out->terms = terms;
  out->beta = Eigen::VectorXd::Zero(p);
  out->std_err = Eigen::VectorXd::Zero(p);
  out->P_beta = Eigen::MatrixXd::Zero(p, p);
  std::vector<int> index(kept.size());
  for (std::size_t k = 0; k < kept.size(); ++k) {
    index[k] = static_cast<int>(std::find(terms.begin(), terms.end(), kept[k]) -
                                terms.begin());
  }
  for (std::size_t a = 0; a < kept.size(); ++a) {
    if (!ols.identified[a]) unidentified.push_back(kept[a].Name());
    out->beta(index[a]) = ols.beta(a);
    out->std_err(index[a]) = ols.std_err(a);
    for (std::size_t b = 0; b < kept.size(); ++b)
      out->P_beta(index[a], index[b]) = ols.P_beta(a, b);
  }
  // Stroke-clustered standard errors beside the i.i.d. ones.
  std::vector<int> cluster;
  if (data.stroke.size() == data.size()) {
    cluster.reserve(rows.size());
    for (std::size_t r : rows) cluster.push_back(data.stroke[r]);
    std::vector<int> ids = cluster;
    if (!std::is_sorted(ids.begin(), ids.end()))  // rows are in time order
      std::sort(ids.begin(), ids.end());
    out->stroke_clusters =
        static_cast<int>(std::unique(ids.begin(), ids.end()) - ids.begin());
  }
  out->std_err_stroke.resize(0);
  if (out->stroke_clusters >= 2) {
    const Eigen::MatrixXd P =
        CalcClusterRobustCovariance(X, ols.residuals, cluster);
    out->std_err_stroke = Eigen::VectorXd::Zero(p);
    for (std::size_t a = 0; a < kept.size(); ++a) {
      if (ols.identified[a])
        out->std_err_stroke(index[a]) = std::sqrt(std::max(0.0, P(a, a)));
    }
  }
  out->unidentified = unidentified;
  out->sigma_eps = ols.sigma_eps;
  out->r2 = ols.r2;
  out->f_stat = ols.f_stat;
  out->p_value = ols.p_value;
  out->samples = ols.samples;
  FillQuantiles(out, ols.residuals);
  if (!unidentified.empty()) {
    *why = "not identified (no span in the data, slope fixed at 0):";
    for (const auto& u : unidentified) *why += " " + u;
    return FitStatus::kPartial;
  }
  return FitStatus::kOk;
}

}  // namespace

SlipLikelihoodFit FitSlipLikelihood(const std::vector<double>& ratio,
                                    const std::vector<int>& slip,
                                    double never_level,
                                    double always_level) {
  return FitSlipLikelihood(ratio.data(),
                           slip.data(),
                           std::min(ratio.size(), slip.size()),
                           never_level,
                           always_level);
}

SlipLikelihoodFit FitSlipLikelihood(const double* ratio,
                                    const int* slip,
                                    std::size_t n,
                                    double never_level,
                                    double always_level,
                                    const SlipLikelihoodFit* start) {
  SlipLikelihoodFit fit;
  fit.never_level = never_level;
  fit.always_level = always_level;
  fit.samples = static_cast<int>(n);
  // Count, mean and variance in one pass (sums shifted by the first ratio
  // against cancellation).
  std::size_t n_slip = 0;
  const double shift = n > 0 ? ratio[0] : 0.0;
  double sum = 0, sum2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    n_slip += slip[i] ? 1 : 0;
    const double d = ratio[i] - shift;
    sum += d;
    sum2 += d * d;
  }
  if (n_slip == 0 || n_slip == n) {
    fit.why = n_slip == 0 ? "no slipping samples" : "no stick samples";
    return fit;
  }
  const double mean_d = sum / n;
  const double mean_r = shift + mean_d;
  const double sd_r = std::sqrt(std::max(0.0, sum2 / n - mean_d * mean_d));
  if (!(sd_r > 0)) {
    fit.why = "all ratios equal";
    return fit;
  }
  // IRLS on the standardised ratio z = (r - mean)/sd: eta = a + b z.
  // A tiny ridge on b keeps separable data finite.
  const Eigen::Vector2d cold(std::log(double(n_slip) / (n - n_slip)), 0.0);
  Eigen::Vector2d w = cold;
  Eigen::Matrix2d H;
  // Newton steps until the step is below `tol`. Convergence is quadratic
  // near the optimum, so after a step of size tol the remaining error is of
  // order tol^2. Each step is one pass of CalcLogisticSums over the pairs.
  // `single`: sums from single-precision probabilities (CalcLogisticSums),
  // for the steps towards the optimum only.
  auto newton = [&w, &H, mean_r, sd_r](const double* r,
                                       const int* y,
                                       std::size_t m,
                                       double tol,
                                       int max_iterations,
                                       bool single) {
    const double ridge = 1e-6 * m;
    for (int it = 0; it < max_iterations; ++it) {
      const LogisticSums s = CalcLogisticSums(r,
                                              y,
                                              m,
                                              {w(0), w(1), mean_r, 1.0 / sd_r},
                                              SimdLevel::kAvx512,
                                              single);
      const Eigen::Vector2d grad(s.g0, s.g1 - ridge * w(1));
      H << s.h00, s.h01, s.h01, s.h11 + ridge;
      const Eigen::Vector2d step = H.ldlt().solve(grad);
      w += step;
      if (step.norm() < tol) return w.allFinite();
    }
    return false;
  };
  // With a start (a fit of similar data, e.g. this window before the
  // pair's latest upload): its (c1, c2) in this set's standardised units,
  // then the same two stages as below to the same tolerances. The
  // objective is strictly concave (the ridge), so steps that converge
  // reach its one optimum; Newton from a far start can overshoot, so a
  // start that has not converged within a few steps is dropped and the
  // fit begins again cold. On a bounded refit's 4,250 samples, eq. (2)'s
  // windows take 2.5 single- and 1.3 double-precision passes from the
  // previous refit's fit instead of 8.6 and 1.3 (142 -> 78 us).
  bool converged = false;
  if (start != nullptr && start->valid && start->c1 > 0 &&
      std::isfinite(start->c1) && std::isfinite(start->c2)) {
    w << start->c1 * (mean_r - start->c2), start->c1 * sd_r;
    converged = w.allFinite() &&
                newton(ratio, slip, n, 1e-2, 4, /*single=*/true) &&
                newton(ratio, slip, n, 1e-3, 8, /*single=*/false);
    if (!converged) w = cold;
  }
  // On large sets, first converge on evenly strided subsamples (512, then
  // 4096 pairs, single precision): the full data then needs one step in
  // single precision and the last (quadratically converging) ones in
  // double.
  bool warm_started = false;
  for (const std::size_t warm : {std::size_t{512}, std::size_t{4096}}) {
    if (converged || n < 4 * warm) break;
    const std::size_t stride = n / warm;
    std::vector<double> rs;
    std::vector<int> ys;
    int ys_slip = 0;
    for (std::size_t i = 0; i + stride <= n; i += stride) {
      rs.push_back(ratio[i]);
      ys.push_back(slip[i] ? 1 : 0);
      ys_slip += ys.back();
    }
    if (ys_slip > 0 && ys_slip < static_cast<int>(ys.size())) {
      newton(rs.data(),
             ys.data(),
             rs.size(),
             warm < 4096 ? 1e-2 : 1e-3,
             100,
             /*single=*/true);
      warm_started = true;
    }
    if (!w.allFinite()) {
      w << std::log(double(n_slip) / (n - n_slip)), 0.0;
      warm_started = false;
    }
  }
  // After the warm start, one single-precision step on the full data (its
  // ~1e-6 relative error is far below the step's own size). Without one
  // (fewer than 2,048 pairs: eq. (2)'s Fn windows hold a few hundred), the
  // steps from the cold start are single precision until a step is below
  // 1e-2: most of a window's ~8 passes at about half the cost (eq. (2) on
  // a bounded refit's 4,250 samples: 190 -> 133 us; c1 and c2 equal to
  // 1e-7 relative over 3,259 windows of 200 simulated data sets, except
  // one separable window whose c2 is undetermined either way). Then
  // double precision until a step is below 1e-3: that leaves an error of
  // order 1e-6 (standardised units), far below the standard error of b
  // (~1/sqrt(n)), and H from double-precision sums.
  if (!converged) {
    if (warm_started) {
      newton(ratio, slip, n, 0.0, 1, /*single=*/true);
    } else {
      newton(ratio, slip, n, 1e-2, 100, /*single=*/true);
    }
    newton(ratio, slip, n, 1e-3, 100, /*single=*/false);
  }
  // Back to L = 1/(1+exp(-c1 (r - c2))).
  fit.c1 = w(1) / sd_r;
  fit.c2 = std::fabs(w(1)) > 0 ? mean_r - w(0) * sd_r / w(1) : mean_r;
  // Covariance of (a, b) is H^-1; map to (c1, c2) by the delta method.
  const Eigen::Matrix2d P_w = H.inverse();
  Eigen::Matrix2d J;  // d(c1, c2)/d(a, b)
  J << 0.0, 1.0 / sd_r, -sd_r / w(1), w(0) * sd_r / (w(1) * w(1));
  fit.P_c = J * P_w * J.transpose();
  auto logit = [](double p) { return std::log(p / (1 - p)); };
  fit.ratio_never = fit.c2 + logit(never_level) / fit.c1;
  fit.ratio_always = fit.c2 + logit(always_level) / fit.c1;
  fit.valid = std::isfinite(fit.c1) && std::isfinite(fit.c2) && fit.c1 > 0;
  if (!fit.valid)
    fit.why = "likelihood does not increase with Ft/Fn (c1 = " +
              std::to_string(fit.c1) + ")";
  return fit;
}

StochasticFit FitStochasticModel(const StrokeData& input,
                                 const StochasticFitOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  StochasticFit fit;
  StochasticFrictionModel& m = fit.model;
  m.labelling = options.labelling;
  // Copy only when labels must be derived.
  StrokeData labelled;
  const bool has_labels =
      input.slip.size() == input.size() && input.stroke.size() == input.size();
  if (!has_labels) {
    labelled = input;
    EnsureLabels(&labelled, options.labelling);
  }
  // Computed columns the terms or the scale read (product columns "x*y",
  // eps_scale.h) are added on the copy.
  std::vector<std::string> computed;
  for (const auto& name : options.terms) {
    const Term t = Term::Parse(name);
    if (!t.input.empty() && !input.Column(t.input)) computed.push_back(t.input);
  }
  if (!options.eps_scale_input.empty() &&
      !input.Column(options.eps_scale_input))
    computed.push_back(options.eps_scale_input);
  if (!has_labels || !computed.empty()) {
    if (has_labels) labelled = input;
    for (const std::string& name : computed) AddComputedColumn(&labelled, name);
  }
  const StrokeData& data = has_labels && computed.empty() ? input : labelled;
  // One pass: mu = Ft/Fn, the samples within the exclusion bounds (for the
  // sigmoid likelihood) and the slipping ones among them (the fit rows,
  // CalcFitMask).
  const std::size_t n = data.size();
  std::vector<double> mu(n);
  std::vector<std::size_t> rows(n);
  std::vector<int> strokes;
  std::vector<double> ratio(n);
  std::vector<int> slip(n);
  std::size_t n_rows = 0, n_ratio = 0;
  int last_stroke = 0;
  for (std::size_t i = 0; i < n; ++i) {
    // Branch-free: every sample is written, the counts advance only for
    // the kept ones.
    mu[i] = data.ft_n[i] / data.fn_n[i];
    const bool in_bounds = data.fn_n[i] < options.labelling.max_fn_n &&
                           data.v_mm_s[i] < options.labelling.max_v_mm_s;
    ratio[n_ratio] = mu[i];
    slip[n_ratio] = data.slip[i];
    n_ratio += in_bounds;
    const bool fit_row = in_bounds && data.slip[i] == 1;
    rows[n_rows] = i;
    n_rows += fit_row;
    if (fit_row && (n_rows == 1 || last_stroke != data.stroke[i])) {
      strokes.push_back(data.stroke[i]);
      last_stroke = data.stroke[i];
    }
  }
  rows.resize(n_rows);
  ratio.resize(n_ratio);
  slip.resize(n_ratio);
  std::sort(strokes.begin(), strokes.end());
  m.samples_total = static_cast<int>(data.size());
  m.samples_slip = static_cast<int>(rows.size());
  m.strokes = static_cast<int>(std::unique(strokes.begin(), strokes.end()) -
                               strokes.begin());
  if (static_cast<int>(rows.size()) < options.min_slip_samples) {
    fit.status = FitStatus::kTooFewSamples;
    fit.field = "v_mm_s";  // slip is labelled from the speed
    fit.why =
        std::to_string(rows.size()) + " slipping samples (need at least " +
        std::to_string(options.min_slip_samples) +
        "; check the slip thresholds slip_peak_mm_s=" +
        std::to_string(options.labelling.peak_mm_s) +
        ", slip_floor_mm_s=" + std::to_string(options.labelling.floor_mm_s) +
        ")";
    return fit;
  }
  std::vector<Term> terms;
  for (const auto& t : options.terms) terms.push_back(Term::Parse(t));
  // Coulomb: the mean mu of slipping samples.
  double sum = 0;
  for (std::size_t r : rows) sum += mu[r];
  m.mu_coulomb = sum / rows.size();
  double mae = 0;
  for (std::size_t r : rows) mae += std::fabs(mu[r] - m.mu_coulomb);
  m.mae_coulomb = mae / rows.size();
  // Input statistics (for defaults and extrapolation flags).
  std::set<std::string> inputs;
  for (const Term& t : terms) {
    if (!t.input.empty()) inputs.insert(t.input);
  }
  // A product's factors and the scale's input are inputs too (given to
  // predict by name, defaulting to their means).
  if (!options.eps_scale_input.empty()) inputs.insert(options.eps_scale_input);
  for (const std::string& name : std::set<std::string>(inputs)) {
    std::string x, y;
    if (SplitProductName(name, &x, &y)) inputs.insert(x), inputs.insert(y);
  }
  inputs.insert("fn_n");
  inputs.insert("v_mm_s");
  for (const auto& name : inputs) {
    const std::vector<double>* col = data.Column(name);
    if (!col)
      throw std::invalid_argument("term input '" + name +
                                  "': no such column in the data");
    InputStats s{0.0, (*col)[rows[0]], (*col)[rows[0]]};
    for (std::size_t r : rows) {
      s.mean += (*col)[r];
      s.min = std::min(s.min, (*col)[r]);
      s.max = std::max(s.max, (*col)[r]);
    }
    s.mean /= rows.size();
    m.inputs[name] = s;
  }
  // eq. (1) and the Fn-only model of III-C.
  std::map<std::string, bool> has_span;
  FitStatus st = FitRegression(data,
                               mu,
                               rows,
                               terms,
                               options.min_relative_span,
                               &has_span,
                               &m.mu,
                               &why,
                               &fit.field);
  if (st == FitStatus::kTooFewSamples || st == FitStatus::kFailed) {
    fit.status = st;
    fit.why = "mu model: " + why;
    return fit;
  }
  std::string why_fn;
  FitStatus st_fn = FitRegression(data,
                                  mu,
                                  rows,
                                  {Term::Intercept(), Term::Linear("fn_n")},
                                  options.min_relative_span,
                                  &has_span,
                                  &m.mu_fn_only,
                                  &why_fn,
                                  &fit.field);
  if (st_fn == FitStatus::kTooFewSamples || st_fn == FitStatus::kFailed) {
    fit.status = st_fn;
    fit.why = "Fn-only model: " + why_fn;
    return fit;
  }
  // eps's time correlation (eps_time.h) from eq. (1)'s residuals: episodes
  // are runs of consecutive fit rows within a stroke without a time gap.
  {
    const Eigen::MatrixXd X = BuildDesign(data, m.mu.terms, rows);
    std::vector<double> residuals(rows.size());
    std::vector<int> episode(rows.size());
    std::vector<double> steps;
    steps.reserve(rows.size());
    for (std::size_t k = 1; k < rows.size(); ++k) {
      if (rows[k] == rows[k - 1] + 1 &&
          data.stroke[rows[k]] == data.stroke[rows[k - 1]])
        steps.push_back(data.t_s[rows[k]] - data.t_s[rows[k - 1]]);
    }
    double dt = 0.0;
    if (!steps.empty()) dt = SelectQuantiles(&steps, {0.5})[0];
    int id = 0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      residuals[k] =
          mu[rows[k]] - X.row(static_cast<Eigen::Index>(k)).dot(m.mu.beta);
      if (k > 0) {
        const bool same = rows[k] == rows[k - 1] + 1 &&
                          data.stroke[rows[k]] == data.stroke[rows[k - 1]] &&
                          data.t_s[rows[k]] - data.t_s[rows[k - 1]] <= 1.5 * dt;
        if (!same) ++id;
      }
      episode[k] = id;
    }
    // Heteroscedastic eps (eps_scale.h): the scale fitted on the residuals,
    // then the stored quantiles and the time model describe the
    // standardised residuals r / ScaleFactor(x).
    if (!options.eps_scale_input.empty()) {
      const std::vector<double>& col = *data.Column(options.eps_scale_input);
      std::vector<double> z(rows.size());
      for (std::size_t k = 0; k < rows.size(); ++k) z[k] = col[rows[k]];
      EpsScaleModel scale;
      if (FitEpsScaleModel(residuals, z, options.eps_scale_input, &scale)) {
        for (std::size_t k = 0; k < rows.size(); ++k)
          residuals[k] /= scale.ScaleFactor(z[k]);
        std::vector<double> e = residuals;
        m.mu.eps_quantiles = SelectQuantiles(&e, EpsQuantileLevels());
        m.eps_scale = std::move(scale);
      } else {
        why += std::string(why.empty() ? "" : "; ") + "eps scale in " +
               options.eps_scale_input +
               " not identified (no span or no residuals): constant scale";
      }
    }
    m.eps_time = FitEpsTimeModel(residuals, episode, dt);
  }
  // Sigmoid likelihood on all samples within the exclusion bounds.
  m.likelihood =
      FitSlipLikelihood(ratio, slip, options.never_level, options.always_level);
  fit.status = st;
  fit.why = st == FitStatus::kPartial || !why.empty() ? why : "";
  return fit;
}

double CalcEpsQuantile(const RegressionModel& model, double p) {
  if (model.eps_quantiles.size() != EpsQuantileLevels().size())
    return NormalQuantile(p) * model.sigma_eps;
  return InterpolateStoredQuantiles(model.eps_quantiles, p);
}

double InterpolateStoredQuantiles(const std::vector<double>& q, double p) {
  const auto& levels = EpsQuantileLevels();
  if (p <= levels.front()) return q.front();
  if (p >= levels.back()) return q.back();
  const auto it = std::upper_bound(levels.begin(), levels.end(), p);
  const std::size_t k = it - levels.begin();
  const double w = (p - levels[k - 1]) / (levels[k] - levels[k - 1]);
  return q[k - 1] + w * (q[k] - q[k - 1]);
}

double CalcEpsCdf(const RegressionModel& model, double e) {
  const auto& levels = EpsQuantileLevels();
  const auto& q = model.eps_quantiles;
  if (q.size() != levels.size())
    return model.sigma_eps > 0 ? NormalCdf(e / model.sigma_eps)
                               : (e >= 0 ? 1.0 : 0.0);
  if (e < q.front()) return 0.0;
  if (e >= q.back()) return 1.0;
  const auto it = std::upper_bound(q.begin(), q.end(), e);
  const std::size_t k = it - q.begin();
  const double dq = q[k] - q[k - 1];
  const double w = dq > 0 ? (e - q[k - 1]) / dq : 1.0;
  return levels[k - 1] + w * (levels[k] - levels[k - 1]);
}

MuPrediction PredictMu(const StochasticFrictionModel& model,
                       const InputValues& inputs) {
  MuPrediction out;
  const RegressionModel& m = model.mu;
  Eigen::VectorXd x(m.terms.size());
  for (std::size_t k = 0; k < m.terms.size(); ++k) {
    const Term& t = m.terms[k];
    if (t.kind == TermKind::kIntercept) {
      x(k) = 1.0;
      continue;
    }
    bool given = false;
    const double value = ResolveInputValue(model, inputs, t.input, &given);
    auto it = model.inputs.find(t.input);
    if (given && it != model.inputs.end() &&
        (value < it->second.min || value > it->second.max)) {
      if (std::find(out.extrapolated_inputs.begin(),
                    out.extrapolated_inputs.end(),
                    t.input) == out.extrapolated_inputs.end()) {
        out.extrapolated_inputs.push_back(t.input);
      }
    }
    x(k) = t.Eval(value);
  }
  // Inputs the model does not use (e.g. an unidentified fn_n) still flag
  // extrapolation.
  for (const auto& [name, v] : inputs) {
    auto it = model.inputs.find(name);
    if (it != model.inputs.end() &&
        (v < it->second.min || v > it->second.max) &&
        std::find(out.extrapolated_inputs.begin(),
                  out.extrapolated_inputs.end(),
                  name) == out.extrapolated_inputs.end()) {
      out.extrapolated_inputs.push_back(name);
    }
  }
  out.extrapolated = !out.extrapolated_inputs.empty();
  out.mu = m.beta.size() == x.size() ? m.beta.dot(x) : 0.0;
  const double var_param =
      m.P_beta.rows() == x.size() ? std::max(0.0, x.dot(m.P_beta * x)) : 0.0;
  if (!model.eps_scale) {
    out.sigma = std::sqrt(m.sigma_eps * m.sigma_eps + var_param);
    const double widen = m.sigma_eps > 0 ? out.sigma / m.sigma_eps : 1.0;
    out.lo95 = out.mu + widen * CalcEpsQuantile(m, 0.025);
    out.hi95 = out.mu + widen * CalcEpsQuantile(m, 0.975);
    return out;
  }
  // Heteroscedastic eps: the scale s at these inputs (eps_scale.h).
  const double s = CalcEpsScaleFactor(model, inputs);
  const double sigma_x = s * m.sigma_eps;
  out.sigma = std::sqrt(sigma_x * sigma_x + var_param);
  const double widen = sigma_x > 0 ? out.sigma / sigma_x : 1.0;
  out.lo95 = out.mu + widen * s * CalcEpsQuantile(m, 0.025);
  out.hi95 = out.mu + widen * s * CalcEpsQuantile(m, 0.975);
  return out;
}

double ResolveInputValue(const StochasticFrictionModel& model,
                         const InputValues& inputs,
                         const std::string& name,
                         bool* given) {
  if (given) *given = false;
  for (const auto& [n, v] : inputs) {
    if (n == name) {
      if (given) *given = true;
      return v;
    }
  }
  // The product rule of eps_scale.h, from the factors' values (each given
  // or at its mean).
  std::string x, y;
  if (SplitProductName(name, &x, &y))
    return ResolveInputValue(model, inputs, x) *
           ResolveInputValue(model, inputs, y);
  auto it = model.inputs.find(name);
  return it != model.inputs.end() ? it->second.mean : 0.0;
}

double CalcEpsScaleFactor(const StochasticFrictionModel& model,
                          const InputValues& inputs) {
  if (!model.eps_scale) return 1.0;
  return model.eps_scale->ScaleFactor(
      ResolveInputValue(model, inputs, model.eps_scale->input));
}

StochasticFitOptions CalcRefitOptions(const StochasticFrictionModel& previous,
                                      const StrokeData& data) {
  StochasticFitOptions o;
  o.labelling = previous.labelling;
  std::vector<std::string> terms;
  bool computable = !previous.mu.terms.empty();
  for (const Term& t : previous.mu.terms) {
    if (t.kind != TermKind::kIntercept && !CanComputeColumn(data, t.input))
      computable = false;
    terms.push_back(t.Name());
  }
  if (computable) o.terms = terms;
  if (previous.eps_scale && CanComputeColumn(data, previous.eps_scale->input))
    o.eps_scale_input = previous.eps_scale->input;
  return o;
}

MuPrediction PredictMu(const StochasticFrictionModel& model,
                       double fn_n,
                       double v_mm_s) {
  return PredictMu(model, InputValues{{"fn_n", fn_n}, {"v_mm_s", v_mm_s}});
}

namespace {

// b0 + b2*Fn of the Fn-only model.
double FnOnlyMean(const RegressionModel& m, double fn_n) {
  double mean = 0.0;
  for (std::size_t k = 0; k < m.terms.size(); ++k)
    mean += m.beta(k) * m.terms[k].Eval(fn_n);
  return mean;
}

}  // namespace

double CalcSlipLikelihood(const StochasticFrictionModel& model,
                          double fn_n,
                          double ft_n) {
  const double r = ft_n / fn_n;
  if (model.likelihood.valid) {
    const double z = model.likelihood.c1 * (r - model.likelihood.c2);
    return 1.0 / (1.0 + std::exp(-z));
  }
  return CalcEpsCdf(model.mu_fn_only, r - FnOnlyMean(model.mu_fn_only, fn_n));
}

}  // namespace frictiond
