#include "frictiond/estimators/mu_windows.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "frictiond/estimators/preprocessing.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Slip {
  std::vector<double> fn, v, mu;
};

Slip SlipSamples(const testing::SimulationSpec& spec, std::uint64_t seed) {
  const StrokeData d = testing::SimulateStrokes(spec, seed);
  Slip s;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (!d.slip[i]) continue;
    s.fn.push_back(d.fn_n[i]);
    s.v.push_back(d.v_mm_s[i]);
    s.mu.push_back(d.mu(i));
  }
  return s;
}

TEST(MuWindows, StdNarrowsTowardsSigmaEpsAsBothWindowsShrink) {
  testing::SimulationSpec spec;  // sigma_eps 0.05, b1 0.004, b2 -0.06
  spec.strokes = 160;
  spec.write_labels = true;
  const Slip s = SlipSamples(spec, 42);
  const auto w = CalcMuStdByWindow(
      s.fn, s.v, s.mu, 2.5, 40.0, {kInf, 2, 1, 0.5}, {kInf, 40, 20, 10});
  ASSERT_EQ(w.size(), 4u);
  for (std::size_t k = 1; k < w.size(); ++k) {
    EXPECT_LT(w[k].std_mu, w[k - 1].std_mu) << "width index " << k;
    EXPECT_LT(w[k].samples, w[k - 1].samples);
  }
  ASSERT_GT(w.back().samples, 100);
  // All data: eps plus the spread of b1 v + b2 Fn (about 0.11).
  EXPECT_GT(w.front().std_mu, 1.8 * spec.sigma_eps);
  // Narrow windows: only eps remains (plus ~0.015 from the window widths).
  EXPECT_NEAR(w.back().std_mu, spec.sigma_eps, 0.15 * spec.sigma_eps)
      << "std " << w.back().std_mu << " in " << w.back().samples;
  EXPECT_NEAR(w.back().mean_mu, spec.b0 + spec.b1 * 40 + spec.b2 * 2.5, 0.02);
}

TEST(MuWindows, AnFnPriorAloneLeavesTheSpeedSpread) {
  testing::SimulationSpec spec;
  spec.strokes = 80;
  spec.write_labels = true;
  const Slip s = SlipSamples(spec, 43);
  const auto fn_only =
      CalcMuStdByWindow(s.fn, s.v, s.mu, 2.5, 40.0, {kInf, 0.5}, {kInf, kInf});
  EXPECT_LT(fn_only[1].std_mu, fn_only[0].std_mu);
  // sqrt(sigma_eps^2 + b1^2 Var(v)) stays well above sigma_eps.
  EXPECT_GT(fn_only[1].std_mu, 1.4 * spec.sigma_eps);
}

TEST(MuWindows, NullCaseNothingPlantedNothingNarrows) {
  testing::SimulationSpec spec;
  spec.b1 = 0.0;
  spec.b2 = 0.0;
  spec.strokes = 80;
  spec.write_labels = true;
  const Slip s = SlipSamples(spec, 44);
  const auto w =
      CalcMuStdByWindow(s.fn, s.v, s.mu, 2.5, 40.0, {kInf, 0.5}, {kInf, 10});
  EXPECT_NEAR(w[0].std_mu, spec.sigma_eps, 0.1 * spec.sigma_eps);
  EXPECT_NEAR(w[1].std_mu, spec.sigma_eps, 0.15 * spec.sigma_eps);
}

TEST(MuWindows, RejectsBadWidthsAndEmptyWindows) {
  EXPECT_THROW(CalcMuStdByWindow({1}, {1}, {1}, 1, 1, {0.0}, {1.0}),
               std::invalid_argument);
  EXPECT_THROW(CalcMuStdByWindow({1}, {1}, {1}, 1, 1, {1.0}, {NAN}),
               std::invalid_argument);
  EXPECT_THROW(CalcMuStdByWindow({1}, {1, 2}, {1}, 1, 1, {1.0}, {1.0}),
               std::invalid_argument);
  const auto w = CalcMuStdByWindow({1}, {1}, {0.5}, 9, 9, {1.0}, {1.0});
  EXPECT_EQ(w[0].samples, 0);
  EXPECT_EQ(w[0].std_mu, 0.0);
}

}  // namespace
}  // namespace frictiond
