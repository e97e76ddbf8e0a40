// Allocation check for the EKF loop (STYLE.md section 9). Eigen's check is
// an eigen_assert, which NDEBUG (Release) compiles out, so this file counts
// failed Eigen assertions instead of relying on assert().
namespace {
int g_eigen_assert_failures = 0;
}  // namespace
#define EIGEN_RUNTIME_NO_MALLOC
#define eigen_assert(x)            \
  do {                             \
    if (!(x)) {                    \
      ++::g_eigen_assert_failures; \
    }                              \
  } while (false)

#include "frictiond/estimators/lugre_identification.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/stats.h"

#include "jacobian_tester.h"

namespace frictiond {
namespace {

using Eigen::VectorXd;

constexpr double kNoise = 0.005;  // sensor noise on mu, 1 sigma

// Truth (issue 5): sigma1 = 0.1 s/mm satisfies the default LM-1/EKF tie
// sigma1 = 0.01414 sqrt(sigma0). All entries well away from zero.
LuGreTheta Truth() { return MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1); }

// A stroke sampled at fs_hz from v(t), simulated with the adaptive
// integrator (not the fits' discrete model) plus Gaussian noise on mu.
LuGreStroke SimulateStroke(const LuGreTheta& theta,
                           const std::function<double(double)>& v_of_t,
                           double duration_s,
                           double fs_hz,
                           double noise,
                           unsigned seed,
                           double z0_mm = 0.0) {
  const int n = static_cast<int>(std::round(duration_s * fs_hz)) + 1;
  LuGreStroke s;
  s.t_s.resize(n);
  s.v_mm_s.resize(n);
  for (int k = 0; k < n; ++k) {
    s.t_s[k] = k / fs_hz;
    s.v_mm_s[k] = v_of_t(s.t_s[k]);
  }
  const VelocityDrivenResult r =
      SimulateVelocityDriven(theta, s.t_s, s.v_mm_s, z0_mm);
  EXPECT_EQ(r.status, SimulationStatus::kOk) << r.why;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise);
  s.mu = r.mu;
  for (int k = 0; k < n; ++k) s.mu[k] += gauss(rng);
  return s;
}

// Step 1 stroke: 0 -> 20 -> 0 mm/s at 2 mm/s^2 (<= 3 mm/s^2, paper).
LuGreStroke SlowStroke(unsigned seed,
                       double fs_hz = 200.0,
                       const LuGreTheta& theta = Truth()) {
  return SimulateStroke(
      theta,
      [](double t) { return t < 10 ? 2.0 * t : 40.0 - 2.0 * t; },
      20.0,
      fs_hz,
      kNoise,
      seed);
}

// Step 2 stroke: 0 -> 10 -> 0 mm/s at 20 mm/s^2 (>= 5 mm/s^2, paper).
LuGreStroke FastStroke(unsigned seed, double fs_hz = 200.0) {
  return SimulateStroke(
      Truth(),
      [](double t) { return t < 0.5 ? 20.0 * t : 20.0 - 20.0 * t; },
      1.0,
      fs_hz,
      kNoise,
      seed);
}

const Eigen::Vector4d kFarQuasiStatic(0.3,
                                      0.2,
                                      1.0,
                                      0.0);  // truth 0.9, 0.6, 5, 0.004

double RelErr(double estimate, double truth) {
  return std::abs(estimate - truth) / std::abs(truth);
}

// ---------------------------------------------------------------- Step 1

class QuasiStaticTest : public ::testing::TestWithParam<QuasiStaticSolver> {};

