// The simulated robot's hidden truth (testing/robot_truth.h) through the
// daemon's core in process, without LCM: one upload of a sweep plus the
// LuGre pair (what the LCM robot streams for one request) must give both
// the stochastic model and the LuGre family at their truths, over several
// seeds. This calibrates the tolerances the LCM robot simulator checks
// (tests/lcm/robot_simulator.h, LuGreTolerances).
#include "frictiond/testing/robot_truth.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>

#include <gtest/gtest.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/routes.h"

namespace frictiond {
namespace {

namespace ft = frictiond::testing;

// Sweep, a 1 s unrecorded gap, then the pair: the robot's stroke.
StrokeData RobotStroke(const ft::RobotTruth& truth,
                       const ft::LuGrePairShape& pair,
                       std::uint64_t seed) {
  StrokeData d = ft::SimulateTruthSweep(truth, 0.5, 4.5, 15.0, 80.0, seed);
  StrokeData p = ft::SimulateTruthLuGrePair(truth, pair, seed);
  const double shift = d.t_s.back() + 1.0;
  for (double& t : p.t_s) t += shift;
  d.Append(p);
  return d;
}

// 24 seeds take ~0.3 s; the tolerances (LuGreTolerances) were calibrated
// with kSeeds = 200.
constexpr std::uint64_t kSeeds = 24;

TEST(RobotTruthTest, SweepPlusPairIdentifiesBothFamilies) {
  const ft::RobotTruth truth;
  const ft::LuGrePairShape pair;
  const LuGreTheta expected = truth.ThetaAt(pair.fn_n);
  const char* names[6] = {"mu_s", "mu_c", "v0", "sigma2", "sigma0", "sigma1"};
  double worst[6] = {0, 0, 0, 0, 0, 0};
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
    FrictionLibrary lib(OpenStore(":memory:"));
    HttpServer http;
    RegisterLuGreFeature(http, lib);
    const StrokeData d = RobotStroke(truth, pair, seed);
    IngestOptions io;
    const auto t0 = std::chrono::steady_clock::now();
    const IngestResult r = lib.IngestStrokes("m", FormatStrokeCsv(d), io);
    const double ms = std::chrono::duration<double, std::milli>(
                          std::chrono::steady_clock::now() - t0)
                          .count();
    ASSERT_TRUE(r.model);
    const auto it = r.model->set.other.find(kLuGreFamilyKey);
    ASSERT_NE(it, r.model->set.other.end())
        << "seed " << seed << " " << r.fit_note;
    const LuGreFamily f = LuGreFromJson(*it);
    std::printf("seed %d (%zu samples, %.0f ms): variant %s strokes %d+%d",
                static_cast<int>(seed),
                d.size(),
                ms,
                f.variant.c_str(),
                f.strokes_quasi_static,
                f.strokes_dynamic);
    for (int i = 0; i < 6; ++i) {
      const double rel = (f.theta[i] - expected[i]) / expected[i];
      worst[i] = std::max(worst[i], std::abs(rel));
      std::printf(" %s %.4g (%+.1f%%)", names[i], f.theta[i], 100 * rel);
    }
    const auto& mu = r.model->set.stochastic->mu;
    std::printf("\n  stochastic:");
    const double beta_truth[3] = {truth.b0, truth.b1, truth.b2};
    for (int i = 0; i < 3; ++i)
      std::printf(" %s %.4g (%.1f se)",
                  mu.terms[i].Name().c_str(),
                  mu.beta[i],
                  (mu.beta[i] - beta_truth[i]) / mu.std_err[i]);
    std::printf(" sigma_eps %.4g\n", mu.sigma_eps);
    // Both families at their truths: LuGre within the calibrated
    // tolerances, the stochastic coefficients within 5 standard errors.
    EXPECT_EQ(ft::CompareLuGreToTruth(f.theta, expected), "")
        << "seed " << seed;
    EXPECT_EQ(f.strokes_dynamic, pair.fast_strokes) << "seed " << seed;
    for (int i = 0; i < 3; ++i)
      EXPECT_NEAR(mu.beta[i], beta_truth[i], 5 * mu.std_err[i])
          << mu.terms[i].Name() << " seed " << seed;
    EXPECT_NEAR(mu.sigma_eps, truth.sigma_eps, 0.1 * truth.sigma_eps);
  }
  std::printf("worst relative errors:");
  for (int i = 0; i < 6; ++i)
    std::printf(" %s %.1f%%", names[i], 100 * worst[i]);
  std::printf("\n");
}

// The tolerances separate truths: another LuGre truth (same stochastic
// part) identifies near itself and fails the first truth's comparison.
TEST(RobotTruthTest, DifferentLuGreTruthDoesNotMatch) {
  const ft::RobotTruth first;
  ft::RobotTruth other;
  other.static_excess = 0.15;
  other.v0_mm_s = 3.5;
  other.sigma0_per_mm = 25.0;
  const ft::LuGrePairShape pair;
  FrictionLibrary lib(OpenStore(":memory:"));
  HttpServer http;
  RegisterLuGreFeature(http, lib);
  const IngestResult r = lib.IngestStrokes(
      "m", FormatStrokeCsv(RobotStroke(other, pair, 3)), IngestOptions{});
  const auto it = r.model->set.other.find(kLuGreFamilyKey);
  ASSERT_NE(it, r.model->set.other.end()) << r.fit_note;
  const LuGreFamily f = LuGreFromJson(*it);
  EXPECT_EQ(ft::CompareLuGreToTruth(f.theta, other.ThetaAt(pair.fn_n)), "");
  const std::string off =
      ft::CompareLuGreToTruth(f.theta, first.ThetaAt(pair.fn_n));
  std::cout << "against the first truth: " << off << "\n";
  EXPECT_NE(off.find("mu_s"), std::string::npos) << off;
  EXPECT_NE(off.find("v0_mm_s"), std::string::npos) << off;
  EXPECT_NE(off.find("sigma0_per_mm"), std::string::npos) << off;
}

// A sweep alone (an old robot's stroke) identifies no LuGre family: the
// pair is what makes it identifiable.
TEST(RobotTruthTest, SweepAloneHasNoLuGreFamily) {
  const ft::RobotTruth truth;
  FrictionLibrary lib(OpenStore(":memory:"));
  HttpServer http;
  RegisterLuGreFeature(http, lib);
  const IngestResult r = lib.IngestStrokes(
      "m",
      FormatStrokeCsv(ft::SimulateTruthSweep(truth, 0.5, 4.5, 15, 80, 3)),
      IngestOptions{});
  EXPECT_EQ(r.model->set.other.count(kLuGreFamilyKey), 0u) << r.fit_note;
  EXPECT_NE(r.fit_note.find("low-acceleration"), std::string::npos)
      << r.fit_note;
}

}  // namespace
}  // namespace frictiond
