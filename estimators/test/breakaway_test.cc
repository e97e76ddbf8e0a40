#include "frictiond/estimators/breakaway.h"

#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/estimators/lugre_identification.h"

namespace frictiond {
namespace {

using Eigen::VectorXd;

constexpr double kNoise = 0.005;
constexpr double kFn = 5.0;

LuGreTheta Truth() { return MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1); }

LuGreStroke SimulateStroke(const std::function<double(double)>& v_of_t,
                           double duration_s,
                           unsigned seed) {
  const int n = static_cast<int>(std::round(duration_s * 200.0)) + 1;
  LuGreStroke s;
  s.t_s = VectorXd::LinSpaced(n, 0.0, (n - 1) / 200.0);
  s.v_mm_s.resize(n);
  for (int k = 0; k < n; ++k) s.v_mm_s[k] = v_of_t(s.t_s[k]);
  const VelocityDrivenResult r =
      SimulateVelocityDriven(Truth(), s.t_s, s.v_mm_s, 0.0);
  EXPECT_EQ(r.status, SimulationStatus::kOk) << r.why;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, kNoise);
  s.mu = r.mu;
  for (int k = 0; k < n; ++k) s.mu[k] += gauss(rng);
  return s;
}

// Two-stroke identification (paper Steps 1-2) from far starts, seed 7.
LuGreTheta Identify(DynamicFitVariant variant, bool ekf) {
  const LuGreStroke slow = SimulateStroke(
      [](double t) { return t < 10 ? 2.0 * t : 40.0 - 2.0 * t; }, 20.0, 7);
  const LuGreStroke fast = SimulateStroke(
      [](double t) { return t < 0.5 ? 20.0 * t : 20.0 - 20.0 * t; }, 1.0, 107);
  const LuGreFitResult qs =
      FitLuGreQuasiStatic(slow, Eigen::Vector4d(0.3, 0.2, 1.0, 0.0));
  EXPECT_EQ(qs.status, LuGreFitStatus::kConverged) << qs.why;
  if (ekf) {
    LuGreEkfOptions o;
    o.x0 = Eigen::Vector2d(20.0, 0.0);
    o.P0 = (Eigen::Matrix2d() << 900.0, 0.0, 0.0, 1e-6).finished();
    o.R = kNoise * kNoise;
    const LuGreFitResult r = FitLuGreEkf(fast, qs.theta, o);
    EXPECT_EQ(r.status, LuGreFitStatus::kConverged) << r.why;
    return r.theta;
  }
  LuGreTheta guess = qs.theta;
  guess[LuGreIndex::kStiffness] = 10.0;
  guess[LuGreIndex::kDamping] = 0.01;
  DynamicFitOptions options;
  options.variant = variant;
  const LuGreFitResult r = FitLuGreDynamic(fast, guess, 0.0, options);
  EXPECT_EQ(r.status, LuGreFitStatus::kConverged) << r.why;
  return r.theta;
}

TEST(BreakawayPredictionTest,
     IdentifiedModelPredictsTruthBfRatioWithin3Percent) {
  struct Case {
    const char* name;
    LuGreTheta theta;
  };
  const Case cases[] = {
      {"GN+LM-1", Identify(DynamicFitVariant::kLm1, false)},
      {"GN+LM-2", Identify(DynamicFitVariant::kLm2, false)},
      {"LM-6 (two strokes)", Identify(DynamicFitVariant::kLm6, false)},
      {"GN+EKF", Identify(DynamicFitVariant::kLm1, true)}};
  for (double rho : {0.05, 0.5, 5.0}) {
    const ForceDrivenResult truth = PredictBreakawayRatio(Truth(), rho, kFn);
    ASSERT_EQ(truth.status, SimulationStatus::kOk) << truth.why;
    for (const Case& c : cases) {
      const ForceDrivenResult p = PredictBreakawayRatio(c.theta, rho, kFn);
      ASSERT_EQ(p.status, SimulationStatus::kOk) << c.name << ": " << p.why;
      const double err = std::abs(p.bf_ratio - truth.bf_ratio) / truth.bf_ratio;
      std::cout << "rho " << rho << " " << c.name << ": BF " << p.bf_ratio
                << " vs truth " << truth.bf_ratio << " (" << 100 * err
                << " %)\n";
      EXPECT_LT(err, 0.03) << c.name << " rho " << rho << ": expected "
                           << truth.bf_ratio << ", got " << p.bf_ratio;
    }
  }
}

