// SolveLeastSquares (least_squares.h) against known truth: an exponential
// decay with planted parameters away from zero, fitted from a far start by
// LM and GN (fixed and dynamic sizes), the closed-form covariance of a
// linear problem, the box, rank deficiency and option validation; the
// extensions (split form with its own criterion, smoothed-L1 residuals,
// Levenberg damping on an underdetermined problem).
#include "frictiond/estimators/least_squares.h"

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// y = a exp(-b t) + c, truth (a, b, c) = (2.5, 0.7, -0.4), noise sigma.
struct Decay {
  Eigen::VectorXd t, y;
  Decay(int m, double sigma, unsigned seed) : t(m), y(m) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, sigma);
    for (int i = 0; i < m; ++i) {
      t[i] = 0.05 * i;
      y[i] = 2.5 * std::exp(-0.7 * t[i]) - 0.4 + noise(rng);
    }
  }
  template <typename Vec, typename Jac>
  bool operator()(const Vec& x, Eigen::VectorXd* r, Jac* J) const {
    for (Eigen::Index i = 0; i < t.size(); ++i) {
      const double e = std::exp(-x[1] * t[i]);
      (*r)[i] = x[0] * e + x[2] - y[i];
      (*J)(i, 0) = e;
      (*J)(i, 1) = -x[0] * t[i] * e;
      (*J)(i, 2) = 1.0;
    }
    return r->allFinite() && J->allFinite();
  }
};

TEST(SolveLeastSquares, RecoversPlantedDecayFromFarStartByLmAndGn) {
  const Decay f(200, 0.0, 1);
  const Eigen::Vector3d lower(-kInf, 0.0, -kInf), upper(kInf, kInf, kInf);
  const Eigen::Vector3d start(0.3, 5.0, 2.0);
  // The start is not a solution.
  ASSERT_GT((start - Eigen::Vector3d(2.5, 0.7, -0.4)).norm(), 1.0);
  for (LeastSquaresMethod method : {LeastSquaresMethod::kLevenbergMarquardt,
                                    LeastSquaresMethod::kGaussNewton}) {
    LeastSquaresOptions o;
    o.method = method;
    LeastSquaresWorkspace<3> ws(200);
    Eigen::Vector3d x = start;
    const LeastSquaresSummary<3> s =
        SolveLeastSquares<3>(f, &x, lower, upper, o, &ws);
    ASSERT_EQ(s.status, LeastSquaresStatus::kConverged) << s.why;
    EXPECT_NEAR(x[0], 2.5, 1e-8) << ToString(s.status);
    EXPECT_NEAR(x[1], 0.7, 1e-8);
    EXPECT_NEAR(x[2], -0.4, 1e-8);
    EXPECT_LT(s.cost, 1e-20);
    EXPECT_GT(s.initial_cost, 1.0);
  }
}

TEST(SolveLeastSquares, DynamicSizeGivesTheFixedSizeAnswer) {
  const Decay f(150, 0.02, 2);
  LeastSquaresWorkspace<3> ws3(150);
  Eigen::Vector3d x3(1.0, 2.0, 0.0);
  const Eigen::Vector3d lo3(-kInf, 0.0, -kInf), hi3(kInf, kInf, kInf);
  const auto s3 = SolveLeastSquares<3>(f, &x3, lo3, hi3, {}, &ws3);
  LeastSquaresWorkspace<Eigen::Dynamic> wsd(150, 3);
  Eigen::VectorXd xd = Eigen::Vector3d(1.0, 2.0, 0.0);
  const Eigen::VectorXd lod = lo3, hid = hi3;
  const auto sd = SolveLeastSquares<Eigen::Dynamic>(f, &xd, lod, hid, {}, &wsd);
  ASSERT_EQ(s3.status, LeastSquaresStatus::kConverged) << s3.why;
  ASSERT_EQ(sd.status, LeastSquaresStatus::kConverged) << sd.why;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(xd[i], x3[i], 1e-10) << i;
    for (int j = 0; j < 3; ++j)
      EXPECT_NEAR(sd.JtJ_inv(i, j),
                  s3.JtJ_inv(i, j),
                  1e-8 * (1 + std::abs(s3.JtJ_inv(i, j))));
  }
  // Truth within 4 standard errors (s^2 (J^T J)^-1).
  const double s2 = s3.cost / (150 - 3);
  const Eigen::Vector3d truth(2.5, 0.7, -0.4);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(x3[i], truth[i], 4 * std::sqrt(s2 * s3.JtJ_inv(i, i))) << i;
}

