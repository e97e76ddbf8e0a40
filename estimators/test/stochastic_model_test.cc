#include "frictiond/estimators/stochastic_model.h"

#include <cmath>

#include <gtest/gtest.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using testing::SimulateStrokes;
using testing::SimulationSpec;

TEST(StochasticModel, RecoversKnownTruthWithinStandardErrors) {
  SimulationSpec spec;  // b0 = 0.9, b1 = 0.004, b2 = -0.06, sigma = 0.05
  const std::uint64_t seed = 7;
  const StochasticFit fit = FitStochasticModel(SimulateStrokes(spec, seed));
  ASSERT_EQ(fit.status, FitStatus::kOk) << fit.why;
  const RegressionModel& m = fit.model.mu;
  ASSERT_EQ(m.terms.size(), 3u);
  const double truth[3] = {spec.b0, spec.b1, spec.b2};
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(m.beta(k), truth[k], 4 * m.std_err(k))
        << m.terms[k].Name() << " seed " << seed;
    EXPECT_GT(m.std_err(k), 0.0);
  }
  EXPECT_NEAR(m.sigma_eps, spec.sigma_eps, 0.1 * spec.sigma_eps);
  EXPECT_LT(m.p_value, 1e-6);
  // The regression beats Coulomb's constant (paper 000, Fig. 7).
  EXPECT_LT(m.mae, fit.model.mae_coulomb);
  // A do-nothing estimator (beta = 0) would be far off: the truth is not at 0.
  EXPECT_GT(std::fabs(spec.b0), 10 * m.std_err(0));
}

TEST(StochasticModel, StandardErrorsShrinkWithMoreStrokes) {
  SimulationSpec few, many;
  few.strokes = 5;
  many.strokes = 40;
  const auto a = FitStochasticModel(SimulateStrokes(few, 11));
  const auto b = FitStochasticModel(SimulateStrokes(many, 11));
  ASSERT_EQ(a.status, FitStatus::kOk) << a.why;
  ASSERT_EQ(b.status, FitStatus::kOk) << b.why;
  for (int k = 0; k < 3; ++k)
    EXPECT_LT(b.model.mu.std_err(k), 0.6 * a.model.mu.std_err(k)) << k;
}

TEST(StochasticModel, CoverageOfIntervalOverSeeds) {
  // The 95% coefficient interval covers the truth in most of 40 seeds.
  SimulationSpec spec;
  spec.strokes = 6;
  int covered = 0;
  const int kSeeds = 40;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const auto fit = FitStochasticModel(SimulateStrokes(spec, seed));
    ASSERT_EQ(fit.status, FitStatus::kOk) << fit.why;
    covered += std::fabs(fit.model.mu.beta(2) - spec.b2) <
               1.96 * fit.model.mu.std_err(2);
  }
  EXPECT_GE(covered, 33) << "covered " << covered << " of " << kSeeds;
}

TEST(StochasticModel, ConstantLoadLeavesFnSlopeUnidentified) {
  SimulationSpec spec;
  spec.fn_min_n = spec.fn_max_n = 5.0;
  StrokeData d = SimulateStrokes(spec, 3);
  for (auto& f : d.fn_n) f = 5.0;
  const auto fit = FitStochasticModel(d);
  ASSERT_EQ(fit.status, FitStatus::kPartial) << fit.why;
  ASSERT_EQ(fit.model.mu.unidentified.size(), 1u);
  EXPECT_EQ(fit.model.mu.unidentified[0], "fn_n");
  EXPECT_EQ(fit.model.mu.beta(2), 0.0);
}

TEST(StochasticModel, SlipLikelihoodAndGripForce) {
  SimulationSpec spec;
  const auto fit = FitStochasticModel(SimulateStrokes(spec, 5));
  ASSERT_TRUE(fit.model.likelihood.valid) << fit.model.likelihood.why;
  const auto& m = fit.model;
  // Ft/Fn = 0.1 lies ~14 sigma_eps below the lowest mean mu of the truth
  // (0.9 - 0.06 * 4.5 = 0.63) and no slipping sample comes near it: the
  // fitted sigmoid must be negligible there (seed 5: 8.8e-6), and certain
  // at 1.2 (0.99993).
  EXPECT_LT(CalcSlipLikelihood(m, 2.0, 0.2), 1e-4);
  EXPECT_GT(CalcSlipLikelihood(m, 2.0, 2.4), 1 - 1e-3);
  EXPECT_LT(m.likelihood.ratio_never, m.likelihood.ratio_always);
  // Lower risk needs more grip force.
  const GripForce coffee = CalcGripForce(m, 1.0, 0.001);
  const GripForce shirt = CalcGripForce(m, 1.0, 0.05);
  ASSERT_TRUE(coffee.attainable) << coffee.why;
  ASSERT_TRUE(shirt.attainable) << shirt.why;
  EXPECT_GT(coffee.fn_n, shirt.fn_n);
  // At the returned force the risk-quantile of mu from eq. (1) at rest
  // (v = 0, grip_force.h) exactly holds the load.
  EXPECT_EQ(shirt.instant_risk, 0.05);  // one instant: the risk itself
  const double q =
      m.mu.beta(0) + m.mu.beta(2) * shirt.fn_n + CalcEpsQuantile(m.mu, 0.05);
  EXPECT_NEAR(q * shirt.fn_n, 1.0, 1e-9);
  // At rest the mean mu is lower than the Fn-only model's, which averages
  // b1 v over the data's sliding speeds (b1 > 0).
  EXPECT_NEAR(m.mu_fn_only.beta(0) - m.mu.beta(0),
              m.mu.beta(1) * m.inputs.at("v_mm_s").mean,
              0.02);
  // mu falls with Fn here (b2 < 0), so Fn * mu(Fn) peaks: a heavy load is
  // unattainable.
  const GripForce heavy = CalcGripForce(m, 10.0, 0.001);
  EXPECT_FALSE(heavy.attainable);
  EXPECT_NE(heavy.why.find("peaks"), std::string::npos) << heavy.why;
  EXPECT_THROW(CalcGripForce(m, -1.0, 0.1), std::invalid_argument);
  EXPECT_THROW(CalcGripForce(m, 1.0, 1.5), std::invalid_argument);
}

