// SolveLeastSquares (least_squares.h) against known truth: an exponential
// decay with planted parameters away from zero, fitted from a far start by
// LM and GN (fixed and dynamic sizes), the closed-form covariance of a
// linear problem, the box, rank deficiency and option validation.
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

}  // namespace
}  // namespace frictiond