// A linear problem: the solution and (J^T J)^-1 in closed form.
TEST(SolveLeastSquares, LinearProblemMatchesNormalEquations) {
  const int m = 40;
  Eigen::MatrixXd A(m, 2);
  Eigen::VectorXd b(m);
  for (int i = 0; i < m; ++i) {
    A(i, 0) = 1.0;
    A(i, 1) = 0.1 * i;
    b[i] = 3.0 - 0.5 * A(i, 1) + 0.01 * std::sin(7.0 * i);
  }
  auto f = [&](const Eigen::Vector2d& x,
               Eigen::VectorXd* r,
               Eigen::Matrix<double, Eigen::Dynamic, 2>* J) {
    *r = A * x - b;
    *J = A;
    return true;
  };
  const Eigen::Matrix2d AtA = A.transpose() * A;
  const Eigen::Vector2d truth = AtA.ldlt().solve(A.transpose() * b);
  const Eigen::Matrix2d AtA_inv = AtA.inverse();
  LeastSquaresWorkspace<2> ws(m);
  Eigen::Vector2d x(-10.0, 10.0);
  const auto s = SolveLeastSquares<2>(f,
                                      &x,
                                      Eigen::Vector2d::Constant(-kInf),
                                      Eigen::Vector2d::Constant(kInf),
                                      {},
                                      &ws);
  ASSERT_EQ(s.status, LeastSquaresStatus::kConverged) << s.why;
  EXPECT_NEAR(x[0], truth[0], 1e-10);
  EXPECT_NEAR(x[1], truth[1], 1e-10);
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      EXPECT_NEAR(s.JtJ_inv(i, j), AtA_inv(i, j), 1e-10);
  EXPECT_NEAR(ws.r.squaredNorm(), s.cost, 1e-14);
}

TEST(SolveLeastSquares, StaysInTheBox) {
  const Decay f(100, 0.0, 3);
  // Upper bound on b below the truth 0.7: the solution sits on it.
  LeastSquaresWorkspace<3> ws(100);
  Eigen::Vector3d x(1.0, 0.2, 0.0);
  const auto s = SolveLeastSquares<3>(f,
                                      &x,
                                      Eigen::Vector3d(-kInf, 0.0, -kInf),
                                      Eigen::Vector3d(kInf, 0.5, kInf),
                                      {},
                                      &ws);
  EXPECT_NE(s.status, LeastSquaresStatus::kFailed) << s.why;
  EXPECT_LE(x[1], 0.5);
  EXPECT_NEAR(x[1], 0.5, 1e-9);
}

