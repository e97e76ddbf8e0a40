#pragma once
/// @file
/// Closed-loop simulation of a position-controlled servo swinging a
/// pendulum, and the identification of its motor constants and joint
/// friction from measured logs (issue 20; data: data/bam_xl330, whose
/// PROVENANCE.md describes the rig).
///
/// Model, per step k (dt from the log):
///
///     duty  = clip(kp g_e s_g (goal_k - q), -1, 1)  (controller; s_g = gain
///                                                   scale, 1 = upstream's)
///     duty  = clip(duty, (kt dq - R i_max) / vin, (kt dq + R i_max) / vin)
///             when a current limit i_max > 0 is set (the XL330 firmware's
///             1.75 A limit, as later upstream versions model it)
///     V     = vin duty
///     R(T)  = R (1 + c_R (T_k - 30 C))              (copper heating; c_R = 0
///                                                   is upstream's model)
///     tau_m = kt V / R(T) - kt^2 dq / R(T)          (DC motor, back-EMF);
///             0 when the log says torque_enable = false (motor released)
///     tau_e = -m g l sin(q + q_offset)              (pendulum gravity)
///     I     = m l^2 + armature
///     tau_f = friction law (actuator_friction.h): clipped stopping torque
///             for the budget laws (static friction holds the joint when the
///             net torque cannot move it), LuGre with 10 sub-steps
///     dq   += (tau_m + tau_e + tau_f) / I dt;  q += dq dt  (semi-implicit)
///
/// with g_e = (4096 / 2 pi) / (256 * 885) (kXl330ErrorGain). The rollout is
/// closed loop: the controller sees the simulated q; it starts at the log's
/// first position and speed. The error is mean |q_sim - q_measured| over the
/// entries (q_sim taken before each step, as upstream).
///
/// Command delay d >= 0: the controller sees goal(t_k - d), linearly
/// interpolated between entries (goal(t_0) before the log starts).
///
/// Departures from upstream BAM (arXiv 2410.08650): semi-implicit Euler
/// (upstream adds 1/2 a dt^2 to q), optional gain scale,
/// resistance temperature coefficient and backlash (zero by default, which
/// is upstream's model).
///
/// Backlash b (kBacklash > 0): the motor side (inertia = armature) and the
/// output (pendulum, friction) move apart while the gap |q_m - q| < b / 2,
/// and together (inelastic contact) once the gap closes and the motor pushes
/// into it. The encoder reads the output.
///
/// Usage:
/// @code
///   ActuatorModel m =
///   MakeDefaultActuatorModel(ActuatorFrictionLaw::kCoulombViscous); const
///   double mae = SimulateActuatorLog(m, log); const ActuatorFitResult r =
///   FitActuatorModel({&log}, m, ActuatorLawParams(m.law), {});
/// @endcode

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "frictiond/estimators/actuator_friction.h"
#include "frictiond/estimators/field_error.h"

