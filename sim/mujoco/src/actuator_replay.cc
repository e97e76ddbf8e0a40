#include "frictiond/mujoco/actuator_replay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "frictiond/mujoco/joint_friction.h"

namespace frictiond::mujoco {
namespace {

constexpr int kLuGreSubsteps = 10;  // as actuator_sim.cc

struct VfsDeleter {
  void operator()(mjVFS* v) const {
    mj_deleteVFS(v);
    delete v;
  }
};

struct DataDeleter {
  void operator()(mjData* d) const { mj_deleteData(d); }
};

std::string Num(double x) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", x);
  return buf;
}

}  // namespace

MjModelPtr LoadMjcfText(const std::string& xml) {
  std::unique_ptr<mjVFS, VfsDeleter> vfs(new mjVFS);
  mj_defaultVFS(vfs.get());
  const char* name = "scene.xml";
  if (mj_makeEmptyFileVFS(vfs.get(), name, static_cast<int>(xml.size())) != 0)
    throw std::invalid_argument("mjcf: cannot stage the text in a VFS");
  const int i = mj_findFileVFS(vfs.get(), name);
  std::memcpy(vfs->filedata[i], xml.data(), xml.size());
  char err[1000] = "";
  mjModel* m = mj_loadXML(name, vfs.get(), err, sizeof(err));
  if (!m) throw std::invalid_argument(std::string("mjcf: ") + err);
  return MjModelPtr(m);
}

std::string MakePendulumMjcf(const ActuatorModel& model,
                             const ActuatorLog& log) {
  const double l = log.length_m;
  const double off = model.q_offset_rad;
  // Rotation by q about y maps the mass at (-l sin(off), 0, -l cos(off)) to
  // x = -l sin(q + off): gravity torque -m g l sin(q + q_offset).
  return R"(<mujoco model="actuator_pendulum">
  <option timestep=")" +
         Num(log.dt_s) + R"(" integrator="Euler" gravity="0 0 )" +
         Num(-kGravityM_s2) + R"("/>
  <worldbody>
    <body name="pendulum">
      <joint name="q" type="hinge" axis="0 1 0" armature=")" +
         Num(model.armature_kg_m2) + R"("/>
      <inertial pos=")" +
         Num(-l * std::sin(off)) + " 0 " + Num(-l * std::cos(off)) +
         R"(" mass=")" + Num(log.mass_kg) +
         R"(" diaginertia="1e-10 1e-10 1e-10"/>
    </body>
  </worldbody>
  <actuator>
    <general name="motor" joint="q" gaintype="fixed" biastype="affine"
             gainprm="1" biasprm="0 0 0"/>
  </actuator>
</mujoco>)";
}

ActuatorReplay ReplayActuatorLog(const ActuatorModel& model,
                                 const ActuatorLog& log) {
  if (model.backlash_rad > 0)
    throw std::invalid_argument(
        "backlash_rad: " + Num(model.backlash_rad) +
        " (the MuJoCo replay has no gearbox play; must be 0)");
  const bool lugre = model.law == ActuatorFrictionLaw::kLuGre;
  const int substeps = lugre ? kLuGreSubsteps : 1;
  MjModelPtr m = LoadMjcfText(MakePendulumMjcf(model, log));
  m->opt.timestep = log.dt_s / substeps;
  std::unique_ptr<mjData, DataDeleter> d(mj_makeData(m.get()));
  const int joint = mj_name2id(m.get(), mjOBJ_JOINT, "q");
  JointFriction friction;
  friction.TagJoint(m.get(), joint, model.law, model.friction);

  const std::size_t n = log.size();
  const double kt = model.kt;
  d->qpos[0] = log.q_rad[0];
  d->qvel[0] = log.dq_rad_s[0];
  ActuatorReplay out;
  out.q_rad.reserve(n);
  out.dq_rad_s.reserve(n);
  out.friction_torque_nm.reserve(n);
  double err = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double q = d->qpos[0];
    out.q_rad.push_back(q);
    err += std::abs(q - log.q_rad[k]);
    // actuator_sim.h's controller on the simulated q.
    const ActuatorCommand command =
        CalcActuatorCommand(model, log, k, q, d->qvel[0]);
    const double r = command.r_ohm;
    const bool enabled = command.enabled;
    const double duty = command.duty;
    // DC motor: tau_m = (kt / R) V - (kt^2 / R) dq, off when released.
    m->actuator_gainprm[0] = enabled ? kt / r : 0.0;
    m->actuator_biasprm[2] = enabled ? -kt * kt / r : 0.0;
    d->ctrl[0] = log.vin_v * duty;
    friction.SetTemperature(joint, log.temp_c[k]);
    double tau_f = 0;
    for (int s = 0; s < substeps; ++s) {
      mj_step1(m.get(), d.get());
      mj_fwdActuation(m.get(), d.get());
      friction.Apply(m.get(), d.get());
      tau_f = friction.joints()[0].torque_nm;
      mj_step2(m.get(), d.get());
    }
    out.dq_rad_s.push_back(d->qvel[0]);
    out.friction_torque_nm.push_back(tau_f);
    if (!std::isfinite(d->qpos[0]) || !std::isfinite(d->qvel[0])) {
      out.q_rad.resize(n, std::nan(""));
      out.mae_rad = 10.0;  // actuator_sim's penalty for a diverged rollout
      return out;
    }
  }
  out.mae_rad = err / static_cast<double>(n);
  return out;
}

double CalcRmsDifference(const std::vector<double>& a,
                         const std::vector<double>& b) {
  const std::size_t n = std::min(a.size(), b.size());
  if (n == 0) return 0.0;
  double s = 0;
  for (std::size_t i = 0; i < n; ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s / static_cast<double>(n));
}

}  // namespace frictiond::mujoco
