#include "frictiond/estimators/breakaway.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/lugre_identification.h"

namespace frictiond {
namespace {

using Eigen::VectorXd;

constexpr double kNoise = 0.005;
constexpr double kFn = 5.0;

LuGreTheta Truth() { return MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1); }

LuGreStroke SimulateStroke(const std::function<double(double)>& v_of_t,
                           double duration_s,
                           unsigned seed) {
  const int n = static_cast<int>(std::round(duration_s * 200.0)) + 1;
  LuGreStroke s;
  s.t_s = VectorXd::LinSpaced(n, 0.0, (n - 1) / 200.0);
  s.v_mm_s.resize(n);
  for (int k = 0; k < n; ++k) s.v_mm_s[k] = v_of_t(s.t_s[k]);
  const VelocityDrivenResult r =
      SimulateVelocityDriven(Truth(), s.t_s, s.v_mm_s, 0.0);
  EXPECT_EQ(r.status, SimulationStatus::kOk) << r.why;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, kNoise);
  s.mu = r.mu;
  for (int k = 0; k < n; ++k) s.mu[k] += gauss(rng);
  return s;
}

// Two-stroke identification (paper Steps 1-2) from far starts; the slow
// stroke's noise from `seed`, the fast one's from seed + 100.
LuGreTheta Identify(DynamicFitVariant variant, bool ekf, unsigned seed = 7) {
  const LuGreStroke slow = SimulateStroke(
      [](double t) { return t < 10 ? 2.0 * t : 40.0 - 2.0 * t; }, 20.0, seed);
  const LuGreStroke fast = SimulateStroke(
      [](double t) { return t < 0.5 ? 20.0 * t : 20.0 - 20.0 * t; },
      1.0,
      seed + 100);
  const LuGreFitResult qs =
      FitLuGreQuasiStatic(slow, Eigen::Vector4d(0.3, 0.2, 1.0, 0.0));
  EXPECT_EQ(qs.status, LuGreFitStatus::kConverged) << qs.why;
  if (ekf) {
    LuGreEkfOptions o;
    o.x0 = Eigen::Vector2d(20.0, 0.0);
    o.P0 = (Eigen::Matrix2d() << 900.0, 0.0, 0.0, 1e-6).finished();
    o.R = kNoise * kNoise;
    const LuGreFitResult r = FitLuGreEkf(fast, qs.theta, o);
    EXPECT_EQ(r.status, LuGreFitStatus::kConverged) << r.why;
    return r.theta;
  }
  LuGreTheta guess = qs.theta;
  guess[LuGreIndex::kStiffness] = 10.0;
  guess[LuGreIndex::kDamping] = 0.01;
  DynamicFitOptions options;
  options.variant = variant;
  const LuGreFitResult r = FitLuGreDynamic(fast, guess, 0.0, options);
  EXPECT_EQ(r.status, LuGreFitStatus::kConverged) << r.why;
  return r.theta;
}

// Every variant's BF-ratio against the truth's over 10 seeds. The
// prediction runs at Table II's rel_tol 1e-3, so two predictions of one
// model differ by up to ~1e-3; the identification adds its own error.
// Measured worst / mean relative error over 10 seeds x 3 rates: GN+LM-1
// 7.4e-4 / 3.4e-4, GN+LM-2 2.1e-3 / 5.2e-4, LM-6 3.2e-3 / 9.4e-4, GN+EKF
// 7.5e-4 / 3.6e-4 (was one seed against a 3 % limit).
TEST(BreakawayPredictionTest, IdentifiedModelPredictsTruthBfRatioOverSeeds) {
  struct Variant {
    const char* name;
    DynamicFitVariant variant;
    bool ekf;
  };
  const Variant variants[] = {
      {"GN+LM-1", DynamicFitVariant::kLm1, false},
      {"GN+LM-2", DynamicFitVariant::kLm2, false},
      {"LM-6 (two strokes)", DynamicFitVariant::kLm6, false},
      {"GN+EKF", DynamicFitVariant::kLm1, true}};
  const double rhos[] = {0.05, 0.5, 5.0};
  double truth_bf[3];
  for (int i = 0; i < 3; ++i) {
    const ForceDrivenResult truth =
        PredictBreakawayRatio(Truth(), rhos[i], kFn);
    ASSERT_EQ(truth.status, SimulationStatus::kOk) << truth.why;
    truth_bf[i] = truth.bf_ratio;
  }
  constexpr int kSeeds = 10;
  for (const Variant& c : variants) {
    double worst = 0, sum = 0;
    int n = 0;
    for (unsigned seed = 1; seed <= kSeeds; ++seed) {
      const LuGreTheta theta = Identify(c.variant, c.ekf, seed);
      for (int i = 0; i < 3; ++i) {
        const ForceDrivenResult p = PredictBreakawayRatio(theta, rhos[i], kFn);
        ASSERT_EQ(p.status, SimulationStatus::kOk) << c.name << ": " << p.why;
        const double err = std::abs(p.bf_ratio / truth_bf[i] - 1);
        worst = std::max(worst, err);
        sum += err;
        ++n;
        EXPECT_LT(err, 5e-3)
            << c.name << " seed " << seed << " rho " << rhos[i] << ": expected "
            << truth_bf[i] << ", got " << p.bf_ratio;
      }
    }
    std::printf(
        "%s: BF-ratio error over %d seeds x 3 rates: worst %.2e, "
        "mean %.2e\n",
        c.name,
        kSeeds,
        worst,
        sum / n);
    EXPECT_LT(sum / n, 1.5e-3) << c.name;
  }
}

