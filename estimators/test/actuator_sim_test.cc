#include "frictiond/estimators/actuator_sim.h"

#include <cmath>
#include <stdexcept>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A synthetic log: goal trajectory `goal(t)`, measured q filled in later.
ActuatorLog MakeLog(double kp, int n, double (*goal)(double), bool enabled) {
  ActuatorLog log;
  log.name = "synthetic";
  log.mass_kg = 0.49;
  log.length_m = 0.1;
  log.kp = kp;
  log.vin_v = 7.4;
  log.dt_s = 0.005;
  for (int k = 0; k < n; ++k) {
    const double t = k * log.dt_s;
    log.t_s.push_back(t);
    log.q_rad.push_back(0.0);
    log.dq_rad_s.push_back(0.0);
    log.goal_rad.push_back(goal(t));
    log.temp_c.push_back(30.0 + 5.0 * k / n);
    log.torque_enable.push_back(enabled ? 1 : 0);
  }
  return log;
}

double SinSin(double t) {
  return 1.2 * std::sin(2 * kPi * 0.4 * t) * std::sin(2 * kPi * 0.13 * t + 0.3);
}
double Zero(double) { return 0.0; }

// Fills log.q with a rollout of `truth` (the planted model).
void Plant(const ActuatorModel& truth, ActuatorLog* log) {
  ActuatorRolloutTrace tr;
  SimulateActuatorLog(truth, *log, &tr);
  log->q_rad = tr.q_rad;
  log->dq_rad_s = tr.dq_rad_s;
  // Entry k's speed is the speed before step k.
  for (std::size_t k = log->size(); k-- > 1;)
    log->dq_rad_s[k] = log->dq_rad_s[k - 1];
  log->dq_rad_s[0] = 0.0;
}

TEST(ActuatorFrictionTest, BudgetsOfTheBamFamily) {
  ActuatorFrictionParams p;
  p.friction_base = 0.01;
  p.friction_viscous = 0.02;
  p.friction_stribeck = 0.005;
  p.dtheta_stribeck = 0.5;
  p.alpha = 2.0;
  p.load_friction_motor = 0.3;
  p.load_friction_external = 0.1;
  const ActuatorFrictionInput in{0.5, 0.2, -0.1, 30};
  EXPECT_DOUBLE_EQ(
      CalcActuatorFrictionBudget(ActuatorFrictionLaw::kCoulombViscous, p, in)
          .frictionloss_nm,
      0.01);
  EXPECT_NEAR(CalcActuatorFrictionBudget(ActuatorFrictionLaw::kStribeck, p, in)
                  .frictionloss_nm,
              0.01 + 0.005 * std::exp(-1.0),
              1e-15);
  // Directional: |l_e tau_e - l_m tau_m| = |-0.01 - 0.06| = 0.07.
  EXPECT_NEAR(
      CalcActuatorFrictionBudget(ActuatorFrictionLaw::kDirectional, p, in)
          .frictionloss_nm,
      0.01 + 0.07 + 0.005 * std::exp(-1.0),
      1e-15);
  EXPECT_DOUBLE_EQ(
      CalcActuatorFrictionBudget(ActuatorFrictionLaw::kCoulombViscous, p, in)
          .TotalNm(-0.5),
      0.01 + 0.02 * 0.5);
  // Mixed lubrication: positive, falls from rest to a lubricated speed.
  const double rest =
      CalcActuatorFrictionBudget(
          ActuatorFrictionLaw::kMixedLubrication, p, {0.0, 0.0, 0.0, 30})
          .frictionloss_nm;
  const double fast =
      CalcActuatorFrictionBudget(
          ActuatorFrictionLaw::kMixedLubrication, p, {50.0, 0.0, 0.0, 30})
          .frictionloss_nm;
  EXPECT_GT(rest, 0.0);
  EXPECT_LT(fast, rest);
}

TEST(ActuatorFrictionTest, StoppingTorqueIsClippedToTheBudget) {
  const ActuatorFrictionBudget b{0.05, 0.0};
  // At rest, a net torque inside the budget is cancelled exactly (stick).
  EXPECT_DOUBLE_EQ(CalcBudgetFrictionTorque(b, 0.01, 0.005, 0.0, 0.03), -0.03);
  // Above it, friction saturates at the budget (slip).
  EXPECT_DOUBLE_EQ(CalcBudgetFrictionTorque(b, 0.01, 0.005, 0.0, 0.08), -0.05);
}

TEST(ActuatorFrictionTest, LuGreReachesItsSteadyState) {
  ActuatorFrictionParams p;
  p.friction_base = 0.01;
  p.friction_stribeck = 0.0;
  p.friction_viscous = 0.0;
  p.lugre_sigma0 = 500;
  p.lugre_sigma1 = 0.0;
  double z = 0;
  double tau = 0;
  for (int i = 0; i < 1000; ++i) tau = CalcLuGreJointTorque(p, 1.0, 1e-3, &z);
  EXPECT_NEAR(tau, -0.01, 1e-9);
}

TEST(ActuatorSimTest, StaticFrictionHoldsAReleasedPendulum) {
  ActuatorLog log = MakeLog(400, 400, Zero, /*enabled=*/false);
  const double q0 = 0.2;  // gravity torque 0.49 * 9.81 * 0.1 * sin 0.2 = 0.095
  for (double& q : log.q_rad) q = q0;
  ActuatorModel m =
      MakeDefaultActuatorModel(ActuatorFrictionLaw::kCoulombViscous);
  m.q_offset_rad = 0.0;
  m.friction.friction_base = 0.1;  // above 0.095: holds
  ActuatorRolloutTrace tr;
  EXPECT_EQ(SimulateActuatorLog(m, log, &tr), 0.0);
  EXPECT_EQ(tr.q_rad.back(), q0);
  m.friction.friction_base = 0.09;  // below: slips, then sticks again
  SimulateActuatorLog(m, log, &tr);
  EXPECT_LT(tr.q_rad.back(), q0 - 0.01);
}

