#include "frictiond/proto/joint_json.h"

#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

using nlohmann::json;

constexpr double kPi = 3.14159265358979323846;

std::string ThrowMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no throw)";
}

TEST(JointJson, FamilyRoundTrips) {
  JointFamily f;
  f.config.surface.salt_um = 0.2;
  f.config.contact.area_mm2 = 80;
  f.wear.k_solid = 3e-6;
  f.mixed.kind = JointModelKind::kMixed;
  f.mixed.status = JointFitStatus::kConverged;
  f.mixed.theta = Eigen::Vector4d(0.1, 0.004, 0.5, 0.6);
  f.mixed.P_theta = Eigen::Matrix4d::Identity() * 1e-6;
  f.mixed.P_theta(0, 1) = f.mixed.P_theta(1, 0) = 2e-7;
  f.stribeck.kind = JointModelKind::kStribeckViscous;
  f.stribeck.status = JointFitStatus::kNotObservable;
  f.stribeck.theta = Eigen::VectorXd::Constant(5, 0.5);
  f.stribeck.P_theta = Eigen::MatrixXd::Zero(5, 5);
  f.stribeck.why = "rank deficient";
  f.lugre.kind = JointModelKind::kLuGreSteadyState;
  f.lugre.status = JointFitStatus::kMaxIterations;
  f.lugre.theta = Eigen::Vector4d(0.2, 0.1, 3, 0);
  f.lugre.P_theta = Eigen::MatrixXd::Zero(4, 4);
  for (JointModelKind k : {JointModelKind::kMixed,
                           JointModelKind::kStribeckViscous,
                           JointModelKind::kLuGreSteadyState}) {
    JointModelScore s;
    s.kind = k;
    s.heldout_rmse = 0.01 + static_cast<int>(k);
    f.scores.push_back(s);
  }
  f.samples = 123;
  f.s_min_um = 1e-4;
  f.s_max_um = 0.2;
  const json j = JointFamilyToJson(f);
  const JointFamily g = JointFamilyFromJson(json::parse(j.dump()));
  EXPECT_EQ(g.config.surface.salt_um, 0.2);
  EXPECT_EQ(g.config.contact.area_mm2, 80);
  EXPECT_EQ(g.wear.k_solid, 3e-6);
  EXPECT_EQ(g.mixed.status, JointFitStatus::kConverged);
  EXPECT_TRUE(g.mixed.theta.isApprox(f.mixed.theta));
  EXPECT_TRUE(g.mixed.P_theta.isApprox(f.mixed.P_theta));
  EXPECT_EQ(g.stribeck.status, JointFitStatus::kNotObservable);
  EXPECT_EQ(g.stribeck.why, "rank deficient");
  EXPECT_EQ(g.lugre.status, JointFitStatus::kMaxIterations);
  ASSERT_EQ(g.scores.size(), 3u);
  EXPECT_DOUBLE_EQ(g.scores[2].heldout_rmse, 2.01);
  EXPECT_EQ(g.samples, 123u);
  EXPECT_EQ(g.s_max_um, 0.2);
  json bad = j;
  bad["models"]["mixed"]["status"] = "great";
  EXPECT_EQ(ThrowMessage([&] { JointFamilyFromJson(bad); }),
            "joint.models.mixed.status: 'great' is not a known status");
  bad = j;
  bad["config"]["surface"]["salt_um"] = -1;
  EXPECT_EQ(ThrowMessage([&] { JointFamilyFromJson(bad); }),
            "joint.config.surface.salt_um = -1 (must be > 0)");
}

TEST(JointJson, CsvNamesLineAndColumn) {
  const Lubricant oil;
  const JointData d = ParseJointCsv(
      "# "
      "c\nmu,v_mm_s,load_n,temp_c,extra\n0.1,10,50,40,x\n\n0.05,100,50,60,y\n",
      oil);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d.v_mm_s[1], 100);
  EXPECT_NEAR(d.eta_pa_s[0], CalcViscosity(oil, 40), 1e-15);
  EXPECT_EQ(ThrowMessage([&] {
              ParseJointCsv("v_mm_s,load_n,mu,eta_pa_s\n1,2,0.1,0\n", oil);
            }),
            "line 2: eta_pa_s = 0 (must be > 0)");
  EXPECT_EQ(ThrowMessage([&] {
              ParseJointCsv("v_mm_s,load_n,mu,temp_c\n1,2,0.1\n", oil);
            }),
            "line 2: 3 cells, header has 4");
  EXPECT_EQ(ThrowMessage([&] { ParseJointCsv("v_mm_s,mu,temp_c\n", oil); }),
            "load_n: required column is missing");
  EXPECT_EQ(ThrowMessage([&] {
              ParseJointCsv("v_mm_s,load_n,mu,temp_c\n1,2,0.1,-400\n", oil);
            }),
            "line 2: temp_c = -400 (outside the lubricant's Vogel range)");
}

TEST(JointJson, RobotRoundTripsInDegreesAndNamesBadFields) {
  const json j = json::parse(R"({
    "joints": [
      {"type": "revolute", "alpha_deg": 90, "d_mm": 300, "stiffness": 2e4,
       "sigma_tau": 5, "q_min": -170, "q_max": 170},
      {"type": "prismatic", "stiffness": 100,
       "friction": {"material": "steel", "joint": "j2", "load_n": 50}}
    ],
    "q_home": [45, 10]
  })");
  const RobotDescription r = RobotFromJson(j);
  ASSERT_EQ(r.arm.joints.size(), 2u);
  EXPECT_NEAR(r.arm.joints[0].alpha_rad, kPi / 2, 1e-15);
  EXPECT_NEAR(r.arm.joints[0].q_max, 170 * kPi / 180, 1e-15);
  EXPECT_NEAR(r.q_home[0], kPi / 4, 1e-15);
  EXPECT_EQ(r.q_home[1], 10);
  ASSERT_TRUE(r.friction[1].has_value());
  EXPECT_EQ(r.friction[1]->load_n, 50);
  const RobotDescription back = RobotFromJson(RobotToJson(r));
  EXPECT_NEAR(back.q_home[0], r.q_home[0], 1e-15);
  EXPECT_EQ(back.friction[1]->joint, "j2");
  json bad = j;
  bad["joints"][0].erase("stiffness");
  EXPECT_EQ(ThrowMessage([&] { RobotFromJson(bad); }),
            "joints[0].stiffness: is missing");
  bad = j;
  bad["joints"][1]["sigma_tau"] = 1;
  EXPECT_EQ(ThrowMessage([&] { RobotFromJson(bad); }),
            "joints[1].sigma_tau: give exactly one of sigma_tau and friction");
  bad = j;
  bad["joints"][1]["friction"]["radius_mm"] = 0;
  EXPECT_EQ(ThrowMessage([&] { RobotFromJson(bad); }),
            "joints[1].friction.radius_mm = 0 (must be > 0)");
  bad = j;
  bad["q_home"] = {1};
  EXPECT_EQ(ThrowMessage([&] { RobotFromJson(bad); }),
            "q_home: must be an array of 2 numbers");
}

}  // namespace
}  // namespace frictiond