TEST(BreakawayPredictionTest, BfRatioIsBetweenCoulombAndStatic) {
  // Paper Section V.B.1: the actual BF-ratio lies between mu_c and mu_s, so
  // mu_s as a slip threshold over-estimates it.
  for (double rho : {0.1, 1.0, 10.0}) {
    const ForceDrivenResult p = PredictBreakawayRatio(Truth(), rho, kFn);
    ASSERT_EQ(p.status, SimulationStatus::kOk) << p.why;
    EXPECT_GT(p.bf_ratio, 0.6) << rho;
    EXPECT_LT(p.bf_ratio, 0.9 + 1e-3) << rho;
  }
}

TEST(BreakawayMonitorTest, MarginShrinksToZeroAtTheTruthBreakaway) {
  const double rho = 0.5;
  const double bf_truth = PredictBreakawayRatio(Truth(), rho, kFn).bf_ratio;
  BreakawayMonitorOptions options;
  options.rho_rel_change = 0.01;  // rho is constant: one simulation
  BreakawayMonitor monitor(Identify(DynamicFitVariant::kLm2, false), options);
  double previous_margin = 2.0;
  double slip_at = -1;
  for (int k = 0; k < 200 && slip_at < 0; ++k) {  // 50 Hz, Ft/Fn = rho t
    const double mu = rho * k / 50.0;
    const BreakawayEstimate e = monitor.Update(mu, rho);
    ASSERT_EQ(e.status, SimulationStatus::kOk);
    EXPECT_LT(e.margin, previous_margin);
    previous_margin = e.margin;
    if (e.slip_predicted) slip_at = mu;
  }
  std::cout << "monitor: slip predicted at Ft/Fn = " << slip_at << ", truth BF "
            << bf_truth << ", simulations " << monitor.simulations() << "\n";
  EXPECT_EQ(monitor.simulations(), 1);
  // The monitor sees Ft/Fn in steps of rho / 50 (one 50 Hz sample): it
  // must flag the first sample at or past the truth's break-away, within
  // the simulation's own tolerance (1e-3 relative).
  EXPECT_GE(slip_at, bf_truth * (1 - 1e-3));
  EXPECT_LE(slip_at, bf_truth * (1 + 1e-3) + rho / 50.0);
  EXPECT_LE(monitor.last().margin, 0.0);
}

TEST(BreakawayMonitorTest, FasterLoadingLowersThePrediction) {
  BreakawayMonitor monitor(Truth());
  const BreakawayEstimate slow = monitor.Update(0.3, 0.1);
  const BreakawayEstimate fast = monitor.Update(0.3, 5.0);
  const BreakawayEstimate unloading = monitor.Update(0.3, -1.0);
  EXPECT_GT(slow.bf_ratio, fast.bf_ratio);
  EXPECT_LT(fast.margin, slow.margin);
  // rho <= 0 is predicted at min_rho_per_s: the slow-loading limit.
  EXPECT_DOUBLE_EQ(unloading.rho_per_s,
                   BreakawayMonitorOptions().min_rho_per_s);
  EXPECT_GE(unloading.bf_ratio, slow.bf_ratio);
  EXPECT_EQ(monitor.simulations(), 3);
}

// ------------------------------------------- from the measured state (eq. 16)

