#pragma once
/// @file
/// The stochastic friction model of paper 000:
///   mu = b0 + b1*v + b2*Fn + eps                       (eq. 1)
/// identified from slipping samples of test strokes, with eps represented by
/// its empirical distribution (quantiles), plus the Fn-only model
///   mu = b0 + b2*Fn + eps                              (section III-C)
/// used for slip prediction from Ft/Fn, and the sigmoid slip likelihood
///   L(Ft/Fn) = 1 / (1 + exp(-c1*(Ft/Fn - c2)))         (section III-A, Fig. 3)
/// fitted by maximum likelihood on all samples.
///
/// Noise assumptions: eps is treated as i.i.d. within the fit (the standard
/// errors are the textbook OLS ones; samples within a stroke are correlated, so
/// treat them as optimistic; diagnosis uses stroke-grouped statistics instead).
/// Its time correlation is identified after the fit (eps_time.h) and used
/// by the grip force for a hold (grip_force.h).
///
/// Usage:
/// @code
///   StrokeData data = ParseStrokeCsv(csv_text);
///   StochasticFitOptions options;               // fingertip defaults
///   StochasticFit fit = FitStochasticModel(data, options);
///   if (fit.status != FitStatus::kOk && fit.status != FitStatus::kPartial) {
///   /* fit.why */ } MuPrediction p = PredictMu(fit.model, /*fn_n=*/2.0,
///   /*v_mm_s=*/20.0); double slip_prob = CalcSlipLikelihood(fit.model,
///   /*fn_n=*/2.0, /*ft_n=*/1.5); GripForce g = CalcGripForce(fit.model,
///   /*load_n=*/3.0, /*risk=*/0.001);  // grip_force.h
/// @endcode

#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "frictiond/estimators/eps_scale.h"
#include "frictiond/estimators/eps_time.h"
#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

/// Probability levels at which eps quantiles are stored: 0.001, 0.0025,
/// 0.005, 0.0075, 0.01, 0.02, ..., 0.99, 0.9925, 0.995, 0.9975, 0.999.
const std::vector<double>& EpsQuantileLevels();

/// A fitted linear model of mu with its error distribution.
struct RegressionModel {
  std::vector<Term> terms;  ///< regressors, terms[0] is usually the intercept
  Eigen::VectorXd beta;     ///< coefficients per term
  Eigen::VectorXd std_err;  ///< standard errors per term (i.i.d. eps)
  Eigen::MatrixXd P_beta;   ///< coefficient covariance (i.i.d. eps)
  /// Stroke-clustered (Liang-Zeger) standard errors per term, valid when eps
  /// is correlated within a stroke or strokes carry offsets (see
  /// robust_covariance.h); 0 for unidentified terms, empty when fewer than
  /// 2 strokes were fitted. Trust them from ~10 strokes on.
  Eigen::VectorXd std_err_stroke;
  int stroke_clusters = 0;  ///< strokes behind std_err_stroke
  std::vector<std::string>
      unidentified;        ///< terms fixed at 0 (no span in their input)
  double sigma_eps = 0.0;  ///< residual standard deviation
  double r2 = 0.0;         ///< R^2 on the fitted samples
  double f_stat = 0.0;     ///< F statistic (Table I)
  double p_value = 1.0;    ///< p-value of the F test
  double mae = 0.0;        ///< mean |residual| on the fitted samples
  int samples = 0;         ///< fitted samples
  std::vector<double>
      eps_quantiles;  ///< residual quantiles at EpsQuantileLevels()

  /// Index of term `name`, or -1.
  int FindTerm(const std::string& name) const;
};

/// Maximum-likelihood sigmoid L(r) = 1/(1+exp(-c1 (r - c2))), r = Ft/Fn.
struct SlipLikelihoodFit {
  bool valid =
      false;        ///< false when there were not both slip and stick samples
  std::string why;  ///< reason when not valid
  double c1 = 0.0;  ///< steepness [1/ratio]
  double c2 = 0.0;  ///< ratio at 50 % slip likelihood
  double ratio_never =
      0.0;  ///< ratio below which L < never_level ("never slips below")
  double ratio_always =
      0.0;  ///< ratio above which L > always_level ("always slips above")
  double never_level = 0.01;
  double always_level = 0.99;
  int samples = 0;
  Eigen::Matrix2d P_c = Eigen::Matrix2d::Zero();  ///< covariance of (c1, c2)
};

