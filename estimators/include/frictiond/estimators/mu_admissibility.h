#pragma once
/// @file
/// The one rule for serving a friction coefficient: mu = |Ft| / Fn is a
/// ratio of magnitudes, so it is never below 0.
///
/// Eq. (1) of paper 000, mu = b0 + b1 v + b2 Fn + eps, is linear: where its
/// terms carry a trend past where it holds, its mean or its quantiles go
/// below 0. The bundled microtribometer trace is the example: b1 = 4.3 per
/// mm/s is fitted on the reversal ramp (docs/diagnosis.md, "Real data"), so
/// mu(v = 0) = -0.635, and the mean is below 0 for v < 0.148 mm/s although
/// that lies inside the box of fitted speeds (0.10-0.26 mm/s: few samples
/// below 0.2). Departure from the paper: the paper states no such bound; a
/// service that hands a simulator or a controller mu < 0 hands it a force
/// that pushes the motion along.
///
/// The rule, applied before a coefficient is served (predict, target-force,
/// export, pairs, slip-likelihood at a grasp state: CalcServedHoldSlip;
/// grip-force already refuses a quantile <= 0):
/// - a mean mu that is not finite or below 0: the model is not valid at
///   these inputs. CheckServableMu says so and names the input that moved
///   it there: of the inputs given, the one whose move to its fitted mean
///   raises mu the most, or first one whose move makes the answer finite
///   (a transport answers 422 with that field).
/// - a quantile or interval bound below 0 while the mean is >= 0: it is 0
///   (the distribution of a non-negative quantity: where the model puts
///   P(mu <= 0) >= p, the quantile at p is 0), and the answer says it was
///   floored.
///
/// @code
///   const InputValues x = {{"fn_n", 5.0}, {"v_mm_s", 0.1}};
///   MuPrediction p = PredictMu(model, x);
///   const MeanMuCheck c = CheckServableMu(model, x, p);
///   if (!c.admissible) { /* c.field == "v_mm_s", c.why: the reason */ }
///   const bool floored = FloorAtZero(&p);  // lo95, hi95 >= 0
/// @endcode

#include <limits>
#include <string>

#include "frictiond/estimators/contact_friction.h"
#include "frictiond/estimators/control.h"
#include "frictiond/estimators/grip_force.h"
#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {

/// CheckServableMu's answer.
struct MeanMuCheck {
  bool admissible = true;
  /// The given input that moved the answer out (empty when admissible, or
  /// when no given input is the reason, e.g. a negative intercept alone).
  std::string field;
  std::string why;  ///< the reason, for a user (empty when admissible)
};

/// Whether PredictMu's answer `p` at `inputs` may be served: its mean is
/// >= 0, and mean, sigma and interval are finite (terms can overflow for
/// huge inputs).
MeanMuCheck CheckServableMu(const StochasticFrictionModel& model,
                            const InputValues& inputs,
                            const MuPrediction& p);
/// The same for CalcMuDistribution's answer (mean, sigma and quantiles).
MeanMuCheck CheckServableMu(const StochasticFrictionModel& model,
                            const InputValues& inputs,
                            const MuDistribution& d);
/// The same for eq. (3)'s answer (CalcTargetTangentialForce: mu, Ft and
/// its interval); `inputs` are the ones it was given (fn_n, v_mm_s and the
/// covariates).
MeanMuCheck CheckServableMu(const StochasticFrictionModel& model,
                            const InputValues& inputs,
                            const TargetForce& f);

/// Floors the interval of `p` at 0; true when a bound was below 0.
bool FloorAtZero(MuPrediction* p);
/// Floors the quantiles of `d` at 0; true when one was below 0.
bool FloorAtZero(MuDistribution* d);
/// Floors the interval of `f` (Ft = mu Fn) at 0; true when a bound was
/// below 0.
bool FloorAtZero(TargetForce* f);

/// CalcHoldSlipProbability as it is served: the one rule behind the
/// slip-likelihood route given a grasp state (v_mm_s or hold_s) and
/// `friction slip --v-mm-s/--hold-s`. The mean mu at (fn_n, v_mm_s) must be
/// servable first (CheckServableMu, as for predict and grip-force at the
/// same state); only then is the probability computed.
struct ServedHoldSlip {
  /// {fn_n, v_mm_s}: the inputs `at` and `check` are of.
  InputValues inputs;
  /// PredictMu at `inputs`: the extrapolation flags of the answer.
  MuPrediction at;
  /// CheckServableMu of `at`; when not admissible, `probability` is NaN.
  MeanMuCheck check;
  /// CalcHoldSlipProbability(model, fn_n, load_n, options).
  double probability = std::numeric_limits<double>::quiet_NaN();
};
/// @throws std::invalid_argument as CalcHoldSlipProbability does, once the
/// mean is servable (e.g. hold_s > 0 on a model without a time model).
ServedHoldSlip CalcServedHoldSlip(const StochasticFrictionModel& model,
                                  double fn_n,
                                  double load_n,
                                  const GripForceOptions& options = {});

}  // namespace frictiond
