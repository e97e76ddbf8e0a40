// Known-truth validation of the grip force for a hold (grip_force.h):
// strokes from a stochastic truth (eq. (1) + per-stroke offset + AR(1)
// noise, Gaussian or heavy-tailed), the model identified from them, and
// held-out holds at the served force. docs/grip_force.md shows the table.
#include "frictiond/estimators/grip_force.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/mu_admissibility.h"
#include "frictiond/estimators/stats.h"
#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {
namespace {

/// The stochastic truth: mu = b0 + b1 v + b2 Fn + offset + w_t, offset
/// once per episode (a stroke or a grasp), w_t AR(1) per sample at rate_hz.
/// t_dof > 0: offset and innovations Student-t with that many degrees of
/// freedom, scaled to the same standard deviations (heavy tails).
struct Truth {
  double b0 = 0.9, b1 = 0.004, b2 = -0.05;
  double offset_sd = 0.05;  ///< per-episode offset of mu
  double ar_sd = 0.02;      ///< stationary sd of the AR(1) part
  double ar_rho = 0.97;     ///< per sample (correlation time 0.33 s)
  double rate_hz = 100.0;
  double t_dof = 0.0;  ///< 0: Gaussian
  /// Outside the estimator's family of equal-shaped parts: the offset a
  /// negative lognormal (sigma 0.6, skewed, long lower tail), the AR(1)
  /// innovations Laplace (t_dof ignored), each scaled to its sd.
  bool skewed_offset = false;
};

class Noise {
 public:
  Noise(const Truth& t, std::uint64_t seed)
      : t_(t), rng_(seed), student_(t.t_dof > 0 ? t.t_dof : 1.0) {}
  // Unit-variance draw (Gaussian or scaled Student-t).
  double Unit() {
    if (t_.t_dof <= 0) return normal_(rng_);
    return student_(rng_) * std::sqrt((t_.t_dof - 2) / t_.t_dof);
  }
  // Unit-variance skewed draw: -(lognormal - mean) / sd.
  double Skewed() {
    const double s2 = 0.36;
    const double mean = std::exp(s2 / 2);
    const double sd = std::sqrt((std::exp(s2) - 1) * std::exp(s2));
    return -(std::exp(0.6 * normal_(rng_)) - mean) / sd;
  }
  // Unit-variance Laplace draw.
  double Laplace() {
    return (exponential_(rng_) - exponential_(rng_)) / std::sqrt(2.0);
  }
  double Innovation() { return t_.skewed_offset ? Laplace() : Unit(); }
  // Starts an episode: a new offset, a stationary AR state.
  void StartEpisode() {
    offset_ = t_.offset_sd * (t_.skewed_offset ? Skewed() : Unit());
    w_ = t_.ar_sd * Innovation();
  }
  double Next(bool first) {
    if (!first)
      w_ = t_.ar_rho * w_ +
           std::sqrt(1 - t_.ar_rho * t_.ar_rho) * t_.ar_sd * Innovation();
    return offset_ + w_;
  }

