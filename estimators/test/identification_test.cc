#include "frictiond/estimators/identification.h"

#include <algorithm>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/preprocessing.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using testing::SimulateStrokes;
using testing::SimulationSpec;

StrokeData Unlabelled(std::uint64_t seed) {
  SimulationSpec spec;  // b0 = 0.9, b1 = 0.004, b2 = -0.06, sigma = 0.05
  StrokeData d = SimulateStrokes(spec, seed);
  d.slip.clear();
  d.stroke.clear();
  return d;
}

// One call gives what the steps give one by one, on one thread and on two,
// and recovers the planted eq. (1).
TEST(IdentifyMaterial, EqualsTheStepsOnOneAndTwoThreads) {
  const StrokeData raw = Unlabelled(31);
  MaterialIdentificationOptions options;
  // The steps one by one.
  StrokeData labelled = raw;
  EnsureLabels(&labelled, options.fit.labelling);
  const StochasticFit fit = FitStochasticModel(labelled, options.fit);
  ASSERT_EQ(fit.status, FitStatus::kOk) << fit.why;
  std::vector<double> ratio, fn, v;
  for (std::size_t i = 0; i < labelled.size(); ++i) {
    ratio.push_back(labelled.mu(i));
    if (labelled.slip[i]) {
      fn.push_back(labelled.fn_n[i]);
      v.push_back(labelled.v_mm_s[i]);
    }
  }
  const ConditionalSlipLikelihood conditional =
      FitConditionalSlipLikelihood(labelled.fn_n, ratio, labelled.slip);
  const SpanCoverage coverage = CalcSpanCoverage(fn, v, options.reference);
  ASSERT_TRUE(conditional.valid) << conditional.why;
  for (int threads : {1, 2}) {
    options.threads = threads;
    const MaterialIdentification id = IdentifyMaterial(raw, options);
    ASSERT_EQ(id.fit.status, FitStatus::kOk) << id.fit.why;
    EXPECT_EQ(id.fit.model.mu.beta, fit.model.mu.beta) << threads;
    EXPECT_EQ(id.fit.model.mu.eps_quantiles, fit.model.mu.eps_quantiles);
    EXPECT_EQ(id.fit.model.likelihood.c1, fit.model.likelihood.c1);
    EXPECT_EQ(id.fit.model.likelihood.c2, fit.model.likelihood.c2);
    EXPECT_EQ(id.conditional.knot_fn_n, conditional.knot_fn_n);
    EXPECT_EQ(id.conditional.knot_c1, conditional.knot_c1);
    EXPECT_EQ(id.conditional.knot_c2, conditional.knot_c2);
    EXPECT_EQ(id.coverage.span_pct, coverage.span_pct);
    EXPECT_EQ(id.coverage.samples, coverage.samples);
    // The paper's hull-relative coverage per stroke (III-C-2).
    std::vector<int> slip_stroke;
    for (std::size_t i = 0; i < labelled.size(); ++i)
      if (labelled.slip[i]) slip_stroke.push_back(labelled.stroke[i]);
    const MaterialHullCoverage hull =
        CalcMaterialHullCoverage(fn, v, slip_stroke);
    ASSERT_FALSE(hull.strokes.empty());
    ASSERT_EQ(id.hull.strokes.size(), hull.strokes.size());
    EXPECT_EQ(id.hull.hull_area, hull.hull_area);
    for (std::size_t k = 0; k < hull.strokes.size(); ++k)
      EXPECT_EQ(id.hull.strokes[k].coverage.span_pct,
                hull.strokes[k].coverage.span_pct);
    const RegressionModel& m = id.fit.model.mu;
    EXPECT_NEAR(m.beta(0), 0.9, 4 * m.std_err(0));
    EXPECT_NEAR(m.beta(1), 0.004, 4 * m.std_err(1));
    EXPECT_NEAR(m.beta(2), -0.06, 4 * m.std_err(2));
    // The paper's definition against an independent computation: the hull
    // of the slipping samples clamped into the plan, over the plan's area.
    std::vector<std::pair<double, double>> clamped;
    const SpanRect& r = options.reference;
    for (std::size_t i = 0; i < fn.size(); ++i)
      clamped.emplace_back(std::clamp(fn[i], r.fn_min_n, r.fn_max_n),
                           std::clamp(v[i], r.v_min_mm_s, r.v_max_mm_s));
    EXPECT_NEAR(id.coverage.span_pct,
                100.0 * CalcConvexHullArea(clamped) / r.Area(),
                1e-9);
    // 20 strokes with peaks over 15-80 mm/s and loads over 0.5-4.5 N cover
    // most of the plan: the hull misses only the corners the half-sine
    // profiles never reach together.
    EXPECT_GT(id.coverage.span_pct, 60.0);
  }
}

TEST(IdentifyMaterial, RejectsBadOptions) {
  const StrokeData raw = Unlabelled(32);
  MaterialIdentificationOptions options;
  options.threads = 0;
  EXPECT_THROW(IdentifyMaterial(raw, options), std::invalid_argument);
  options.threads = 2;
  options.reference = {1.0, 1.0, 15.0, 80.0};  // empty Fn range
  EXPECT_THROW(IdentifyMaterial(raw, options), std::invalid_argument);
  options.reference = {0.5, 4.5, 15.0, 80.0};
  options.conditional.window_n = -1.0;
  EXPECT_THROW(IdentifyMaterial(raw, options), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
