#include "frictiond/estimators/repeatability.h"

#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "jacobian_tester.h"

namespace frictiond {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr double kPi = 3.14159265358979323846;

std::string ThrowMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no throw)";
}

// Paper 002's robot: three prismatic axes x, y, z (a Cartesian gantry).
SerialArm Cartesian() {
  SerialArm arm;
  DhJoint x, y, z;
  x.type = y.type = z.type = JointType::kPrismatic;
  x.alpha_rad = -kPi / 2;  // z0 -> z1 along y
  x.theta_rad = -kPi / 2;
  y.alpha_rad = -kPi / 2;
  y.theta_rad = -kPi / 2;
  x.stiffness = 100.0;  // N/mm
  y.stiffness = 200.0;
  z.stiffness = 400.0;
  x.sigma_tau = 2.0;  // N
  y.sigma_tau = 3.0;
  z.sigma_tau = 4.0;
  arm.joints = {x, y, z};
  return arm;
}

// An anthropomorphic (PUMA-like) 3R arm, lengths in mm.
SerialArm Spatial3R() {
  SerialArm arm;
  DhJoint j1, j2, j3;
  j1.alpha_rad = kPi / 2;
  j1.d_mm = 300;
  j2.a_mm = 400;
  j3.a_mm = 350;
  for (DhJoint* j : {&j1, &j2, &j3}) {
    j->stiffness = 2e4;  // N m/rad
    j->sigma_tau = 5.0;  // N m
  }
  arm.joints = {j1, j2, j3};
  return arm;
}

TEST(Repeatability, JacobianMatchesForwardKinematics) {
  for (const SerialArm& arm : {Cartesian(), Spatial3R()}) {
    const VectorXd q = Eigen::Vector3d(0.3, -0.7, 1.1);
    auto f = [&](const VectorXd& x) {
      return VectorXd(CalcEndEffectorPosition(arm, x));
    };
    EXPECT_TRUE(internal::CheckJacobian<double>(
        f, q, MatrixXd(CalcPositionJacobian(arm, q))));
  }
}

TEST(Repeatability, CartesianRobotHasAxisAlignedEllipsoid) {
  const SerialArm arm = Cartesian();
  const VectorXd q = Eigen::Vector3d(100, 50, 20);
  const Eigen::Vector3d x = CalcEndEffectorPosition(arm, q);
  // The gantry moves one axis per joint (up to sign and order).
  EXPECT_NEAR(std::abs(x[0]) + std::abs(x[1]) + std::abs(x[2]), 170, 1e-9);
  const Eigen::Matrix3d P = CalcPositionCovariance(arm, q);
  Eigen::Vector3d ev =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(P).eigenvalues();
  // sd = sigma / k: 0.02, 0.015, 0.01 mm.
  EXPECT_NEAR(ev[0], 1e-4, 1e-15);
  EXPECT_NEAR(ev[1], 2.25e-4, 1e-15);
  EXPECT_NEAR(ev[2], 4e-4, 1e-15);
  const Ellipsoid e = CalcRepeatabilityEllipsoid(arm, q, 0.95);
  EXPECT_EQ(e.rank, 3);
  EXPECT_NEAR(e.semi_axes_mm[2], std::sqrt(7.814727903 * 4e-4), 1e-9);
}

TEST(Repeatability, ChiSquareQuantilesMatchTables) {
  EXPECT_NEAR(CalcChiSquareQuantile(1, 0.95), 3.841458821, 1e-8);
  EXPECT_NEAR(CalcChiSquareQuantile(2, 0.95), 5.991464547, 1e-8);
  EXPECT_NEAR(CalcChiSquareQuantile(3, 0.95), 7.814727903, 1e-8);
  EXPECT_NEAR(CalcChiSquareQuantile(3, 0.5), 2.365973884, 1e-8);
  EXPECT_EQ(ThrowMessage([] { CalcChiSquareQuantile(3, 1.0); }),
            "probability = 1 (must be in (0, 1))");
}