TEST(SolveLeastSquares, ReportsRankDeficiencyAndTooFewResiduals) {
  // r = (x0 + x1) - 1: only the sum is identified.
  auto f = [](const Eigen::Vector2d& x,
              Eigen::VectorXd* r,
              Eigen::Matrix<double, Eigen::Dynamic, 2>* J) {
    for (Eigen::Index i = 0; i < r->size(); ++i) {
      (*r)[i] = x[0] + x[1] - 1.0;
      (*J)(i, 0) = 1.0;
      (*J)(i, 1) = 1.0;
    }
    return true;
  };
  const Eigen::Vector2d lo = Eigen::Vector2d::Constant(-kInf);
  const Eigen::Vector2d hi = Eigen::Vector2d::Constant(kInf);
  LeastSquaresWorkspace<2> ws(10);
  Eigen::Vector2d x(3.0, 3.0);
  const auto s = SolveLeastSquares<2>(f, &x, lo, hi, {}, &ws);
  EXPECT_EQ(s.status, LeastSquaresStatus::kRankDeficient);
  EXPECT_NE(s.why.find("rank deficient"), std::string::npos) << s.why;
  EXPECT_NEAR(x[0] + x[1], 1.0, 1e-8);
  EXPECT_TRUE(std::isnan(s.JtJ_inv(0, 0)));

  LeastSquaresWorkspace<2> one(1);
  Eigen::Vector2d y(0.0, 0.0);
  const auto t = SolveLeastSquares<2>(f, &y, lo, hi, {}, &one);
  EXPECT_EQ(t.status, LeastSquaresStatus::kNotEnoughData);
  EXPECT_EQ(y, Eigen::Vector2d(0.0, 0.0));
}

TEST(SolveLeastSquares, NonFiniteStartFailsAndNonFiniteTrialsAreRejected) {
  // Model sqrt(x) - 2: not finite for x < 0.
  auto f =
      [](const Eigen::VectorXd& x, Eigen::VectorXd* r, Eigen::MatrixXd* J) {
        if (!(x[0] > 0)) return false;
        r->setConstant(std::sqrt(x[0]) - 2.0);
        J->setConstant(0.5 / std::sqrt(x[0]));
        return true;
      };
  const Eigen::VectorXd lo = Eigen::VectorXd::Constant(1, -kInf);
  const Eigen::VectorXd hi = Eigen::VectorXd::Constant(1, kInf);
  LeastSquaresWorkspace<Eigen::Dynamic> ws(3, 1);
  Eigen::VectorXd x = Eigen::VectorXd::Constant(1, -1.0);
  EXPECT_EQ(SolveLeastSquares<Eigen::Dynamic>(f, &x, lo, hi, {}, &ws).status,
            LeastSquaresStatus::kFailed);
  x[0] = 0.01;  // the full GN step overshoots below 0 first
  LeastSquaresOptions o;
  o.method = LeastSquaresMethod::kGaussNewton;
  const auto s = SolveLeastSquares<Eigen::Dynamic>(f, &x, lo, hi, o, &ws);
  ASSERT_EQ(s.status, LeastSquaresStatus::kConverged) << s.why;
  EXPECT_NEAR(x[0], 4.0, 1e-8);
}

TEST(SolveLeastSquares, RejectsBadOptionsNamingTheField) {
  const Decay f(10, 0.0, 4);
  LeastSquaresWorkspace<3> ws(10);
  Eigen::Vector3d x(1, 1, 1);
  const Eigen::Vector3d lo = Eigen::Vector3d::Constant(-kInf);
  const Eigen::Vector3d hi = Eigen::Vector3d::Constant(kInf);
  LeastSquaresOptions o;
  o.lambda_increase = 1.0;
  try {
    SolveLeastSquares<3>(f, &x, lo, hi, o, &ws);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("lambda_increase"), std::string::npos)
        << e.what();
  }
  o = LeastSquaresOptions();
  o.cost_tolerance = std::nan("");
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("cost_tolerance"), std::string::npos) << why;
  // A start outside the box.
  EXPECT_THROW(SolveLeastSquares<3>(f,
                                    &x,
                                    lo,
                                    Eigen::Vector3d::Constant(0.5),
                                    LeastSquaresOptions(),
                                    &ws),
               std::invalid_argument);
}

