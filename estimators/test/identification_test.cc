#include "frictiond/estimators/identification.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/preprocessing.h"
#include "frictiond/testing/lugre_strokes.h"
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

// The second share handed to `post`: the same result whether a worker runs
// it (here a thread started by the test), whether the caller gets to it
// first (the posted task is dropped, or runs only after the call), or
// whether `post` throws; a late worker finds the task already claimed.
TEST(IdentifyMaterial, PostedShareRunsExactlyOnceWhoeverClaimsIt) {
  const StrokeData raw = Unlabelled(32);
  MaterialIdentificationOptions options;
  options.threads = 1;
  const MaterialIdentification want = IdentifyMaterial(raw, options);
  options.threads = 2;
  std::vector<std::function<void()>> late;  // run after the call returns
  std::vector<std::thread> workers;
  const std::vector<
      std::pair<std::string, std::function<void(std::function<void()>)>>>
      posts = {
          {"worker thread",
           [&workers](std::function<void()> f) {
             workers.emplace_back(std::move(f));
           }},
          {"dropped", [](std::function<void()>) {}},
          {"run after the call",
           [&late](std::function<void()> f) { late.push_back(std::move(f)); }},
          {"post throws",
           [](std::function<void()>) { throw std::runtime_error("full"); }},
      };
  for (const auto& [name, post] : posts) {
    options.post = post;
    const MaterialIdentification id = IdentifyMaterial(raw, options);
    for (std::thread& t : workers) t.join();
    workers.clear();
    for (auto& f : late) f();  // claimed already: does nothing
    late.clear();
    EXPECT_EQ(id.fit.model.mu.beta, want.fit.model.mu.beta) << name;
    EXPECT_EQ(id.conditional.knot_c1, want.conditional.knot_c1) << name;
    EXPECT_EQ(id.coverage.span_pct, want.coverage.span_pct) << name;
    EXPECT_EQ(id.lugre.why, want.lugre.why) << name;
    EXPECT_EQ(id.hull.hull_area, want.hull.hull_area) << name;
  }
}

// LuGre strokes of one material from a generator wider than the
// identification assumes: per-stroke normal force 2-5 N (the LM-1 tie and
// the pooled fits assume nothing about it), per-stroke peak speed and
// acceleration drawn from ranges, sensor noise on mu; two slow strokes
// (1.5-2.5 mm/s^2, Step 1) then six fast ones (15-40 mm/s^2 to 8-12 mm/s, Step
// 2).
StrokeData LuGreMaterial(std::uint64_t seed) {
  testing::LuGreStrokeSpec slow;
  slow.strokes = 2;
  slow.accel_min_mm_s2 = 1.5;
  slow.accel_max_mm_s2 = 2.5;
  slow.v_min_mm_s = 15.0;
  slow.v_max_mm_s = 25.0;
  StrokeData d = testing::SimulateLuGreStrokes(slow, seed);
  testing::LuGreStrokeSpec fast;
  fast.strokes = 6;
  // Slow enough starts that the bristles deflect over several samples at
  // 200 Hz (faster ones leave sigma0 unobservable: kNotObservable).
  fast.v_min_mm_s = 8.0;
  fast.v_max_mm_s = 12.0;
  fast.accel_min_mm_s2 = 15.0;
  fast.accel_max_mm_s2 = 40.0;
  StrokeData f = testing::SimulateLuGreStrokes(fast, seed + 1);
  const double t0 = d.t_s.back() + 5.0;
  for (double& t : f.t_s) t += t0;
  d.Append(f);
  return d;
}

