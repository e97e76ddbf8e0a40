#include "frictiond/estimators/control.h"

#include <cmath>

#include <gtest/gtest.h>

#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using testing::SimulateStrokes;
using testing::SimulationSpec;

// One fit of the default truth (b0 = 0.9, b1 = 0.004, b2 = -0.06,
// sigma_eps = 0.05), seed 7.
const StochasticFrictionModel& FittedModel() {
  static const StochasticFrictionModel model = [] {
    const StochasticFit fit = FitStochasticModel(SimulateStrokes({}, 7));
    EXPECT_EQ(fit.status, FitStatus::kOk) << fit.why;
    return fit.model;
  }();
  return model;
}

TEST(Control, TargetForceIsEquationThreeOfTheFittedCoefficients) {
  const StochasticFrictionModel& m = FittedModel();
  ASSERT_EQ(m.mu.terms.size(), 3u);
  const double b0 = m.mu.beta(0), b1 = m.mu.beta(1), b2 = m.mu.beta(2);
  const InputStats fn_in = m.inputs.at("fn_n"), v_in = m.inputs.at("v_mm_s");
  for (double a : {0.2, 0.5, 0.8}) {
    const double fn = fn_in.min + a * (fn_in.max - fn_in.min);
    for (double b : {0.2, 0.5, 0.8}) {
      const double v = v_in.min + b * (v_in.max - v_in.min);
      const TargetForce f = CalcTargetTangentialForce(m, fn, v);
      const double eq3 = b0 * fn + b1 * v * fn + b2 * fn * fn;
      EXPECT_NEAR(f.ft_n, eq3, 1e-12) << "fn " << fn << " v " << v;
      EXPECT_LT(f.ft_lo95_n, f.ft_n);
      EXPECT_GT(f.ft_hi95_n, f.ft_n);
      EXPECT_FALSE(f.extrapolated);
    }
  }
  EXPECT_TRUE(CalcTargetTangentialForce(m, 9.0, 40.0).extrapolated);
}

TEST(Control, TargetForceRecoversTruthWithinParameterUncertainty) {
  const SimulationSpec truth;
  const StochasticFrictionModel& m = FittedModel();
  for (double fn : {1.0, 2.5, 4.0}) {
    for (double v : {20.0, 60.0}) {
      const double ft_truth =
          truth.b0 * fn + truth.b1 * v * fn + truth.b2 * fn * fn;
      Eigen::Vector3d x(1.0, v, fn);
      const double se_mu = std::sqrt(x.dot(m.mu.P_beta * x));
      const TargetForce f = CalcTargetTangentialForce(m, fn, v);
      EXPECT_NEAR(f.ft_n, ft_truth, 4 * se_mu * fn)
          << "fn " << fn << " v " << v;
      // The truth is far from a do-nothing answer.
      EXPECT_GT(ft_truth, 0.3 * fn);
    }
  }
}

TEST(Control, EquationFourInvertsEquationThree) {
  const StochasticFrictionModel& m = FittedModel();
  for (double fn : {0.8, 2.5, 4.2}) {
    for (double v : {15.0, 40.0, 75.0}) {
      const TargetForce f = CalcTargetTangentialForce(m, fn, v);
      const SlidingSpeed s = PredictSlidingSpeed(m, fn, f.ft_n);
      ASSERT_EQ(s.status, SlidingSpeedStatus::kOk) << s.why;
      EXPECT_NEAR(s.v_mm_s, v, 1e-9) << "fn " << fn;
      EXPECT_LT(s.v_lo95_mm_s, v);
      EXPECT_GT(s.v_hi95_mm_s, v);
      EXPECT_FALSE(s.below_model_range);
    }
  }
  // Far below mu_hat(Fn, 0): the model says it sticks.
  EXPECT_TRUE(PredictSlidingSpeed(m, 2.0, 0.2).below_model_range);
}

TEST(Control, EquationFourOnHeldOutSlipSamplesIsUnbiasedAndCovered) {
  // Speeds predicted from the forces of a new simulation (seed 8) against
  // the speeds it actually had: no bias, spread sigma_eps/b1 = 12.5 mm/s,
  // and the 95 % interval covers about 95 % of samples.
  SimulationSpec spec;
  spec.write_labels = true;
  const StrokeData d = SimulateStrokes(spec, 8);
  const StochasticFrictionModel& m = FittedModel();
  double sum_err = 0, sum_err2 = 0;
  int n = 0, covered = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (!d.slip[i] || d.fn_n[i] >= 5.0) continue;
    const SlidingSpeed s = PredictSlidingSpeed(m, d.fn_n[i], d.ft_n[i]);
    ASSERT_EQ(s.status, SlidingSpeedStatus::kOk);
    const double e = s.v_mm_s - d.v_mm_s[i];
    sum_err += e;
    sum_err2 += e * e;
    covered += s.v_lo95_mm_s <= d.v_mm_s[i] && d.v_mm_s[i] <= s.v_hi95_mm_s;
    ++n;
  }
  ASSERT_GT(n, 1000);
  const double mean = sum_err / n;
  const double sd = std::sqrt(sum_err2 / n - mean * mean);
  const double sd_truth = spec.sigma_eps / spec.b1;
  EXPECT_NEAR(mean, 0.0, 0.1 * sd_truth);
  EXPECT_NEAR(sd, sd_truth, 0.15 * sd_truth);
  const double coverage = static_cast<double>(covered) / n;
  EXPECT_GT(coverage, 0.92);
  EXPECT_LT(coverage, 0.98);
}

TEST(Control, EquationFourRefusesModelsWithoutALinearSpeedTerm) {
  StochasticFitOptions fn_only;
  fn_only.terms = {"intercept", "fn_n"};
  const StochasticFit a = FitStochasticModel(SimulateStrokes({}, 3), fn_only);
  ASSERT_EQ(a.status, FitStatus::kOk) << a.why;
  const SlidingSpeed s = PredictSlidingSpeed(a.model, 2.0, 1.7);
  EXPECT_EQ(s.status, SlidingSpeedStatus::kNoSpeedTerm);
  EXPECT_NE(s.why.find("b1 = 0"), std::string::npos) << s.why;

  StochasticFitOptions quadratic;
  quadratic.terms = {"intercept", "v_mm_s", "v_mm_s^2", "fn_n"};
  const StochasticFit b = FitStochasticModel(SimulateStrokes({}, 3), quadratic);
  const SlidingSpeed q = PredictSlidingSpeed(b.model, 2.0, 1.7);
  EXPECT_EQ(q.status, SlidingSpeedStatus::kNonLinearInV);
  EXPECT_NE(q.why.find("v_mm_s^2"), std::string::npos) << q.why;
}

TEST(Control, BadForcesThrowNamingTheArgument) {
  const StochasticFrictionModel& m = FittedModel();
  try {
    CalcTargetTangentialForce(m, 0.0, 10.0);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fn_n = 0"), std::string::npos);
  }
  EXPECT_THROW(CalcTargetTangentialForce(m, 1.0, -1.0), std::invalid_argument);
  EXPECT_THROW(CalcTargetTangentialForce(m, 1.0, NAN), std::invalid_argument);
  try {
    PredictSlidingSpeed(m, 1.0, -0.5);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ft_n = -0.5"), std::string::npos);
  }
}

}  // namespace
}  // namespace frictiond
