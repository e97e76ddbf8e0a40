#pragma once
/// @file
/// Break-away friction ratio (BF-ratio) prediction, paper 001 Section III,
/// Step 3 (eqs. 16-20): given identified LuGre parameters and the current
/// drag-ratio rate rho = d(Ft/Fn)/dt, simulate the held object until its
/// velocity jumps; the friction ratio reached there is the BF-ratio. With
/// mu_s > mu_c the BF-ratio falls as rho grows (paper Fig. 2, Table IV);
/// with mu_s < mu_c it rises (paper Section V.B.2, Fig. 17).
///
/// Usage:
/// @code
///   const ForceDrivenResult p = PredictBreakawayRatio(theta, 0.1, 5.0);
///   BreakawayMonitor monitor(theta, BreakawayMonitorOptions());
///   for (...) {
///     const BreakawayEstimate e = monitor.Update(ft_n / fn_n, rho_per_s);
///     if (e.margin < 0.05) { /* grip harder */ }
///   }
/// @endcode

#include <string>

#include "frictiond/estimators/lugre.h"

namespace frictiond {

/// Predicts the BF-ratio for a constant drag-ratio rate (eqs. 16-20) by
/// SimulateForceDriven from rest (v = 0, z = 0, mu_e = options.mu_applied0).
/// bf_ratio is valid when status == SimulationStatus::kOk.
/// @param rho_per_s drag-ratio rate [1/s], finite and > 0.
/// @param fn_n grasping (normal) force [N], finite and > 0.
/// @throws std::invalid_argument for invalid theta, rho, fn_n or options.
ForceDrivenResult PredictBreakawayRatio(
    const LuGreTheta& theta,
    double rho_per_s,
    double fn_n,
    const ForceDrivenOptions& options = ForceDrivenOptions());

/// Options of BreakawayMonitor. Copyable value type.
struct BreakawayMonitorOptions {
  /// Simulation settings of each prediction (mass, tolerances, ...).
  ForceDrivenOptions simulation;
  /// Grasping force [N], finite and > 0.
  double fn_n = 5.0;
  /// Rates below this (including rho <= 0, unloading) are predicted at
  /// this rate [1/s], finite and > 0: the slow-loading BF-ratio, which is
  /// the conservative choice when mu_s > mu_c. Keep
  /// (max BF-ratio) / min_rho_per_s below simulation.t_end_s, or slow
  /// rates end in kNoBreakaway.
  double min_rho_per_s = 0.02;
  /// A new simulation runs only when rho changed by more than this
  /// fraction of the last simulated rho [-], finite and >= 0 (0: always).
  double rho_rel_change = 0.0;

  /// True if all fields satisfy their rules; otherwise *why names the
  /// field, its value and the rule.
  bool IsValid(std::string* why) const;
};

/// What the monitor says about one sample.
struct BreakawayEstimate {
  SimulationStatus status = SimulationStatus::kOk;  ///< of the prediction
  double bf_ratio = 0.0;    ///< predicted BF-ratio at the current rho [-]
  double mu_applied = 0.0;  ///< current Ft/Fn [-]
  double rho_per_s = 0.0;   ///< rate used for the prediction [1/s]
  /// (bf_ratio - mu_applied) / bf_ratio [-]: 1 with no load, 0 at the
  /// predicted break-away, negative beyond it. NaN if status != kOk.
  double margin = 0.0;
  /// mu_applied >= bf_ratio (paper Section V.B.1: the necessary condition
  /// for slip).
  bool slip_predicted = false;
};

/// Online slip monitor (paper 001 Fig. 14): feed one (Ft/Fn, rho) sample per
/// control tick; each returns the BF-ratio predicted for the current rate
/// and the margin to it. Not thread-safe; copyable and movable.
class BreakawayMonitor {
 public:
  /// @throws std::invalid_argument for invalid theta or options.
  explicit BreakawayMonitor(
      const LuGreTheta& theta,
      const BreakawayMonitorOptions& options = BreakawayMonitorOptions());

  /// Processes one sample: mu_applied = Ft/Fn [-] (finite), rho_per_s =
  /// d(Ft/Fn)/dt [1/s] (finite). @throws std::invalid_argument otherwise.
  BreakawayEstimate Update(double mu_applied, double rho_per_s);

  /// The last estimate (default-constructed before the first Update).
  const BreakawayEstimate& last() const { return last_; }
  /// Number of simulations run so far.
  int simulations() const { return simulations_; }

 private:
  LuGreTheta theta_;
  BreakawayMonitorOptions options_;
  BreakawayEstimate last_;
  double last_rho_ = 0.0;
  double last_bf_ = 0.0;
  SimulationStatus last_status_ = SimulationStatus::kOk;
  int simulations_ = 0;
};

}  // namespace frictiond