namespace frictiond {

/// Duty per (firmware gain x radian) of the XL330 (PROVENANCE.md):
/// (4096 / 2 pi) / (256 * 885); upstream calls the divisor 256 empirical.
constexpr double kXl330ErrorGain =
    (4096.0 / (2.0 * 3.14159265358979323846)) / (256.0 * 885.0);
/// Gravity [m/s^2].
constexpr double kGravityM_s2 = 9.81;
/// Reference temperature of the resistance law [C].
constexpr double kResistanceRefTempC = 30.0;

/// One measured closed-loop log (format: docs/actuator.md, the JSON of
/// data/bam_xl330/logs). All vectors have the same length >= 2; t strictly
/// increasing. Copyable.
struct ActuatorLog {
  std::string name;                         ///< label (file stem), for reports
  std::string motor;                        ///< e.g. "xl330"
  std::string trajectory;                   ///< e.g. "sin_sin"
  double mass_kg = 0;                       ///< pendulum point mass [kg], > 0
  double length_m = 0;                      ///< pendulum length [m], > 0
  double kp = 0;                            ///< firmware position gain [-], > 0
  double vin_v = 0;                         ///< supply voltage [V], > 0
  double dt_s = 0;                          ///< simulation step [s], > 0
  std::vector<double> t_s;                  ///< timestamps [s]
  std::vector<double> q_rad;                ///< measured position [rad]
  std::vector<double> dq_rad_s;             ///< measured speed [rad/s]
  std::vector<double> goal_rad;             ///< commanded position [rad]
  std::vector<double> temp_c;               ///< motor temperature [C]
  std::vector<std::uint8_t> torque_enable;  ///< 0 = motor released
  std::size_t size() const { return q_rad.size(); }
};

/// Motor constants, rig nuisances and the friction law. Copyable.
struct ActuatorModel {
  ActuatorFrictionLaw law = ActuatorFrictionLaw::kCoulombViscous;
  double kt = 0.3;                 ///< torque constant [N m/A], > 0
  double r_ohm = 4.0;              ///< winding resistance at 30 C [ohm], > 0
  double armature_kg_m2 = 0.0016;  ///< reflected rotor inertia [kg m^2]
  double q_offset_rad = 0.0;       ///< encoder offset in the gravity term [rad]
  double gain_scale = 1.0;         ///< s_g: actual / upstream error gain [-]
  double r_temp_coeff_per_c = 0.0;  ///< c_R [1/C] (copper: 0.0039)
  double backlash_rad = 0.0;        ///< b, total gearbox play [rad], >= 0
  double current_limit_a = 0.0;     ///< firmware current limit [A]; 0 = none
  double command_delay_s = 0.0;     ///< goal seen this late [s] (bus, firmware)
  ActuatorFrictionParams friction;
};

/// A model with BAM-like starting values for `law`.
ActuatorModel MakeDefaultActuatorModel(ActuatorFrictionLaw law);

/// Per-step quantities of one rollout (optional output).
struct ActuatorRolloutTrace {
  std::vector<double> q_rad;               ///< simulated q (before step)
  std::vector<double> dq_rad_s;            ///< simulated dq
  std::vector<double> motor_torque_nm;     ///< tau_m
  std::vector<double> external_torque_nm;  ///< tau_e
  std::vector<double> friction_torque_nm;  ///< tau_f applied
};

/// Closed-loop rollout of `model` on `log`; returns mean |q_sim - q| [rad].
/// Pure; no allocation unless `trace` is given. Preconditions: the log
/// passed validation (ValidateActuatorLog) and the model's constants are
/// positive (kt, r_ohm, armature >= 0 with m l^2 + armature > 0). Returns a
/// large finite penalty (10 rad) when the rollout diverges (non-finite).
double SimulateActuatorLog(const ActuatorModel& model,
                           const ActuatorLog& log,
                           ActuatorRolloutTrace* trace = nullptr);

/// What the controller commands at log entry `k` (the rule every rollout
/// shares: SimulateActuatorLog, sim/mujoco's ReplayActuatorLog).
struct ActuatorCommand {
  double r_ohm = 0;      ///< winding resistance at the entry's temperature
  double duty = 0;       ///< in [-1, 1]; the motor voltage is vin_v * duty
  bool enabled = false;  ///< torque enabled (else the motor is released)
};

/// The controller at entry `k` given the simulated output angle `q_rad` and
/// the motor speed `motor_speed_rad_s` (the current limit centres on its
/// back-EMF): goal delayed by the model's command delay (interpolated),
/// duty = g kp g_e (goal - q), clipped to the current limit and to [-1, 1];
/// r = r_ohm (1 + alpha (T - 30 C)), at least 1e-3 ohm.
ActuatorCommand CalcActuatorCommand(const ActuatorModel& model,
                                    const ActuatorLog& log,
                                    std::size_t k,
                                    double q_rad,
                                    double motor_speed_rad_s);

/// @throws FieldError naming the field, value and rule (header fields > 0,
/// equal lengths >= 2, finite values, strictly increasing t).
void ValidateActuatorLog(const ActuatorLog& log);

/// Every parameter that identification may free.
enum class ActuatorParam {
  kKt,
  kR,
  kArmature,
  kQOffset,
  kGainScale,
  kRTempCoeff,
  kBacklash,
  kCurrentLimit,
  kCommandDelay,
  kFrictionBase,
  kFrictionViscous,
  kFrictionStribeck,
  kDthetaStribeck,
  kAlpha,
  kLoadFrictionBase,
  kLoadFrictionStribeck,
  kLoadFrictionMotor,
  kLoadFrictionExternal,
  kLoadFrictionMotorStribeck,
  kLoadFrictionExternalStribeck,
  kLoadFrictionMotorQuad,
  kLoadFrictionExternalQuad,
  kFrictionTempCoeff,
  kLuGreSigma0,
  kLuGreSigma1,
  kMixedLoadBase,
  kMixedLoadGain,
  kMixedFluidRatio,
  kMixedFilmRef,
  kMixedFilmPower,
  kCount
};

/// Name (as in model files and BAM parameter files where shared) and
/// identification bounds of a parameter.
struct ActuatorParamInfo {
  const char* name;
  double lo;
  double hi;
};
const ActuatorParamInfo& GetActuatorParamInfo(ActuatorParam p);
/// The parameter's field in `model`.
double& ActuatorParamRef(ActuatorModel& model, ActuatorParam p);
double ActuatorParamValue(const ActuatorModel& model, ActuatorParam p);

/// Parameters a law identifies: kt, R, armature, q_offset and the law's own
/// friction parameters.
std::vector<ActuatorParam> ActuatorLawParams(ActuatorFrictionLaw law);

/// Identification options (defaults suit the 12 bundled logs).
struct ActuatorFitOptions {
  int nm_max_evaluations = 2500;  ///< derivative-free (Nelder-Mead) budget
  int nm_restarts = 1;            ///< simplex restarts around the best
  int lm_iterations = 8;          ///< Levenberg-Marquardt polish iterations
  double huber_rad = 1e-3;        ///< LM residual e / sqrt(|e| + delta) ~ L1
  int bootstrap = 0;              ///< log-resampling refits (0 = none)
  std::uint64_t seed = 1;         ///< bootstrap seed
};

/// Outcome of an identification (statuses, not exceptions).
struct ActuatorFitResult {
  bool converged = false;  ///< false: budget exhausted or bad start
  std::string why;         ///< reason when not converged
  ActuatorModel model;     ///< identified model
  double mae_rad = 0;      ///< mean |q_sim - q| over all entries of all logs
  std::vector<ActuatorParam> free;  ///< identified parameters
  std::vector<double> stderr_;      ///< Gauss-Newton standard error per free
                                    ///< parameter (smoothed-L1 residuals,
                                    ///< inflated for autocorrelation)
  std::vector<double> boot_lo, boot_hi;  ///< 5th/95th bootstrap percentiles
  int evaluations = 0;                   ///< rollouts of the whole set
};

/// Mean |q_sim - q| over all entries of `logs`.
double CalcActuatorSetMae(const ActuatorModel& model,
                          const std::vector<const ActuatorLog*>& logs);

/// Identifies the `free` parameters of `start` on `logs` by minimising the
/// closed-loop error: a bounded (logistic-mapped) Nelder-Mead stage on the
/// mean absolute error, then Levenberg-Marquardt on smoothed-L1 residuals
/// with finite-difference Jacobians (accepting only steps that lower the
/// mean absolute error), then standard errors and optional bootstrap.
/// Precondition: logs validated and non-empty; `free` non-empty.
ActuatorFitResult FitActuatorModel(const std::vector<const ActuatorLog*>& logs,
                                   const ActuatorModel& start,
                                   const std::vector<ActuatorParam>& free,
                                   const ActuatorFitOptions& options = {});

/// Phase vs shape of a rollout error: the time shift (|shift| <= max_shift_s)
/// of the simulated trajectory that minimises the MAE; phase = mae -
/// mae_shifted, shape = mae_shifted.
struct PhaseShapeSplit {
  double mae_rad = 0;
  double shift_s = 0;
  double mae_shifted_rad = 0;
};
PhaseShapeSplit CalcPhaseShapeSplit(const std::vector<double>& q_sim,
                                    const ActuatorLog& log,
                                    double max_shift_s = 0.1);

/// Friction torque implied by the measured motion under `model`'s motor and
/// pendulum: tau_f = I ddq - tau_m(q, dq, goal) - tau_e(q), with ddq from
/// the measured speed (central differences, 5-point moving average). One
/// value per entry (0 where the motor state is undefined at the ends).
std::vector<double> CalcMeasuredFrictionTorque(const ActuatorModel& model,
                                               const ActuatorLog& log);

}  // namespace frictiond
