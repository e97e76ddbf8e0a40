#include "frictiond/estimators/eps_time.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/stats.h"
#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {
namespace {

// Monte Carlo P(any z_t < c) of the latent process, with its standard error.
double SimulateCrossing(
    double c, int n, double phi, double f, int trials, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double s = std::sqrt(1 - phi * phi);
  const double sf = std::sqrt(f), sr = std::sqrt(1 - f);
  int hits = 0;
  for (int k = 0; k < trials; ++k) {
    const double a = normal(rng);
    double w = normal(rng);
    bool hit = false;
    for (int t = 0; t < n && !hit; ++t) {
      if (t > 0) w = phi * w + s * normal(rng);
      hit = sf * a + sr * w < c;
    }
    hits += hit;
  }
  return static_cast<double>(hits) / trials;
}

TEST(EpsTime, SurvivalMatchesClosedForms) {
  // n = 1: Phi(-b); phi = 0: (1 - Phi(b))^n, both exact.
  EXPECT_NEAR(CalcAr1Survival(-1.0, 1, 0.9), 1 - NormalCdf(-1.0), 1e-15);
  EXPECT_NEAR(
      CalcAr1Survival(-2.0, 50, 0.0), std::pow(1 - NormalCdf(-2.0), 50), 1e-12);
  // phi -> 0 through the quadrature (phi = 1e-3 differs from i.i.d. by
  // O(1e-3 * density) only).
  const double iid = 1 - std::pow(1 - NormalCdf(-2.5), 200);
  EXPECT_NEAR(1 - CalcAr1Survival(-2.5, 200, 1e-3), iid, 2e-3 * iid);
  // Two samples: P(w0 >= b, w1 >= b) is a bivariate normal orthant; by
  // symmetry at b = 0 it is 1/4 + asin(phi) / (2 pi) (Sheppard).
  for (double phi : {0.3, 0.9, 0.98}) {
    EXPECT_NEAR(
        CalcAr1Survival(0.0, 2, phi), 0.25 + std::asin(phi) / (2 * M_PI), 5e-6)
        << phi;
  }
}

// An offset decomposition with normal G (sd sqrt(f)) and H (sd sqrt(1 - f)):
// quantiles at EpsQuantileLevels(), exponential tails (no GPD fit).
EpsTimeModel GaussianDecomposition(double phi, double f) {
  EpsTimeModel t;
  t.valid = true;
  t.dt_s = 0.01;
  t.phi = phi;
  t.offset_fraction = f;
  t.offset.valid = true;
  for (double p : EpsQuantileLevels()) {
    t.offset.offset_quantiles.push_back(std::sqrt(f) * NormalQuantile(p));
    t.offset.within_quantiles.push_back(std::sqrt(1 - f) * NormalQuantile(p));
  }
  return t;
}

TEST(EpsTime, GaussianDecompositionMatchesCopula) {
  // With normal G and H, Y_t = a + u_t is the copula's z_t: the hold's
  // probability must match CalcHoldCrossingProbability (up to the stored
  // quantiles' interpolation).
  for (double f : {0.3, 0.877}) {
    const EpsTimeModel t = GaussianDecomposition(0.967, f);
    for (int n : {101, 501}) {
      for (double p : {0.0005, 0.002, 0.01}) {
        const double old = CalcHoldCrossingProbability(
            NormalQuantile(p), n, t.phi, t.offset_fraction);
        const double now = CalcHoldSlipFromInstant(p, n, t);
        std::printf("f %.3f n %d p %.4f: copula %.5f decomposition %.5f\n",
                    f,
                    n,
                    p,
                    old,
                    now);
        // 6 %: the stored quantiles' exponential tails below the 0.001
        // level (a normal tail is lighter) and their linear interpolation.
        EXPECT_NEAR(now, old, 0.06 * old) << f << " " << n << " " << p;
      }
    }
  }
}

TEST(EpsTime, HoldCrossingMatchesMonteCarlo) {
  // 100,000 simulated holds per case: require agreement within 4 binomial
  // standard errors.
  struct Case {
    double c;
    int n;
    double phi, f;
  };
  const Case cases[] = {{-3.0, 101, 0.9, 0.0},
                        {-3.2, 201, 0.95, 0.3},
                        {-2.6, 101, 0.7, 0.6},
                        {-2.5, 31, 0.98, 0.1}};
  int k = 0;
  for (const Case& c : cases) {
    const int trials = 100000;
    const double mc = SimulateCrossing(c.c, c.n, c.phi, c.f, trials, 11 + k++);
    const double p = CalcHoldCrossingProbability(c.c, c.n, c.phi, c.f);
    const double se = std::sqrt(p * (1 - p) / trials);
    EXPECT_NEAR(p, mc, 4 * se)
        << "c " << c.c << " n " << c.n << " phi " << c.phi << " f " << c.f;
    // Bounds: at least the instant's probability, at most i.i.d. looks.
    EXPECT_GE(p, NormalCdf(c.c));
    EXPECT_LE(p, 1 - std::pow(1 - NormalCdf(c.c), c.n));
  }
}

TEST(EpsTime, IdentifiesAr1AndOffsetFromEpisodes) {
  // 400 episodes of 150 samples: z = sqrt(f) A + sqrt(1 - f) w, w AR(1);
  // eps = exp(z) (a skewed marginal: the copula fit is rank based).
  const double phi = 0.85, f = 0.4;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<double> eps;
  std::vector<int> episode;
  for (int e = 0; e < 400; ++e) {
    const double a = normal(rng);
    double w = normal(rng);
    for (int t = 0; t < 150; ++t) {
      if (t > 0) w = phi * w + std::sqrt(1 - phi * phi) * normal(rng);
      eps.push_back(std::exp(0.05 * (std::sqrt(f) * a + std::sqrt(1 - f) * w)));
      episode.push_back(e);
    }
  }
  const EpsTimeModel m = FitEpsTimeModel(eps, episode, 0.01);
  ASSERT_TRUE(m.valid) << m.why;
  // Standard errors at this size (by simulation over seeds): phi ~0.005,
  // f ~0.03.
  EXPECT_NEAR(m.phi, phi, 0.02);
  EXPECT_NEAR(m.offset_fraction, f, 0.1);
  EXPECT_NEAR(m.corr_time_s, -0.01 / std::log(phi), 0.01);
  EXPECT_EQ(m.episodes, 400);
  EXPECT_GT(m.effective_samples, 400.0);
  EXPECT_LT(m.effective_samples, 400.0 / f);
  // Null case: i.i.d. eps gives phi ~ 0 and f ~ 0.
  std::vector<double> white(eps.size());
  for (double& x : white) x = normal(rng);
  const EpsTimeModel w = FitEpsTimeModel(white, episode, 0.01);
  ASSERT_TRUE(w.valid) << w.why;
  EXPECT_LT(w.phi, 0.1);
  EXPECT_LT(w.offset_fraction, 0.02);
  // Too little data is a status, not an exception.
  EXPECT_FALSE(FitEpsTimeModel({1.0, 2.0}, {0, 0}, 0.01).valid);
  EXPECT_FALSE(FitEpsTimeModel(eps, episode, 0.0).valid);
}

TEST(EpsTime, RejectsBadArguments) {
  EXPECT_THROW(CalcAr1Survival(0.0, 0, 0.5), std::invalid_argument);
  EXPECT_THROW(CalcAr1Survival(0.0, 3, 1.0), std::invalid_argument);
  EXPECT_THROW(CalcHoldCrossingProbability(0.0, 3, 0.5, 1.5),
               std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
