#pragma once
/// @file
/// Risk-based grip force (paper 000, section IV-A), for the state the grasp
/// is in and for a hold of given duration.
///
/// Model: mu(t) = b0 + b1 v + b2 Fn (+ further terms at their fitted means)
/// + eps_t, eq. (1), with eps_t the time-correlated process of eps_time.h.
/// A grasp holding load_n at normal force Fn slips when mu(t) Fn < load_n at
/// any sample of the hold. CalcGripForce answers the smallest Fn with
///   P(slip at any time during hold_s) <= risk,
/// i.e. with c such that CalcHoldCrossingProbability(c, n, phi, f) = risk
/// and u = CalcEpsQuantileExtended(model.mu, Phi(c), model.eps_time) it
/// solves
///   Fn * (b0 + b1 v + b2 Fn + u) = load_n.                         (*)
///
/// Heteroscedastic eps (model.eps_scale, eps_scale.h): u is a quantile of
/// the standardised eps and (*) reads Fn (x(Fn)' beta + s(Fn, v) u) =
/// load_n with s = ScaleFactor of the scale's input at the answer (Fn, v,
/// or the input's fitted mean). Without a scale model s = 1 and the code
/// path is the one before (bit for bit).
///
/// Departures from the paper: the paper's grip force uses one instant and
/// the Fn-only model (mu = b0 + b2 Fn, whose intercept averages the speed
/// effect over the data's sliding speeds). A held grasp is at v = 0, where
/// eq. (1) gives a lower mu whenever b1 > 0, so the full eq. (1) is used at
/// options.v_mm_s (default 0: at rest; usually an extrapolation below the
/// slowest slipping sample, reported with its uncertainty).
///
/// Uncertainty: fn_n is the plug-in answer; fn_n_sd propagates the
/// coefficient covariance (P_beta, rescaled to the stroke-clustered
/// standard errors when stored) through (*) by the delta method.
///
/// Supported risks: the per-instant slip probability Phi(c) may not be
/// below EpsTimeModel::min_instant_risk (one effectively independent sample
/// in the data); the smallest supported risk of a hold is the hold's
/// crossing probability at that level (CalcMinSupportedRisk). A smaller
/// risk is refused (status kUnsupportedRisk, naming it), never clamped.
///
/// Usage (also the client library's local evaluation):
/// @code
///   GripForceOptions o;
///   o.hold_s = 3.0;                       // held 3 s, at rest
///   GripForce g = CalcGripForce(model, /*load_n=*/2.0, /*risk=*/0.01, o);
///   if (g.status == GripForceStatus::kOk) command(g.fn_n);
///   else if (g.status == GripForceStatus::kUnsupportedRisk)
///     /* g.min_supported_risk */;
/// @endcode

#include <string>
#include <vector>

#include "frictiond/estimators/eps_time.h"
#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {

/// The grasp's state and duration. Defaults: one instant, at rest.
struct GripForceOptions {
  /// Seconds the grasp is held; 0 = one instant. Must be in [0, 3600].
  double hold_s = 0.0;
  /// Sliding speed of the grasp [mm/s]; 0 = at rest. Must be >= 0.
  double v_mm_s = 0.0;

  /// True when usable; otherwise *why names the field, value and rule.
  bool IsValid(std::string* why) const;
};

/// Outcome of CalcGripForce.
enum class GripForceStatus {
  kOk,               ///< fn_n holds the load at the risk
  kUnattainable,     ///< no normal force holds the load at that risk
  kUnsupportedRisk,  ///< risk below min_supported_risk (the data's limit)
  kNoTimeModel,      ///< hold_s > 0 but the model has no eps time model
};

/// Grip force for a risk level.
struct GripForce {
  GripForceStatus status = GripForceStatus::kUnattainable;
  bool attainable = false;    ///< status == kOk
  std::string why;            ///< reason when not kOk
  double fn_n = 0.0;          ///< smallest Fn with P(slip during hold) <= risk
  double fn_n_sd = 0.0;       ///< its standard deviation (coefficient cov.)
  double mu_used = 0.0;       ///< load_n / fn_n: the mu the hold relies on
  double instant_risk = 0.0;  ///< per-instant slip probability at fn_n
  int hold_samples = 1;       ///< samples of the hold (1 + hold_s / dt_s)
  /// Smallest risk the data support for this hold (0 when unknown).
  double min_supported_risk = 0.0;
  bool extrapolated = false;  ///< fn_n or v_mm_s outside the fitted range
};

/// Smallest Fn with P(slip at any time during options.hold_s) <= risk
/// (see the file comment).
/// @throws std::invalid_argument for load_n <= 0 or not finite, risk outside
/// (0, 1), or invalid options.
GripForce CalcGripForce(const StochasticFrictionModel& model,
                        double load_n,
                        double risk,
                        const GripForceOptions& options = {});

/// Smallest risk CalcGripForce answers for a hold of hold_s seconds; 0 when
/// the model has no valid time model and hold_s = 0 (then only the stored
/// quantile levels bound it: EpsQuantileLevels().front()).
/// @throws std::invalid_argument for hold_s outside [0, 3600].
double CalcMinSupportedRisk(const StochasticFrictionModel& model,
                            double hold_s);

/// P(slip at any time during the hold) when holding load_n at fn_n: the
/// forward model of CalcGripForce, so that
///   CalcHoldSlipProbability(m, CalcGripForce(m, L, r, o).fn_n, L, o) = r
/// (for checks, for simulators, and the slip-likelihood route when it is
/// given the grasp's state: v_mm_s or hold_s). load_n = 0 answers 0: a
/// grasp that holds no load has nothing to slip from.
/// @throws std::invalid_argument for load_n < 0 or not finite, fn_n <= 0
/// or not finite, invalid options, or hold_s > 0 on a model without an eps
/// time model (the message names hold_s).
double CalcHoldSlipProbability(const StochasticFrictionModel& model,
                               double fn_n,
                               double load_n,
                               const GripForceOptions& options = {});

/// Quantile of eps at probability p in (0, 1): the stored empirical
/// quantiles (CalcEpsQuantile) above the lowest level (0.001); below it the
/// generalised Pareto tail of `tail` (EpsTimeModel::tail_xi, tail_scale)
/// anchored at the 0.001 quantile, or, without a fitted tail, an
/// exponential tail through the 0.001 and 0.01 quantiles.
double CalcEpsQuantileExtended(const RegressionModel& model,
                               double p,
                               const EpsTimeModel& tail);
/// The same without a fitted tail (exponential below 0.001).
double CalcEpsQuantileExtended(const RegressionModel& model, double p);
/// The rule of CalcEpsQuantileExtended on any quantile set `q` at
/// EpsQuantileLevels() (q.size() must equal theirs) with its tail
/// (tail_xi, tail_scale; tail_scale 0: exponential below 0.001); serves
/// the offset decomposition's stored distributions too (eps_time.h).
double CalcStoredQuantileExtended(const std::vector<double>& q,
                                  double tail_xi,
                                  double tail_scale,
                                  double p);
/// The CDF matching CalcStoredQuantileExtended.
double CalcStoredCdfExtended(const std::vector<double>& q,
                             double tail_xi,
                             double tail_scale,
                             double x);
/// The CDF of eps matching CalcEpsQuantileExtended (its inverse).
double CalcEpsCdfExtended(const RegressionModel& model,
                          double e,
                          const EpsTimeModel& tail);

}  // namespace frictiond