TEST_P(QuasiStaticTest, RecoversTruthFromFarStart) {
  const LuGreTheta truth = Truth();
  for (double fs : {50.0, 200.0, 300.0}) {
    const unsigned seed = 7;
    const LuGreStroke stroke = SlowStroke(seed, fs);
    QuasiStaticFitOptions options;
    options.solver = GetParam();
    // The start is not a solution: its residual is far above the noise.
    LuGreTheta start = truth;
    start.head<4>() = kFarQuasiStatic;
    double sse = 0;
    for (Eigen::Index k = 0; k < stroke.size(); ++k) {
      sse += std::pow(
          CalcSteadyStateFrictionRatio(start, stroke.v_mm_s[k]) - stroke.mu[k],
          2);
    }
    ASSERT_GT(std::sqrt(sse / stroke.size()), 20 * kNoise);

    const LuGreFitResult r =
        FitLuGreQuasiStatic(stroke, kFarQuasiStatic, options);
    ASSERT_EQ(r.status, LuGreFitStatus::kConverged) << r.why;
    std::cout << (GetParam() == QuasiStaticSolver::kGaussNewton ? "GN" : "LM")
              << " fs=" << fs << " seed=" << seed
              << ": theta = " << r.theta.head<4>().transpose() << ", std = "
              << r.P_theta.diagonal().head<4>().cwiseSqrt().transpose()
              << ", iterations = " << r.iterations
              << ", rms = " << r.residual_rms << "\n";
    EXPECT_LT(RelErr(r.theta[0], 0.9), 0.02)
        << "mu_s expected 0.9, got " << r.theta[0];
    EXPECT_LT(RelErr(r.theta[1], 0.6), 0.02)
        << "mu_c expected 0.6, got " << r.theta[1];
    EXPECT_LT(RelErr(r.theta[2], 5.0), 0.10)
        << "v0 expected 5, got " << r.theta[2];
    EXPECT_NEAR(r.theta[3], 0.004, 0.001)
        << "sigma2 expected 0.004, got " << r.theta[3];
    for (int i = 0; i < 4; ++i) {
      EXPECT_NEAR(r.theta[i],
                  truth[i],
                  4 * std::sqrt(r.P_theta(i, i)) + 1e-3 * std::abs(truth[i]))
          << "entry " << i;
    }
    EXPECT_NEAR(r.residual_rms, kNoise, 0.2 * kNoise);
    EXPECT_TRUE(std::isnan(r.theta[4]));
  }
}

INSTANTIATE_TEST_SUITE_P(
    Solvers,
    QuasiStaticTest,
    ::testing::Values(QuasiStaticSolver::kGaussNewton,
                      QuasiStaticSolver::kLevenbergMarquardt));

TEST(QuasiStaticFitTest, StandardErrorsCoverTheTruthOverSeeds) {
  int covered = 0;
  const int seeds = 400;
  double sum_z = 0, sum_z2 = 0;
  for (int seed = 1; seed <= seeds; ++seed) {
    const LuGreFitResult r =
        FitLuGreQuasiStatic(SlowStroke(seed), kFarQuasiStatic);
    ASSERT_EQ(r.status, LuGreFitStatus::kConverged)
        << "seed " << seed << ": " << r.why;
    const double z = (r.theta[0] - 0.9) / std::sqrt(r.P_theta(0, 0));
    sum_z += z;
    sum_z2 += z * z;
    covered += std::abs(z) <= 2 ? 1 : 0;
  }
  std::cout << "mu_s within 2 std in " << covered << " of " << seeds
            << " seeds; z mean " << sum_z / seeds << ", z rms "
            << std::sqrt(sum_z2 / seeds) << "\n";
  // The standard error is right: the z-scores' spread is 1 (400 seeds: its
  // 99 % sampling interval is about 1 +- 0.09; measured 1.00). But the
  // finite 2 mm/s^2 ramp lags, biasing mu_s low by about 0.8 standard
  // errors (measured z mean -0.79, sampling sd 0.05), so the nominal 95.4 %
  // 2-sigma interval covers about 88 % (measured 354 of 400): stated here
  // rather than hidden behind a loose count.
  const double mean_z = sum_z / seeds;
  const double sd_z = std::sqrt(sum_z2 / seeds - mean_z * mean_z);
  EXPECT_NEAR(sd_z, 1.0, 0.09);
  EXPECT_NEAR(mean_z, -0.79, 0.15);
  // Coverage predicted from N(mean_z, sd_z), within its 99 % binomial
  // interval (+- 2.6 sd of the count).
  const double p_cover =
      NormalCdf((2 - mean_z) / sd_z) - NormalCdf((-2 - mean_z) / sd_z);
  EXPECT_NEAR(covered,
              p_cover * seeds,
              2.6 * std::sqrt(p_cover * (1 - p_cover) * seeds));
}

TEST(QuasiStaticFitTest, NullCaseWithoutStribeckFindsNone) {
  // Nothing planted: mu_s = mu_c. v0 is then unidentifiable, and the fit
  // may park the Stribeck drop below the slowest used speed (0.6 mm/s) with
  // any mu_s. What must hold: no drop inside the observed speed range
  // (measured: 0.018 right at 0.6 mm/s, < 1e-4 from 1 mm/s on), and
  // no false claim of convergence when mu_s is not pinned down.
  const LuGreTheta flat = MakeLuGreTheta(0.6, 0.6, 5.0, 0.004, 50.0, 0.1);
  const LuGreFitResult r =
      FitLuGreQuasiStatic(SlowStroke(3, 200.0, flat), kFarQuasiStatic);
  double max_drop = 0;
  for (double v = 1.0; v <= 20.0; v += 0.1) {
    max_drop = std::max(max_drop,
                        std::abs(CalcStribeckRatio(r.theta, v) - r.theta[1]));
  }
  std::cout << "null case: status " << ToString(r.status)
            << ", theta = " << r.theta.head<4>().transpose()
            << ", max |g(v) - mu_c| on 1..20 mm/s = " << max_drop << " ("
            << r.why << ")\n";
  EXPECT_LT(max_drop, 0.01);
  EXPECT_NEAR(r.theta[1], 0.6, 0.01);
  EXPECT_TRUE(r.status != LuGreFitStatus::kConverged ||
              std::abs(r.theta[0] - r.theta[1]) < 0.01)
      << ToString(r.status)
      << " with mu_s - mu_c = " << r.theta[0] - r.theta[1];
}