TEST(StochasticModel, PredictionIntervalCoversHeldOutSamples) {
  SimulationSpec spec;
  const auto fit = FitStochasticModel(SimulateStrokes(spec, 21));
  StrokeData test = SimulateStrokes(spec, 22);
  EnsureLabels(&test, fit.model.labelling);
  int n = 0, inside = 0;
  for (std::size_t i = 0; i < test.size(); ++i) {
    if (!test.slip[i]) continue;
    const auto p = PredictMu(fit.model, test.fn_n[i], test.v_mm_s[i]);
    ++n;
    inside += test.mu(i) >= p.lo95 && test.mu(i) <= p.hi95;
  }
  ASSERT_GT(n, 1000);
  EXPECT_NEAR(double(inside) / n, 0.95, 0.02);
}

TEST(StrokeCsv, RejectsBadInputNamingLineAndField) {
  auto expect_error = [](const std::string& csv,
                         std::size_t line,
                         const std::string& field,
                         const std::string& text) {
    try {
      ParseStrokeCsv(csv);
      ADD_FAILURE() << "accepted: " << csv;
    } catch (const StrokeCsvError& e) {
      EXPECT_EQ(e.line(), line) << e.what();
      EXPECT_EQ(e.field(), field) << e.what();
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos)
          << e.what();
    }
  };
  expect_error("", 0, "body", "empty");
  expect_error("t_s,fn_n,ft_n\n0,1,1\n",
               1,
               "v_mm_s",
               "missing required column 'v_mm_s'");
  expect_error("t_s,fn_n,ft_n,v_mm_s\n0,1,1,0\n0.1,abc,1,0\n",
               3,
               "fn_n",
               "not a number");
  expect_error(
      "t_s,fn_n,ft_n,v_mm_s\n0,nan,1,0\n", 2, "fn_n", "must be finite");
  expect_error("t_s,fn_n,ft_n,v_mm_s\n0,0,1,0\n", 2, "fn_n", "must be > 0");
  expect_error(
      "t_s,fn_n,ft_n,v_mm_s\n# c\n1,1,1,0\n0.5,1,1,0\n", 4, "t_s", "backwards");
  expect_error("t_s,fn_n,ft_n,v_mm_s\n0,1,1\n", 2, "row", "cells");
  expect_error("t_s,fn_n,ft_n,v_mm_s,t_s\n", 1, "t_s", "twice");
  expect_error(
      "t_s,fn_n,ft_n,v_mm_s,x;drop\n", 1, "header", "not a valid column name");
  expect_error("t_s,fn_n,ft_n,v_mm_s,intercept\n0,1,1,0,2\n",
               1,
               "header",
               "'intercept' is reserved");
  // Derived feature names are reserved too (a user column of that name
  // was replaced by the derived values without a word).
  for (const char* derived : {"distance_mm", "dwell_s", "time_s"})
    expect_error(
        std::string("t_s,fn_n,ft_n,v_mm_s,") + derived + "\n0,1,1,0,2\n",
        1,
        derived,
        "is a derived feature");
  // A NUL or other control byte in a quoted cell is shown as '?': a NUL
  // ended the message at what() and lost the reason.
  expect_error(std::string("t_s,fn_n,ft_n,v_mm_s\n0,1,0.5\0"
                           "9,0\n",
                           33),
               2,
               "ft_n",
               "ft_n = '0.5?9' (not a number)");
  expect_error(
      std::string("t_s\0x,fn_n,ft_n,v_mm_s\n", 23), 1, "header", "'t_s?x'");
}

TEST(StrokeCsv, ParsesCovariatesCommentsAndRoundTrips) {
  const std::string csv =
      "# "
      "comment\r\nt_s,fn_n,ft_n,v_mm_s,temp_c\r\n0,1.5,0.75,0,20.5\r\n0.01,1.5,"
      "0.9,12,21\r\n";
  StrokeData d = ParseStrokeCsv(csv);
  ASSERT_EQ(d.size(), 2u);
  ASSERT_EQ(d.covariate_names.size(), 1u);
  EXPECT_EQ(d.covariate_names[0], "temp_c");
  EXPECT_DOUBLE_EQ(d.covariates[0][1], 21.0);
  EXPECT_DOUBLE_EQ(d.mu(1), 0.6);
  const StrokeData back = ParseStrokeCsv(FormatStrokeCsv(d));
  EXPECT_EQ(back.ft_n, d.ft_n);
  EXPECT_EQ(back.covariates, d.covariates);
}

}  // namespace
}  // namespace frictiond