// Paper 001 Table I (simulation parameters; Fn = 20 N, m = 0.2 kg) in
// friction-ratio form: sigma0 8 N/mm / 20 N, sigma1 0.089 Ns/mm / 20 N.
LuGreTheta TableI() {
  return MakeLuGreTheta(0.3, 0.15, 1.0, 4e-5, 8.0 / 20, 0.089 / 20);
}

// A drag ramp from rest, cut at t0: the state there (Ft/Fn, v) is what a
// robot measures. Predicting from it (eq. 16) must continue the ramp's own
// break-away; the bristle deflection it implies (held equilibrium, eq. 17
// with dv/dt = 0) must match the simulated one. Table II's start at the
// same load (z = 0, v = 0) releases the loaded bristles at once and gets
// the BF-ratio wrong.
TEST(BreakawayFromStateTest, ContinuesTheRampFromItsMeasuredState) {
  struct Case {
    const char* name;
    LuGreTheta theta;
    double fn_n;
    double rho;
  };
  // Table I only at slow loading: its bristles are so compliant that the
  // stick-phase creep rho / sigma0 (1.25 mm/s at 0.5 /s) reaches the
  // break-away threshold 2 v0 = 2 mm/s, and "break-away" then only marks
  // that creep (docs/lugre.md).
  for (const Case& c : {Case{"docs truth", Truth(), kFn, 0.05},
                        Case{"docs truth", Truth(), kFn, 0.5},
                        Case{"docs truth", Truth(), kFn, 5.0},
                        Case{"Table I", TableI(), 20.0, 0.02},
                        Case{"Table I", TableI(), 20.0, 0.05}}) {
    {
      const double rho = c.rho;
      std::vector<ForceDrivenSample> path;
      const ForceDrivenResult full =
          SimulateForceDriven(c.theta, rho, c.fn_n, {}, &path);
      ASSERT_EQ(full.status, SimulationStatus::kOk) << full.why;
      for (double fraction : {0.3, 0.6, 0.9}) {
        // First accepted step past fraction of the break-away time.
        const ForceDrivenSample* at = nullptr;
        for (const ForceDrivenSample& p : path)
          if (p.t_s >= fraction * full.t_breakaway_s) {
            at = &p;
            break;
          }
        ASSERT_NE(at, nullptr);
        const double z_held =
            CalcHeldBristleDeflection(c.theta, at->mu_applied, at->v_mm_s);
        EXPECT_NEAR(z_held, at->z_mm, 2e-3 * std::abs(at->z_mm))
            << c.name << " rho " << rho << " t " << at->t_s;
        const ForceDrivenResult from_state = PredictBreakawayRatioFromState(
            c.theta, at->mu_applied, at->v_mm_s, rho, c.fn_n);
        ASSERT_EQ(from_state.status, SimulationStatus::kOk) << from_state.why;
        ForceDrivenOptions table_ii;  // x = [mu_e(t0), 0, 0]
        table_ii.mu_applied0 = at->mu_applied;
        const ForceDrivenResult jolted =
            SimulateForceDriven(c.theta, rho, c.fn_n, table_ii);
        const double err = std::abs(from_state.bf_ratio / full.bf_ratio - 1);
        const double err_jolt =
            jolted.status == SimulationStatus::kOk
                ? std::abs(jolted.bf_ratio / full.bf_ratio - 1)
                : INFINITY;
        std::printf(
            "%s rho %.2f from %.0f %%: BF %.5f vs %.5f (%.1e), t %.4f "
            "vs %.4f; Table II start: BF %.5f (%.1e)\n",
            c.name,
            rho,
            100 * fraction,
            from_state.bf_ratio,
            full.bf_ratio,
            err,
            at->t_s + from_state.t_breakaway_s,
            full.t_breakaway_s,
            jolted.bf_ratio,
            err_jolt);
        // Both simulations run at rel_tol 1e-3 (Table II).
        EXPECT_LT(err, 2e-3) << c.name << " rho " << rho;
        EXPECT_NEAR(at->t_s + from_state.t_breakaway_s,
                    full.t_breakaway_s,
                    5e-3 * full.t_breakaway_s)
            << c.name << " rho " << rho;
        // The jolt matters once the load is near the break-away (measured
        // 13-17 % low at 90 % on the docs truth) and always on Table I's
        // compliant bristles (92-95 % low).
        if (fraction >= 0.9 || c.theta[4] < 1) {
          EXPECT_GT(err_jolt, 0.1) << c.name << " rho " << rho;
        }
      }
    }
  }
}

