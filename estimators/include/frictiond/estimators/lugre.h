#pragma once
/// @file
/// LuGre friction model in friction-ratio form and its simulators (paper 001,
/// Song et al., "Efficient break-away friction ratio and slip prediction based
/// on haptic surface exploration", IEEE T-RO 2013, Section II and eqs. 1-4,
/// 8-9, 16-20; standard equations from Canudas de Wit et al. 1995).
///
/// Model (friction-ratio form: every force is divided by the normal force Fn):
///
///     g(v)   = mu_c + (mu_s - mu_c) * exp(-(v / v0)^2)           (eq. 2 / Fn)
///     dz/dt  = v - sigma0 * |v| * z / g(v)                       (eq. 1, 8)
///     mu_f   = sigma0 * z + sigma1 * dz/dt + sigma2 * v          (eq. 3, 9)
///     mu_ss  = sign(v) * g(v) + sigma2 * v  (steady state, dz/dt = 0, eq. 4)
///
/// Units: v in mm/s, z in mm, t in s, sigma0 in 1/mm, sigma1 and sigma2 in
/// s/mm, mu dimensionless. The paper's force-form coefficients (N/mm, Ns/mm)
/// are these times Fn. mu_f > 0 is friction opposing a motion with v > 0.
///
/// Usage:
/// @code
///   const LuGreTheta theta = MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1);
///   const VelocityDrivenResult r = SimulateVelocityDriven(theta, t_s, v_mm_s,
///   0.0); if (r.status != SimulationStatus::kOk) { /* r.why */ }
/// @endcode

#include <string>
#include <vector>

#include <Eigen/Core>