// The split form with cost = |r|^2 is the functor form: same answer, and
// the Jacobian is evaluated once at the start and once per accepted step.
TEST(SolveLeastSquares, SplitFormWithSquaredNormCostMatchesFunctorForm) {
  const Decay f(120, 0.01, 5);
  const Eigen::Vector3d lo(-kInf, 0.0, -kInf), hi(kInf, kInf, kInf);
  LeastSquaresWorkspace<3> ws(120);
  Eigen::Vector3d x(0.3, 5.0, 2.0);
  const auto s = SolveLeastSquares<3>(f, &x, lo, hi, {}, &ws);
  ASSERT_EQ(s.status, LeastSquaresStatus::kConverged) << s.why;

  int jacobians = 0;
  Eigen::Matrix<double, Eigen::Dynamic, 3> J_scratch(120, 3);
  Eigen::VectorXd r_scratch(120);
  auto residual =
      [&](const Eigen::Vector3d& at, Eigen::VectorXd* r, double* cost) {
        if (!f(at, r, &J_scratch)) return false;
        *cost = r->squaredNorm();
        return true;
      };
  auto jacobian = [&](const Eigen::Vector3d& at,
                      const Eigen::VectorXd&,
                      Eigen::Matrix<double, Eigen::Dynamic, 3>* J) {
    ++jacobians;
    return f(at, &r_scratch, J);
  };
  LeastSquaresWorkspace<3> ws2(120);
  Eigen::Vector3d y(0.3, 5.0, 2.0);
  const auto t = SolveLeastSquares<3>(residual, jacobian, &y, lo, hi, {}, &ws2);
  ASSERT_EQ(t.status, LeastSquaresStatus::kConverged) << t.why;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(y[i], x[i], 1e-12) << i;
  EXPECT_EQ(t.iterations, s.iterations);
  EXPECT_NEAR(t.cost, s.cost, 1e-12 * (1 + s.cost));
  EXPECT_GE(jacobians, 2);
  EXPECT_LE(jacobians, t.iterations + 1);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(t.JtJ_inv(i, i), s.JtJ_inv(i, i), 1e-9 * s.JtJ_inv(i, i));
}

// Smoothed-L1 residuals e / sqrt(|e| + delta) judged by sum |e| (the form
// the actuator fit uses): a line y = 1.5 - 0.8 t with 15% gross outliers
// is recovered, where plain least squares is pulled away.
TEST(SolveLeastSquares, SplitFormSmoothedL1ResistsOutliers) {
  const int m = 200;
  Eigen::VectorXd t(m), y(m);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> gross(2.0, 6.0);
  for (int i = 0; i < m; ++i) {
    t[i] = 0.01 * i;
    y[i] = 1.5 - 0.8 * t[i] + noise(rng) + (i % 7 == 3 ? gross(rng) : 0.0);
  }
  const double delta = 1e-3;
  auto errors = [&](const Eigen::Vector2d& x) -> Eigen::VectorXd {
    return (x[0] + x[1] * t.array() - y.array()).matrix();
  };
  auto residual =
      [&](const Eigen::Vector2d& x, Eigen::VectorXd* r, double* cost) {
        const Eigen::VectorXd e = errors(x);
        *r = (e.array() / (e.array().abs() + delta).sqrt()).matrix();
        *cost = e.cwiseAbs().sum();
        return r->allFinite();
      };
  auto jacobian = [&](const Eigen::Vector2d& x,
                      const Eigen::VectorXd&,
                      Eigen::Matrix<double, Eigen::Dynamic, 2>* J) {
    // d/de [e (|e| + delta)^-1/2] = (|e| / 2 + delta) (|e| + delta)^-3/2.
    const Eigen::ArrayXd a = errors(x).array().abs();
    const Eigen::ArrayXd d = (0.5 * a + delta) / (a + delta).pow(1.5);
    J->col(0) = d.matrix();
    J->col(1) = (d * t.array()).matrix();
    return J->allFinite();
  };
  const Eigen::Vector2d lo = Eigen::Vector2d::Constant(-kInf);
  const Eigen::Vector2d hi = Eigen::Vector2d::Constant(kInf);
  LeastSquaresOptions o;
  o.max_iterations = 200;
  o.cost_tolerance = 0.0;
  o.strict_decrease = true;
  LeastSquaresWorkspace<2> ws(m);
  Eigen::Vector2d x(-2.0, 3.0);
  const auto s = SolveLeastSquares<2>(residual, jacobian, &x, lo, hi, o, &ws);
  ASSERT_NE(s.status, LeastSquaresStatus::kFailed) << s.why;
  EXPECT_LT(s.cost, s.initial_cost);
  EXPECT_NEAR(x[0], 1.5, 0.02) << x.transpose();
  EXPECT_NEAR(x[1], -0.8, 0.04) << x.transpose();
  // Plain least squares on the same data is biased by the outliers.
  const Eigen::Vector2d ls =
      (Eigen::MatrixXd(m, 2) << Eigen::VectorXd::Ones(m), t)
          .finished()
          .colPivHouseholderQr()
          .solve(y);
  EXPECT_GT(std::abs(ls[0] - 1.5), 0.2) << ls.transpose();
}