TEST(ActuatorSimTest, FrictionlessSmallSwingHasThePendulumPeriod) {
  ActuatorLog log = MakeLog(400, 2000, Zero, /*enabled=*/false);
  log.q_rad[0] = 0.05;
  ActuatorModel m =
      MakeDefaultActuatorModel(ActuatorFrictionLaw::kCoulombViscous);
  m.q_offset_rad = 0.0;
  m.armature_kg_m2 = 0.0;
  m.friction.friction_base = 0.0;
  m.friction.friction_viscous = 0.0;
  ActuatorRolloutTrace tr;
  SimulateActuatorLog(m, log, &tr);
  // Count downward zero crossings: period 2 pi sqrt(l / g) = 0.634 s.
  std::vector<double> crossings;
  for (std::size_t k = 1; k < tr.q_rad.size(); ++k)
    if (tr.q_rad[k - 1] > 0 && tr.q_rad[k] <= 0)
      crossings.push_back(k * log.dt_s);
  ASSERT_GE(crossings.size(), 10u);
  const double period =
      (crossings.back() - crossings.front()) / (crossings.size() - 1);
  EXPECT_NEAR(period, 2 * kPi * std::sqrt(0.1 / 9.81), 0.01);
}

TEST(ActuatorSimTest, RecoversAPlantedCoulombViscousModel) {
  ActuatorModel truth =
      MakeDefaultActuatorModel(ActuatorFrictionLaw::kCoulombViscous);
  truth.kt = 0.35;
  truth.r_ohm = 3.5;
  truth.armature_kg_m2 = 0.002;
  truth.q_offset_rad = 0.03;
  truth.friction.friction_base = 0.02;
  truth.friction.friction_viscous = 0.015;
  ActuatorLog a = MakeLog(100, 1200, SinSin, true);
  ActuatorLog b = MakeLog(400, 1200, SinSin, true);
  Plant(truth, &a);
  Plant(truth, &b);
  ActuatorModel start = truth;
  start.kt = 0.6;
  start.r_ohm = 6.0;
  start.armature_kg_m2 = 0.004;
  start.q_offset_rad = 0.0;
  start.friction.friction_base = 0.005;
  start.friction.friction_viscous = 0.05;
  ASSERT_GT(CalcActuatorSetMae(start, {&a, &b}), 0.01);
  ActuatorFitOptions o;
  o.nm_max_evaluations = 1500;
  const ActuatorFitResult r =
      FitActuatorModel({&a, &b},
                       start,
                       ActuatorLawParams(ActuatorFrictionLaw::kCoulombViscous),
                       o);
  ASSERT_TRUE(r.converged) << r.why;
  EXPECT_LT(r.mae_rad, 2e-3);
  EXPECT_NEAR(r.model.kt / r.model.r_ohm, 0.1, 0.01);
  EXPECT_NEAR(r.model.q_offset_rad, 0.03, 0.01);
  EXPECT_NEAR(r.model.friction.friction_base, 0.02, 0.006);
  ASSERT_EQ(r.stderr_.size(), r.free.size());
}

TEST(ActuatorSimTest, CommandDelayShiftsTheGoal) {
  ActuatorLog log = MakeLog(400, 600, SinSin, true);
  ActuatorLog shifted = log;
  for (std::size_t k = 0; k < log.size(); ++k)
    shifted.goal_rad[k] = log.goal_rad[k < 2 ? 0 : k - 2];
  ActuatorModel m =
      MakeDefaultActuatorModel(ActuatorFrictionLaw::kCoulombViscous);
  ActuatorRolloutTrace a, b;
  m.command_delay_s = 2 * log.dt_s;
  SimulateActuatorLog(m, log, &a);
  m.command_delay_s = 0;
  SimulateActuatorLog(m, shifted, &b);
  for (std::size_t k = 0; k < log.size(); ++k)
    ASSERT_NEAR(a.q_rad[k], b.q_rad[k], 1e-12) << k;
}

TEST(ActuatorSimTest, PhaseShapeSplitFindsAShift) {
  ActuatorLog log = MakeLog(400, 600, SinSin, true);
  for (std::size_t k = 0; k < log.size(); ++k)
    log.q_rad[k] = SinSin(log.t_s[k]);
  std::vector<double> sim(log.size());
  for (std::size_t k = 0; k < log.size(); ++k)
    sim[k] = SinSin(log.t_s[k] - 0.03);
  const PhaseShapeSplit s = CalcPhaseShapeSplit(sim, log, 0.1);
  EXPECT_NEAR(s.shift_s, 0.03, 1e-9);
  EXPECT_LT(s.mae_shifted_rad, 1e-3 * s.mae_rad + 1e-12);
}

TEST(ActuatorSimTest, ValidationNamesTheField) {
  ActuatorLog log = MakeLog(400, 10, Zero, true);
  log.t_s[4] = log.t_s[3];
  try {
    ValidateActuatorLog(log);
    FAIL() << "accepted a repeated timestamp";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("entries[4].timestamp"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace frictiond