namespace frictiond {

/// LuGre parameters theta = [mu_s, mu_c, v0, sigma2, sigma0, sigma1]:
/// static ratio [-], Coulomb ratio [-], Stribeck velocity [mm/s], viscous
/// coefficient [s/mm], bristle stiffness [1/mm], bristle damping [s/mm].
using LuGreTheta = Eigen::Matrix<double, 6, 1>;
/// Covariance of LuGreTheta (units are products of the entries' units).
using LuGreThetaCov = Eigen::Matrix<double, 6, 6>;
/// Row Jacobian of a scalar with respect to theta.
using LuGreThetaRow = Eigen::Matrix<double, 1, 6>;

/// Indices into LuGreTheta.
struct LuGreIndex {
  static constexpr int kMuStatic = 0;          ///< mu_s [-]
  static constexpr int kMuCoulomb = 1;         ///< mu_c [-]
  static constexpr int kStribeckVelocity = 2;  ///< v0 [mm/s]
  static constexpr int kViscous = 3;           ///< sigma2 [s/mm]
  static constexpr int kStiffness = 4;         ///< sigma0 [1/mm]
  static constexpr int kDamping = 5;           ///< sigma1 [s/mm]
};

/// Builds theta from named values (units as in LuGreTheta). No validation.
LuGreTheta MakeLuGreTheta(double mu_s,
                          double mu_c,
                          double v0_mm_s,
                          double sigma2_s_mm,
                          double sigma0_per_mm,
                          double sigma1_s_mm);

/// True if theta is usable: all finite, mu_s > 0, mu_c > 0, v0 > 0,
/// sigma0 > 0, sigma1 >= 0 (sigma2 may be negative, as in paper 001 Table
/// III). Otherwise false and *why (if given) names the field, value and rule.
bool IsValidLuGreTheta(const LuGreTheta& theta, std::string* why = nullptr);

/// @throws std::invalid_argument with the IsValidLuGreTheta message.
void ValidateLuGreTheta(const LuGreTheta& theta);

/// Stribeck curve g(v) = mu_c + (mu_s - mu_c) exp(-(v/v0)^2) (eq. 2 divided
/// by Fn) [-]. Even in v. Optional J_g_theta (only the first three entries
/// are non-zero) and J_g_v [1/(mm/s)].
double CalcStribeckRatio(const LuGreTheta& theta,
                         double v_mm_s,
                         LuGreThetaRow* J_g_theta = nullptr,
                         double* J_g_v = nullptr);

/// Steady-state (quasi-static) friction ratio mu_ss = sign(v) g(v) +
/// sigma2 v (eq. 4 divided by Fn) [-]; sign(0) = 0. Optional J_mu_theta.
double CalcSteadyStateFrictionRatio(const LuGreTheta& theta,
                                    double v_mm_s,
                                    LuGreThetaRow* J_mu_theta = nullptr);

/// Bristle rate dz/dt = v - sigma0 |v| z / g(v) (eq. 1 / eq. 8) [mm/s] at
/// velocity v [mm/s] and bristle deflection z [mm]. Optional Jacobians
/// J_zdot_z [1/s], J_zdot_theta, J_zdot_v [-].
double CalcBristleRate(const LuGreTheta& theta,
                       double v_mm_s,
                       double z_mm,
                       double* J_zdot_z = nullptr,
                       LuGreThetaRow* J_zdot_theta = nullptr,
                       double* J_zdot_v = nullptr);

/// Friction ratio mu_f = sigma0 z + sigma1 dz/dt + sigma2 v (eq. 3 / eq. 9)
/// [-]. Optional Jacobians J_mu_z [1/mm], J_mu_theta, J_mu_v [s/mm].
double CalcFrictionRatio(const LuGreTheta& theta,
                         double v_mm_s,
                         double z_mm,
                         double* J_mu_z = nullptr,
                         LuGreThetaRow* J_mu_theta = nullptr,
                         double* J_mu_v = nullptr);

/// One step of the bristle dynamics over dt with the velocity held at
/// v_mid (exact solution of eq. 1 for constant v, used instead of the
/// paper's forward Euler eq. 10, which is unstable once sigma0 |v| dt / g > 2):
///
///     a = sigma0 |v| / g(v),  z_ss = sign(v) g(v) / sigma0,
///     z(t + dt) = z_ss + (z - z_ss) exp(-a dt)
///
/// Returns z(t + dt) [mm]. Optional J_z1_z [-] and J_z1_theta.
/// Precondition: theta valid, dt_s >= 0.
double CalcBristleStep(const LuGreTheta& theta,
                       double v_mid_mm_s,
                       double dt_s,
                       double z_mm,
                       double* J_z1_z = nullptr,
                       LuGreThetaRow* J_z1_theta = nullptr);

/// Gain c in the tie sigma1 = c * sqrt(sigma0) [s/mm^(1/2)] for a contact
/// carrying a mass m [kg] at normal force Fn [N] with damping ratio zeta.
/// From m x'' + Fn (sigma0 x + sigma1 x') = 0 (x in mm, forces in N, the
/// 1000 converts mm to m): omega^2 = 1000 Fn sigma0 / m and
/// sigma1 = 2 zeta sqrt(m sigma0 / (1000 Fn)). Paper 001 (Section III, after
/// eq. 10) uses sigma1 = sqrt(sigma0) in N/m, Ns/m, i.e. 0.0316 sqrt(sigma0)
/// in N/mm, Ns/mm: that is zeta = 0.5 and m = 1 kg here.
/// @throws std::invalid_argument if any argument is not > 0.
double CalcDampingGain(double mass_kg, double fn_n, double damping_ratio);

/// Outcome of a simulation.
enum class SimulationStatus {
  kOk,            ///< reached the end (or, force-driven, the break-away)
  kStepTooSmall,  ///< step control asked for a step below min_step_s
  kMaxSteps,      ///< max_steps accepted + rejected steps used up
  kNonFinite,     ///< the state became NaN or infinite
  kNoBreakaway,   ///< force-driven: t_end_s reached without break-away
};

/// Returns a short name ("ok", "step_too_small", ...).
const char* ToString(SimulationStatus status);

/// Options of the adaptive Dormand-Prince 4(5) integrator used by
/// SimulateVelocityDriven. Copyable value type.
struct VelocityDrivenOptions {
  /// Relative error tolerance per step [-], > 0.
  double rel_tol = 1e-8;
  /// Absolute error tolerance on z [mm], > 0.
  double abs_tol_mm = 1e-11;
  /// Largest step [s], > 0. Steps also end on every sample time.
  double max_step_s = 0.01;
  /// Smallest step [s], > 0 and <= max_step_s; below it: kStepTooSmall.
  double min_step_s = 1e-12;
  /// Accepted + rejected steps before kMaxSteps, > 0.
  int max_steps = 10000000;

