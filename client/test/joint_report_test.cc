#include "frictiond/client/joint_report.h"

#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

using nlohmann::json;

JointFamily Family() {
  JointFamily f;
  f.mixed.kind = JointModelKind::kMixed;
  f.mixed.status = JointFitStatus::kConverged;
  f.mixed.theta = Eigen::Vector4d(0.1, 0.004, 0.5, 0.6);
  f.mixed.P_theta = Eigen::Matrix4d::Identity() * 1e-8;
  f.stribeck.kind = JointModelKind::kStribeckViscous;
  f.stribeck.theta = Eigen::VectorXd::Constant(5, 0.1);
  f.stribeck.P_theta = Eigen::MatrixXd::Zero(5, 5);
  f.lugre.kind = JointModelKind::kLuGreSteadyState;
  f.lugre.theta = Eigen::Vector4d(0.1, 0.05, 10, 0);
  f.lugre.P_theta = Eigen::MatrixXd::Zero(4, 4);
  JointModelScore s;
  s.kind = JointModelKind::kMixed;
  s.heldout_rmse = 0.00226;
  f.scores.push_back(s);
  f.s_min_um = 1e-3;
  f.s_max_um = 0.1;
  return f;
}

int Count(const std::string& s, const std::string& what) {
  int n = 0;
  for (auto p = s.find(what); p != std::string::npos; p = s.find(what, p + 1))
    ++n;
  return n;
}

TEST(JointReport, CurveSpansThePapersRange) {
  const std::string svg = RenderFrictionCurveSvg(Family(), 1e-5, 1.0);
  EXPECT_EQ(Count(svg, "<svg"), 1);
  EXPECT_EQ(Count(svg, "class=\"curve\""), 1);
  EXPECT_EQ(Count(svg, "class=\"band\""), 1);
  EXPECT_EQ(Count(svg, "class=\"span\""), 1);
  // Decade ticks 1e-5 .. 1e0.
  EXPECT_NE(svg.find(">1e-5<"), std::string::npos);
  EXPECT_NE(svg.find(">1e0<"), std::string::npos);
  EXPECT_THROW(RenderFrictionCurveSvg(Family(), 1.0, 1e-5),
               std::invalid_argument);
}

TEST(JointReport, GridCellsAndPage) {
  json grid = {{"n", 2}, {"z_mm", -400}, {"probability", 0.95}};
  grid["points"] = json::array();
  for (int i = 0; i < 4; ++i)
    grid["points"].push_back(
        {{"x_mm", i % 2 * 400.0},
         {"y_mm", i / 2 * 400.0},
         {"reachable", i != 3},
         {"semi_axes_um", i != 3 ? json{1.0, 2.0, 10.0 + i} : json()}});
  const std::string svg = RenderRepeatabilityGridSvg(grid);
  EXPECT_EQ(Count(svg, "<rect"), 4 + 2);  // cells + legend
  EXPECT_NE(svg.find("unreachable"), std::string::npos);
  EXPECT_NE(svg.find("12 um (max)"), std::string::npos);
  EXPECT_NE(svg.find("10 um (min)"), std::string::npos);
  const std::string html =
      RenderJointReportHtml("steel<oil>", "j2", Family(), grid);
  EXPECT_NE(html.find("steel&lt;oil&gt;"), std::string::npos);
  EXPECT_EQ(Count(html, "<svg"), 2);
  EXPECT_NE(html.find("0.00226"), std::string::npos);
  EXPECT_NE(html.find("z = -400.0 mm"), std::string::npos);
  grid["points"].erase(0);
  EXPECT_THROW(RenderRepeatabilityGridSvg(grid), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