TEST(QuasiStaticFitTest, RejectsBadOptionsNamingFieldValueAndRule) {
  QuasiStaticFitOptions options;
  options.min_speed_fraction = 1.5;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why, "min_speed_fraction = 1.5 (must be in [0, 1))");
  options = QuasiStaticFitOptions();
  options.lower_bounds[2] = 1e5;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why,
            "lower_bounds[2] = 100000 (must be finite and < upper_bounds[i] = "
            "10000)");
  try {
    FitLuGreQuasiStatic(SlowStroke(1), Eigen::Vector4d(0.5, 0.5, -1, 0));
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "initial_guess[2] = -1 (must be within [0.0001, 10000])");
  }
  LuGreStroke bad = SlowStroke(1);
  bad.mu[3] = std::nan("");
  try {
    FitLuGreQuasiStatic(bad, kFarQuasiStatic);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "stroke.mu[3] = nan (must be finite)");
  }
}

// ---------------------------------------------------------------- Step 2

TEST(DynamicModelTest, DiscreteResponseJacobianMatchesPerturbation) {
  const LuGreStroke s = FastStroke(1, 50.0);
  VectorXd x(7);
  x << Truth(), 0.003;
  auto f = [&](const VectorXd& xx) {
    VectorXd mu;
    CalcLuGreDiscreteResponse(
        LuGreTheta(xx.head<6>()), xx[6], s.t_s, s.v_mm_s, &mu);
    return mu;
  };
  VectorXd mu;
  Eigen::Matrix<double, Eigen::Dynamic, 7> J;
  CalcLuGreDiscreteResponse(Truth(), 0.003, s.t_s, s.v_mm_s, &mu, &J);
  EXPECT_TRUE(internal::CheckJacobian<double>(f, x, Eigen::MatrixXd(J)));
}

TEST(DynamicModelTest, DiscreteModelTracksTheAdaptiveSimulator) {
  // The fits use the exact-exponential step; at 200 Hz its model error must
  // be well below the sensor noise.
  const LuGreStroke s = FastStroke(1, 200.0);
  const VelocityDrivenResult ref =
      SimulateVelocityDriven(Truth(), s.t_s, s.v_mm_s, 0.0);
  VectorXd mu;
  CalcLuGreDiscreteResponse(Truth(), 0.0, s.t_s, s.v_mm_s, &mu);
  const double err = (mu - ref.mu).cwiseAbs().maxCoeff();
  std::cout << "discrete vs adaptive, 200 Hz: max |d mu| = " << err << "\n";
  EXPECT_LT(err, kNoise);
}

struct Step1Then2 {
  LuGreFitResult quasi_static;
  LuGreFitResult dynamic;
};

Step1Then2 RunTwoStroke(DynamicFitVariant variant,
                        unsigned seed,
                        double fs_hz = 200.0) {
  Step1Then2 out;
  out.quasi_static =
      FitLuGreQuasiStatic(SlowStroke(seed, fs_hz), kFarQuasiStatic);
  LuGreTheta guess = out.quasi_static.theta;
  guess[LuGreIndex::kStiffness] = 10.0;  // truth 50
  guess[LuGreIndex::kDamping] = 0.01;    // truth 0.1
  DynamicFitOptions options;
  options.variant = variant;
  out.dynamic =
      FitLuGreDynamic(FastStroke(seed + 100, fs_hz), guess, 0.0, options);
  return out;
}

class DynamicFitTest : public ::testing::TestWithParam<DynamicFitVariant> {};

