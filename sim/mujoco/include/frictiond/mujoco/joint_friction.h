#pragma once
/// @file
/// Identified joint friction in MuJoCo 2.2 (issue 21 item 2,
/// docs/mujoco.md): each tagged hinge or slide joint gets, every step, the
/// friction torque of an actuator friction law (estimators/actuator_friction.h,
/// identified from actuator logs by FitActuatorModel) as a joint torque in
/// d->qfrc_applied.
///
/// The budget laws (BAM M1..M6, mixed lubrication, extended) are applied as
/// the project's actuator simulator applies them (actuator_sim.h): the torque
/// that would stop the joint within the step, clipped to the law's budget,
///
///     tau_stop = (M_jj / dt) dq + tau_net
///     tau_f    = -sign(tau_stop) min(|tau_stop|, frictionloss + damping |dq|)
///
/// with M_jj the joint's diagonal of the joint-space inertia (d->qM),
/// tau_net = qfrc_actuator + qfrc_passive - qfrc_bias (motor, springs and
/// dampers, gravity and Coriolis), the motor torque tau_m = qfrc_actuator
/// and the external torque tau_e = qfrc_passive - qfrc_bias. LuGre
/// (paper 001 eqs. 1-3) advances the bristle state z of each joint once per
/// step (CalcLuGreJointTorque, exact for constant speed).
///
/// Limits / departures from actuator_sim.h:
///  - M_jj is the diagonal element: exact for one joint, an approximation
///    when joints are coupled (the stop torque then ignores the coupling);
///  - constraint forces (joint limits, contacts, equality) are not in
///    tau_net: friction may fail to hold a joint pushed by a contact;
///  - LuGre is advanced once per MuJoCo step (actuator_sim: 10 sub-steps);
///  - no backlash (actuator_sim's two-body gearbox play): model it with a
///    second body if needed.
///
/// Usage, between mj_step1 and mj_step2 (or through
/// FrictionAdapter::SetJointFriction, which calls it inside Step):
/// @code
///   JointFriction jf;
///   jf.TagJoint(m, "shoulder", model.law, model.friction);
///   mj_step1(m, d);
///   d->ctrl[0] = ...;           // the controller
///   mj_fwdActuation(m, d);      // qfrc_actuator for this step
///   jf.Apply(m, d);             // writes qfrc_applied of tagged joints
///   mj_step2(m, d);
/// @endcode

#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "frictiond/estimators/actuator_friction.h"

namespace frictiond::mujoco {

/// One tagged joint and its state. Copyable.
struct TaggedJoint {
  int joint = -1;  ///< MuJoCo joint id (hinge or slide)
  int dof = -1;    ///< its degree of freedom (m->jnt_dofadr)
  ActuatorFrictionLaw law = ActuatorFrictionLaw::kCoulombViscous;
  ActuatorFrictionParams params;
  double temp_c = 30.0;          ///< motor temperature the law reads [C]
  double lugre_z_rad = 0.0;      ///< LuGre bristle state
  double torque_nm = 0.0;        ///< friction torque written at the last Apply
  double motor_torque_nm = 0.0;  ///< tau_m seen at the last Apply
  double external_torque_nm = 0.0;  ///< tau_e seen at the last Apply
};

/// Joint friction from identified actuator laws. Copyable and movable; holds
/// no pointer to the model or data between calls.
class JointFriction {
 public:
  /// Tags joint `joint` (id) with a law. Re-tagging replaces the law.
  /// @throws std::invalid_argument for a null model, an id out of range or
  /// a joint that is not a hinge or slide.
  void TagJoint(const mjModel* m,
                int joint,
                ActuatorFrictionLaw law,
                const ActuatorFrictionParams& params);
  /// The same by joint name. @throws std::invalid_argument for an unknown
  /// name (naming it).
  void TagJoint(const mjModel* m,
                const std::string& name,
                ActuatorFrictionLaw law,
                const ActuatorFrictionParams& params);

  /// Sets the motor temperature a tagged joint's law reads [C].
  /// @throws std::invalid_argument for an untagged joint or a non-finite
  /// temperature.
  void SetTemperature(int joint, double temp_c);

  /// Computes each tagged joint's friction torque from the current state
  /// and writes it to d->qfrc_applied[dof] (the adapter owns those entries).
  /// Preconditions: the position and velocity stages and mj_fwdActuation
  /// ran for this state (mj_step1 + mj_fwdActuation); m->opt.timestep > 0.
  void Apply(const mjModel* m, mjData* d);

  /// Clears the LuGre states and last torques (start of a new episode).
  void Reset();

  /// The tagged joints, in tagging order.
  const std::vector<TaggedJoint>& joints() const { return joints_; }

 private:
  std::vector<TaggedJoint> joints_;
};

}  // namespace frictiond::mujoco
