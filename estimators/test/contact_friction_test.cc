#include "frictiond/estimators/contact_friction.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

// Known truth: mu = b0 + b1*v + b2*Fn + eps with eps ~ U(-half, half), whose
// quantile function -half + 2*half*p is linear, so the stored quantiles
// interpolate it exactly at every p in [0.001, 0.999].
constexpr double kB0 = 0.9, kB1 = 0.004, kB2 = -0.06, kHalf = 0.1;

StochasticFrictionModel UniformEpsModel(double intercept_var = 0.0) {
  StochasticFrictionModel m;
  m.mu.terms = {
      Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")};
  m.mu.beta = Eigen::Vector3d(kB0, kB1, kB2);
  m.mu.std_err = Eigen::Vector3d(std::sqrt(intercept_var), 0.0, 0.0);
  m.mu.P_beta = Eigen::Matrix3d::Zero();
  m.mu.P_beta(0, 0) = intercept_var;
  m.mu.sigma_eps = 2 * kHalf / std::sqrt(12.0);
  for (double p : EpsQuantileLevels())
    m.mu.eps_quantiles.push_back(-kHalf + 2 * kHalf * p);
  m.inputs["fn_n"] = {2.5, 0.5, 4.5};
  m.inputs["v_mm_s"] = {40.0, 15.0, 80.0};
  return m;
}

double TruthQuantile(double fn_n, double v_mm_s, double p, double widen = 1) {
  return kB0 + kB1 * v_mm_s + kB2 * fn_n + widen * (-kHalf + 2 * kHalf * p);
}

TEST(ContactFriction, RiskQuantileEqualsAnalyticalQuantile) {
  const StochasticFrictionModel m = UniformEpsModel();
  const double fn = 3.0, v = 20.0;
  const MuDistribution d = CalcMuDistribution(m, {{"fn_n", fn}, {"v_mm_s", v}});
  EXPECT_NEAR(d.mean, kB0 + kB1 * v + kB2 * fn, 1e-12);
  EXPECT_NEAR(d.sigma, m.mu.sigma_eps, 1e-12);
  EXPECT_FALSE(d.extrapolated);
  // On stored levels and between them (0.0123, 0.0371 are not levels).
  for (double r : {0.001, 0.0123, 0.0371, 0.05, 0.25, 0.5}) {
    const SimFrictionValues s = CalcSimFrictionValues(d, r);
    const double truth = TruthQuantile(fn, v, r);
    EXPECT_NEAR(s.sliding, truth, 1e-12 * std::fabs(truth)) << "risk " << r;
    EXPECT_DOUBLE_EQ(s.range_low, s.sliding);
    EXPECT_NEAR(s.range_high, TruthQuantile(fn, v, 1 - r), 1e-12) << r;
    EXPECT_LE(s.range_low, s.range_high);
  }
  // A do-nothing answer (the mean) is far from the 0.1 % quantile.
  EXPECT_GT(d.mean - CalcSimFrictionValues(d, 0.001).sliding, 0.09);
}

TEST(ContactFriction, CoefficientUncertaintyWidensTheDistribution) {
  const double var0 = 0.03 * 0.03;
  const StochasticFrictionModel m = UniformEpsModel(var0);
  const double se = m.mu.sigma_eps;
  const double widen = std::sqrt(se * se + var0) / se;
  ASSERT_GT(widen, 1.05);  // the planted effect is visible
  const MuDistribution d = CalcMuDistribution(m, {{"fn_n", 1}, {"v_mm_s", 60}});
  EXPECT_NEAR(d.sigma, std::sqrt(se * se + var0), 1e-12);
  for (double r : {0.001, 0.02, 0.3}) {
    EXPECT_NEAR(CalcSimFrictionValues(d, r).sliding,
                TruthQuantile(1, 60, r, widen),
                1e-12)
        << r;
  }
}

TEST(ContactFriction, MatchesPredictMuInterval) {
  const StochasticFrictionModel m = UniformEpsModel(1e-4);
  const MuPrediction p = PredictMu(m, 4.0, 70.0);
  const MuDistribution d = CalcMuDistribution(m, {{"fn_n", 4}, {"v_mm_s", 70}});
  EXPECT_NEAR(d.Quantile(0.025), p.lo95, 1e-12);
  EXPECT_NEAR(d.Quantile(0.975), p.hi95, 1e-12);
  EXPECT_DOUBLE_EQ(d.mean, p.mu);
}

TEST(ContactFriction, FlagsExtrapolation) {
  const MuDistribution d =
      CalcMuDistribution(UniformEpsModel(), {{"fn_n", 9}, {"v_mm_s", 20}});
  EXPECT_TRUE(d.extrapolated);
  ASSERT_EQ(d.extrapolated_inputs.size(), 1u);
  EXPECT_EQ(d.extrapolated_inputs[0], "fn_n");
}

TEST(ContactFriction, ModelWithoutStoredQuantilesUsesNormal) {
  StochasticFrictionModel m = UniformEpsModel();
  m.mu.eps_quantiles.clear();
  m.mu.sigma_eps = 0.05;
  const MuDistribution d = CalcMuDistribution(m, {{"fn_n", 2}, {"v_mm_s", 30}});
  // Phi^-1(0.05) = -1.6448536269514722 (tabulated).
  EXPECT_NEAR(CalcSimFrictionValues(d, 0.05).sliding,
              d.mean - 1.6448536269514722 * 0.05,
              1e-9);
}

TEST(ContactFriction, RejectsRiskOutsideRangeNamingIt) {
  const MuDistribution d =
      CalcMuDistribution(UniformEpsModel(), {{"fn_n", 2}, {"v_mm_s", 30}});
  for (double r : {0.0, 0.0005, 0.51, 1.0, -0.1, std::nan("")}) {
    try {
      CalcSimFrictionValues(d, r);
      ADD_FAILURE() << "risk " << r << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("risk = "), std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW(CalcSimFrictionValues(MuDistribution{}, 0.05),
               std::invalid_argument);
}

MuDistribution PointMass(double mu) {
  MuDistribution d;
  d.mean = mu;
  d.levels = EpsQuantileLevels();
  d.quantiles.assign(d.levels.size(), mu);
  return d;
}

MuDistribution Uniform(double lo, double hi) {
  MuDistribution d;
  d.mean = 0.5 * (lo + hi);
  d.sigma = (hi - lo) / std::sqrt(12.0);
  d.levels = EpsQuantileLevels();
  for (double p : d.levels) d.quantiles.push_back(lo + (hi - lo) * p);
  return d;
}

TEST(ContactFriction, CombinesPointMassesExactly) {
  const MuDistribution a = PointMass(0.6), b = PointMass(0.9);
  const MuDistribution mx = CombineMuDistributions(a, b, CombineRule::kMax);
  const MuDistribution hm =
      CombineMuDistributions(a, b, CombineRule::kHarmonicMean);
  const MuDistribution av = CombineMuDistributions(a, b, CombineRule::kAverage);
  EXPECT_NEAR(mx.mean, 0.9, 1e-15);
  EXPECT_NEAR(hm.mean, 2 * 0.6 * 0.9 / 1.5, 1e-15);
  EXPECT_NEAR(av.mean, 0.75, 1e-15);
  for (const MuDistribution* d : {&mx, &hm, &av}) {
    EXPECT_NEAR(d->sigma, 0.0, 1e-15);
    EXPECT_NEAR(d->Quantile(0.001), d->mean, 1e-15);
  }
  EXPECT_EQ(CombineMuDistributions(
                PointMass(0), PointMass(0), CombineRule::kHarmonicMean)
                .mean,
            0.0);
}

TEST(ContactFriction, AveragePropagatesSigmaOfIndependentInputs) {
  const MuDistribution a = Uniform(0.5, 0.7), b = Uniform(0.8, 1.0);
  const MuDistribution c = CombineMuDistributions(a, b, CombineRule::kAverage);
  const double truth_sigma = 0.5 * std::hypot(a.sigma, b.sigma);
  EXPECT_NEAR(c.mean, 0.75, 1e-12);
  EXPECT_NEAR(c.sigma, truth_sigma, 1e-3 * truth_sigma);
  EXPECT_NEAR(c.Quantile(0.5), 0.75, 1e-4);
  // (A + B) is triangular on [1.3, 1.7]: F(s) = (s - 1.3)^2 / (2 * 0.2^2).
  const double s01 = 1.3 + 0.2 * std::sqrt(2 * 0.01);
  EXPECT_NEAR(c.Quantile(0.01), 0.5 * s01, 1e-3);
}

TEST(ContactFriction, MaxOfIndependentInputsHasProductCdf) {
  const MuDistribution a = Uniform(0.5, 0.7);
  const MuDistribution c = CombineMuDistributions(a, a, CombineRule::kMax);
  // P(max <= x) = F(x)^2, so the median is at F = sqrt(0.5).
  EXPECT_NEAR(c.Quantile(0.5), 0.5 + 0.2 * std::sqrt(0.5), 2e-3);
  // E[max] of two U(0, 1) is 2/3.
  EXPECT_NEAR(c.mean, 0.5 + 0.2 * 2.0 / 3.0, 1e-4);
}

TEST(ContactFriction, RulesAreOrderedAndClampNegativeMu) {
  const MuDistribution a = Uniform(0.3, 0.6), b = Uniform(0.7, 1.1);
  const double hm =
      CombineMuDistributions(a, b, CombineRule::kHarmonicMean).mean;
  const double av = CombineMuDistributions(a, b, CombineRule::kAverage).mean;
  const double mx = CombineMuDistributions(a, b, CombineRule::kMax).mean;
  EXPECT_LT(hm, av);
  EXPECT_LT(av, mx);
  const MuDistribution neg = Uniform(-0.2, 0.2);
  const MuDistribution c =
      CombineMuDistributions(neg, neg, CombineRule::kAverage);
  EXPECT_GE(c.Quantile(0.001), 0.0);
  EXPECT_THROW(CombineMuDistributions(MuDistribution{}, a, CombineRule::kMax),
               std::invalid_argument);
  EXPECT_THROW(CombineMuDistributions(a, b, CombineRule::kMax, 1),
               std::invalid_argument);
}

TEST(ContactFriction, ParsesRuleNames) {
  for (CombineRule r :
       {CombineRule::kMax, CombineRule::kHarmonicMean, CombineRule::kAverage}) {
    EXPECT_EQ(ParseCombineRule(CombineRuleName(r)), r);
  }
  EXPECT_STREQ(CombineRuleEngine(CombineRule::kMax), "MuJoCo");
  EXPECT_STREQ(CombineRuleEngine(CombineRule::kHarmonicMean), "Drake");
  EXPECT_STREQ(CombineRuleEngine(CombineRule::kAverage), "PhysX");
  try {
    ParseCombineRule("min");
    ADD_FAILURE() << "accepted 'min'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rule = 'min'"), std::string::npos);
  }
}

}  // namespace
}  // namespace frictiond
