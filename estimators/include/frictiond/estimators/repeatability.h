#pragma once
/// @file
/// Stochastic repeatability ellipsoids (paper 002, Section 6): random joint
/// friction torques deflect compliant joints, and the deflections map
/// through the arm's kinematics to a scatter of the end-effector position.
///
///     dq_i  = tau_i / k_i                   (joint stiffness k_i)
///     P_q   = diag(sigma_tau_i^2 / k_i^2)
///     P_x   = J_x_q P_q J_x_q^T             (3 x 3, mm^2)
///
/// J_x_q is the position Jacobian of standard Denavit-Hartenberg kinematics
/// (T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i); q adds to theta for a
/// revolute joint, to d for a prismatic one). The repeatability ellipsoid of
/// probability c is {x : x^T P_x^-1 x <= chi2_r(c)} with r = rank P_x; its
/// semi-axes are sqrt(chi2_r(c) lambda_i) along the eigenvectors of P_x.
///
/// Units: lengths in mm, angles in rad; revolute stiffness in N m/rad with
/// torques in N m, prismatic stiffness in N/mm with forces in N.
///
/// Usage:
/// @code
///   SerialArm arm = ...;                       // DH + stiffness + sigma
///   IkResult ik = SolvePositionIk(arm, Eigen::Vector3d(300, 0, -400), q0);
///   Ellipsoid e = CalcRepeatabilityEllipsoid(arm, ik.q, 0.95);
/// @endcode

#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "frictiond/estimators/field_error.h"

namespace frictiond {

enum class JointType { kRevolute, kPrismatic };

/// One DH joint with its compliance and friction scatter.
struct DhJoint {
  JointType type = JointType::kRevolute;
  double a_mm = 0;         ///< link length a_i
  double alpha_rad = 0;    ///< link twist alpha_i
  double d_mm = 0;         ///< link offset d_i (prismatic: added to q)
  double theta_rad = 0;    ///< joint angle offset (revolute: added to q)
  double stiffness = 1e4;  ///< k_i [N m/rad] or [N/mm], > 0
  double sigma_tau = 0;    ///< sd of the friction torque [N m] or force [N]
  double q_min = -1e9;     ///< joint limit [rad] or [mm]
  double q_max = 1e9;
};

/// Serial arm (base frame at the origin). Copyable.
struct SerialArm {
  std::vector<DhJoint> joints;
};

/// @throws FieldError naming "joints[i].field", value and rule.
void ValidateArm(const SerialArm& arm);

/// End-effector position [mm] at joint coordinates q.
Eigen::Vector3d CalcEndEffectorPosition(
    const SerialArm& arm, const Eigen::Ref<const Eigen::VectorXd>& q);

/// Position Jacobian J_x_q (3 x n): mm/rad (revolute), mm/mm (prismatic).
Eigen::Matrix<double, 3, Eigen::Dynamic> CalcPositionJacobian(
    const SerialArm& arm, const Eigen::Ref<const Eigen::VectorXd>& q);

/// End-effector position covariance P_x [mm^2] from the joint friction
/// scatter at configuration q.
Eigen::Matrix3d CalcPositionCovariance(
    const SerialArm& arm, const Eigen::Ref<const Eigen::VectorXd>& q);

/// Inverse of the chi-square CDF with r = 1, 2 or 3 degrees of freedom.
/// @throws std::invalid_argument for r outside 1..3 or c outside (0, 1).
double CalcChiSquareQuantile(int r, double c);

/// A repeatability ellipsoid.
struct Ellipsoid {
  Eigen::Matrix3d P_x = Eigen::Matrix3d::Zero();  ///< covariance [mm^2]
  Eigen::Vector3d semi_axes_mm = Eigen::Vector3d::Zero();  ///< ascending
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();      ///< unit columns
  int rank = 0;            ///< dimensions with scatter (eigenvalue > 1e-12 max)
  double probability = 0;  ///< c
  double chi2 = 0;         ///< chi2_rank(c)
};

/// Ellipsoid of probability c in (0, 1) at configuration q.
Ellipsoid CalcRepeatabilityEllipsoid(const SerialArm& arm,
                                     const Eigen::Ref<const Eigen::VectorXd>& q,
                                     double probability);

/// Position inverse kinematics by damped least squares.
struct IkResult {
  bool converged = false;
  Eigen::VectorXd q;    ///< joint coordinates
  double error_mm = 0;  ///< |x(q) - target|
  int iterations = 0;
  std::string why;
};

/// Solves x(q) = target from q_start (joint limits respected by clamping).
/// Converges when the error is below tolerance_mm.
IkResult SolvePositionIk(const SerialArm& arm,
                         const Eigen::Vector3d& target_mm,
                         const Eigen::Ref<const Eigen::VectorXd>& q_start,
                         double tolerance_mm = 1e-6,
                         int max_iterations = 200);

/// Fraction of `samples` Monte Carlo draws tau ~ N(0, diag sigma_tau^2)
/// whose end-effector displacement through the full (nonlinear) forward
/// kinematics at q + tau/k lies inside the ellipsoid.
double CalcMonteCarloContainment(const SerialArm& arm,
                                 const Eigen::Ref<const Eigen::VectorXd>& q,
                                 const Ellipsoid& ellipsoid,
                                 int samples,
                                 std::mt19937_64* rng);

/// One grid point of CalcEllipsoidGrid.
struct GridEllipsoid {
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  bool reachable = false;
  Eigen::Vector3d semi_axes_mm = Eigen::Vector3d::Zero();  ///< ascending
};

/// Ellipsoids over an nx x ny grid of the plane z = z_mm, x in
/// [x0, x0 + size_x], y in [y0, y0 + size_y] (paper: 400 x 400 mm). IK is
/// warm-started from the previous grid point (row-major, serpentine).
std::vector<GridEllipsoid> CalcEllipsoidGrid(
    const SerialArm& arm,
    double x0_mm,
    double y0_mm,
    double size_x_mm,
    double size_y_mm,
    double z_mm,
    int nx,
    int ny,
    const Eigen::Ref<const Eigen::VectorXd>& q_start,
    double probability);

}  // namespace frictiond