// The one entry point identifies the LuGre family from the recognised
// strokes, equal to IdentifyLuGreFromStrokes on one and two threads, and
// recovers the planted parameters (docs/lugre.md's truth, all away from
// zero) over several seeds.
TEST(IdentifyMaterial, IdentifiesLuGreFromRecognisedStrokes) {
  const testing::LuGreStrokeSpec spec;
  const LuGreTheta truth = spec.theta;
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    const StrokeData data = LuGreMaterial(seed);
    const LuGreIdentification direct = IdentifyLuGreFromStrokes(data);
    ASSERT_TRUE(direct.identified) << "seed " << seed << ": " << direct.why;
    EXPECT_EQ(direct.strokes_quasi_static, 2) << seed;
    EXPECT_EQ(direct.strokes_dynamic, 6) << seed;
    const LuGreFamily& f = direct.family;
    // Step 1 pools both slow strokes, Step 2 combines up to four fast ones.
    EXPECT_EQ(f.strokes_quasi_static, 2);
    EXPECT_GE(f.strokes_dynamic, 1);
    EXPECT_LT(std::abs(f.theta[0] / truth[0] - 1), 0.03) << f.theta[0];
    EXPECT_LT(std::abs(f.theta[1] / truth[1] - 1), 0.03) << f.theta[1];
    EXPECT_LT(std::abs(f.theta[2] / truth[2] - 1), 0.2) << f.theta[2];
    EXPECT_LT(std::abs(f.theta[4] / truth[4] - 1), 0.2) << f.theta[4];
    EXPECT_LT(f.residual_rms, 2.0 * spec.noise_mu);
    MaterialIdentificationOptions options;
    for (int threads : {1, 2}) {
      options.threads = threads;
      const MaterialIdentification id = IdentifyMaterial(data, options);
      ASSERT_TRUE(id.lugre.identified) << id.lugre.why;
      EXPECT_EQ(id.lugre.family.theta, f.theta) << threads;
      EXPECT_EQ(id.lugre.family.P_theta, f.P_theta) << threads;
      // The other families come from the same call.
      EXPECT_GT(id.fit.model.mu.beta.size(), 0);
      EXPECT_GT(id.coverage.samples, 0);
    }
  }
}

// Null case: stochastic strokes only (all fast, no low-acceleration pair):
// nothing is identified and the reason names what is missing; with
// options.lugre = false nothing is attempted.
TEST(IdentifyMaterial, LuGreNeedsTheIdentifyingPair) {
  const StrokeData raw = Unlabelled(33);
  const MaterialIdentification id = IdentifyMaterial(raw);
  ASSERT_EQ(id.fit.status, FitStatus::kOk) << id.fit.why;
  EXPECT_FALSE(id.lugre.identified);
  EXPECT_NE(id.lugre.why.find("acceleration stroke"), std::string::npos)
      << id.lugre.why;
  MaterialIdentificationOptions options;
  options.lugre = false;
  const MaterialIdentification off = IdentifyMaterial(raw, options);
  EXPECT_FALSE(off.lugre.identified);
  EXPECT_EQ(off.lugre.why, "not requested");
  EXPECT_EQ(off.fit.model.mu.beta, id.fit.model.mu.beta);
}

