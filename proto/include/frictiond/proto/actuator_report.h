#pragma once
/// @file
/// Identification recipes, held-out scores and the diagnosis of the
/// actuator simulation (issue 20, docs/actuator.md), as JSON for the CLI
/// and the daemon.
///
/// A *variant* is a friction law plus extra non-friction parameters freed
/// beside it (gain scale, resistance temperature coefficient, backlash,
/// current limit). Fits are staged: the Coulomb-viscous model first, then
/// the variant started from it.

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/actuator_sim.h"

namespace frictiond {

/// A law plus the extra parameters identified with it.
struct ActuatorVariant {
  std::string name;  ///< e.g. "coulomb_viscous+current_limit"
  ActuatorFrictionLaw law = ActuatorFrictionLaw::kCoulombViscous;
  std::vector<ActuatorParam> extra;
  /// false: free only the Coulomb-viscous parameters and `extra` (the law's
  /// other terms stay at their start values, zero from a CV start).
  bool law_free = true;
};

/// The law `--law auto` identifies (the diagnosed, extended model).
extern const ActuatorFrictionLaw kAutoActuatorLaw;
/// The full variant behind `auto` (law and extras).
ActuatorVariant AutoActuatorVariant();
/// The variant of a plain law (no extras).
ActuatorVariant LawVariant(ActuatorFrictionLaw law);

/// Staged identification of `variant` on `logs` (Coulomb-viscous first,
/// unless `warm` gives a start).
ActuatorFitResult FitActuatorVariant(
    const std::vector<const ActuatorLog*>& logs,
    const ActuatorVariant& variant,
    const ActuatorFitOptions& options = {},
    const ActuatorModel* warm = nullptr);
/// FitActuatorVariant of LawVariant(law), or of AutoActuatorVariant() when
/// law == kAutoActuatorLaw.
ActuatorFitResult FitActuatorLaw(const std::vector<ActuatorLog>& logs,
                                 ActuatorFrictionLaw law,
                                 const ActuatorFitOptions& options = {});

/// Held-out MAE per log: for each group g, fit on the logs outside g (warm
/// started from `warm` when given) and roll out on the logs of g.
/// `group[i]` is log i's group (leave-one-log-out: 0..n-1).
std::vector<double> CalcHeldOutMae(const std::vector<ActuatorLog>& logs,
                                   const ActuatorVariant& variant,
                                   const std::vector<int>& group,
                                   const ActuatorFitOptions& options,
                                   const ActuatorModel* warm = nullptr);

/// {"model": model JSON, "mae_rad", "converged", "why", "evaluations",
///  "params": [{"name", "value", "stderr", "boot_lo", "boot_hi"}]}.
nlohmann::json ActuatorFitToJson(const ActuatorFitResult& fit);

/// Diagnosis of the Coulomb-viscous simulation on `logs` (>= 3 logs), in
/// the shape of CONTRACT's `friction diagnose`: {"baseline": {"model",
/// "cv_mae"}, "findings": [{"cause", "kind", "p_value", "cv_mae_gain_pct",
/// "effect", "summary"}], "extended": {"model", "cv_mae", "gain_pct"},
/// "departures": [...per log...]}. cv_mae is the leave-one-log-out MAE
/// [rad]; p_value a paired sign-flip permutation test over the folds
/// (kind "cause") or a slope test of the residual friction torque (kind
/// "covariate", autocorrelation-inflated).
/// @throws std::invalid_argument when fewer than 3 logs are given.
nlohmann::json DiagnoseActuatorLogs(const std::vector<ActuatorLog>& logs);

}  // namespace frictiond
