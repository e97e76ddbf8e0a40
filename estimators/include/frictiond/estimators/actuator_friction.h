#pragma once
/// @file
/// Joint friction laws of a geared servo (issue 20), as small pure functions
/// that a simulator (ours in actuator_sim.h, or MuJoCo through a joint
/// torque, issue 21) evaluates once per step.
///
/// Every law except LuGre is a *friction budget* (Rhoban BAM's formulation,
/// arXiv 2410.08650, Section III): the law gives the largest torque friction
/// can deliver at this state, tau_fm = frictionloss + damping |dq|, and the
/// simulator applies the torque that would stop the joint within the step,
/// clipped to that budget:
///
///     tau_stop = (I / dt) dq + tau_motor + tau_external
///     tau_f    = -sign(tau_stop) min(|tau_stop|, tau_fm)
///
/// so a joint at rest stays at rest while the net torque is inside the
/// budget (static friction holds), and friction never reverses the motion
/// within one step. The budget of the BAM family (M1..M6) is
///
///     s(dq)  = exp(-|dq / dtheta_stribeck|^alpha)            (Stribeck)
///     g      = |l_e tau_e - l_m tau_m|   (directional)
///            = l |tau_e - tau_m|         (load-dependent, one coefficient)
///     g_s    = |l_es tau_e - l_ms tau_m| (directional, Stribeck part)
///            = l_s |tau_e - tau_m|
///     q      = [sign tau_e != sign tau_m] (|tau_e| < |tau_m| ? q_e tau_e^2
///                                                         : q_m tau_m^2)
///     frictionloss = f_c + g + s (f_s + g_s + q)
///     damping      = f_v
///
/// with tau_m the motor torque (motor driving) and tau_e the external
/// (gravity) torque (the load back-driving the gearbox). Our extended law
/// (kExtended) adds to M5 a Coulomb term that changes linearly with the
/// motor temperature (f_c (1 + c_T (T - 30 C))).
///
/// Paper 002's mixed lubrication (kMixedLubrication) replaces the constant
/// f_c by a load and speed dependent one: the gearbox contact carries the
/// normal load N = (n_0 + n_l |tau_e - tau_m|) / r, the sliding speed is
/// V = r |dq| (r = kMixedContactRadiusMm), the Sommerfeld number is
/// S = eta(T) V / p (Vogel viscosity at the motor temperature) and
///
///     frictionloss = r N f(S),  f(S) = alpha f_s + (1 - alpha) f_l (eq. 1)
///
/// with f_s = 1 (the scale sits in n_0, n_l) and f_l = mixed_fluid_ratio.
/// Departure from paper 002: the contact geometry (radius, area, surface)
/// is fixed, not measured; only the film law and the load enter the fit.
///
/// LuGre (paper 001, eqs. 1-3, in torque form with v = dq in rad/s):
///
///     g(v)   = f_c + f_s exp(-(v / dtheta_stribeck)^2)
///     dz/dt  = v - sigma0 |v| z / g(v)
///     tau_f  = -(sigma0 z + sigma1 dz/dt + f_v v)
///
/// is a state law: CalcLuGreJointTorque advances z and returns the torque.
/// The simulator integrates it with sub-steps (stiff bristles).

#include <string>

#include "frictiond/estimators/field_error.h"