TEST_P(DynamicFitTest, TwoStrokeIdentificationRecoversTruth) {
  const LuGreTheta truth = Truth();
  const Step1Then2 r = RunTwoStroke(GetParam(), 7);
  ASSERT_EQ(r.quasi_static.status, LuGreFitStatus::kConverged)
      << r.quasi_static.why;
  ASSERT_EQ(r.dynamic.status, LuGreFitStatus::kConverged) << r.dynamic.why;
  const LuGreTheta& th = r.dynamic.theta;
  std::cout << "variant " << static_cast<int>(GetParam())
            << ": theta = " << th.transpose() << ", z0 = " << r.dynamic.z0_mm
            << ", std = "
            << r.dynamic.P_theta.diagonal().cwiseSqrt().transpose()
            << ", iterations = " << r.dynamic.iterations
            << ", rms = " << r.dynamic.residual_rms
            << ", excited = " << r.dynamic.excited_samples << "\n";
  EXPECT_LT(RelErr(th[0], 0.9), 0.02) << "mu_s expected 0.9, got " << th[0];
  EXPECT_LT(RelErr(th[1], 0.6), 0.02) << "mu_c expected 0.6, got " << th[1];
  EXPECT_LT(RelErr(th[4], 50.0), 0.10) << "sigma0 expected 50, got " << th[4];
  EXPECT_LT(RelErr(th[5], 0.1), 0.25) << "sigma1 expected 0.1, got " << th[5];
  EXPECT_NEAR(th[4],
              truth[4],
              4 * std::sqrt(r.dynamic.P_theta(4, 4)) + 0.02 * truth[4]);
  EXPECT_NEAR(r.dynamic.residual_rms, kNoise, 0.3 * kNoise);
  EXPECT_GE(r.dynamic.excited_samples, 5);
}

INSTANTIATE_TEST_SUITE_P(Variants,
                         DynamicFitTest,
                         ::testing::Values(DynamicFitVariant::kLm1,
                                           DynamicFitVariant::kLm2,
                                           DynamicFitVariant::kLm6));

TEST(DynamicFitTest, Lm6FromTheFastStrokeAloneIsWorseThanTwoSteps) {
  // Paper Section V.B.1: estimating all six at once from the dynamic stroke
  // was unreliable (mu_s 0.98 vs 0.36). Same data here, far start for all.
  const LuGreStroke fast = FastStroke(107);
  DynamicFitOptions lm6;
  lm6.variant = DynamicFitVariant::kLm6;
  const LuGreTheta far = MakeLuGreTheta(0.3, 0.2, 1.0, 0.0, 10.0, 0.01);
  const LuGreFitResult one_go = FitLuGreDynamic(fast, far, 0.0, lm6);
  const Step1Then2 two_step = RunTwoStroke(DynamicFitVariant::kLm2, 7);
  std::cout << "LM-6 on the fast stroke alone: status "
            << ToString(one_go.status)
            << ", theta = " << one_go.theta.transpose()
            << ", std = " << one_go.P_theta.diagonal().cwiseSqrt().transpose()
            << ", " << one_go.why << "\n"
            << "two-step GN+LM-2:             theta = "
            << two_step.dynamic.theta.transpose() << "\n";
  // What actually happens (measured, see docs/lugre.md): the one-go fit
  // fits the loop but its Stribeck parameters are far less certain.
  const double std_mu_c_one_go = std::sqrt(one_go.P_theta(1, 1));
  const double std_mu_c_two = std::sqrt(two_step.quasi_static.P_theta(1, 1));
  EXPECT_GT(std_mu_c_one_go, 3 * std_mu_c_two)
      << "one-go std(mu_c) " << std_mu_c_one_go << " vs two-step "
      << std_mu_c_two;
  const double err_one_go =
      std::abs(one_go.theta[1] - 0.6) + std::abs(one_go.theta[2] - 5.0) / 5;
  const double err_two = std::abs(two_step.dynamic.theta[1] - 0.6) +
                         std::abs(two_step.dynamic.theta[2] - 5.0) / 5;
  EXPECT_GT(err_one_go, err_two)
      << "one-go error " << err_one_go << " vs two-step " << err_two;
}

TEST(DynamicFitTest, SteadySlidingIsNotObservable) {
  // Constant velocity from the steady-state deflection: dz/dt = 0 throughout,
  // so sigma0 and sigma1 cannot be seen (paper eq. 10 discussion).
  const LuGreTheta truth = Truth();
  const double v = 8.0;
  const double z_ss = CalcStribeckRatio(truth, v) / truth[4];
  const LuGreStroke s = SimulateStroke(
      truth, [v](double) { return v; }, 1.0, 200.0, kNoise, 5, z_ss);
  LuGreTheta guess = truth;
  guess[4] = 10.0;
  guess[5] = 0.01;
  const LuGreFitResult r = FitLuGreDynamic(s, guess, z_ss);
  std::cout << "steady sliding: " << ToString(r.status) << ", " << r.why
            << "\n";
  EXPECT_EQ(r.status, LuGreFitStatus::kNotObservable) << r.why;
  EXPECT_FALSE(r.why.empty());
}

