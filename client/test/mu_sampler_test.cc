#include "frictiond/client/mu_sampler.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/stats.h"

namespace frictiond {
namespace {

// A fingertip-like model: mu = 0.9 + 0.004 v - 0.03 Fn + eps, eps skewed
// (quantiles of a shifted gamma-like shape), plus optional extra terms.
StochasticFrictionModel MakeModel(bool extended) {
  StochasticFrictionModel m;
  RegressionModel& r = m.mu;
  r.terms = {Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")};
  std::vector<double> beta = {0.9, 0.004, -0.03};
  if (extended) {
    r.terms.push_back(Term::Parse("fn_n^2"));
    r.terms.push_back(Term::Linear("temp_c"));
    beta.push_back(0.0021);
    beta.push_back(-0.011);
    m.inputs["temp_c"] = InputStats{23.5, 20.0, 27.0};
  }
  r.beta = Eigen::Map<Eigen::VectorXd>(beta.data(), beta.size());
  const int n = static_cast<int>(beta.size());
  Eigen::MatrixXd a = Eigen::MatrixXd::Identity(n, n) * 1e-4;
  a(0, 1) = a(1, 0) = 2e-5;
  a(1, 2) = 3e-6;  // not symmetric: the evaluation must not assume it
  a(2, 1) = -1e-6;
  r.P_beta = a;
  r.sigma_eps = 0.08;
  for (double p : EpsQuantileLevels()) {
    const double z = NormalQuantile(p);
    r.eps_quantiles.push_back(0.08 * (z + 0.15 * (z * z - 1)));
  }
  m.inputs["fn_n"] = InputStats{2.0, 0.5, 4.0};
  m.inputs["v_mm_s"] = InputStats{20.0, 5.0, 60.0};
  m.mu_fn_only = r;
  return m;
}

TEST(MuSamplerTest, MeanEqualsPredictMuBitForBit) {
  for (bool extended : {false, true}) {
    const StochasticFrictionModel model = MakeModel(extended);
    const MuSampler sampler(model);
    std::mt19937_64 gen(11);
    std::uniform_real_distribution<double> fn(0.01, 10.0), v(0.0, 100.0);
    for (int i = 0; i < 20000; ++i) {
      const double f = fn(gen), s = v(gen);
      ASSERT_EQ(sampler.CalcMean(f, s), PredictMu(model, f, s).mu)
          << "fn_n=" << f << " v_mm_s=" << s << " extended=" << extended;
    }
  }
}

TEST(MuSamplerTest, PredictionEqualsPredictMuBitForBit) {
  for (bool extended : {false, true}) {
    const StochasticFrictionModel model = MakeModel(extended);
    const MuSampler sampler(model);
    std::mt19937_64 gen(13);
    // Wider than the fitted ranges, so extrapolation is flagged too.
    std::uniform_real_distribution<double> fn(0.01, 6.0), v(0.0, 90.0);
    int flagged = 0;
    for (int i = 0; i < 20000; ++i) {
      const double f = fn(gen), s = v(gen);
      const MuPrediction want = PredictMu(model, f, s);
      const MuPoint got = sampler.CalcPrediction(f, s);
      ASSERT_EQ(got.mu, want.mu) << f << " " << s;
      ASSERT_EQ(got.sigma, want.sigma) << f << " " << s;
      ASSERT_EQ(got.lo95, want.lo95) << f << " " << s;
      ASSERT_EQ(got.hi95, want.hi95) << f << " " << s;
      ASSERT_EQ(got.extrapolated, want.extrapolated) << f << " " << s;
      flagged += got.extrapolated;
    }
    EXPECT_GT(flagged, 1000);
    EXPECT_LT(flagged, 19000);
    const double nan = std::nan("");
    EXPECT_EQ(sampler.CalcPrediction(nan, 1.0).extrapolated,
              PredictMu(model, nan, 1.0).extrapolated);
  }
}

// The extended model plus interaction terms (product columns of fn_n,
// v_mm_s and temp_c) and an eps scale in `scale_input` (eps_scale.h).
StochasticFrictionModel MakeScaledModel(const std::string& scale_input) {
  StochasticFrictionModel m = MakeModel(true);
  RegressionModel& r = m.mu;
  const std::vector<std::string> extra = {
      "fn_n*v_mm_s", "temp_c*fn_n", "v_mm_s*temp_c", "log(fn_n*v_mm_s)"};
  const std::vector<double> beta_extra = {-0.0004, 0.0013, 0.0002, 0.01};
  const Eigen::Index n0 = r.beta.size();
  const Eigen::Index n = n0 + static_cast<Eigen::Index>(extra.size());
  r.beta.conservativeResize(n);
  for (std::size_t k = 0; k < extra.size(); ++k) {
    r.terms.push_back(Term::Parse(extra[k]));
    r.beta(n0 + static_cast<Eigen::Index>(k)) = beta_extra[k];
  }
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(n, n) * 1e-5;
  P.topLeftCorner(n0, n0) = r.P_beta;
  r.P_beta = P;
  EpsScaleModel s;
  s.input = scale_input;
  s.log_sigma_intercept = std::log(0.03);
  s.log_sigma_slope = scale_input == "temp_c"        ? 0.05
                      : scale_input == "fn_n*v_mm_s" ? 0.01
                                                     : 0.3;
  s.x_min = m.inputs.count(scale_input) ? m.inputs.at(scale_input).min : 1.0;
  s.x_max = m.inputs.count(scale_input) ? m.inputs.at(scale_input).max : 200.0;
  s.sigma_ref = 0.08;
  m.eps_scale = s;
  return m;
}

TEST(MuSamplerTest, ScaledInteractionModelEqualsPredictMuBitForBit) {
  for (const std::string input : {"fn_n", "v_mm_s", "temp_c", "fn_n*v_mm_s"}) {
    const StochasticFrictionModel model = MakeScaledModel(input);
    const MuSampler sampler(model);
    std::mt19937_64 gen(17);
    std::uniform_real_distribution<double> fn(0.01, 6.0), v(0.0, 90.0);
    for (int i = 0; i < 20000; ++i) {
      const double f = fn(gen), s = v(gen);
      const MuPrediction want = PredictMu(model, f, s);
      const MuPoint got = sampler.CalcPrediction(f, s);
      ASSERT_EQ(sampler.CalcMean(f, s), want.mu) << input << " " << f;
      ASSERT_EQ(got.mu, want.mu) << input << " " << f << " " << s;
      ASSERT_EQ(got.sigma, want.sigma) << input << " " << f << " " << s;
      ASSERT_EQ(got.lo95, want.lo95) << input << " " << f << " " << s;
      ASSERT_EQ(got.hi95, want.hi95) << input << " " << f << " " << s;
      ASSERT_EQ(sampler.CalcEpsScale(f, s),
                CalcEpsScaleFactor(model, {{"fn_n", f}, {"v_mm_s", s}}));
    }
  }
  // The interval scales with the eps scale (coefficients known exactly
  // here): exp(0.3 x 3.3) = 2.7 times wider at 3.9 N than at 0.6 N.
  StochasticFrictionModel model = MakeScaledModel("fn_n");
  model.mu.P_beta.setZero();
  const MuSampler sampler(model);
  const MuPoint lo = sampler.CalcPrediction(0.6, 20.0);
  const MuPoint hi = sampler.CalcPrediction(3.9, 20.0);
  EXPECT_NEAR((hi.hi95 - hi.lo95) / (lo.hi95 - lo.lo95),
              std::exp(0.3 * (3.9 - 0.6)),
              1e-9);
  // Draws carry the scale: the 0.9 draw minus the mean is s * q(0.9).
  EXPECT_NEAR(
      sampler.Draw(3.0, 20.0, 0.9) - sampler.CalcMean(3.0, 20.0),
      model.eps_scale->ScaleFactor(3.0) * CalcEpsQuantile(model.mu, 0.9),
      1e-12);
}

TEST(MuSamplerTest, EpsQuantileEqualsEstimatorBitForBit) {
  const StochasticFrictionModel model = MakeModel(false);
  const MuSampler sampler(model);
  std::vector<double> ps = {0.0,
                            1e-9,
                            0.001,
                            0.0025,
                            0.5,
                            0.99,
                            0.999,
                            0.9999,
                            std::nextafter(1.0, 0.0)};
  for (double l : EpsQuantileLevels()) {
    ps.push_back(l);
    ps.push_back(std::nextafter(l, 0.0));
    ps.push_back(std::nextafter(l, 1.0));
  }
  for (int b = 0; b <= 4096; ++b) ps.push_back(b / 4096.0 * (1 - 1e-16));
  std::mt19937_64 gen(3);
  std::uniform_real_distribution<double> unif(0.0, 1.0);
  for (int i = 0; i < 200000; ++i) ps.push_back(unif(gen));
  for (double p : ps) {
    ASSERT_EQ(sampler.CalcEpsQuantile(p), CalcEpsQuantile(model.mu, p))
        << "p=" << p;
  }
}

TEST(MuSamplerTest, WithoutStoredQuantilesFallsBackToTheEstimator) {
  StochasticFrictionModel model = MakeModel(false);
  model.mu.eps_quantiles.clear();  // normal eps with sigma_eps
  const MuSampler sampler(model);
  for (double p : {0.01, 0.3, 0.5, 0.97})
    EXPECT_EQ(sampler.CalcEpsQuantile(p), CalcEpsQuantile(model.mu, p));
}

TEST(MuSamplerTest, RejectsAModelWithoutCoefficients) {
  StochasticFrictionModel model = MakeModel(false);
  model.mu.beta.resize(0);
  try {
    MuSampler s(model);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("3 terms but 0 coefficients"),
              std::string::npos)
        << e.what();
  }
}

struct Mt {
  std::mt19937_64 gen;
  static double Next(void* self) {
    return std::uniform_real_distribution<double>(
        0.0, 1.0)(static_cast<Mt*>(self)->gen);
  }
};

TEST(MuSamplerTest, IndependentEpisodesUseOneUniformPerStep) {
  const StochasticFrictionModel model = MakeModel(false);
  const MuSampler sampler(model);
  const double fn = 2.0, v = 10.0;
  EpisodeSampleOptions o;
  o.envs = 3;
  o.steps = 5;
  Mt a{std::mt19937_64(5)}, b{std::mt19937_64(5)};
  std::vector<double> out(15);
  SampleMuEpisodes(
      sampler, {&fn, 0, 0}, {&v, 0, 0}, o, {&Mt::Next, &a}, out.data());
  for (int i = 0; i < 15; ++i)
    EXPECT_EQ(out[i], sampler.Draw(fn, v, Mt::Next(&b))) << i;
}

TEST(MuSamplerTest, Ar1KeepsTheMarginalAndTheCorrelation) {
  const StochasticFrictionModel model = MakeModel(false);
  const MuSampler sampler(model);
  const double fn = 2.0, v = 10.0;
  const double mean = sampler.CalcMean(fn, v);
  const double median = mean + sampler.CalcEpsQuantile(0.5);
  const double q90 = mean + sampler.CalcEpsQuantile(0.9);
  for (double phi : {0.0, 0.5, 0.9}) {
    EpisodeSampleOptions o;
    o.envs = 2000;
    o.steps = 50;
    o.ar1 = phi;
    Mt g{std::mt19937_64(17)};
    std::vector<double> out(o.envs * o.steps);
    SampleMuEpisodes(
        sampler, {&fn, 0, 0}, {&v, 0, 0}, o, {&Mt::Next, &g}, out.data());
    // Marginal at the first and last step: P(mu < median) = 0.5 and
    // P(mu < q90) = 0.9 within 4 binomial sd (n = 2000).
    for (int t : {0, o.steps - 1}) {
      int below50 = 0, below90 = 0;
      for (int e = 0; e < o.envs; ++e) {
        below50 += out[e * o.steps + t] < median;
        below90 += out[e * o.steps + t] < q90;
      }
      EXPECT_NEAR(below50 / 2000.0, 0.5, 4 * std::sqrt(0.25 / 2000)) << phi;
      EXPECT_NEAR(below90 / 2000.0, 0.9, 4 * std::sqrt(0.09 / 2000)) << phi;
    }
    // Lag-1 correlation of the normal scores Phi^-1(F(mu)) is phi: recover
    // the score through the eps CDF of the model.
    double sxy = 0, sxx = 0, syy = 0;
    for (int e = 0; e < o.envs; ++e) {
      for (int t = 1; t < o.steps; ++t) {
        const double x = NormalQuantile(
            CalcEpsCdf(model.mu, out[e * o.steps + t - 1] - mean));
        const double y =
            NormalQuantile(CalcEpsCdf(model.mu, out[e * o.steps + t] - mean));
        if (!std::isfinite(x) || !std::isfinite(y)) continue;
        sxy += x * y;
        sxx += x * x;
        syy += y * y;
      }
    }
    EXPECT_NEAR(sxy / std::sqrt(sxx * syy), phi, 0.02) << "ar1=" << phi;
  }
}

TEST(MuSamplerTest, EpisodeOffsetAddsAConstantCorrelation) {
  // corr(z_t, z_{t+k}) = f + (1 - f) phi^k, recovered from the samples'
  // normal scores at lags 1 and 10, for offsets with and without AR(1).
  const StochasticFrictionModel model = MakeModel(false);
  const MuSampler sampler(model);
  const double fn = 2.0, v = 10.0;
  const double mean = sampler.CalcMean(fn, v);
  for (const auto& [f, phi] : {std::pair{0.4, 0.0}, std::pair{0.3, 0.8}}) {
    EpisodeSampleOptions o;
    o.envs = 4000;
    o.steps = 12;
    o.ar1 = phi;
    o.offset_fraction = f;
    Mt g{std::mt19937_64(23)};
    std::vector<double> out(o.envs * o.steps);
    SampleMuEpisodes(
        sampler, {&fn, 0, 0}, {&v, 0, 0}, o, {&Mt::Next, &g}, out.data());
    for (int lag : {1, 10}) {
      double sxy = 0, sxx = 0, syy = 0;
      for (int e = 0; e < o.envs; ++e) {
        const double x =
            NormalQuantile(CalcEpsCdf(model.mu, out[e * o.steps] - mean));
        const double y =
            NormalQuantile(CalcEpsCdf(model.mu, out[e * o.steps + lag] - mean));
        if (!std::isfinite(x) || !std::isfinite(y)) continue;
        sxy += x * y;
        sxx += x * x;
        syy += y * y;
      }
      const double want = f + (1 - f) * std::pow(phi, lag);
      EXPECT_NEAR(sxy / std::sqrt(sxx * syy), want, 0.04)
          << "f=" << f << " phi=" << phi << " lag=" << lag;
    }
  }
}

TEST(MuSamplerTest, Ar1OfOneHoldsOneDrawPerEpisode) {
  const StochasticFrictionModel model = MakeModel(false);
  const MuSampler sampler(model);
  const double fn = 2.0, v = 10.0;
  EpisodeSampleOptions o;
  o.envs = 4;
  o.steps = 6;
  o.ar1 = 1.0;
  Mt g{std::mt19937_64(1)};
  std::vector<double> out(24);
  SampleMuEpisodes(
      sampler, {&fn, 0, 0}, {&v, 0, 0}, o, {&Mt::Next, &g}, out.data());
  for (int e = 0; e < 4; ++e)
    for (int t = 1; t < 6; ++t) EXPECT_EQ(out[e * 6 + t], out[e * 6]);
  EXPECT_NE(out[0], out[6]);
}

TEST(MuSamplerTest, RejectsBadOptionsNamingTheField) {
  const MuSampler sampler(MakeModel(false));
  const double fn = 2.0, v = 10.0;
  Mt g{std::mt19937_64(1)};
  double out[4];
  EpisodeSampleOptions o;
  o.ar1 = 1.5;
  EXPECT_THROW(SampleMuEpisodes(
                   sampler, {&fn, 0, 0}, {&v, 0, 0}, o, {&Mt::Next, &g}, out),
               std::invalid_argument);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why, "ar1 = 1.500000 (must be in [0, 1])");
  o.ar1 = std::nan("");
  EXPECT_FALSE(o.IsValid(&why));
  o.ar1 = 0.5;
  o.offset_fraction = -0.1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why, "offset_fraction = -0.100000 (must be in [0, 1])");
  o = {};
  o.envs = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why, "envs = 0 (must be > 0)");
}

}  // namespace
}  // namespace frictiond
