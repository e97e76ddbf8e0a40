#pragma once
/// @file
/// Shared perturbation check of analytic Jacobians (STYLE.md section 11,
/// after manif's test/common_tester.h): central differences column by
/// column, plus one first-order check f(x + dx) ~ f(x) + J dx along a mixed
/// direction. Tolerances are looser for float.
///
/// Usage:
/// @code
///   auto f = [&](const Eigen::VectorXd& x) { return Eigen::VectorXd(...); };
///   EXPECT_TRUE(internal::CheckJacobian<double>(f, x, J_analytic));
/// @endcode

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include <Eigen/Core>
#include <gtest/gtest.h>

namespace frictiond {
namespace internal {

/// Relative step and tolerance per scalar type.
template <typename Scalar>
struct JacobianTolerance;
template <>
struct JacobianTolerance<double> {
  static constexpr double kRelStep =
      1e-6;  ///< step = kRelStep * max(|x_j|, min_scale)
  static constexpr double kTol = 1e-6;  ///< relative error allowed per entry
};
template <>
struct JacobianTolerance<float> {
  static constexpr double kRelStep = 1e-3;
  static constexpr double kTol = 1e-2;
};

/// Checks J (rows = outputs, cols = inputs) against central differences of
/// f at x. Entry (i, j) passes when |J_num - J| <= tol * max(|J_num(i, j)|,
/// 1e-3 * max|J_num(:, j)|, r_j / tol), where r_j = 100 eps (1 + max|f|) /
/// step_j bounds the round-off of the difference quotient. min_scale bounds the
/// step from below for inputs near zero. On failure the message names the worst
/// entry with expected (numeric) and actual (analytic) values.
template <typename Scalar, typename Function>
::testing::AssertionResult CheckJacobian(
    Function&& f,
    const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>& x,
    const Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>& J,
    double tol = JacobianTolerance<Scalar>::kTol,
    double min_scale = 1e-3) {
  using Vec = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  using Mat = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
  const Vec f0 = f(x);
  if (J.rows() != f0.size() || J.cols() != x.size()) {
    return ::testing::AssertionFailure()
           << "J is " << J.rows() << "x" << J.cols() << ", expected "
           << f0.size() << "x" << x.size();
  }
  Mat J_num(J.rows(), J.cols());
  Vec steps(x.size());
  for (Eigen::Index j = 0; j < x.size(); ++j) {
    const Scalar h = static_cast<Scalar>(
        JacobianTolerance<Scalar>::kRelStep *
        std::max<double>(std::abs(double(x[j])), min_scale));
    steps[j] = h;
    Vec xp = x;
    Vec xm = x;
    xp[j] += h;
    xm[j] -= h;
    J_num.col(j) = (f(xp) - f(xm)) / (xp[j] - xm[j]);
  }
  double worst = 0;
  Eigen::Index wi = 0, wj = 0;
  const double f_scale = 1.0 + f0.cwiseAbs().maxCoeff();
  const double eps = std::numeric_limits<Scalar>::epsilon();
  for (Eigen::Index j = 0; j < J.cols(); ++j) {
    const double col_scale = J_num.col(j).cwiseAbs().maxCoeff();
    // Round-off of the central difference itself, made relative.
    const double roundoff = 100.0 * eps * f_scale / double(steps[j]) / tol;
    for (Eigen::Index i = 0; i < J.rows(); ++i) {
      const double scale = std::max(
          {std::abs(double(J_num(i, j))), 1e-3 * col_scale, roundoff, 1e-12});
      const double e = std::abs(double(J_num(i, j) - J(i, j))) / scale;
      if (e > worst) {
        worst = e;
        wi = i;
        wj = j;
      }
    }
  }
  if (!(worst <= tol)) {
    return ::testing::AssertionFailure()
           << "Jacobian entry (" << wi << ", " << wj
           << "): expected (central difference) " << J_num(wi, wj)
           << ", actual (analytic) " << J(wi, wj) << ", relative error "
           << worst << " > tol " << tol;
  }
  // First-order check along a mixed direction: f(x + d) - f(x) ~ J d.
  Vec d(x.size());
  for (Eigen::Index j = 0; j < x.size(); ++j)
    d[j] = steps[j] * Scalar((j % 3) - 1 + 0.5);
  const Vec lhs = f(x + d) - f0;
  const Vec rhs = J * d;
  const double err = (lhs - rhs).norm();
  const double ref = std::max<double>(rhs.norm(), 1e-12 * (1 + f0.norm()));
  if (!(err <= 100 * tol * ref + 1e-12)) {
    return ::testing::AssertionFailure()
           << "f(x+d) - f(x) = " << lhs.transpose()
           << " but J d = " << rhs.transpose();
  }
  return ::testing::AssertionSuccess();
}

}  // namespace internal
}  // namespace frictiond