TEST(DynamicFitTest, RejectsBadInputNamingFieldValueAndRule) {
  DynamicFitOptions options;
  options.damping_gain = -1;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why, "damping_gain = -1 (must be finite and > 0)");
  LuGreTheta guess = Truth();
  try {
    FitLuGreDynamic(FastStroke(1), guess, 20.0);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "z0_guess_mm = 20 (must be within [-10, 10])");
  }
  guess[4] = 0;
  try {
    FitLuGreDynamic(FastStroke(1), guess, 0.0);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "initial_theta.sigma0_per_mm = 0 (must be finite and > 0)");
  }
}

// ---------------------------------------------------------------- EKF

LuGreEkfOptions EkfOptions() {
  LuGreEkfOptions o;
  o.x0 = Eigen::Vector2d(20.0, 0.0);  // truth sigma0 = 50
  o.P0 = (Eigen::Matrix2d() << 900.0, 0.0, 0.0, 1e-6).finished();
  o.R = kNoise * kNoise;
  return o;
}

TEST(EkfTest, JacobiansMatchPerturbation) {
  const LuGreStiffnessEkf ekf(Truth(), EkfOptions());
  for (double v : {-3.0, 0.2, 4.0}) {
    const Eigen::Vector2d x(42.0, 0.007);
    LuGreStiffnessEkf::StateCov Phi;
    ekf.CalcProcess(x, 0.005, v, &Phi);
    auto fp = [&](const VectorXd& xx) {
      return VectorXd(ekf.CalcProcess(Eigen::Vector2d(xx), 0.005, v, nullptr));
    };
    EXPECT_TRUE(
        internal::CheckJacobian<double>(fp, VectorXd(x), Eigen::MatrixXd(Phi)))
        << v;
    LuGreStiffnessEkf::Row H;
    ekf.CalcMeasurement(x, v, &H);
    auto fm = [&](const VectorXd& xx) {
      return VectorXd::Constant(
          1, ekf.CalcMeasurement(Eigen::Vector2d(xx), v, nullptr));
    };
    EXPECT_TRUE(
        internal::CheckJacobian<double>(fm, VectorXd(x), Eigen::MatrixXd(H)))
        << v;
  }
}

TEST(EkfTest, RecoversStiffnessLikeTheLmFits) {
  const LuGreFitResult qs = FitLuGreQuasiStatic(SlowStroke(7), kFarQuasiStatic);
  ASSERT_EQ(qs.status, LuGreFitStatus::kConverged) << qs.why;
  const LuGreFitResult r = FitLuGreEkf(FastStroke(107), qs.theta, EkfOptions());
  std::cout << "EKF: sigma0 = " << r.theta[4] << " +- "
            << std::sqrt(r.P_theta(4, 4)) << ", sigma1 = " << r.theta[5]
            << ", z_end = " << r.z0_mm
            << ", innovation rms = " << r.residual_rms
            << ", excited = " << r.excited_samples << "\n";
  ASSERT_EQ(r.status, LuGreFitStatus::kConverged) << r.why;
  EXPECT_LT(RelErr(r.theta[4], 50.0), 0.10)
      << "sigma0 expected 50, got " << r.theta[4];
  EXPECT_NEAR(r.theta[4], 50.0, 4 * std::sqrt(r.P_theta(4, 4)) + 1.0);
}

TEST(EkfTest, SteadySlidingIsNotObservable) {
  const LuGreTheta truth = Truth();
  const double z_ss = CalcStribeckRatio(truth, 8.0) / truth[4];
  const LuGreStroke s = SimulateStroke(
      truth, [](double) { return 8.0; }, 1.0, 200.0, kNoise, 5, z_ss);
  LuGreEkfOptions o = EkfOptions();
  o.x0[1] = z_ss;
  const LuGreFitResult r = FitLuGreEkf(s, truth, o);
  EXPECT_EQ(r.status, LuGreFitStatus::kNotObservable) << r.why;
}

TEST(EkfTest, FilterLoopDoesNotAllocate) {
  const LuGreFitResult qs = FitLuGreQuasiStatic(SlowStroke(7), kFarQuasiStatic);
  const LuGreStroke s = FastStroke(107);
  LuGreStiffnessEkf ekf(qs.theta, EkfOptions());
  // The check is live: an allocation in the forbidden region is counted.
  const int before = g_eigen_assert_failures;
  Eigen::internal::set_is_malloc_allowed(false);
  {
    VectorXd probe(16);
    (void)probe;
  }
  Eigen::internal::set_is_malloc_allowed(true);
  ASSERT_GT(g_eigen_assert_failures, before)
      << "EIGEN_RUNTIME_NO_MALLOC check is not active";
  const int baseline = g_eigen_assert_failures;
  const Eigen::Index n = s.size();
  Eigen::internal::set_is_malloc_allowed(false);
  for (Eigen::Index k = 0; k < n; ++k) {
    if (k > 0)
      ekf.Predict(s.t_s[k] - s.t_s[k - 1],
                  0.5 * (s.v_mm_s[k - 1] + s.v_mm_s[k]));
    ekf.Update(s.v_mm_s[k], s.mu[k]);
  }
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_EQ(g_eigen_assert_failures, baseline)
      << "the EKF loop allocated or failed an assertion";
  EXPECT_NEAR(ekf.state()[0], 50.0, 5.0);
}