TEST(Repeatability, MonteCarloPointsFillTheStatedFraction) {
  // 20000 draws, seed 3: binomial sd of the fraction is 0.0015 at 0.95.
  std::mt19937_64 rng(3);
  const SerialArm arm = Spatial3R();
  const VectorXd q = Eigen::Vector3d(0.4, 0.6, -1.2);
  for (double c : {0.5, 0.95}) {
    const Ellipsoid e = CalcRepeatabilityEllipsoid(arm, q, c);
    ASSERT_EQ(e.rank, 3);
    const double frac = CalcMonteCarloContainment(arm, q, e, 20000, &rng);
    std::cout << "c = " << c << ": Monte Carlo fraction inside " << frac
              << "\n";
    EXPECT_NEAR(frac, c, 0.01) << "c = " << c;
  }
  // An ellipsoid half as large must fail the check (the test can fail).
  Ellipsoid small = CalcRepeatabilityEllipsoid(arm, q, 0.95);
  small.chi2 *= 0.25;
  EXPECT_LT(CalcMonteCarloContainment(arm, q, small, 5000, &rng), 0.6);
  // Planar 2R arm: rank 2, chi2 with 2 degrees of freedom.
  SerialArm planar;
  planar.joints.resize(2);
  planar.joints[0].a_mm = 300;
  planar.joints[1].a_mm = 250;
  for (DhJoint& j : planar.joints) j.sigma_tau = 3.0;
  const VectorXd q2 = Eigen::Vector2d(0.3, 1.0);
  const Ellipsoid e2 = CalcRepeatabilityEllipsoid(planar, q2, 0.9);
  EXPECT_EQ(e2.rank, 2);
  EXPECT_EQ(e2.semi_axes_mm[0], 0.0);
  EXPECT_NEAR(
      CalcMonteCarloContainment(planar, q2, e2, 20000, &rng), 0.9, 0.01);
}

TEST(Repeatability, InverseKinematicsReachesTargetsAndReportsUnreachable) {
  const SerialArm arm = Spatial3R();
  const VectorXd q0 = Eigen::Vector3d(0.1, 0.5, -1.0);
  const Eigen::Vector3d target(350, 150, 100);
  const IkResult r = SolvePositionIk(arm, target, q0);
  ASSERT_TRUE(r.converged) << r.why;
  EXPECT_LT((CalcEndEffectorPosition(arm, r.q) - target).norm(), 1e-6);
  const IkResult far = SolvePositionIk(arm, Eigen::Vector3d(2000, 0, 0), q0);
  EXPECT_FALSE(far.converged);
  EXPECT_NE(far.why.find("outside the workspace"), std::string::npos);
}

TEST(Repeatability, GridOverThePapersWorkspace) {
  // 400 x 400 mm at z = 0 in front of the arm, 6 x 6 points.
  const SerialArm arm = Spatial3R();
  const auto grid = CalcEllipsoidGrid(arm,
                                      200,
                                      -200,
                                      400,
                                      400,
                                      0.0,
                                      6,
                                      6,
                                      Eigen::Vector3d(0.0, 0.3, -1.0),
                                      0.95);
  ASSERT_EQ(grid.size(), 36u);
  double smallest = 1e9, largest = 0;
  for (const GridEllipsoid& g : grid) {
    ASSERT_TRUE(g.reachable) << g.target_mm.transpose();
    EXPECT_GT(g.semi_axes_mm[0], 0) << g.target_mm.transpose();
    smallest = std::min(smallest, g.semi_axes_mm[2]);
    largest = std::max(largest, g.semi_axes_mm[2]);
  }
  // Repeatability varies over the workspace (the paper's point).
  EXPECT_GT(largest, 1.2 * smallest);
}

TEST(Repeatability, ValidationNamesTheJoint) {
  SerialArm arm = Spatial3R();
  arm.joints[1].stiffness = 0;
  EXPECT_EQ(ThrowMessage([&] { ValidateArm(arm); }),
            "joints[1].stiffness = 0 (must be > 0)");
  arm = Spatial3R();
  arm.joints[2].sigma_tau = -1;
  EXPECT_EQ(ThrowMessage([&] { ValidateArm(arm); }),
            "joints[2].sigma_tau = -1 (must be >= 0)");
  EXPECT_EQ(ThrowMessage([] { ValidateArm(SerialArm{}); }),
            "joints has 0 entries (must be 1..32)");
}

}  // namespace
}  // namespace frictiond
