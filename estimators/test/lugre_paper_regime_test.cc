// Known-truth tests of the LuGre identification in the parameter regime of
// paper 001 (issue 19 item 3): bristle stiffness of Tables I and III (a few
// N/mm, i.e. ~0.4 /mm in friction-ratio form, 100x softer than the truth of
// lugre_identification_test.cc), the paper's protocol (one slow stroke at
// 2 mm/s^2 and one fast stroke at 10 mm/s^2, both sampled at 50 Hz, Section
// V.A), sensor noise on mu over several seeds, and the rubber tape - glass
// truth of Table V, whose sigma1 is 32x the tie sigma1 = 0.0316 sqrt(sigma0)
// that LM-1 and the EKF assume (Section III after eq. 10; Section V.B.2).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <iostream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/breakaway.h"
#include "frictiond/estimators/lugre_identification.h"
#include "frictiond/testing/lugre_strokes.h"

namespace frictiond {
namespace {

using Eigen::VectorXd;

constexpr double kFs = 50.0;      // Hz, the paper's sensor rate (V.A)
constexpr double kNoise = 0.003;  // mu, the paper's Step-1 RMSE (V.B.1)
constexpr double kMassKg = 0.2;   // Table I
constexpr int kSeeds = 10;

struct PaperTruth {
  const char* name;
  LuGreTheta theta;
  double fn_n;  // normal force during the strokes
};

// Table I (simulation parameters, Fn = 20 N): sigma0 8 N/mm, sigma1 0.089
// Ns/mm, sigma2 4e-5 s/mm, mu_s 0.3, mu_c 0.15, v0 1 mm/s. Force-form
// sigma0, sigma1 are divided by Fn. sigma1 satisfies the tie (0.0316
// sqrt(8) = 0.089).
PaperTruth TableI() {
  return {"Table I",
          MakeLuGreTheta(0.3, 0.15, 1.0, 4e-5, 8.0 / 20, 0.089 / 20),
          20.0};
}

// Table III, plastic - rubber tape (GNR + EKF column; stroke Fn 13.5-15.5 N,
// Fig. 12): mu_s 0.36, mu_c 0.13, v0 1.6 mm/s, sigma2 -0.002 s/mm, sigma0
// 5.47 N/mm, sigma1 = 0.0316 sqrt(5.47) = 0.074 Ns/mm (the tie).
PaperTruth TableIII() {
  const double fn = 14.5;
  const double s0 = 5.47 / fn;
  return {"Table III",
          MakeLuGreTheta(0.36,
                         0.13,
                         1.6,
                         -0.002,
                         s0,
                         CalcDampingGain(1.0, fn, 0.5) * std::sqrt(s0)),
          fn};
}

// Table V, rubber tape - glass (GNR + LM-2): mu_s 0.08 < mu_c 0.28, v0 0.70
// mm/s, sigma2 3.3e-3 s/mm, sigma0 7.68 N/mm, sigma1 2.84 Ns/mm, 32x the
// tie 0.0316 sqrt(7.68) = 0.088. Fn is not given for glass; the rig's
// 14.5 N is used.
PaperTruth Glass() {
  const double fn = 14.5;
  return {"Table V glass",
          MakeLuGreTheta(0.08, 0.28, 0.70, 3.3e-3, 7.68 / fn, 2.84 / fn),
          fn};
}

// A stroke sampled at kFs from v(t), simulated with the adaptive integrator
// (not the fits' discrete model), plus Gaussian noise on mu.
LuGreStroke Simulate(const LuGreTheta& theta,
                     const std::function<double(double)>& v_of_t,
                     double duration_s,
                     unsigned seed) {
  const int n = static_cast<int>(std::round(duration_s * kFs)) + 1;
  LuGreStroke s;
  s.t_s = VectorXd::LinSpaced(n, 0.0, (n - 1) / kFs);
  s.v_mm_s.resize(n);
  for (int k = 0; k < n; ++k) s.v_mm_s[k] = v_of_t(s.t_s[k]);
  const VelocityDrivenResult r =
      SimulateVelocityDriven(theta, s.t_s, s.v_mm_s, 0.0);
  EXPECT_EQ(r.status, SimulationStatus::kOk) << r.why;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, kNoise);
  s.mu = r.mu;
  for (int k = 0; k < n; ++k) s.mu[k] += gauss(rng);
  return s;
}

// Step 1 stroke: 0 -> 10 -> 0 mm/s at 2 mm/s^2 (paper: <= 3 mm/s^2, peak
// 5-15 mm/s, V.B.1).
LuGreStroke SlowStroke(const LuGreTheta& theta, unsigned seed) {
  return Simulate(
      theta,
      [](double t) { return t < 5 ? 2.0 * t : 20.0 - 2.0 * t; },
      10.0,
      seed);
}

// Step 2 stroke: 0 -> 10 -> 0 mm/s at 10 mm/s^2 (paper: >= 5 and
// "practically <= 10 mm/s^2", V.A; Fig. 12 loop up to ~10 mm/s).
LuGreStroke FastStroke(const LuGreTheta& theta, unsigned seed) {
  return Simulate(
      theta,
      [](double t) { return t < 1 ? 10.0 * t : 20.0 - 10.0 * t; },
      2.0,
      seed);
}

struct Outcome {
  LuGreFitStatus status = LuGreFitStatus::kFailed;
  double sigma0_err = NAN;  // relative
  double sigma1_err = NAN;  // relative
  double bf_err = NAN;      // worst relative BF-ratio error over kRhos
  double rms = NAN;
};

constexpr double kRhos[] = {0.05, 0.5};

double WorstBfError(const LuGreTheta& estimate, const PaperTruth& truth) {
  ForceDrivenOptions o;
  o.mass_kg = kMassKg;
  double worst = 0;
  for (double rho : kRhos) {
    const ForceDrivenResult t =
        PredictBreakawayRatio(truth.theta, rho, truth.fn_n, o);
    EXPECT_EQ(t.status, SimulationStatus::kOk) << t.why;
    std::string why;
    if (!IsValidLuGreTheta(estimate, &why)) return INFINITY;
    const ForceDrivenResult p =
        PredictBreakawayRatio(estimate, rho, truth.fn_n, o);
    if (p.status != SimulationStatus::kOk) return INFINITY;
    worst = std::max(worst, std::abs(p.bf_ratio / t.bf_ratio - 1));
  }
  return worst;
}

Outcome Evaluate(const LuGreFitResult& r, const PaperTruth& truth) {
  Outcome o;
  o.status = r.status;
  o.sigma0_err = r.theta[4] / truth.theta[4] - 1;
  o.sigma1_err = r.theta[5] / truth.theta[5] - 1;
  o.rms = r.residual_rms;
  if (r.status == LuGreFitStatus::kConverged)
    o.bf_err = WorstBfError(r.theta, truth);
  return o;
}

enum Estimator { kLm1, kLm2, kLm6, kEkf, kNumEstimators };
const char* const kEstimatorNames[] = {
    "GNR+LM-1", "GNR+LM-2", "LM-6", "GNR+EKF"};

struct SeedRun {
  LuGreFitResult step1;
  Outcome out[kNumEstimators];
};

SeedRun RunSeed(const PaperTruth& truth, unsigned seed) {
  SeedRun run;
  const LuGreStroke slow = SlowStroke(truth.theta, seed);
  const LuGreStroke fast = FastStroke(truth.theta, seed + 1000);
  QuasiStaticFitOptions qs_options;
  qs_options.solver = QuasiStaticSolver::kGaussNewton;  // the paper's GNR
  // Far start: every Stribeck entry off by a factor 2-3 from each truth.
  run.step1 = FitLuGreQuasiStatic(
      slow, Eigen::Vector4d(0.6, 0.05, 3.0, 0.0), qs_options);
  const double gain = CalcDampingGain(1.0, truth.fn_n, 0.5);
  LuGreTheta guess = run.step1.theta;
  guess[LuGreIndex::kStiffness] = 4.0;  // 5-10x every truth
  guess[LuGreIndex::kDamping] = 0.01;
  for (Estimator e : {kLm1, kLm2, kLm6}) {
    DynamicFitOptions options;
    options.variant = e == kLm1   ? DynamicFitVariant::kLm1
                      : e == kLm2 ? DynamicFitVariant::kLm2
                                  : DynamicFitVariant::kLm6;
    options.damping_gain = gain;
    LuGreTheta start = guess;
    if (e == kLm6)  // the paper's LM-6 has no Step 1: far start for all
      start.head<4>() = Eigen::Vector4d(0.6, 0.05, 3.0, 0.0);
    run.out[e] = Evaluate(FitLuGreDynamic(fast, start, 0.0, options), truth);
  }
  LuGreEkfOptions ekf;
  ekf.damping_gain = gain;
  ekf.x0 = Eigen::Vector2d(4.0, 0.0);
  ekf.P0 = (Eigen::Matrix2d() << 16.0, 0.0, 0.0, 1e-2).finished();
  ekf.Q = (Eigen::Matrix2d() << 1e-8, 0.0, 0.0, 1e-10).finished();
  ekf.R = kNoise * kNoise;
  run.out[kEkf] = Evaluate(FitLuGreEkf(fast, run.step1.theta, ekf), truth);
  return run;
}

void Print(const PaperTruth& truth, const std::vector<SeedRun>& runs) {
  std::printf("%s: theta = [%g %g %g %g %g %g], Fn %g N\n",
              truth.name,
              truth.theta[0],
              truth.theta[1],
              truth.theta[2],
              truth.theta[3],
              truth.theta[4],
              truth.theta[5],
              truth.fn_n);
  for (std::size_t s = 0; s < runs.size(); ++s) {
    const LuGreFitResult& q = runs[s].step1;
    std::printf("  seed %zu GNR %s [%.4f %.4f %.3f %.5f] rms %.4f\n",
                s,
                ToString(q.status),
                q.theta[0],
                q.theta[1],
                q.theta[2],
                q.theta[3],
                q.residual_rms);
    for (int e = 0; e < kNumEstimators; ++e) {
      const Outcome& o = runs[s].out[e];
      std::printf(
          "    %-9s %-15s d_sigma0 %+8.3f d_sigma1 %+9.3f rms %.4f "
          "BF err %.4f\n",
          kEstimatorNames[e],
          ToString(o.status),
          o.sigma0_err,
          o.sigma1_err,
          o.rms,
          o.bf_err);
    }
  }
  // Summary row per estimator (docs/lugre.md "Paper regime" table).
  auto row = [&](const char* name, auto get) {
    int conv = 0, s0 = 0, s1 = 0, bf = 0;
    for (const SeedRun& r : runs) {
      const Outcome o = get(r);
      conv += o.status == LuGreFitStatus::kConverged;
      s0 += std::abs(o.sigma0_err) <= 0.1;
      s1 += std::abs(o.sigma1_err) <= 0.3;
      bf += o.bf_err <= 0.1;
    }
    std::printf("  | %s | %s | %d | %d | %d | %d |\n",
                truth.name,
                name,
                conv,
                s0,
                s1,
                bf);
  };
  for (int e = 0; e < kNumEstimators; ++e)
    row(kEstimatorNames[e], [e](const SeedRun& r) { return r.out[e]; });
  int gnr = 0;
  for (const SeedRun& r : runs)
    gnr += std::abs(r.step1.theta[0] / truth.theta[0] - 1) <= 0.1 &&
           std::abs(r.step1.theta[1] / truth.theta[1] - 1) <= 0.1;
  std::printf("  | %s | GNR (Step 1): mu_s, mu_c within 10 %% | %d |\n",
              truth.name,
              gnr);
}

// Counts of seeds (of kSeeds) meeting a predicate.
template <typename F>
int Count(const std::vector<SeedRun>& runs, F pred) {
  int n = 0;
  for (const SeedRun& r : runs) n += pred(r) ? 1 : 0;
  return n;
}

std::vector<SeedRun> RunSeeds(const PaperTruth& truth) {
  std::vector<SeedRun> runs;
  for (int s = 0; s < kSeeds; ++s) runs.push_back(RunSeed(truth, 1 + s));
  Print(truth, runs);
  return runs;
}

bool Converged(const Outcome& o) {
  return o.status == LuGreFitStatus::kConverged;
}
// A two-step BF-ratio is useless when it is off by more than 20 %.
bool BfOff(const Outcome& o) { return !(o.bf_err <= 0.2); }

// Tables I and III satisfy the tie. Step 1 (GNR) is what fails there: the
// bristles relax over g / sigma0 ~ 0.4-0.75 mm while the 2 mm/s^2 stroke
// crosses the Stribeck region (v < 2 v0) in 1-2.6 mm, so the slow stroke is
// not quasi-static (eq. 4's premise) and GNR flattens the Stribeck peak.
// Step 2 then finds sigma0 (LM-1, the EKF on Table I) but the BF-ratio of
// every two-step result is wrong.
TEST(PaperRegimeTest, TieTruthsStepOneIsNotQuasiStatic) {
  for (const PaperTruth& truth : {TableI(), TableIII()}) {
    SCOPED_TRACE(truth.name);
    const std::vector<SeedRun> runs = RunSeeds(truth);
    // Step 1: mu_s below half the truth and RMS above 5x the noise on every
    // seed (measured: mu_s 0.117 / 0.143 for 0.30 / 0.36, RMS 7-9x noise).
    EXPECT_EQ(Count(runs,
                    [&](const SeedRun& r) {
                      return r.step1.theta[0] < 0.5 * truth.theta[0] &&
                             r.step1.residual_rms > 5 * kNoise;
                    }),
              kSeeds);
    // LM-1 (tie with the stroke's Fn) still finds sigma0 within 10 %.
    EXPECT_EQ(Count(runs,
                    [](const SeedRun& r) {
                      return Converged(r.out[kLm1]) &&
                             std::abs(r.out[kLm1].sigma0_err) < 0.10;
                    }),
              kSeeds);
    // ... but every two-step BF-ratio is off by > 20 % (measured 61-100 %).
    for (Estimator e : {kLm1, kLm2, kEkf})
      EXPECT_EQ(Count(runs, [e](const SeedRun& r) { return BfOff(r.out[e]); }),
                kSeeds)
          << kEstimatorNames[e];
  }
}

TEST(PaperRegimeTest, TableIEkfAndLm2) {
  // The tie in friction-ratio form needs the stroke's own Fn: at Table I's
  // 20 N, CalcDampingGain(1 kg, 20 N, 0.5) sqrt(sigma0) is Table I's sigma1
  // (0.089 = 0.0316 sqrt(8) in force form) to 0.5 %; the 5 N default gain
  // would tie sigma1 to twice that.
  const PaperTruth t = TableI();
  EXPECT_NEAR(CalcDampingGain(1.0, t.fn_n, 0.5) * std::sqrt(t.theta[4]),
              t.theta[5],
              5e-3 * t.theta[5]);
  EXPECT_NEAR(DynamicFitOptions().damping_gain * std::sqrt(t.theta[4]),
              2.0 * t.theta[5],
              1e-2 * t.theta[5]);
  const std::vector<SeedRun> runs = RunSeeds(TableI());
  // The EKF (tie) recovers sigma0 within 6 % on every seed (measured max
  // 5.0 %) ...
  EXPECT_EQ(Count(runs,
                  [](const SeedRun& r) {
                    return Converged(r.out[kEkf]) &&
                           std::abs(r.out[kEkf].sigma0_err) < 0.06;
                  }),
            kSeeds);
  // ... while LM-2 cannot separate sigma1 (0.0045 s/mm, its loop term is
  // ~1e-3 against noise 3e-3): it stops at max_iterations or misses sigma1
  // by more than 15 % on at least 7 of 10 seeds (measured 8).
  EXPECT_GE(Count(runs,
                  [](const SeedRun& r) {
                    return !Converged(r.out[kLm2]) ||
                           std::abs(r.out[kLm2].sigma1_err) > 0.15;
                  }),
            7);
}

TEST(PaperRegimeTest, TableIIIEkfIsBiasedLm6Helps) {
  const std::vector<SeedRun> runs = RunSeeds(TableIII());
  // The EKF on the biased Step-1 curve puts sigma0 20-40 % low on every
  // seed (measured -29 to -36 %).
  EXPECT_EQ(Count(runs,
                  [](const SeedRun& r) {
                    return r.out[kEkf].sigma0_err < -0.2 &&
                           r.out[kEkf].sigma0_err > -0.4;
                  }),
            kSeeds);
  // LM-6 from the far start fits the fast stroke to the noise and predicts
  // the BF-ratio within 10 % on most seeds (measured 8 of 10).
  EXPECT_GE(Count(runs,
                  [](const SeedRun& r) {
                    return Converged(r.out[kLm6]) &&
                           r.out[kLm6].rms < 1.3 * kNoise &&
                           r.out[kLm6].bf_err < 0.10;
                  }),
            7);
}

// Table V (glass): sigma1 is 32x the tie. LM-1 and the EKF cannot fit the
// loop (RMS > 10x noise, sigma0 off by > 10x on every seed) - the paper's
// observation (V.B.2). LM-2 finds sigma1 within 2 % whenever Step 1 lands
// in the mu_s < mu_c basin.
TEST(PaperRegimeTest, GlassBreaksTheTie) {
  const PaperTruth truth = Glass();
  const std::vector<SeedRun> runs = RunSeeds(truth);
  for (Estimator e : {kLm1, kEkf})
    EXPECT_EQ(Count(runs,
                    [e](const SeedRun& r) {
                      return r.out[e].rms > 10 * kNoise &&
                             r.out[e].sigma0_err > 10.0;
                    }),
              kSeeds)
        << kEstimatorNames[e];
  const int mu_s_below_mu_c = Count(runs, [](const SeedRun& r) {
    return r.step1.theta[0] < r.step1.theta[1];
  });
  EXPECT_GE(mu_s_below_mu_c, 6);  // measured 7 of 10
  EXPECT_EQ(Count(runs,
                  [](const SeedRun& r) {
                    return r.step1.theta[0] < r.step1.theta[1] &&
                           Converged(r.out[kLm2]) &&
                           std::abs(r.out[kLm2].sigma1_err) < 0.02;
                  }),
            mu_s_below_mu_c);
  // Step 1 is not quasi-static here either (the damping term sigma1 dz/dt
  // reaches 0.2 at 1 mm/s): RMS > 3x noise on every seed.
  EXPECT_EQ(
      Count(runs,
            [](const SeedRun& r) { return r.step1.residual_rms > 3 * kNoise; }),
      kSeeds);
}

// The paper's protocol as the service receives it: one upload, slow stroke
// then fast stroke, each with 0.5 s of rest either side, 50 Hz, Ft = |mu| Fn
// (magnitudes, one direction).
StrokeData ProtocolUpload(const PaperTruth& truth, unsigned seed) {
  StrokeData d;
  d.slip.clear();
  d.stroke.clear();
  double t0 = 0;
  int id = 0;
  for (const auto& [accel, peak] : {std::pair{2.0, 10.0}, {10.0, 10.0}}) {
    const double ramp = peak / accel, rest = 0.5;
    const double a = accel, vp = peak;
    const LuGreStroke s = Simulate(
        truth.theta,
        [=](double t) {
          const double u = t - rest;
          if (u <= 0 || u >= 2 * ramp) return 0.0;
          return u < ramp ? a * u : vp - a * (u - ramp);
        },
        2 * ramp + 2 * rest,
        seed + 7919u * id);
    for (Eigen::Index k = 0; k < s.size(); ++k) {
      d.t_s.push_back(t0 + s.t_s[k]);
      d.fn_n.push_back(truth.fn_n);
      d.ft_n.push_back(std::abs(s.mu[k]) * truth.fn_n);
      d.v_mm_s.push_back(s.v_mm_s[k]);
      d.slip.push_back(s.v_mm_s[k] > 0 ? 1 : 0);
      d.stroke.push_back(id);
    }
    t0 += s.t_s[s.size() - 1] + 3.0;
    ++id;
  }
  return d;
}

// The service (IdentifyLuGreFromStrokes) on the paper's protocol. It tries
// LM-2 then LM-1 after Step 1; when Step 1's premise fails (its RMS > 2x
// the noise from second differences) it tries LM-6 from the two-step result
// and keeps it only if it fits to the noise and pins mu_s, mu_c, v0 and
// sigma1; otherwise it identifies nothing and says why. Before this check
// it stored GNR+LM-2 with BF-ratio errors of 31 % (Table I), 68-86 %
// (Table III) and 8-10 % (glass) on every seed.
TEST(PaperRegimeTest, ServicePicksLm6OnGlassAndRefusesTieTruths) {
  for (const PaperTruth& truth : {TableI(), TableIII()}) {
    for (int s = 0; s < kSeeds; ++s) {
      const LuGreIdentification id =
          IdentifyLuGreFromStrokes(ProtocolUpload(truth, 1 + s));
      EXPECT_EQ(id.strokes_quasi_static, 1) << truth.name << " seed " << s;
      EXPECT_EQ(id.strokes_dynamic, 1) << truth.name << " seed " << s;
      EXPECT_FALSE(id.identified)
          << truth.name << " seed " << s << ": variant " << id.family.variant
          << ", BF error " << WorstBfError(id.family.theta, truth);
      EXPECT_NE(id.why.find("cannot identify LuGre from these strokes: the "
                            "low-acceleration stroke is not quasi-static"),
                std::string::npos)
          << id.why;
    }
  }
  const PaperTruth glass = Glass();
  double sum_bf = 0;
  for (int s = 0; s < kSeeds; ++s) {
    const LuGreIdentification id =
        IdentifyLuGreFromStrokes(ProtocolUpload(glass, 1 + s));
    ASSERT_TRUE(id.identified) << "seed " << s << ": " << id.why;
    EXPECT_EQ(id.family.variant, "lm6") << id.why;
    const LuGreTheta& th = id.family.theta;
    const double bf = WorstBfError(th, glass);
    std::printf(
        "service, glass seed %d: [%.4f %.4f %.3f %.5f %.4f %.5f] BF "
        "error %.4f\n",
        s,
        th[0],
        th[1],
        th[2],
        th[3],
        th[4],
        th[5],
        bf);
    sum_bf += bf;
    // Measured over the 10 seeds: sigma0 within 1.9 %, sigma1 within
    // 0.9 %, mu_s within 7.0 %, mu_c within 0.6 %, BF-ratio within 3.2 %.
    EXPECT_LT(std::abs(th[4] / glass.theta[4] - 1), 0.04) << s;
    EXPECT_LT(std::abs(th[5] / glass.theta[5] - 1), 0.02) << s;
    EXPECT_LT(std::abs(th[0] / glass.theta[0] - 1), 0.10) << s;
    EXPECT_LT(std::abs(th[1] / glass.theta[1] - 1), 0.01) << s;
    EXPECT_LT(bf, 0.05) << s;
    EXPECT_NE(id.why.find("kept LM-6"), std::string::npos) << id.why;
  }
  std::printf("service, glass: mean BF-ratio error %.4f\n", sum_bf / kSeeds);
  EXPECT_LT(sum_bf / kSeeds, 0.025);
}

// Where Step 1's premise holds (the stiff docs truth, sigma0 50 /mm, 200 Hz,
// per-stroke Fn 2-5 N) the service keeps the two-step GNR+LM-2 and says so.
TEST(PaperRegimeTest, ServiceKeepsTwoStepWhereTheSlowStrokeIsQuasiStatic) {
  for (std::uint64_t seed : {21u, 22u, 23u}) {
    testing::LuGreStrokeSpec slow;
    slow.strokes = 1;
    slow.hold_s = 0.0;
    slow.accel_min_mm_s2 = 1.5;
    slow.accel_max_mm_s2 = 2.5;
    slow.v_min_mm_s = 15.0;
    slow.v_max_mm_s = 25.0;
    StrokeData d = testing::SimulateLuGreStrokes(slow, seed);
    testing::LuGreStrokeSpec fast;
    fast.strokes = 2;
    fast.v_min_mm_s = 8.0;
    fast.v_max_mm_s = 12.0;
    fast.accel_min_mm_s2 = 15.0;
    fast.accel_max_mm_s2 = 40.0;
    StrokeData f = testing::SimulateLuGreStrokes(fast, seed + 100);
    const double t0 = d.t_s.back() + 5.0;
    for (double& t : f.t_s) t += t0;
    d.Append(f);
    const LuGreIdentification id = IdentifyLuGreFromStrokes(d);
    ASSERT_TRUE(id.identified) << seed << ": " << id.why;
    EXPECT_EQ(id.family.variant, "lm2") << id.why;
    EXPECT_EQ(id.why.rfind("two-step GNR+LM-2: Step-1 RMS", 0), 0u) << id.why;
    const LuGreTheta truth = slow.theta;
    EXPECT_LT(std::abs(id.family.theta[4] / truth[4] - 1), 0.1)
        << id.family.theta[4];
  }
}

}  // namespace
}  // namespace frictiond