TEST(EkfTest, RejectsBadOptionsNamingFieldValueAndRule) {
  LuGreEkfOptions o;
  o.R = 0;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why, "R = 0 (must be finite and > 0)");
  try {
    LuGreStiffnessEkf ekf(Truth(), o);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "LuGreEkfOptions.R = 0 (must be finite and > 0)");
  }
}

// ---------------------------------------------------------------- speed

// Issue 5 item 5 at the other sampling rates of the issue (200 Hz above).
// Same truth, noise, seeds and far starts as TwoStrokeIdentification.
// 300 Hz: every LM variant and the EKF recover sigma0 within 10 % from the
// 20 mm/s^2 stroke. 50 Hz: that stroke's presliding lasts ~40 ms, 2 samples
// with |dz/dt| > 2 % of max|v|, so every variant must say kNotObservable
// rather than return a sigma0; a reciprocating stroke at the same
// acceleration adds two reversals (8 excited samples) and must recover
// sigma0 within 10 % again.
TEST(DynamicFitTest, Sigma0RecoveredAt50And300Hz) {
  const LuGreTheta truth = Truth();
  const std::vector<DynamicFitVariant> variants = {DynamicFitVariant::kLm1,
                                                   DynamicFitVariant::kLm2,
                                                   DynamicFitVariant::kLm6};
  auto fit = [](const LuGreStroke& fast,
                const LuGreFitResult& quasi_static,
                DynamicFitVariant variant) {
    LuGreTheta guess = quasi_static.theta;
    guess[LuGreIndex::kStiffness] = 10.0;  // truth 50
    guess[LuGreIndex::kDamping] = 0.01;    // truth 0.1
    DynamicFitOptions options;
    options.variant = variant;
    return FitLuGreDynamic(fast, guess, 0.0, options);
  };
  auto expect_near_truth = [&truth](const LuGreFitResult& r,
                                    const std::string& what) {
    ASSERT_EQ(r.status, LuGreFitStatus::kConverged) << what << ": " << r.why;
    std::cout << what << ": sigma0 = " << r.theta[4] << " +- "
              << std::sqrt(r.P_theta(4, 4)) << ", sigma1 = " << r.theta[5]
              << ", mu_s = " << r.theta[0] << ", mu_c = " << r.theta[1]
              << ", excited = " << r.excited_samples << "\n";
    EXPECT_LT(RelErr(r.theta[0], truth[0]), 0.02) << what << ": mu_s";
    EXPECT_LT(RelErr(r.theta[1], truth[1]), 0.02) << what << ": mu_c";
    EXPECT_LT(RelErr(r.theta[4], truth[4]), 0.10)
        << what << ": sigma0 expected 50, got " << r.theta[4];
  };
  for (double fs : {50.0, 300.0}) {
    const std::string hz = std::to_string(static_cast<int>(fs)) + " Hz";
    const LuGreFitResult qs =
        FitLuGreQuasiStatic(SlowStroke(7, fs), kFarQuasiStatic);
    ASSERT_EQ(qs.status, LuGreFitStatus::kConverged) << hz << ": " << qs.why;
    LuGreStroke fast = FastStroke(107, fs);
    if (fs < 100) {
      for (DynamicFitVariant variant : variants) {
        const LuGreFitResult r = fit(fast, qs, variant);
        EXPECT_EQ(r.status, LuGreFitStatus::kNotObservable)
            << hz << ", 20 mm/s^2, variant " << static_cast<int>(variant)
            << ": " << r.why << ", sigma0 " << r.theta[4];
      }
      // Reciprocating at 20 mm/s^2, 0 -> 10 -> -10 -> 10 -> 0 mm/s: each
      // reversal moves the bristle by 2 g / sigma0 (~3 samples at 50 Hz).
      fast = SimulateStroke(
          Truth(),
          [](double t) {
            if (t < 0.5) return 20.0 * t;
            if (t < 1.5) return 20.0 - 20.0 * t;
            if (t < 2.5) return 20.0 * t - 40.0;
            return 60.0 - 20.0 * t;
          },
          3.0,
          fs,
          kNoise,
          107);
    }
    for (DynamicFitVariant variant : variants) {
      expect_near_truth(
          fit(fast, qs, variant),
          hz + ", variant " + std::to_string(static_cast<int>(variant)));
    }
    expect_near_truth(
        [&] {
          LuGreFitResult r = FitLuGreEkf(fast, qs.theta, EkfOptions());
          // The EKF estimates [sigma0, z]; the Stribeck part is Step 1's.
          return r;
        }(),
        hz + ", EKF");
  }
}

