#include "frictiond/estimators/eps_time.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <type_traits>
#include <utility>
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

// Quantiles at EpsQuantileLevels() of 400,000 draws of `draw`.
template <class Draw>
std::vector<double> SampleQuantiles(Draw draw, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> x(400000);
  for (double& v : x) v = draw(rng);
  return SelectQuantiles(&x, EpsQuantileLevels());
}

// y with K(y) = p (bisection on CalcOffsetSumCdf).
double SumLevel(const EpsTimeModel& t, double p) {
  double lo = -10, hi = 10;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    (CalcOffsetSumCdf(t, mid) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Monte Carlo P(any a + u_t < y, t < n) of the decomposed process, drawn
// through the stored quantile functions (so it checks the quadrature and
// the first-passage chain, not the representation).
double SimulateOffsetHold(
    const EpsTimeModel& t, double y, int n, int trials, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unif(1e-12, 1 - 1e-12);
  std::normal_distribution<double> normal(0.0, 1.0);
  const bool linear = !t.offset.innovation_quantiles.empty();
  const double s = std::sqrt(1 - t.phi * t.phi);
  int hits = 0;
  for (int k = 0; k < trials; ++k) {
    const double a = CalcOffsetQuantile(t, unif(rng));
    double w = normal(rng);
    double u = linear ? CalcWithinQuantile(t, unif(rng)) : 0.0;
    bool hit = false;
    for (int i = 0; i < n && !hit; ++i) {
      if (linear) {
        if (i > 0) u = t.phi * u + CalcInnovationQuantile(t, unif(rng));
      } else {
        if (i > 0) w = t.phi * w + s * normal(rng);
        u = CalcWithinQuantile(t, NormalCdf(w));
      }
      hit = a + u < y;
    }
    hits += hit;
  }
  return static_cast<double>(hits) / trials;
}

TEST(EpsTime, OffsetDecompositionMatchesMonteCarlo) {
  // Heavy-tailed (Student-t 3) and skewed (negative lognormal) offsets,
  // Gaussian-copula and linear AR(1) within parts with Gaussian and
  // Student-t 3 innovations. 40,000 simulated holds per case: within 4
  // binomial standard errors plus 4 % of p (the chain's cells and the
  // quadrature).
  auto t3 = [](double scale) {
    return [scale](std::mt19937_64& rng) {
      return scale * std::student_t_distribution<double>(3.0)(rng);
    };
  };
  auto normal = [](double scale) {
    return [scale](std::mt19937_64& rng) {
      return scale * std::normal_distribution<double>(0.0, 1.0)(rng);
    };
  };
  auto skewed = [](std::mt19937_64& rng) {  // long lower tail
    return 0.3 - std::exp(-1.2 + 0.8 * std::normal_distribution<double>(
                                           0.0, 1.0)(rng));
  };
  struct Case {
    const char* name;
    std::vector<double> g, h, e;  // e empty: copula within part
    double phi, p;
    int n;
  };
  std::vector<Case> cases;
  cases.push_back({"t3 offset, copula",
                   SampleQuantiles(t3(0.5), 1),
                   SampleQuantiles(normal(0.5), 2),
                   {},
                   0.95,
                   0.002,
                   101});
  cases.push_back({"skewed offset, copula",
                   SampleQuantiles(skewed, 3),
                   SampleQuantiles(normal(0.3), 4),
                   {},
                   0.9,
                   0.005,
                   51});
  {
    // Linear AR(1) with t3 innovations: H from a long run of the chain.
    const double phi = 0.95;
    std::mt19937_64 rng(5);
    std::student_t_distribution<double> st(3.0);
    std::vector<double> path(400000);
    double u = 0;
    for (int i = -2000; i < 400000; ++i) {
      u = phi * u + 0.1 * st(rng);
      if (i >= 0) path[i] = u;
    }
    cases.push_back({"t3 offset, linear t3 AR(1)",
                     SampleQuantiles(t3(0.5), 6),
                     SelectQuantiles(&path, EpsQuantileLevels()),
                     SampleQuantiles(t3(0.1), 7),
                     phi,
                     0.002,
                     101});
  }
  int k = 0;
  for (const Case& c : cases) {
    EpsTimeModel t;
    t.valid = true;
    t.dt_s = 0.01;
    t.phi = c.phi;
    t.offset_fraction = 0.5;
    t.offset.valid = true;
    t.offset.offset_quantiles = c.g;
    t.offset.within_quantiles = c.h;
    t.offset.innovation_quantiles = c.e;
    const double y = SumLevel(t, c.p);
    const int trials = 40000;
    const double mc = SimulateOffsetHold(t, y, c.n, trials, 21 + k++);
    const double p = CalcHoldSlipFromInstant(c.p, c.n, t);
    const double se = std::sqrt(p * (1 - p) / trials);
    std::printf("%s: n %d instant %.4f: hold %.5f, Monte Carlo %.5f\n",
                c.name,
                c.n,
                c.p,
                p,
                mc);
    EXPECT_NEAR(p, mc, 4 * se + 0.04 * p) << c.name;
    // The inverse returns the instant's probability.
    EXPECT_NEAR(CalcInstantRiskForHold(p, c.n, t), c.p, 1e-3 * c.p) << c.name;
    // One instant is the marginal itself.
    EXPECT_EQ(CalcHoldSlipFromInstant(c.p, 1, t), c.p);
    // The tabulated rule answers exactly as the functions, also after a
    // move and after the model it was built from is gone.
    std::unique_ptr<EpsTimeModel> owned = std::make_unique<EpsTimeModel>(t);
    HoldSlipRule built(*owned, c.n);
    owned.reset();
    const HoldSlipRule rule = std::move(built);
    EXPECT_EQ(rule.SlipFromInstant(c.p), p) << c.name;
    EXPECT_EQ(rule.InstantRiskFor(p), CalcInstantRiskForHold(p, c.n, t));
    EXPECT_EQ(rule.samples(), c.n);
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

TEST(EpsTime, IdentifiesOffsetDecomposition) {
  // 3000 episodes of 80 samples: a Student-t(4) offset (sd 1) plus a linear
  // AR(1) (phi 0.9, stationary sd 0.5) with Gaussian innovations.
  const double phi = 0.9, sd_u = 0.5;
  std::mt19937_64 rng(8);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::student_t_distribution<double> st(4.0);
  std::vector<double> eps, offsets;
  std::vector<int> episode;
  for (int e = 0; e < 3000; ++e) {
    const double a = st(rng) / std::sqrt(2.0);
    offsets.push_back(a);
    double u = sd_u * normal(rng);
    for (int t = 0; t < 80; ++t) {
      if (t > 0) u = phi * u + sd_u * std::sqrt(1 - phi * phi) * normal(rng);
      eps.push_back(a + u);
      episode.push_back(e);
    }
  }
  const EpsTimeModel m = FitEpsTimeModel(eps, episode, 0.01);
  ASSERT_TRUE(m.valid) << m.why;
  const EpsOffsetModel& o = m.offset;
  ASSERT_TRUE(o.valid);
  EXPECT_EQ(o.episodes_used, 3000);
  const auto& levels = EpsQuantileLevels();
  const std::vector<double> truth = SelectQuantiles(&offsets, levels);
  auto at = [&](const std::vector<double>& q, double p) {
    return q[std::lower_bound(levels.begin(), levels.end(), p - 1e-12) -
             levels.begin()];
  };
  // G against the offsets' own quantiles (their sampling noise removed):
  // the deconvolution's error only. Tolerances: 2 standard errors of the
  // noise the episode means still carry (sd ~0.23 against 1).
  for (double p : {0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99}) {
    std::printf("G at %.2f: %.3f (offsets %.3f)\n",
                p,
                at(o.offset_quantiles, p),
                at(truth, p));
    EXPECT_NEAR(at(o.offset_quantiles, p),
                at(truth, p),
                p == 0.01 || p == 0.99 ? 0.12 : 0.05)
        << p;
  }
  // A variance-matched G would shrink the 0.01 quantile by sqrt(rho) ~
  // 0.975 and widen the body; the heavy tail stays heavy.
  EXPECT_LT(at(o.offset_quantiles, 0.01), -2.0);
  // H and E: spreads of the within part and its innovations.
  const double h_sd =
      0.5 * (at(o.within_quantiles, 0.84) - at(o.within_quantiles, 0.16));
  const double e_sd = 0.5 * (at(o.innovation_quantiles, 0.84) -
                             at(o.innovation_quantiles, 0.16));
  EXPECT_NEAR(h_sd, sd_u, 0.05 * sd_u);
  EXPECT_NEAR(e_sd, sd_u * std::sqrt(1 - phi * phi), 0.05 * sd_u);
  EXPECT_NEAR(at(o.innovation_quantiles, 0.5), 0.0, 0.01);
  // No offset (f = 0 identified): no decomposition, holds on the copula.
  std::vector<double> white(eps.size());
  for (double& x : white) x = normal(rng);
  EXPECT_FALSE(FitEpsTimeModel(white, episode, 0.01).offset.valid);
}

static_assert(std::is_nothrow_move_constructible_v<HoldSlipRule>);
static_assert(std::is_nothrow_move_assignable_v<HoldSlipRule>);

TEST(EpsTime, RejectsBadArguments) {
  EXPECT_THROW(HoldSlipRule(EpsTimeModel{}, 0), std::invalid_argument);
  EXPECT_THROW(CalcHoldSlipFromInstant(1.5, 3, EpsTimeModel{}),
               std::invalid_argument);
  EXPECT_THROW(CalcInstantRiskForHold(0.0, 3, EpsTimeModel{}),
               std::invalid_argument);
  EXPECT_THROW(CalcOffsetQuantile(EpsTimeModel{}, 0.5), std::invalid_argument);
  EXPECT_THROW(CalcAr1Survival(0.0, 0, 0.5), std::invalid_argument);
  EXPECT_THROW(CalcAr1Survival(0.0, 3, 1.0), std::invalid_argument);
  EXPECT_THROW(CalcHoldCrossingProbability(0.0, 3, 0.5, 1.5),
               std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