// Underdetermined, Levenberg damping: r = A x - b with A 2 x 4. From
// x = 0 the damped least-norm steps stay in the row space of A, so the
// solve ends at the minimum-norm solution A^T (A A^T)^-1 b, stopping on
// target_cost.
TEST(SolveLeastSquares, LevenbergDampingSolvesUnderdeterminedMinimumNorm) {
  Eigen::Matrix<double, 2, 4> A;
  A << 1.0, 2.0, -1.0, 0.5,  //
      0.0, 1.0, 3.0, -2.0;
  const Eigen::Vector2d b(4.0, -3.0);
  auto f = [&](const Eigen::Vector4d& x,
               Eigen::VectorXd* r,
               Eigen::Matrix<double, Eigen::Dynamic, 4>* J) {
    *r = A * x - b;
    *J = A;
    return true;
  };
  const Eigen::Vector4d lo = Eigen::Vector4d::Constant(-kInf);
  const Eigen::Vector4d hi = Eigen::Vector4d::Constant(kInf);
  LeastSquaresWorkspace<4> ws(2);
  Eigen::Vector4d x = Eigen::Vector4d::Zero();
  LeastSquaresOptions o;
  EXPECT_EQ(SolveLeastSquares<4>(f, &x, lo, hi, o, &ws).status,
            LeastSquaresStatus::kNotEnoughData);
  o.damping = LeastSquaresDamping::kLevenberg;
  o.allow_underdetermined = true;
  o.target_cost = 1e-20;
  o.cost_tolerance = 0.0;
  o.step_tolerance = 0.0;
  const auto s = SolveLeastSquares<4>(f, &x, lo, hi, o, &ws);
  ASSERT_EQ(s.status, LeastSquaresStatus::kConverged) << s.why;
  EXPECT_LE(s.cost, 1e-20);
  EXPECT_EQ(s.rcond, 0.0);
  const Eigen::Vector4d min_norm =
      A.transpose() * (A * A.transpose()).ldlt().solve(b);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(x[i], min_norm[i], 1e-8) << i;
  // Without the final covariance: same answer, rcond NaN.
  o.compute_covariance = false;
  Eigen::Vector4d z = Eigen::Vector4d::Zero();
  const auto t = SolveLeastSquares<4>(f, &z, lo, hi, o, &ws);
  ASSERT_EQ(t.status, LeastSquaresStatus::kConverged) << t.why;
  EXPECT_TRUE(std::isnan(t.rcond));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(z[i], x[i]) << i;
}

TEST(SolveLeastSquares, RejectsBadExtensionOptionsNamingTheField) {
  std::string why;
  LeastSquaresOptions o;
  o.min_lambda = 1.0;  // > initial_lambda
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("min_lambda"), std::string::npos) << why;
  o = LeastSquaresOptions();
  o.target_cost = -1.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("target_cost"), std::string::npos) << why;
  o = LeastSquaresOptions();
  o.allow_underdetermined = true;
  o.method = LeastSquaresMethod::kGaussNewton;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("allow_underdetermined"), std::string::npos) << why;
}

}  // namespace
}  // namespace frictiond