TEST(IdentificationSpeedTest, FullSixParameterIdentificationOfTwoStrokes) {
  const LuGreStroke slow = SlowStroke(7);
  const LuGreStroke fast = FastStroke(107);
  std::vector<double> ms;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    const LuGreFitResult qs = FitLuGreQuasiStatic(slow, kFarQuasiStatic);
    LuGreTheta guess = qs.theta;
    guess[4] = 10.0;
    guess[5] = 0.01;
    const LuGreFitResult dyn = FitLuGreDynamic(fast, guess, 0.0);
    ms.push_back(std::chrono::duration<double, std::milli>(
                     std::chrono::steady_clock::now() - t0)
                     .count());
    ASSERT_EQ(dyn.status, LuGreFitStatus::kConverged) << dyn.why;
  }
  std::sort(ms.begin(), ms.end());
  std::cout << "two-stroke identification (" << slow.size() << " + "
            << fast.size() << " samples): median " << ms[2] << " ms\n";
  EXPECT_LT(ms[2], 50.0);
}

// ---------------------------------------------------------------- measured

struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<double>> columns;
  int Column(const std::string& name) const {
    for (size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    return -1;
  }
};

bool ReadCsv(const std::string& path, Csv* csv) {
  std::ifstream in(path);
  if (!in) return false;
  std::string line;
  if (!std::getline(in, line)) return false;
  std::stringstream hs(line);
  for (std::string cell; std::getline(hs, cell, ',');)
    csv->header.push_back(cell);
  csv->columns.assign(csv->header.size(), {});
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::stringstream ls(line);
    size_t i = 0;
    for (std::string cell;
         std::getline(ls, cell, ',') && i < csv->header.size();
         ++i) {
      csv->columns[i].push_back(std::strtod(cell.c_str(), nullptr));
    }
    if (i != csv->header.size()) return false;
  }
  return true;
}

