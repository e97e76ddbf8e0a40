// Known truth with correlated noise (AR(1) within strokes) and per-stroke
// offsets: the textbook OLS intervals of eq. (1) under-cover there, as
// stochastic_model.h documents; the stroke-clustered covariance restores
// the coverage.
#include "frictiond/estimators/robust_covariance.h"

#include <cmath>

#include <gtest/gtest.h>

#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

struct Coverage {
  int ols = 0;
  int robust = 0;
  double mean_ratio = 0;  // mean robust SE / OLS SE of b2
};

// Fits eq. (1) to the slipping samples of `seeds` simulations and counts
// how often the 95 % interval of b2 covers the truth.
Coverage CoverageOfB2(const testing::SimulationSpec& spec, int seeds) {
  Coverage c;
  for (int seed = 1; seed <= seeds; ++seed) {
    const StrokeData d = testing::SimulateStrokes(spec, 1000 + seed);
    std::vector<std::size_t> rows;
    std::vector<int> cluster;
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (!d.slip[i]) continue;
      rows.push_back(i);
      cluster.push_back(d.stroke[i]);
    }
    const Eigen::MatrixXd X = BuildDesign(
        d,
        {Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")},
        rows);
    Eigen::VectorXd y(rows.size());
    for (std::size_t r = 0; r < rows.size(); ++r) y(r) = d.mu(rows[r]);
    const OlsResult ols = FitOls(X, y);
    EXPECT_EQ(ols.status, FitStatus::kOk) << ols.why;
    const Eigen::MatrixXd P =
        CalcClusterRobustCovariance(X, ols.residuals, cluster);
    const double err = std::fabs(ols.beta(2) - spec.b2);
    const double se_robust = std::sqrt(P(2, 2));
    // t quantile with G - 1 = strokes - 1 degrees of freedom (~2.09 for 19).
    c.ols += err < 1.96 * ols.std_err(2);
    c.robust += err < 2.09 * se_robust;
    c.mean_ratio += se_robust / ols.std_err(2) / seeds;
  }
  return c;
}

TEST(RobustCovariance, OlsUnderCoversWithArNoiseAndStrokeOffsets) {
  testing::SimulationSpec spec;
  spec.strokes = 20;
  spec.ar_rho = 0.95;
  spec.stroke_offset_sd = 0.03;
  spec.write_labels = true;
  const int kSeeds = 60;
  const Coverage c = CoverageOfB2(spec, kSeeds);
  // Documented behaviour: the i.i.d. standard errors are far too small.
  EXPECT_LT(c.ols, 0.6 * kSeeds) << "OLS covered " << c.ols << "/" << kSeeds;
  EXPECT_GT(c.mean_ratio, 3.0);
  // Stroke-clustered intervals cover about 95 %.
  EXPECT_GE(c.robust, 0.85 * kSeeds)
      << "robust covered " << c.robust << "/" << kSeeds;
}

TEST(RobustCovariance, AgreesWithOlsUnderWhiteNoise) {
  testing::SimulationSpec spec;  // i.i.d. eps, no offsets
  spec.strokes = 20;
  spec.write_labels = true;
  const int kSeeds = 30;
  const Coverage c = CoverageOfB2(spec, kSeeds);
  EXPECT_NEAR(c.mean_ratio, 1.0, 0.3);
  EXPECT_GE(c.ols, 0.8 * kSeeds);
  EXPECT_GE(c.robust, 0.8 * kSeeds);
}

// The served model (FitStochasticModel) carries the stroke-clustered
// standard errors: same numbers as computed here directly, and intervals
// from them cover the truth where the i.i.d. ones do not.
TEST(RobustCovariance, ServedModelCarriesStrokeClusteredErrors) {
  testing::SimulationSpec spec;
  spec.strokes = 20;
  spec.ar_rho = 0.95;
  spec.stroke_offset_sd = 0.03;
  const int kSeeds = 40;
  int covered_iid = 0, covered_stroke = 0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const StochasticFit fit =
        FitStochasticModel(testing::SimulateStrokes(spec, 2000 + seed));
    ASSERT_EQ(fit.status, FitStatus::kOk) << fit.why;
    const RegressionModel& m = fit.model.mu;
    ASSERT_EQ(m.std_err_stroke.size(), m.std_err.size());
    EXPECT_EQ(m.stroke_clusters, fit.model.strokes);
    const int b2 = m.FindTerm("fn_n");
    ASSERT_GE(b2, 0);
    EXPECT_GT(m.std_err_stroke(b2), 2.0 * m.std_err(b2)) << "seed " << seed;
    const double err = std::fabs(m.beta(b2) - spec.b2);
    covered_iid += err < 1.96 * m.std_err(b2);
    covered_stroke += err < 2.09 * m.std_err_stroke(b2);
  }
  EXPECT_LT(covered_iid, 0.6 * kSeeds) << covered_iid << "/" << kSeeds;
  EXPECT_GE(covered_stroke, 0.85 * kSeeds) << covered_stroke << "/" << kSeeds;
  // One stroke: no clustered errors (not enough clusters), not zeros.
  spec.strokes = 1;
  const StochasticFit one =
      FitStochasticModel(testing::SimulateStrokes(spec, 1));
  EXPECT_EQ(one.model.mu.std_err_stroke.size(), 0);
}

TEST(RobustCovariance, DegenerateInputs) {
  Eigen::MatrixXd X(3, 2);
  X << 1, 1, 1, 2, 1, 3;
  const Eigen::Vector3d u(0.1, -0.2, 0.1);
  EXPECT_TRUE(CalcClusterRobustCovariance(X, u, {0, 0, 0}).isZero());
  EXPECT_THROW(CalcClusterRobustCovariance(X, u, {0, 1}),
               std::invalid_argument);
  const Eigen::MatrixXd empty(0, 0);
  EXPECT_EQ(CalcClusterRobustCovariance(empty, Eigen::VectorXd(0), {}).size(),
            0);
}

}  // namespace
}  // namespace frictiond