  /// True if all fields satisfy their rules; otherwise *why names the
  /// field, its value and the rule.
  bool IsValid(std::string* why) const;
};

/// Result of SimulateVelocityDriven. mu and z_mm have one entry per sample
/// (valid up to the failure point when status != kOk; the rest is NaN).
struct VelocityDrivenResult {
  SimulationStatus status = SimulationStatus::kOk;
  Eigen::VectorXd mu;    ///< friction ratio at the sample times [-]
  Eigen::VectorXd z_mm;  ///< bristle deflection at the sample times [mm]
  int steps = 0;         ///< accepted steps
  int rejected_steps = 0;
  std::string why;  ///< empty when kOk
};

/// Velocity-driven simulation (mode a): v(t) is given at sample times t_s
/// (strictly increasing) and linearly interpolated between them; eq. 1 is
/// integrated with an embedded Dormand-Prince 4(5) pair with step control
/// from z(t_s[0]) = z0_mm, and eq. 3 gives mu at every sample.
/// The sliding phase is stiff (rate sigma0 |v| / g up to 1e3/s); step
/// control keeps the explicit method stable there.
/// @throws std::invalid_argument for invalid theta, options, sizes, or a
/// non-increasing or non-finite t_s / v_mm_s.
VelocityDrivenResult SimulateVelocityDriven(
    const LuGreTheta& theta,
    const Eigen::Ref<const Eigen::VectorXd>& t_s,
    const Eigen::Ref<const Eigen::VectorXd>& v_mm_s,
    double z0_mm,
    const VelocityDrivenOptions& options = VelocityDrivenOptions());

/// Options of the force-driven (break-away) simulation, paper 001 eqs.
/// 16-20 and Table II. Copyable value type.
struct ForceDrivenOptions {
  /// Mass of the object carried by the contact [kg], > 0 (Table I: 0.2).
  double mass_kg = 0.2;
  /// Applied drag ratio at t = 0 [-] (Table II: G/Fn), finite, >= 0.
  double mu_applied0 = 0.0;
  /// Sliding velocity of the object at t = 0 [mm/s], finite (Table II: 0).
  double initial_v_mm_s = 0.0;
  /// Bristle deflection at t = 0 [mm], finite (Table II: 0). To start from
  /// a measured held state use CalcHeldBristleDeflection (breakaway.h).
  double initial_z_mm = 0.0;
  /// Give up (kNoBreakaway) at this time [s], > 0 (Table II: 50).
  double t_end_s = 50.0;
  /// Break-away is declared when v exceeds factor * v0, > 0.
  double breakaway_speed_factor = 2.0;
  /// Relative tolerance [-], > 0 (Table II: 1e-3).
  double rel_tol = 1e-3;
  /// Absolute tolerance on v [mm/s] and z [mm], > 0 (Table II: 1e-6).
  double abs_tol = 1e-6;
  /// Step bounds [s], 0 < min_step_s <= max_step_s.
  double min_step_s = 1e-10;
  double max_step_s = 0.5;
  /// Accepted + rejected steps before kMaxSteps, > 0.
  int max_steps = 200000;

  /// True if all fields satisfy their rules; otherwise *why names the
  /// field, its value and the rule.
  bool IsValid(std::string* why) const;
};

/// One accepted step of a force-driven trajectory.
struct ForceDrivenSample {
  double t_s;         ///< time [s]
  double mu_applied;  ///< applied drag ratio mu_e = mu_applied0 + rho t [-]
  double mu;          ///< friction ratio of the contact (eq. 9) [-]
  double v_mm_s;      ///< sliding velocity of the object [mm/s]
  double z_mm;        ///< bristle deflection [mm]
};

/// Result of SimulateForceDriven / PredictBreakawayRatio.
struct ForceDrivenResult {
  SimulationStatus status = SimulationStatus::kOk;
  /// Break-away friction ratio: the largest friction ratio mu_f reached up
  /// to the velocity jump [-]. NaN unless status == kOk.
  double bf_ratio = 0.0;
  /// Time of the velocity jump [s] (or where the simulation stopped).
  double t_breakaway_s = 0.0;
  /// Applied drag ratio at the velocity jump [-].
  double mu_applied = 0.0;
  int steps = 0;  ///< accepted steps
  int rejected_steps = 0;
  std::string why;  ///< empty when kOk
};

/// Force-driven simulation (mode b, paper 001 eqs. 16-20): an object of
/// mass m held by the contact at normal force fn_n is pulled with applied
/// drag ratio mu_e(t) = mu_applied0 + rho t (eq. 16); its velocity obeys
/// m dv/dt = Fn (mu_e - mu_f) (eqs. 17, 19) and z obeys eq. 1 (eq. 20),
/// from v = initial_v_mm_s, z = initial_z_mm (Table II: both 0). The stick
/// phase is stiff (contact frequency sqrt(1000 Fn sigma0 / m) ~ 1e3 rad/s
/// against a ramp of seconds), so this uses the linearly implicit Rosenbrock
/// 2(3) pair of Shampine & Reichelt (MATLAB ode23s) with step control instead
/// of the paper's ode45; that is what keeps one prediction in the tens of
/// microseconds. Break-away: v > breakaway_speed_factor * v0; bf_ratio = max
/// mu_f so far.
/// @param rho_per_s drag-ratio rate rho [1/s], finite and > 0.
/// @param fn_n normal force [N], > 0.
/// @param trajectory if not null, receives every accepted step.
/// @throws std::invalid_argument for invalid theta, rho, fn_n or options.
ForceDrivenResult SimulateForceDriven(
    const LuGreTheta& theta,
    double rho_per_s,
    double fn_n,
    const ForceDrivenOptions& options = ForceDrivenOptions(),
    std::vector<ForceDrivenSample>* trajectory = nullptr);

}  // namespace frictiond