TEST(BreakawayPredictionTest, BfRatioIsBetweenCoulombAndStatic) {
  // Paper Section V.B.1: the actual BF-ratio lies between mu_c and mu_s, so
  // mu_s as a slip threshold over-estimates it.
  for (double rho : {0.1, 1.0, 10.0}) {
    const ForceDrivenResult p = PredictBreakawayRatio(Truth(), rho, kFn);
    ASSERT_EQ(p.status, SimulationStatus::kOk) << p.why;
    EXPECT_GT(p.bf_ratio, 0.6) << rho;
    EXPECT_LT(p.bf_ratio, 0.9 + 1e-3) << rho;
  }
}

TEST(BreakawayMonitorTest, MarginShrinksToZeroAtTheTruthBreakaway) {
  const double rho = 0.5;
  const double bf_truth = PredictBreakawayRatio(Truth(), rho, kFn).bf_ratio;
  BreakawayMonitorOptions options;
  options.rho_rel_change = 0.01;  // rho is constant: one simulation
  BreakawayMonitor monitor(Identify(DynamicFitVariant::kLm2, false), options);
  double previous_margin = 2.0;
  double slip_at = -1;
  for (int k = 0; k < 200 && slip_at < 0; ++k) {  // 50 Hz, Ft/Fn = rho t
    const double mu = rho * k / 50.0;
    const BreakawayEstimate e = monitor.Update(mu, rho);
    ASSERT_EQ(e.status, SimulationStatus::kOk);
    EXPECT_LT(e.margin, previous_margin);
    previous_margin = e.margin;
    if (e.slip_predicted) slip_at = mu;
  }
  std::cout << "monitor: slip predicted at Ft/Fn = " << slip_at << ", truth BF "
            << bf_truth << ", simulations " << monitor.simulations() << "\n";
  EXPECT_EQ(monitor.simulations(), 1);
  // The monitor sees Ft/Fn in steps of rho / 50 (one 50 Hz sample): it
  // must flag the first sample at or past the truth's break-away, within
  // the simulation's own tolerance (1e-3 relative).
  EXPECT_GE(slip_at, bf_truth * (1 - 1e-3));
  EXPECT_LE(slip_at, bf_truth * (1 + 1e-3) + rho / 50.0);
  EXPECT_LE(monitor.last().margin, 0.0);
}

TEST(BreakawayMonitorTest, FasterLoadingLowersThePrediction) {
  BreakawayMonitor monitor(Truth());
  const BreakawayEstimate slow = monitor.Update(0.3, 0.1);
  const BreakawayEstimate fast = monitor.Update(0.3, 5.0);
  const BreakawayEstimate unloading = monitor.Update(0.3, -1.0);
  EXPECT_GT(slow.bf_ratio, fast.bf_ratio);
  EXPECT_LT(fast.margin, slow.margin);
  // rho <= 0 is predicted at min_rho_per_s: the slow-loading limit.
  EXPECT_DOUBLE_EQ(unloading.rho_per_s,
                   BreakawayMonitorOptions().min_rho_per_s);
  EXPECT_GE(unloading.bf_ratio, slow.bf_ratio);
  EXPECT_EQ(monitor.simulations(), 3);
}

TEST(BreakawayMonitorTest, RejectsBadInputNamingFieldValueAndRule) {
  BreakawayMonitorOptions options;
  options.fn_n = 0;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why, "fn_n = 0.000000 (must be finite and > 0)");
  options = BreakawayMonitorOptions();
  options.simulation.rel_tol = -1;
  try {
    BreakawayMonitor monitor(Truth(), options);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "BreakawayMonitorOptions.simulation.rel_tol = -1 (must be finite "
              "and > 0)");
  }
  BreakawayMonitor monitor(Truth());
  EXPECT_THROW(monitor.Update(std::nan(""), 0.1), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