namespace frictiond {

/// Friction laws; the BAM family shares CalcActuatorFrictionBudget.
enum class ActuatorFrictionLaw {
  kCoulombViscous,    ///< BAM M1: f_c, f_v
  kStribeck,          ///< BAM M2: + f_s, dtheta_stribeck, alpha
  kLoadDependent,     ///< BAM M4: Stribeck + l, l_s on |tau_e - tau_m|
  kDirectional,       ///< BAM M5: Stribeck + l_e, l_m, l_es, l_ms
  kBamM6,             ///< BAM M6: M5 + quadratic q_e, q_m
  kLuGre,             ///< paper 001 LuGre in torque form (state z)
  kMixedLubrication,  ///< paper 002 mixed lubrication f(S(dq, load, T))
  kExtended,          ///< ours: M5 + temperature-dependent Coulomb
};

/// Name used in files and on the command line ("coulomb_viscous",
/// "stribeck", "load_dependent", "directional", "m6", "lugre", "mixed",
/// "extended").
std::string ActuatorFrictionLawName(ActuatorFrictionLaw law);
/// Inverse of ActuatorFrictionLawName.
/// @throws FieldError naming the unknown law.
ActuatorFrictionLaw ParseActuatorFrictionLaw(const std::string& name);

/// Contact radius of the mixed-lubrication law [mm] (sliding speed and
/// normal load from joint speed and torque).
constexpr double kMixedContactRadiusMm = 5.0;
/// Reference temperature of the extended law's Coulomb slope [C].
constexpr double kFrictionRefTempC = 30.0;

/// Parameters of all laws (names as BAM's parameter files where shared);
/// a law reads only its own. Torques in N m, speeds in rad/s. Copyable.
struct ActuatorFrictionParams {
  double friction_base = 0.01;                ///< f_c [N m]
  double friction_viscous = 0.01;             ///< f_v [N m s/rad]
  double friction_stribeck = 0.0;             ///< f_s [N m]
  double dtheta_stribeck = 0.5;               ///< Stribeck speed [rad/s], > 0
  double alpha = 2.0;                         ///< Stribeck exponent [-], > 0
  double load_friction_base = 0.0;            ///< l [-] (M4)
  double load_friction_stribeck = 0.0;        ///< l_s [-] (M4)
  double load_friction_motor = 0.0;           ///< l_m [-] (M5, M6)
  double load_friction_external = 0.0;        ///< l_e [-]
  double load_friction_motor_stribeck = 0.0;  ///< l_ms [-]
  double load_friction_external_stribeck = 0.0;  ///< l_es [-]
  double load_friction_motor_quad = 0.0;         ///< q_m [1/(N m)] (M6)
  double load_friction_external_quad = 0.0;      ///< q_e [1/(N m)]
  double friction_temp_coeff = 0.0;              ///< c_T [1/C] (kExtended)
  double lugre_sigma0 = 200.0;     ///< bristle stiffness [N m/rad]
  double lugre_sigma1 = 0.1;       ///< bristle damping [N m s/rad]
  double mixed_load_base = 0.01;   ///< n_0 [N m] (kMixedLubrication)
  double mixed_load_gain = 0.1;    ///< n_l [-]
  double mixed_fluid_ratio = 0.2;  ///< f_l / f_s [-], in [0, 1]
  double mixed_film_ref_um = 0.5;  ///< d_ref [um] of the film law
  double mixed_film_power = 0.6;   ///< n of the film law, (0, 3]
};

/// State of the joint that a friction law may read.
struct ActuatorFrictionInput {
  double dq_rad_s = 0;            ///< joint speed [rad/s]
  double motor_torque_nm = 0;     ///< tau_m, torque of the motor [N m]
  double external_torque_nm = 0;  ///< tau_e, gravity/load torque [N m]
  double temp_c = 30;             ///< motor temperature [C]
};

/// Friction budget tau_fm = frictionloss + damping |dq| (see the file
/// comment); frictionloss >= 0 and damping >= 0 for valid parameters.
struct ActuatorFrictionBudget {
  double frictionloss_nm = 0;             ///< speed-independent part [N m]
  double damping_nm_s_rad = 0;            ///< viscous part [N m s/rad]
  double TotalNm(double dq_rad_s) const;  ///< frictionloss + damping |dq|
};

/// Friction budget of a budget law at a state (file comment equations).
/// Pure, no allocation; about 10-40 ns. For kLuGre it returns the LuGre
/// steady state g(|dq|) and f_v (used by diagnosis, not by the simulator).
ActuatorFrictionBudget CalcActuatorFrictionBudget(
    ActuatorFrictionLaw law,
    const ActuatorFrictionParams& params,
    const ActuatorFrictionInput& input);

/// Applies a budget the way the simulator does: the torque that stops the
/// joint within dt, tau_stop = (inertia / dt) dq + tau_net, clipped to the
/// budget [N m] (negative of tau_stop's sign).
double CalcBudgetFrictionTorque(const ActuatorFrictionBudget& budget,
                                double inertia_kg_m2,
                                double dt_s,
                                double dq_rad_s,
                                double net_torque_nm);

/// LuGre joint torque (paper 001 eqs. 1-3, torque form): advances the
/// bristle state *z_rad over dt_s at constant speed dq (exact solution of
/// the linear-in-z ODE, stable for any step) and returns the friction
/// torque tau_f [N m] (opposing the motion).
double CalcLuGreJointTorque(const ActuatorFrictionParams& params,
                            double dq_rad_s,
                            double dt_s,
                            double* z_rad);

}  // namespace frictiond