// The memo (identification_memo.h) changes no answer: a refit's data as
// the daemon's ingestor gives it (older uploads, the oldest dropped, a new
// one last; LuGre strokes among them, and one upload whose clock continues
// the previous one's, so that their runs merge) identified with and
// without it. A call looks up the strokes the previous one saw and the
// memo keeps only what the last call used.
TEST(IdentifyMaterial, MemoChangesNoAnswerAndKeepsOnlyTheLastCall) {
  std::vector<StrokeData> uploads;
  for (std::uint64_t k = 0; k < 9; ++k) {
    if (k == 2) {
      uploads.push_back(LuGreMaterial(11));
      continue;
    }
    SimulationSpec spec;
    spec.strokes = 1 + static_cast<int>(k % 3);
    StrokeData u = SimulateStrokes(spec, 500 + k);
    u.slip.clear();
    u.stroke.clear();
    if (k == 6) {  // continues upload 5's clock: one run with it
      const double shift = uploads.back().t_s.back() + 0.01 - u.t_s.front();
      for (double& t : u.t_s) t += shift;
    }
    uploads.push_back(std::move(u));
  }
  IdentificationMemo memo;
  MaterialIdentificationOptions with;
  with.memo = &memo;
  const MaterialIdentificationOptions without;
  std::uint64_t misses_before = 0;
  double previous_dt = 0;
  int compared = 0;
  for (std::size_t last = 4; last < uploads.size(); ++last) {
    StrokeData data;
    for (std::size_t k = last - 4; k <= last; ++k) data.Append(uploads[k]);
    const MaterialIdentification a = IdentifyMaterial(data, with);
    const MaterialIdentification b = IdentifyMaterial(data, without);
    ASSERT_EQ(a.fit.status, b.fit.status) << last;
    EXPECT_EQ(a.fit.model.mu.beta, b.fit.model.mu.beta) << last;
    EXPECT_EQ(a.fit.model.mu.eps_quantiles, b.fit.model.mu.eps_quantiles);
    EXPECT_EQ(a.coverage.span_pct, b.coverage.span_pct) << last;
    EXPECT_EQ(a.hull.hull_area, b.hull.hull_area) << last;
    EXPECT_EQ(a.hull.hull, b.hull.hull) << last;
    ASSERT_EQ(a.hull.strokes.size(), b.hull.strokes.size()) << last;
    for (std::size_t s = 0; s < a.hull.strokes.size(); ++s) {
      EXPECT_EQ(a.hull.strokes[s].stroke, b.hull.strokes[s].stroke);
      EXPECT_EQ(a.hull.strokes[s].coverage.hull_area,
                b.hull.strokes[s].coverage.hull_area);
      EXPECT_EQ(a.hull.strokes[s].coverage.span_pct,
                b.hull.strokes[s].coverage.span_pct);
    }
    EXPECT_EQ(a.lugre.identified, b.lugre.identified) << last;
    EXPECT_EQ(a.lugre.why, b.lugre.why) << last;
    EXPECT_EQ(a.lugre.strokes_quasi_static, b.lugre.strokes_quasi_static);
    EXPECT_EQ(a.lugre.strokes_dynamic, b.lugre.strokes_dynamic);
    EXPECT_EQ(a.lugre.strokes_too_short, b.lugre.strokes_too_short);
    if (a.lugre.identified) {
      EXPECT_EQ(a.lugre.family.theta, b.lugre.family.theta) << last;
      EXPECT_EQ(a.lugre.family.P_theta, b.lugre.family.P_theta) << last;
    }
    EXPECT_EQ(a.conditional.valid, b.conditional.valid) << last;
    // Bounded: what this call used (its runs and its strokes' hulls).
    const std::size_t runs = memo.lugre_runs.size();
    const double step = CalcMedianDt(data.t_s);
    std::size_t data_runs = 1;  // RecognizeLuGreStrokes' step 2 cuts
    for (std::size_t i = 1; i < data.size(); ++i)
      data_runs += data.t_s[i] < data.t_s[i - 1] ||
                   data.t_s[i] - data.t_s[i - 1] > 10 * step;
    EXPECT_GE(runs, 1u);
    EXPECT_LE(runs, data_runs) << last;
    // Two hulls per stroke: its own (the material hull) and its clamped one
    // (the span coverage).
    EXPECT_LE(memo.stroke_hulls.size(), 2 * a.hull.strokes.size()) << last;
    // The same data again: every step looked up.
    const std::uint64_t misses = memo.lugre_runs.misses();
    IdentifyMaterial(data, with);
    EXPECT_EQ(memo.lugre_runs.misses(), misses) << last;
    EXPECT_EQ(memo.lugre_runs.size(), runs) << last;
    // After the first call, a new upload is one new run, or two when its
    // clock continues the previous upload's (the merged run is new). When
    // dropping the oldest upload moves the median time step (the LuGre
    // upload's rate differs), every run is new: the step is an input.
    const double dt = step;
    if (last > 4 && dt == previous_dt) {
      EXPECT_LE(misses - misses_before, last == 6 ? 2u : 1u) << last;
      ++compared;
    }
    misses_before = misses;
    previous_dt = dt;
  }
  EXPECT_GE(compared, 2);
  EXPECT_GT(memo.lugre_runs.hits(), 0u);
  EXPECT_GT(memo.stroke_hulls.hits(), 0u);
  memo.Clear();
  EXPECT_EQ(memo.lugre_runs.size(), 0u);
  EXPECT_EQ(memo.stroke_hulls.size(), 0u);
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