// LuGre's bound |z| <= max g / sigma0: a held contact cannot carry Ft/Fn
// above mu_s (it has broken away), so no state is made up for it.
TEST(BreakawayFromStateTest, HeldRatioAboveStaticIsNoState) {
  const LuGreTheta theta = Truth();
  const double mu_s = theta[LuGreIndex::kMuStatic];
  EXPECT_NEAR(CalcHeldBristleDeflection(theta, mu_s, 0.0) *
                  theta[LuGreIndex::kStiffness],
              mu_s,
              1e-12);
  for (double ratio : {1.001, 1.2}) {
    try {
      CalcHeldBristleDeflection(theta, ratio * mu_s, 0.0);
      ADD_FAILURE() << "held at " << ratio << " mu_s";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("mu_applied"), std::string::npos)
          << e.what();
    }
    EXPECT_THROW(
        PredictBreakawayRatioFromState(theta, ratio * mu_s, 0.0, 0.5, kFn),
        std::invalid_argument);
  }
}

// Acceleration-driven case (paper 001 Section II.B, Fig. 2a; Fig. 3 at
// 3 m/s^3): the hand lifts a 0.2 kg object held at 20 N (Table I). Checked
// against an independent fixed-step RK4 of the object's slip in the hand's
// frame, dv/dt = (g + jerk t) - Fn mu_f / m, from the held state.
TEST(BreakawayLiftTest, MatchesAFingerFrameSimulationAndFallsWithJerk) {
  const LuGreTheta theta = TableI();
  const double fn = 20.0, m = 0.2;
  ForceDrivenOptions options;
  options.mass_kg = m;
  auto reference = [&](double jerk) {
    const double h = 1e-4;  // s; stick-phase frequency 200 rad/s: h w = 0.02
    double t = 0, v = 0;
    double z = m * kGravityM_S2 / (fn * theta[4]);  // held: sigma0 z = mg/Fn
    double mu_max = theta[4] * z;
    auto rhs = [&](double tt, double vv, double zz, double* mu) {
      const double zdot = CalcBristleRate(theta, vv, zz);
      const double mu_f = theta[4] * zz + theta[5] * zdot + theta[3] * vv;
      if (mu) *mu = mu_f;
      // [mm/s^2]: 1000 (g + a) - 1000 Fn mu_f / m.
      return std::pair<double, double>(
          1000.0 * (kGravityM_S2 + jerk * tt) - 1000.0 * fn * mu_f / m, zdot);
    };
    while (v <= 2.0 * theta[2] && t < 60) {
      const auto k1 = rhs(t, v, z, nullptr);
      const auto k2 =
          rhs(t + h / 2, v + h / 2 * k1.first, z + h / 2 * k1.second, nullptr);
      const auto k3 =
          rhs(t + h / 2, v + h / 2 * k2.first, z + h / 2 * k2.second, nullptr);
      const auto k4 = rhs(t + h, v + h * k3.first, z + h * k3.second, nullptr);
      v += h / 6 * (k1.first + 2 * k2.first + 2 * k3.first + k4.first);
      z += h / 6 * (k1.second + 2 * k2.second + 2 * k3.second + k4.second);
      t += h;
      double mu;
      rhs(t, v, z, &mu);
      mu_max = std::max(mu_max, mu);
    }
    return std::pair<double, double>(mu_max, t);
  };
  double previous = INFINITY;
  std::vector<double> bfs;
  for (double jerk : {0.5, 1.0, 3.0, 10.0}) {
    const ForceDrivenResult p =
        PredictLiftBreakawayRatio(theta, jerk, fn, options);
    ASSERT_EQ(p.status, SimulationStatus::kOk) << p.why;
    const auto [bf_ref, t_ref] = reference(jerk);
    std::printf(
        "lift, Table I, jerk %4.1f m/s^3: BF %.5f (RK4 %.5f), "
        "break-away after %.4f s (RK4 %.4f)\n",
        jerk,
        p.bf_ratio,
        bf_ref,
        p.t_breakaway_s,
        t_ref);
    // Table II tolerance rel 1e-3; the time also carries the step size at
    // the velocity jump.
    EXPECT_NEAR(p.bf_ratio, bf_ref, 1e-3 * bf_ref) << jerk;
    EXPECT_NEAR(p.t_breakaway_s, t_ref, 5e-3 * t_ref) << jerk;
    // Fig. 2a: the BF-ratio falls as the acceleration rate grows, and stays
    // between mu_c and mu_s (Section V.B.1).
    EXPECT_LT(p.bf_ratio, previous) << jerk;
    EXPECT_GT(p.bf_ratio, theta[1]) << jerk;
    EXPECT_LT(p.bf_ratio, theta[0] * (1 + 1e-3)) << jerk;
    previous = p.bf_ratio;
    bfs.push_back(p.bf_ratio);
  }
  // Equivalent to the drag case ("the second case is equivalent to the
  // first", Section II.B): mu_e0 = m g / Fn, rho = m jerk / Fn.
  const ForceDrivenResult drag = PredictBreakawayRatioFromState(
      theta, m * kGravityM_S2 / fn, 0.0, m * 3.0 / fn, fn, options);
  EXPECT_DOUBLE_EQ(drag.bf_ratio,
                   PredictLiftBreakawayRatio(theta, 3.0, fn, options).bf_ratio);
  std::printf("lift: BF at 0.5 / 10 m/s^3 = %.3f\n", bfs.front() / bfs.back());
}

