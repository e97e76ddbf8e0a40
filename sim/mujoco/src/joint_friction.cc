#include "frictiond/mujoco/joint_friction.h"

#include <cmath>
#include <stdexcept>

namespace frictiond::mujoco {

void JointFriction::TagJoint(const mjModel* m,
                             int joint,
                             ActuatorFrictionLaw law,
                             const ActuatorFrictionParams& params) {
  if (!m) throw std::invalid_argument("m: no MuJoCo model");
  if (joint < 0 || joint >= m->njnt)
    throw std::invalid_argument("joint: id " + std::to_string(joint) +
                                " (must be in [0, " + std::to_string(m->njnt) +
                                "))");
  const int type = m->jnt_type[joint];
  if (type != mjJNT_HINGE && type != mjJNT_SLIDE)
    throw std::invalid_argument("joint: id " + std::to_string(joint) +
                                " is not a hinge or slide joint");
  TaggedJoint t;
  t.joint = joint;
  t.dof = m->jnt_dofadr[joint];
  t.law = law;
  t.params = params;
  for (TaggedJoint& j : joints_) {
    if (j.joint == joint) {
      j = t;
      return;
    }
  }
  joints_.push_back(t);
}

void JointFriction::TagJoint(const mjModel* m,
                             const std::string& name,
                             ActuatorFrictionLaw law,
                             const ActuatorFrictionParams& params) {
  if (!m) throw std::invalid_argument("m: no MuJoCo model");
  const int id = mj_name2id(m, mjOBJ_JOINT, name.c_str());
  if (id < 0)
    throw std::invalid_argument("joint: no joint named '" + name + "'");
  TagJoint(m, id, law, params);
}

void JointFriction::SetTemperature(int joint, double temp_c) {
  if (!std::isfinite(temp_c))
    throw std::invalid_argument("temp_c: must be finite");
  for (TaggedJoint& j : joints_) {
    if (j.joint == joint) {
      j.temp_c = temp_c;
      return;
    }
  }
  throw std::invalid_argument("joint: id " + std::to_string(joint) +
                              " is not tagged");
}

void JointFriction::Reset() {
  for (TaggedJoint& j : joints_) {
    j.lugre_z_rad = 0.0;
    j.torque_nm = 0.0;
    j.motor_torque_nm = 0.0;
    j.external_torque_nm = 0.0;
  }
}

void JointFriction::Apply(const mjModel* m, mjData* d) {
  const double dt = m->opt.timestep;
  for (TaggedJoint& j : joints_) {
    const int v = j.dof;
    const double dq = d->qvel[v];
    const double tau_m = d->qfrc_actuator[v];
    const double tau_e = d->qfrc_passive[v] - d->qfrc_bias[v];
    double tau_f = 0.0;
    if (j.law == ActuatorFrictionLaw::kLuGre) {
      // Paper 001 eqs. 1-3 in torque form, one step at constant speed.
      tau_f = CalcLuGreJointTorque(j.params, dq, dt, &j.lugre_z_rad);
    } else {
      // Budget law applied as in actuator_sim.h: the stopping torque with
      // the joint's diagonal inertia, clipped to the budget.
      const ActuatorFrictionBudget b = CalcActuatorFrictionBudget(
          j.law, j.params, {dq, tau_m, tau_e, j.temp_c});
      const double inertia = d->qM[m->dof_Madr[v]];
      tau_f = CalcBudgetFrictionTorque(b, inertia, dt, dq, tau_m + tau_e);
    }
    if (!std::isfinite(tau_f)) tau_f = 0.0;
    d->qfrc_applied[v] = tau_f;
    j.torque_nm = tau_f;
    j.motor_torque_nm = tau_m;
    j.external_torque_nm = tau_e;
  }
}

}  // namespace frictiond::mujoco