TEST(MeasuredDataTest, LuGreBeatsCoulombOnHeldOutCycles) {
  const char* root = std::getenv("FRICTIOND_SOURCE_DIR");
  if (!root) GTEST_SKIP() << "FRICTIOND_SOURCE_DIR not set";
  const std::string path =
      std::string(root) + "/data/microtribo_recip/test_data_2.strokes.csv";
  Csv csv;
  ASSERT_TRUE(ReadCsv(path, &csv)) << path;
  const int ct = csv.Column("t_s"), cfn = csv.Column("fn_n"),
            cft = csv.Column("ft_n"), cv = csv.Column("v_mm_s"),
            cd = csv.Column("dir_sign");
  ASSERT_TRUE(ct >= 0 && cfn >= 0 && cft >= 0 && cv >= 0 && cd >= 0);
  // Constant-load part only (Fn = 5 N from 7.7 s to 209.8 s).
  std::vector<double> t, v, ft_ratio;
  for (size_t k = 0; k < csv.columns[ct].size(); ++k) {
    const double tk = csv.columns[ct][k];
    if (tk < 8.0 || tk > 209.5 || csv.columns[cfn][k] < 4.9) continue;
    t.push_back(tk);
    v.push_back(csv.columns[cd][k] * csv.columns[cv][k]);
    ft_ratio.push_back(csv.columns[cft][k] / csv.columns[cfn][k]);
  }
  const int n = static_cast<int>(t.size());
  ASSERT_GT(n, 30000);
  // Sign of the force: Ft is a magnitude. After each reversal of the stage
  // the force keeps its old sign until |Ft| passes its minimum (the force
  // reversal, ~0.3 s into the stroke), then takes the new direction.
  // motion_dir is the Coulomb model's direction (last clear motion).
  std::vector<int> motion_dir(n, 0), force_dir(n, 0);
  std::vector<int> reversals;  // index of the force zero crossing
  int dir = 0;
  std::vector<std::pair<int, int>> flips;  // (index of force zero, new dir)
  for (int k = 0; k < n; ++k) {
    const int s = v[k] > 0.05 ? 1 : (v[k] < -0.05 ? -1 : 0);
    if (s != 0 && s != dir) {
      if (dir != 0) {
        int best = k;
        for (int j = std::max(0, k - 40); j < std::min(n, k + 200); ++j)
          if (ft_ratio[j] < ft_ratio[best]) best = j;
        flips.push_back({best, s});
      } else {
        flips.push_back({0, s});
      }
      dir = s;
    }
    motion_dir[k] = dir;
  }
  size_t f = 0;
  int fdir = flips.empty() ? 1 : flips[0].second;
  for (int k = 0; k < n; ++k) {
    while (f < flips.size() && flips[f].first <= k) fdir = flips[f++].second;
    force_dir[k] = fdir;
  }
  std::cout << "measured: " << n << " samples, " << flips.size() - 1
            << " reversals\n";
  ASSERT_GT(flips.size(), 80u);
  LuGreStroke all;
  all.t_s = Eigen::Map<const VectorXd>(t.data(), n);
  all.v_mm_s = Eigen::Map<const VectorXd>(v.data(), n);
  all.mu.resize(n);
  for (int k = 0; k < n; ++k) all.mu[k] = force_dir[k] * ft_ratio[k];
  // Train on the first 10 cycles (20 reversals), hold out the rest.
  const int split = flips[21].first - 100;  // in the dwell before reversal 21
  LuGreStroke train;
  train.t_s = all.t_s.head(split);
  train.v_mm_s = all.v_mm_s.head(split);
  train.mu = all.mu.head(split);

  DynamicFitOptions options;
  options.variant = DynamicFitVariant::kLm6;
  const LuGreTheta guess = MakeLuGreTheta(0.5, 0.45, 0.05, 0.0, 10.0, 0.01);
  const LuGreFitResult fit = FitLuGreDynamic(train, guess, 0.0, options);
  std::cout << "LM-6 on " << split << " samples: " << ToString(fit.status)
            << " " << fit.why << "\n  theta = " << fit.theta.transpose()
            << ", z0 = " << fit.z0_mm
            << "\n  std   = " << fit.P_theta.diagonal().cwiseSqrt().transpose()
            << "\n  train rms = " << fit.residual_rms
            << ", iterations = " << fit.iterations << "\n";
  // Measured (docs/lugre.md): LM-6 does not settle here (kMaxIterations)
  // and bends the Stribeck curve to mimic the stage's presliding shape, so
  // its six numbers are not material constants. Accept either outcome.
  ASSERT_TRUE(fit.status == LuGreFitStatus::kConverged ||
              fit.status == LuGreFitStatus::kMaxIterations)
      << fit.why;

  // Coulomb: mu = c * (direction of the last motion), c fitted on training.
  double c = 0;
  for (int k = 0; k < split; ++k) c += all.mu[k] * motion_dir[k];
  c /= split;
  // Predict the whole record from the training z0 (no re-initialisation).
  VectorXd mu_lugre;
  CalcLuGreDiscreteResponse(
      fit.theta, fit.z0_mm, all.t_s, all.v_mm_s, &mu_lugre);
  double sse_l = 0, sse_c = 0, sse_l_slide = 0, sse_c_slide = 0, sse_l_pre = 0,
         sse_c_pre = 0;
  int m = 0, m_slide = 0, m_pre = 0;
  for (int k = split; k < n; ++k) {
    const double el = mu_lugre[k] - all.mu[k];
    const double ec = c * motion_dir[k] - all.mu[k];
    sse_l += el * el;
    sse_c += ec * ec;
    ++m;
    if (motion_dir[k] * force_dir[k] > 0 && std::abs(all.v_mm_s[k]) > 0.05) {
      sse_l_slide += el * el;
      sse_c_slide += ec * ec;
      ++m_slide;
    } else if (motion_dir[k] * force_dir[k] < 0) {
      sse_l_pre += el * el;
      sse_c_pre += ec * ec;
      ++m_pre;
    }
  }
  const double rmse_l = std::sqrt(sse_l / m), rmse_c = std::sqrt(sse_c / m);
  std::cout << "held-out " << m << " samples: RMSE LuGre = " << rmse_l
            << ", Coulomb (c = " << c << ") = " << rmse_c << "\n"
            << "  moving with the force along the motion (" << m_slide
            << "): LuGre " << std::sqrt(sse_l_slide / m_slide) << ", Coulomb "
            << std::sqrt(sse_c_slide / m_slide) << "\n"
            << "  force still opposite the new motion (" << m_pre << "): LuGre "
            << std::sqrt(sse_l_pre / m_pre) << ", Coulomb "
            << std::sqrt(sse_c_pre / m_pre) << "\n";
  EXPECT_LT(rmse_l, rmse_c);
  EXPECT_LT(std::sqrt(sse_l_pre / m_pre), std::sqrt(sse_c_pre / m_pre));
}

}  // namespace
}  // namespace frictiond