/// Range and mean of one input over the fitted samples.
struct InputStats {
  double mean = 0.0;
  double min = 0.0;
  double max = 0.0;
};

/// Everything the library stores for one material-fingertip pair.
struct StochasticFrictionModel {
  RegressionModel mu;  ///< eq. (1), possibly extended with more terms
  RegressionModel
      mu_fn_only;  ///< mu = b0 + b2 Fn + eps (slip prediction, III-C)
  SlipLikelihoodFit likelihood;              ///< sigmoid L(Ft/Fn)
  std::map<std::string, InputStats> inputs;  ///< per input column used by mu
  double mu_coulomb =
      0.0;  ///< Coulomb's coefficient: mean mu of slipping samples
  double mae_coulomb = 0.0;    ///< mean |mu - mu_coulomb|
  int strokes = 0;             ///< strokes that contributed slipping samples
  int samples_total = 0;       ///< all samples offered
  int samples_slip = 0;        ///< slipping samples used for mu
  SlipLabelOptions labelling;  ///< rule that labelled slip
  /// Time correlation of mu's eps (eps_time.h): AR(1) within episodes plus
  /// a per-episode offset, identified from the fitted slipping samples.
  EpsTimeModel eps_time;
  /// Heteroscedastic eps (eps_scale.h; a diagnosed `spread`): when set,
  /// eps at inputs x is ScaleFactor(x) times a draw of the constant-scale
  /// distribution, and mu.eps_quantiles (and eps_time) describe the
  /// standardised residuals r / ScaleFactor(x). Absent: eps has one scale
  /// (paper 000), every evaluation as before.
  std::optional<EpsScaleModel> eps_scale;
};

/// Options of FitStochasticModel.
struct StochasticFitOptions {
  /// Slip labelling and exclusion bounds (paper II-C).
  SlipLabelOptions labelling;
  /// Terms of the mu model. Default: eq. (1).
  std::vector<std::string> terms = {"intercept", "v_mm_s", "fn_n"};
  /// An input whose 5-95 % range is below this fraction of its median
  /// magnitude is not identified (its slope is fixed at 0 and reported), so
  /// that a constant-load stroke does not produce a meaningless Fn slope.
  double min_relative_span = 0.02;
  /// Fewest slipping samples for a model.
  int min_slip_samples = 20;
  /// Levels of the "never slips below" and "always slips above" ratios.
  double never_level = 0.01;
  double always_level = 0.99;
  /// Column the scale of eps depends on (eps_scale.h), e.g. the input of a
  /// diagnosed `spread` finding; empty (default): a constant scale. A
  /// product name "x*y" is computed from its factors.
  std::string eps_scale_input;

  /// True when usable; otherwise *why names the field, value and rule.
  bool IsValid(std::string* why) const;
};

/// Result of FitStochasticModel.
struct StochasticFit {
  FitStatus status =
      FitStatus::kFailed;  ///< kOk, kPartial (some slope unidentified),
                           ///< kTooFewSamples, kFailed
  std::string why;
  /// The input a failure traces to: a column whose values cannot be
  /// fitted ("fn_n", "ft_n" for mu = ft_n/fn_n, "v_mm_s" or a covariate),
  /// or "v_mm_s" when too few samples slip (slip is read from the speed);
  /// empty when fitted.
  std::string field;
  StochasticFrictionModel model;
};

/// Identifies the model from strokes. Missing slip/stroke labels are derived
/// (EnsureLabels); mu is fitted on slipping samples within the bounds.
/// @throws std::invalid_argument when options are invalid or a term names a
/// column the data does not have.
StochasticFit FitStochasticModel(const StrokeData& data,
                                 const StochasticFitOptions& options = {});

/// Options to refit `previous` on (new) data: its labelling, its term list
/// and its eps scale input when every column they read is in `data` or can
/// be computed from it (eps_scale.h: CanComputeColumn), otherwise eq. (1)
/// and a constant scale. The one rule the daemon uses when strokes arrive.
StochasticFitOptions CalcRefitOptions(const StochasticFrictionModel& previous,
                                      const StrokeData& data);

