// Joint friction in MuJoCo (issue 21 item 2, docs/mujoco.md): identified
// actuator friction laws applied as joint torques, checked against the
// project's actuator simulator (SimulateActuatorLog) on the measured
// XL330 logs (data/bam_xl330, PROVENANCE.md) with the same commanded input.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/mujoco/actuator_replay.h"
#include "frictiond/mujoco/friction_adapter.h"
#include "frictiond/mujoco/joint_friction.h"
#include "frictiond/proto/actuator_json.h"

namespace frictiond::mujoco {
namespace {

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string DataDir() {
  const char* root = std::getenv("FRICTIOND_SOURCE_DIR");
  if (!root) throw std::runtime_error("FRICTIOND_SOURCE_DIR is not set");
  return std::string(root) + "/data/";
}

std::vector<ActuatorLog> Logs() {
  std::vector<ActuatorLog> logs;
  for (const char* kp : {"100", "200", "400", "800"}) {
    for (const char* traj : {"sin_sin", "lift_and_drop", "sin_time_square"}) {
      const std::string name = std::string("xl330_kp") + kp + "_" + traj;
      logs.push_back(ParseActuatorLog(
          ReadText(DataDir() + "bam_xl330/logs/" + name + ".json"), name));
    }
  }
  return logs;
}

// The project's identified model (data/actuator, issue 20) without its
// gearbox play, which the MuJoCo replay does not model.
ActuatorModel Identified() {
  const nlohmann::json j = nlohmann::json::parse(
      ReadText(DataDir() + "actuator/xl330_pendulum.model.json"));
  ActuatorModel m = ActuatorModelFromJson(j.at("model"));
  m.backlash_rad = 0.0;
  return m;
}

struct Comparison {
  double rms_sim = 0;      // RMS(q_actuator_sim - q_measured)
  double rms_mujoco = 0;   // RMS(q_mujoco - q_measured)
  double rms_between = 0;  // RMS(q_mujoco - q_actuator_sim)
  double mae_sim = 0, mae_mujoco = 0;
};

Comparison Compare(const ActuatorModel& model,
                   const std::vector<ActuatorLog>& logs) {
  Comparison c;
  double s_sim = 0, s_mj = 0, s_between = 0;
  std::size_t n = 0;
  for (const ActuatorLog& log : logs) {
    ActuatorRolloutTrace trace;
    c.mae_sim += SimulateActuatorLog(model, log, &trace) * log.size();
    const ActuatorReplay r = ReplayActuatorLog(model, log);
    c.mae_mujoco += r.mae_rad * log.size();
    const std::size_t k = log.size();
    s_sim += std::pow(CalcRmsDifference(trace.q_rad, log.q_rad), 2) * k;
    s_mj += std::pow(CalcRmsDifference(r.q_rad, log.q_rad), 2) * k;
    s_between += std::pow(CalcRmsDifference(r.q_rad, trace.q_rad), 2) * k;
    n += k;
  }
  c.rms_sim = std::sqrt(s_sim / n);
  c.rms_mujoco = std::sqrt(s_mj / n);
  c.rms_between = std::sqrt(s_between / n);
  c.mae_sim /= n;
  c.mae_mujoco /= n;
  return c;
}

TEST(JointFriction, MujocoRolloutMatchesTheActuatorSimulatorOnMeasuredLogs) {
  const std::vector<ActuatorLog> logs = Logs();
  ASSERT_EQ(logs.size(), 12u);
  struct Case {
    const char* name;
    ActuatorModel model;
  };
  std::vector<Case> cases = {
      {"identified extended (no backlash)", Identified()}};
  for (const char* bam : {"m1", "m2", "m6"})
    cases.push_back(
        {bam,
         ParseBamParams(ReadText(DataDir() + "bam_xl330/published_params/" +
                                 bam + ".json"))});
  for (const Case& c : cases) {
    const Comparison r = Compare(c.model, logs);
    std::printf(
        "%-34s RMS vs measured: actuator_sim %.5f rad, MuJoCo %.5f rad, "
        "ratio %.4f; MAE %.5f / %.5f; RMS MuJoCo - actuator_sim %.2e rad\n",
        c.name,
        r.rms_sim,
        r.rms_mujoco,
        r.rms_mujoco / r.rms_sim,
        r.mae_sim,
        r.mae_mujoco,
        r.rms_between);
    // Same equations, same integrator: equal to rounding.
    EXPECT_NEAR(r.rms_mujoco / r.rms_sim, 1.0, 1e-4) << c.name;
    EXPECT_LT(r.rms_between, 1e-6) << c.name;
  }
  // A do-nothing adapter fails: without joint friction the MuJoCo rollout
  // is much worse than the identified model.
  ActuatorModel none = Identified();
  none.law = ActuatorFrictionLaw::kCoulombViscous;
  none.friction.friction_base = 0.0;
  none.friction.friction_viscous = 0.0;
  const Comparison with = Compare(Identified(), logs);
  const Comparison without = Compare(none, logs);
  std::printf("no joint friction: RMS vs measured %.5f rad (%.2fx)\n",
              without.rms_mujoco,
              without.rms_mujoco / with.rms_mujoco);
  EXPECT_GT(without.rms_mujoco, 1.5 * with.rms_mujoco);
  // For reference: the identified model with its gearbox play, in
  // actuator_sim only (the MuJoCo replay has none).
  ActuatorModel play = Identified();
  play.backlash_rad =
      nlohmann::json::parse(
          ReadText(DataDir() + "actuator/xl330_pendulum.model.json"))
          .at("model")
          .at("params")
          .at("backlash");
  double s2 = 0;
  std::size_t n = 0;
  for (const ActuatorLog& log : logs) {
    ActuatorRolloutTrace trace;
    SimulateActuatorLog(play, log, &trace);
    s2 += std::pow(CalcRmsDifference(trace.q_rad, log.q_rad), 2) * log.size();
    n += log.size();
  }
  std::printf(
      "identified with backlash %.4f rad, actuator_sim only: RMS "
      "%.5f rad\n",
      play.backlash_rad,
      std::sqrt(s2 / n));
}

TEST(JointFriction, LuGreReplayMatchesTheActuatorSimulator) {
  const std::vector<ActuatorLog> logs = Logs();
  ActuatorModel m = MakeDefaultActuatorModel(ActuatorFrictionLaw::kLuGre);
  const Comparison r = Compare(m, {logs[0], logs[1]});
  std::printf(
      "LuGre default: RMS actuator_sim %.5f, MuJoCo %.5f, between "
      "%.2e rad\n",
      r.rms_sim,
      r.rms_mujoco,
      r.rms_between);
  EXPECT_LT(r.rms_between, 1e-6);
}

constexpr const char* kHinge = R"(<mujoco>
  <option timestep="0.002" integrator="Euler" gravity="0 0 -9.81"/>
  <worldbody>
    <body>
      <joint name="h" type="hinge" axis="0 1 0"/>
      <inertial pos="0.1 0 0" mass="0.5" diaginertia="1e-6 1e-6 1e-6"/>
    </body>
    <body pos="0 0.5 0">
      <joint name="free" type="free"/>
      <geom type="sphere" size="0.01" mass="0.1"/>
    </body>
  </worldbody>
</mujoco>)";

TEST(JointFriction, StaticFrictionHoldsBelowItsBudgetAndSlipsAbove) {
  MjModelPtr m = LoadMjcfText(kHinge);
  // Gravity torque at q = 0: m g x = 0.5 * 9.81 * 0.1 = 0.4905 N m.
  for (double fc : {0.55, 0.45}) {
    mjData* d = mj_makeData(m.get());
    JointFriction jf;
    ActuatorFrictionParams p;
    p.friction_base = fc;
    p.friction_viscous = 0.0;
    jf.TagJoint(m.get(), "h", ActuatorFrictionLaw::kCoulombViscous, p);
    for (int i = 0; i < 500; ++i) {
      mj_step1(m.get(), d);
      mj_fwdActuation(m.get(), d);
      jf.Apply(m.get(), d);
      mj_step2(m.get(), d);
    }
    if (fc > 0.4905) {
      EXPECT_NEAR(d->qpos[0], 0.0, 1e-12) << "held with budget " << fc;
      EXPECT_NEAR(jf.joints()[0].torque_nm, -0.4905, 1e-3);
    } else {
      EXPECT_GT(std::fabs(d->qpos[0]), 0.05) << "slips with budget " << fc;
    }
    mj_deleteData(d);
  }
}

// FrictionAdapter::Step with the joint friction attached gives the same
// rollout as mj_step1 / Apply / mj_step2.
TEST(JointFriction, AdapterStepAppliesIt) {
  MjModelPtr m = LoadMjcfText(kHinge);
  ActuatorFrictionParams p;
  p.friction_base = 0.1;
  p.friction_viscous = 0.05;
  std::vector<double> q;
  {
    mjData* d = mj_makeData(m.get());
    JointFriction jf;
    jf.TagJoint(m.get(), "h", ActuatorFrictionLaw::kCoulombViscous, p);
    for (int i = 0; i < 300; ++i) {
      mj_step1(m.get(), d);
      mj_fwdActuation(m.get(), d);
      jf.Apply(m.get(), d);
      mj_step2(m.get(), d);
      q.push_back(d->qpos[0]);
    }
    mj_deleteData(d);
  }
  mjData* d = mj_makeData(m.get());
  JointFriction jf;
  jf.TagJoint(m.get(), "h", ActuatorFrictionLaw::kCoulombViscous, p);
  FrictionAdapter adapter(AdapterOptions{});
  adapter.SetJointFriction(&jf);
  for (int i = 0; i < 300; ++i) {
    adapter.Step(m.get(), d);
    EXPECT_NEAR(d->qpos[0], q[i], 1e-12) << i;
  }
  EXPECT_GT(std::fabs(q.back()), 0.1);  // it swung: friction did not hold
  mj_deleteData(d);
}

TEST(JointFriction, RefusesBadInput) {
  MjModelPtr m = LoadMjcfText(kHinge);
  JointFriction jf;
  const ActuatorFrictionParams p;
  const auto law = ActuatorFrictionLaw::kCoulombViscous;
  EXPECT_THROW(jf.TagJoint(nullptr, 0, law, p), std::invalid_argument);
  EXPECT_THROW(jf.TagJoint(m.get(), 5, law, p), std::invalid_argument);
  EXPECT_THROW(jf.TagJoint(m.get(), "free", law, p), std::invalid_argument);
  EXPECT_THROW(jf.TagJoint(m.get(), "nope", law, p), std::invalid_argument);
  EXPECT_THROW(jf.SetTemperature(0, 30.0), std::invalid_argument);
  jf.TagJoint(m.get(), "h", law, p);
  EXPECT_THROW(jf.SetTemperature(0, std::nan("")), std::invalid_argument);
  EXPECT_THROW(LoadMjcfText("<mujoco><bad/></mujoco>"), std::invalid_argument);
  const std::vector<ActuatorLog> logs = Logs();
  ActuatorModel with_play = Identified();
  with_play.backlash_rad = 0.01;
  EXPECT_THROW(ReplayActuatorLog(with_play, logs[0]), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond::mujoco
