#pragma once
/// @file
/// A measured actuator log (data/bam_xl330, docs/actuator.md) replayed in
/// MuJoCo with the joint friction of an identified actuator model
/// (issue 21 item 2, docs/mujoco.md): the same commanded input as the
/// project's actuator simulator (SimulateActuatorLog, actuator_sim.h), so
/// the two rollouts can be compared entry by entry.
///
/// Scene (MakePendulumMjcf): one hinge (axis y) carrying a point mass m at
/// length l, rotated by q_offset so that MuJoCo's gravity torque is
/// -m g l sin(q + q_offset); joint armature = the model's armature; a
/// `general` actuator with gain kt / R(T) and velocity bias -kt^2 / R(T)
/// (the DC motor with back-EMF, R(T) updated every entry from the log's
/// temperature; both zero while torque_enable is false) driven by
/// ctrl = V = vin duty. The controller is actuator_sim.h's, written out
/// here: duty = clip(kp g_e s_g (goal(t - delay) - q), current limit, +-1)
/// on the simulated q. Joint friction: JointFriction (joint_friction.h)
/// with the model's law and the log's temperature. Euler integrator
/// (semi-implicit, as actuator_sim), timestep = the log's dt, or dt / 10
/// with the controller held for LuGre (actuator_sim's sub-steps).
///
/// Departure: backlash is not modelled (a model with backlash_rad > 0 is
/// refused; compare with backlash set to 0 in both simulators).

#include <memory>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "frictiond/estimators/actuator_sim.h"

namespace frictiond::mujoco {

/// Owns an mjModel (deleter mj_deleteModel).
struct MjModelDeleter {
  void operator()(mjModel* m) const { mj_deleteModel(m); }
};
using MjModelPtr = std::unique_ptr<mjModel, MjModelDeleter>;

/// Compiles MJCF text from memory (no file).
/// @throws std::invalid_argument "mjcf: <MuJoCo's error>" when it fails.
MjModelPtr LoadMjcfText(const std::string& xml);

/// The pendulum scene of a log and model (file comment); joint "q",
/// actuator "motor".
std::string MakePendulumMjcf(const ActuatorModel& model,
                             const ActuatorLog& log);

/// One MuJoCo rollout of a log.
struct ActuatorReplay {
  std::vector<double> q_rad;               ///< simulated q before each entry
  std::vector<double> dq_rad_s;            ///< simulated dq after each entry
  std::vector<double> friction_torque_nm;  ///< joint friction applied
  double mae_rad = 0;  ///< mean |q_sim - q_measured| (as SimulateActuatorLog)
};

/// Replays `log` in MuJoCo with `model` (file comment).
/// Preconditions: the log passed ValidateActuatorLog.
/// @throws std::invalid_argument for backlash_rad > 0 or a model MuJoCo
/// refuses (naming the field).
ActuatorReplay ReplayActuatorLog(const ActuatorModel& model,
                                 const ActuatorLog& log);

/// RMS of (a - b) over the common length of two trajectories.
double CalcRmsDifference(const std::vector<double>& a,
                         const std::vector<double>& b);

}  // namespace frictiond::mujoco