 private:
  Truth t_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::exponential_distribution<double> exponential_{1.0};
  std::student_t_distribution<double> student_;
  double offset_ = 0, w_ = 0;
};

// Training strokes: each one slipping episode of 0.6 s with Fn and peak v
// drawn per stroke, labelled.
StrokeData TrainingStrokes(const Truth& t, int strokes, std::uint64_t seed) {
  Noise noise(t, seed);
  std::mt19937_64 rng(seed + 1000);
  std::uniform_real_distribution<double> unif(0.0, 1.0);
  StrokeData d;
  const int n = static_cast<int>(0.6 * t.rate_hz);
  double time = 0;
  for (int s = 0; s < strokes; ++s) {
    const double fn = 0.5 + 4.0 * unif(rng);
    const double v_peak = 15.0 + 65.0 * unif(rng);
    noise.StartEpisode();
    for (int i = 0; i < n; ++i) {
      const double v = v_peak * (0.2 + 0.8 * std::sin(M_PI * (i + 0.5) / n));
      const double f = fn * (1.0 + 0.1 * std::sin(2 * M_PI * i / n));
      const double mu = t.b0 + t.b1 * v + t.b2 * f + noise.Next(i == 0);
      d.t_s.push_back(time);
      d.fn_n.push_back(f);
      d.ft_n.push_back(std::max(0.0, mu * f));
      d.v_mm_s.push_back(v);
      d.slip.push_back(1);
      d.stroke.push_back(s);
      time += 1.0 / t.rate_hz;
    }
    time += 1.0;  // a pause between strokes
  }
  return d;
}

// Held-out holds at rest: slips when mu_t * fn < load at any sample.
int CountSlips(const Truth& t,
               double fn,
               double load,
               int samples,
               int trials,
               std::uint64_t seed) {
  Noise noise(t, seed);
  const double margin = t.b0 + t.b2 * fn - load / fn;  // slip: eps < -margin
  int slips = 0;
  for (int k = 0; k < trials; ++k) {
    noise.StartEpisode();
    for (int i = 0; i < samples; ++i) {
      if (noise.Next(i == 0) < -margin) {
        ++slips;
        break;
      }
    }
  }
  return slips;
}

// The 99 % interval [lo, hi] of Binomial(n, p): P(X < lo) <= 0.005 and
// P(X > hi) <= 0.005.
std::pair<int, int> BinomialInterval99(int n, double p) {
  double cdf = 0;
  int lo = -1, hi = n;
  for (int k = 0; k <= n; ++k) {
    const double logpmf = std::lgamma(n + 1.0) - std::lgamma(k + 1.0) -
                          std::lgamma(n - k + 1.0) + k * std::log(p) +
                          (n - k) * std::log1p(-p);
    cdf += std::exp(logpmf);
    if (lo < 0 && cdf > 0.005) lo = k;
    if (cdf >= 0.995) {
      hi = k;
      break;
    }
  }
  return {lo, hi};
}

void CheckServedRisk(const Truth& truth,
                     int strokes,
                     std::uint64_t seed,
                     const std::string& label) {
  const StochasticFit fit =
      FitStochasticModel(TrainingStrokes(truth, strokes, seed));
  ASSERT_EQ(fit.status, FitStatus::kOk) << fit.why;
  const StochasticFrictionModel& m = fit.model;
  ASSERT_TRUE(m.eps_time.valid) << m.eps_time.why;
  std::printf(
      "%s: phi %.3f (truth %.3f), offset_fraction %.3f, n_eff %.0f, "
      "min_instant_risk %.2g\n",
      label.c_str(),
      m.eps_time.phi,
      truth.ar_rho,
      m.eps_time.offset_fraction,
      m.eps_time.effective_samples,
      m.eps_time.min_instant_risk);
  const double load = 1.0;
  const int kTrials = 20000;
  int k = 0;
  for (double hold_s : {0.0, 1.0, 5.0}) {
    for (double risk : {0.001, 0.01, 0.05}) {
      GripForceOptions o;
      o.hold_s = hold_s;
      const GripForce g = CalcGripForce(m, load, risk, o);
      ASSERT_EQ(g.status, GripForceStatus::kOk)
          << label << " risk " << risk << " hold " << hold_s << ": " << g.why;
      const int slips = CountSlips(
          truth, g.fn_n, load, g.hold_samples, kTrials, seed * 100 + ++k);
      const auto [lo, hi] = BinomialInterval99(kTrials, risk);
      std::printf("| %s | %.3f | %.0f | %.4f | %.4f | %d | %.5f | [%d, %d] |\n",
                  label.c_str(),
                  risk,
                  hold_s,
                  g.fn_n,
                  g.fn_n_sd,
                  g.hold_samples,
                  static_cast<double>(slips) / kTrials,
                  lo,
                  hi);
      EXPECT_GE(slips, lo) << label << " risk " << risk << " hold " << hold_s
                           << " fn " << g.fn_n;
      EXPECT_LE(slips, hi) << label << " risk " << risk << " hold " << hold_s
                           << " fn " << g.fn_n;
    }
  }
}

TEST(GripForce, ServedRiskHoldsForGaussianTruth) {
  CheckServedRisk(Truth{}, 24000, 3, "gaussian");
}

TEST(GripForce, ServedRiskHoldsForHeavyTailedTruth) {
  Truth t;
  t.t_dof = 4.0;
  // Heavy-tailed offsets persist through a hold and heavy-tailed shocks
  // decay over ~1 / (1 - phi) samples: the offset decomposition with a
  // linear AR(1) within part (eps_time.h) represents both; the Gaussian
  // copula alone served holds 2x safer than requested (docs/grip_force.md).
  CheckServedRisk(t, 24000, 4, "student-t4");
}

TEST(GripForce, ServedRiskForSkewedOffsetOutsideTheFamily) {
  // Wider than the estimator's assumptions in shape: a skewed offset with a
  // long lower tail and Laplace shocks. Reported in docs/grip_force.md;
  // asserted two-sided like the others.
  Truth t;
  t.skewed_offset = true;
  CheckServedRisk(t, 24000, 5, "skewed-laplace");
}

TEST(GripForce, ServedHoldSlipChecksTheMeanBeforeTheProbability) {
  Truth t;
  const StochasticFit fit = FitStochasticModel(TrainingStrokes(t, 400, 6));
  ASSERT_EQ(fit.status, FitStatus::kOk) << fit.why;
  StochasticFrictionModel m = fit.model;
  GripForceOptions o;
  o.v_mm_s = 30.0;
  o.hold_s = 1.0;
  // Servable: the probability is the forward model's, at the given state,
  // and it inverts the grip force.
  const GripForce g = CalcGripForce(m, 1.0, 0.05, o);
  ASSERT_EQ(g.status, GripForceStatus::kOk) << g.why;
  const ServedHoldSlip ok = CalcServedHoldSlip(m, g.fn_n, 1.0, o);
  EXPECT_TRUE(ok.check.admissible) << ok.check.why;
  EXPECT_EQ(ok.probability, CalcHoldSlipProbability(m, g.fn_n, 1.0, o));
  EXPECT_NEAR(ok.probability, 0.05, 1e-4);
  EXPECT_FALSE(ok.at.extrapolated);
  // A normal force far outside the fit: flagged; where the mean mu goes
  // below 0 (b2 < 0 here: mu = 0.9 - 0.05 Fn), refused before the hold's
  // probability is computed, naming the force.
  const ServedHoldSlip bad = CalcServedHoldSlip(m, 1000.0, 1.0, o);
  EXPECT_TRUE(bad.at.extrapolated);
  EXPECT_FALSE(bad.check.admissible);
  EXPECT_EQ(bad.check.field, "fn_n");
  EXPECT_TRUE(std::isnan(bad.probability));
  // Servable but a hold on a model without a time model: the hold's own
  // refusal (the transports map it to hold_s).
  m.eps_time.valid = false;
  EXPECT_THROW(CalcServedHoldSlip(m, g.fn_n, 1.0, o), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
