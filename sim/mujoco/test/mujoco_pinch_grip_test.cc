// Two-contact grip force (pinch_grip.h) against closed forms.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <gtest/gtest.h>

#include "frictiond/estimators/eps_time.h"
#include "frictiond/mujoco/pinch_grip.h"

namespace frictiond::mujoco {
namespace {

StochasticFrictionModel Normal(double b0, double b2, double sigma) {
  StochasticFrictionModel t;
  t.mu.terms = {
      Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")};
  t.mu.beta = Eigen::Vector3d(b0, -0.002, b2);
  t.mu.sigma_eps = sigma;
  t.mu.samples = 100000;
  for (double p : EpsQuantileLevels())
    t.mu.eps_quantiles.push_back(CalcEpsQuantile(t.mu, p));
  return t;
}

double Phi(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }

TEST(PinchGrip, NormalEpsSumIsNormal) {
  const StochasticFrictionModel a = Normal(0.8, -0.01, 0.1);
  const StochasticFrictionModel b = Normal(0.6, -0.005, 0.07);
  const double load = 3.0;
  for (double fn : {1.8, 2.2, 2.6, 3.0}) {
    // eps_a + eps_b ~ N(0, sqrt(0.1^2 + 0.07^2)).
    const double c = load / fn - (0.8 - 0.01 * fn) - (0.6 - 0.005 * fn);
    const double truth = Phi(c / std::hypot(0.1, 0.07));
    EXPECT_NEAR(CalcPinchSlipProbability(a, b, fn, load), truth, 2e-3)
        << "Fn " << fn;
  }
  for (double risk : {0.01, 0.05, 0.2}) {
    const PinchGripForce g = CalcPinchGripForce(a, b, load, risk);
    ASSERT_TRUE(g.attainable);
    EXPECT_NEAR(g.slip_probability, risk, 1e-3);
    // A higher risk needs less force.
    EXPECT_LT(CalcPinchGripForce(a, b, load, risk * 2).fn_n, g.fn_n);
  }
}

TEST(PinchGrip, UnattainableAndRefusals) {
  const StochasticFrictionModel a = Normal(0.8, -0.01, 0.1);
  // Largest capacity Fn (1.6 - 0.02 Fn) is 32 N at Fn = 40 N.
  EXPECT_FALSE(CalcPinchGripForce(a, a, 40.0, 0.05).attainable);
  EXPECT_THROW(CalcPinchGripForce(a, a, -1.0, 0.05), std::invalid_argument);
  EXPECT_THROW(CalcPinchGripForce(a, a, 1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(CalcPinchSlipProbability(a, a, std::nan(""), 1.0),
               std::invalid_argument);
}

TEST(PinchHoldRisk, EpsHeldPerEpisodeIsTheConvolution) {
  // No eps time model: one draw per hold, the case CalcPinchSlipProbability
  // computes exactly.
  const StochasticFrictionModel a = Normal(0.8, -0.01, 0.1);
  const StochasticFrictionModel b = Normal(0.6, -0.005, 0.07);
  const PinchHoldRisk hold(a, b, 3.0);
  EXPECT_EQ(hold.samples_a(), 1);
  for (double fn : {1.8, 2.2, 2.6}) {
    const double exact = CalcPinchSlipProbability(a, b, fn, 3.0);
    // Monte Carlo: 4 standard errors of 200,000 paths, plus the grid.
    EXPECT_NEAR(hold.SlipProbability(fn),
                exact,
                4 * std::sqrt(exact * (1 - exact) / 200000) + 2e-3)
        << "Fn " << fn;
  }
  const PinchGripForce g = hold.GripForce(0.05);
  ASSERT_TRUE(g.attainable);
  EXPECT_NEAR(g.fn_n, CalcPinchGripForce(a, b, 3.0, 0.05).fn_n, 0.01);
}

TEST(PinchHoldRisk, OneNoisyContactIsTheServicesHoldRisk) {
  // Contact b without eps: the pinch's hold risk is contact a's
  // first-passage probability (eps_time.h, CalcHoldCrossingProbability).
  StochasticFrictionModel a = Normal(0.8, -0.01, 0.1);
  a.eps_time.valid = true;
  a.eps_time.dt_s = 0.01;
  a.eps_time.phi = 0.9;
  a.eps_time.offset_fraction = 0.4;
  StochasticFrictionModel b = Normal(0.6, -0.005, 0.0);
  std::fill(b.mu.eps_quantiles.begin(), b.mu.eps_quantiles.end(), 0.0);
  PinchHoldOptions o;
  o.hold_s = 0.5;
  const PinchHoldRisk hold(a, b, 3.0, o);
  EXPECT_EQ(hold.samples_a(), 51);
  EXPECT_EQ(hold.samples_b(), 1);
  for (double fn : {2.2, 2.4, 2.6}) {
    const double c = 3.0 / fn - (0.8 - 0.01 * fn) - (0.6 - 0.005 * fn);
    const double z = c / 0.1;  // eps_a ~ N(0, 0.1): latent level
    const double exact = CalcHoldCrossingProbability(z, 51, 0.9, 0.4);
    EXPECT_NEAR(hold.SlipProbability(fn),
                exact,
                4 * std::sqrt(exact * (1 - exact) / 200000) + 2e-3)
        << "Fn " << fn;
  }
  EXPECT_THROW(PinchHoldRisk(a, b, -1.0), std::invalid_argument);
  EXPECT_THROW(hold.GripForce(0.0), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond::mujoco