// The online monitor from the measured state (Fig. 14): the drag-ratio rate
// drops from 0.5 to 0.1 /s halfway; after the drop the prediction from the
// measured state is the truth's actual break-away, with the time left to it.
TEST(BreakawayMonitorTest, FromMeasuredStateFollowsARateChange) {
  const LuGreTheta theta = Truth();
  const double rho1 = 0.5, rho2 = 0.1;
  const double t1 = 0.5 * PredictBreakawayRatio(theta, rho1, kFn).t_breakaway_s;
  // Truth: ramp at rho1 up to t1, then at rho2 from the state reached.
  ForceDrivenOptions first;
  first.t_end_s = t1;
  std::vector<ForceDrivenSample> path;
  const ForceDrivenResult leg1 =
      SimulateForceDriven(theta, rho1, kFn, first, &path);
  ASSERT_EQ(leg1.status, SimulationStatus::kNoBreakaway);
  const ForceDrivenSample& s1 = path.back();
  ForceDrivenOptions second;
  second.mu_applied0 = s1.mu_applied;
  second.initial_v_mm_s = s1.v_mm_s;
  second.initial_z_mm = s1.z_mm;
  const ForceDrivenResult truth = SimulateForceDriven(theta, rho2, kFn, second);
  ASSERT_EQ(truth.status, SimulationStatus::kOk) << truth.why;
  BreakawayMonitorOptions options;
  options.fn_n = kFn;
  options.from_measured_state = true;
  BreakawayMonitor monitor(theta, options);
  const BreakawayEstimate e = monitor.Update(s1.mu_applied, rho2, s1.v_mm_s);
  ASSERT_EQ(e.status, SimulationStatus::kOk);
  std::printf(
      "monitor from state after the rate drop: BF %.5f (truth %.5f), "
      "%.4f s left (truth %.4f), margin %.4f\n",
      e.bf_ratio,
      truth.bf_ratio,
      e.t_breakaway_s,
      truth.t_breakaway_s,
      e.margin);
  EXPECT_NEAR(e.bf_ratio, truth.bf_ratio, 2e-3 * truth.bf_ratio);
  EXPECT_NEAR(e.t_breakaway_s, truth.t_breakaway_s, 5e-3 * truth.t_breakaway_s);
  EXPECT_NEAR(e.margin, 1 - s1.mu_applied / e.bf_ratio, 1e-12);
  EXPECT_EQ(monitor.simulations(), 1);
  monitor.Update(s1.mu_applied, rho2, s1.v_mm_s);
  EXPECT_EQ(monitor.simulations(), 2);  // no reuse from a measured state
}

TEST(BreakawayMonitorTest, RejectsBadInputNamingFieldValueAndRule) {
  BreakawayMonitorOptions options;
  options.fn_n = 0;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why, "fn_n = 0.000000 (must be finite and > 0)");
  options = BreakawayMonitorOptions();
  options.simulation.rel_tol = -1;
  try {
    BreakawayMonitor monitor(Truth(), options);
    ADD_FAILURE() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "BreakawayMonitorOptions.simulation.rel_tol = -1 (must be finite "
              "and > 0)");
  }
  BreakawayMonitor monitor(Truth());
  EXPECT_THROW(monitor.Update(std::nan(""), 0.1), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