/// Fits the sigmoid slip likelihood by maximum likelihood (IRLS) on (ratio,
/// slip) pairs. Separable data get a mild ridge on c1 so the answer stays
/// finite.
SlipLikelihoodFit FitSlipLikelihood(const std::vector<double>& ratio,
                                    const std::vector<int>& slip,
                                    double never_level = 0.01,
                                    double always_level = 0.99);
/// The same on n pairs in plain arrays (slip: 0 = stick, else slip).
/// `start`, optional: a fit of similar data (e.g. the same pairs before the
/// latest upload) whose c1, c2 start the Newton steps. The answer is the
/// same optimum to the steps' tolerance (differences of order 1e-10
/// relative); a start from which the steps do not converge quickly is
/// dropped for the usual cold start.
SlipLikelihoodFit FitSlipLikelihood(const double* ratio,
                                    const int* slip,
                                    std::size_t n,
                                    double never_level = 0.01,
                                    double always_level = 0.99,
                                    const SlipLikelihoodFit* start = nullptr);

/// Prediction of mu at an operating point.
struct MuPrediction {
  double mu = 0.0;     ///< mean mu
  double sigma = 0.0;  ///< sqrt(sigma_eps^2 + x' P_beta x)
  double lo95 = 0.0;   ///< 2.5 % quantile (empirical eps, widened by parameter
                       ///< uncertainty)
  double hi95 = 0.0;   ///< 97.5 % quantile
  bool extrapolated = false;  ///< an input lies outside the fitted range
  std::vector<std::string> extrapolated_inputs;
};

/// Inputs by name; inputs the model uses but that are missing take their
/// fitted mean.
using InputValues = std::vector<std::pair<std::string, double>>;

/// Value of model input `name` at `inputs`: the given value; else, for a
/// product "x*y" (eps_scale.h), the product of its factors' values; else
/// its fitted mean (0 when unknown). *given (optional): the value itself
/// was given.
double ResolveInputValue(const StochasticFrictionModel& model,
                         const InputValues& inputs,
                         const std::string& name,
                         bool* given = nullptr);

/// eps scale factor at the inputs: model.eps_scale->ScaleFactor of its
/// input's value (ResolveInputValue), exactly 1 without a scale model.
double CalcEpsScaleFactor(const StochasticFrictionModel& model,
                          const InputValues& inputs);

/// Predicts mu at the given inputs (fn_n and v_mm_s, plus any covariates an
/// extended model uses). With an eps scale model the interval and sigma use
/// the scale at these inputs (sigma = sqrt((s sigma_eps)^2 + x' P_beta x),
/// quantiles s * q_e).
MuPrediction PredictMu(const StochasticFrictionModel& model,
                       const InputValues& inputs);
/// Convenience overload for eq. (1)'s inputs.
MuPrediction PredictMu(const StochasticFrictionModel& model,
                       double fn_n,
                       double v_mm_s);

/// Empirical CDF of eps at e (linear between stored quantiles).
double CalcEpsCdf(const RegressionModel& model, double e);
/// Empirical quantile of eps at probability p.
double CalcEpsQuantile(const RegressionModel& model, double p);
/// The quantile at p of a quantile set `q` stored at EpsQuantileLevels()
/// (same size): linear between the levels, the end quantiles beyond them
/// (CalcEpsQuantile's rule).
double InterpolateStoredQuantiles(const std::vector<double>& q, double p);

/// Likelihood of slip at (Fn, Ft): the sigmoid L(Ft/Fn) when fitted,
/// otherwise P(mu <= Ft/Fn) from the Fn-only model's eps distribution.
/// Returns a value in [0, 1].
double CalcSlipLikelihood(const StochasticFrictionModel& model,
                          double fn_n,
                          double ft_n);

}  // namespace frictiond

// The grip force (CalcGripForce, GripForceOptions) lives in grip_force.h,
// included here so that existing includers keep seeing it.
#include "frictiond/estimators/grip_force.h"  // IWYU pragma: export
