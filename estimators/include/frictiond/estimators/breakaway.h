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

/// Bristle deflection [mm] of a contact that carries the measured drag ratio
/// mu_applied = Ft/Fn at sliding velocity v_mm_s without the object
/// accelerating relative to the fingers (eq. 17 with dv/dt = 0 gives
/// mu_f = mu_e). From eq. 9 with eq. 8 for dz/dt:
///
///     mu_e = sigma0 z + sigma1 (v - sigma0 |v| z / g(v)) + sigma2 v
///     z    = (mu_e - (sigma1 + sigma2) v) / (sigma0 (1 - sigma1 |v| / g(v)))
///
/// and z = mu_e / sigma0 for a held object (v = 0). The deflection is not
/// measured; this is the state the measured force implies.
/// @throws std::invalid_argument for invalid theta, non-finite mu_applied or
/// v_mm_s, sigma1 |v| >= g(v) (no such equilibrium), or a deflection with
/// sigma0 |z| > max(mu_s, mu_c) (beyond LuGre's bound on z: held, a
/// mu_applied above mu_s has broken away already).
double CalcHeldBristleDeflection(const LuGreTheta& theta,
                                 double mu_applied,
                                 double v_mm_s);

/// BF-ratio predicted from the measured state (paper 001 eq. 16: the drag
/// ratio continues from its measured value, mu_e(t) = mu_e(t0) + rho
/// (t - t0)): SimulateForceDriven from mu_applied0 = mu_applied (the
/// measured Ft/Fn), v = v_mm_s (the measured slip velocity, 0 when held) and
/// z = CalcHeldBristleDeflection(theta, mu_applied, v_mm_s); those fields of
/// `options` are overridden. t_breakaway_s counts from t0.
/// Departure from Table II, which starts at z = 0 with x1 = G/Fn: a contact
/// already carrying a load has deflected bristles; releasing them at once
/// jolts the object and predicts an early break-away (breakaway_test.cc).
/// @throws std::invalid_argument as SimulateForceDriven and
/// CalcHeldBristleDeflection, or for mu_applied < 0.
ForceDrivenResult PredictBreakawayRatioFromState(
    const LuGreTheta& theta,
    double mu_applied,
    double v_mm_s,
    double rho_per_s,
    double fn_n,
    const ForceDrivenOptions& options = ForceDrivenOptions());

/// Standard gravity [m/s^2] used by the lift case.
constexpr double kGravityM_S2 = 9.80665;

/// Acceleration-driven case (paper 001 Section II.B, Figs. 2a and 3): the
/// hand holds an object of mass options.mass_kg at normal force fn_n and
/// lifts it with acceleration a(t) = accel0_m_s2 + jerk_m_s3 t. In the hand's
/// frame the object is pulled down by m (g + a) and held by Fn mu_f, so its
/// slip velocity obeys m dv/dt = m (g + a) - Fn mu_f: the drag case (eqs.
/// 17-20) with mu_e(t) = m (g + a(t)) / Fn, i.e. mu_e(0) = m (g + accel0) /
/// Fn and rho = m jerk / Fn ("the second case is equivalent to the first").
/// Starts from the held state (v = 0, z = CalcHeldBristleDeflection at
/// mu_e(0)), not from Table II's z = 0. fn_n is the normal force of the
/// contact(s) carrying the object (two fingers sharing the load equally:
/// their sum). bf_ratio is the BF-ratio; t_breakaway_s the time from the
/// start of the lift.
/// @param jerk_m_s3 acceleration rate [m/s^3], finite and > 0.
/// @param accel0_m_s2 hand acceleration at t = 0 [m/s^2], finite, with
/// g + accel0 >= 0.
/// @throws std::invalid_argument for invalid arguments or options.
ForceDrivenResult PredictLiftBreakawayRatio(
    const LuGreTheta& theta,
    double jerk_m_s3,
    double fn_n,
    const ForceDrivenOptions& options = ForceDrivenOptions(),
    double accel0_m_s2 = 0.0);

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
  /// Ignored when from_measured_state is set.
  double rho_rel_change = 0.0;
  /// Predict from the measured state (PredictBreakawayRatioFromState, eq.
  /// 16): every Update simulates from the sample's Ft/Fn and slip velocity.
  /// Otherwise every prediction starts from rest (v = 0, z = 0,
  /// simulation.mu_applied0) and depends only on rho.
  bool from_measured_state = false;

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
  /// Predicted time to the break-away at the current rho [s]: from this
  /// sample with from_measured_state, else from rest. NaN if status != kOk.
  double t_breakaway_s = 0.0;
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
  /// d(Ft/Fn)/dt [1/s] (finite), v_mm_s = measured slip velocity [mm/s]
  /// (finite; used with from_measured_state).
  /// @throws std::invalid_argument otherwise, or (from_measured_state) for
  /// mu_applied < 0.
  BreakawayEstimate Update(double mu_applied,
                           double rho_per_s,
                           double v_mm_s = 0.0);

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
  double last_t_breakaway_s_ = 0.0;
  SimulationStatus last_status_ = SimulationStatus::kOk;
  int simulations_ = 0;
};

}  // namespace frictiond
