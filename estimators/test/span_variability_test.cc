#include "frictiond/estimators/span_variability.h"

#include <cmath>

#include <gtest/gtest.h>

#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

struct Slip {
  std::vector<double> fn, v, mu;
  std::vector<int> stroke;
};

Slip SlipSamples(const testing::SimulationSpec& spec, std::uint64_t seed) {
  const StrokeData d = testing::SimulateStrokes(spec, seed);
  Slip s;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (!d.slip[i]) continue;
    s.fn.push_back(d.fn_n[i]);
    s.v.push_back(d.v_mm_s[i]);
    s.mu.push_back(d.mu(i));
    s.stroke.push_back(d.stroke[i]);
  }
  return s;
}

// Pooled std of coefficient j over bins in [lo, hi) span percent, weighted
// by subsets; and the subsets counted.
double PooledStd(
    const SpanVariability& r, double lo, double hi, int j, int* count) {
  double ss = 0;
  int n = 0;
  for (const SpanBin& b : r.bins) {
    if (b.span_lo_pct < lo || b.span_hi_pct > hi || b.subsets < 2) continue;
    ss += b.beta_std[j] * b.beta_std[j] * (b.subsets - 1);
    n += b.subsets - 1;
  }
  *count = n;
  return n > 0 ? std::sqrt(ss / n) : 0.0;
}

TEST(SpanVariability, SpreadOfEstimatesFallsAsSpanGrows) {
  testing::SimulationSpec spec;  // b0 0.9, b1 0.004, b2 -0.06
  spec.strokes = 40;
  spec.write_labels = true;
  const Slip s = SlipSamples(spec, 77);
  SpanVariabilityOptions o;
  o.subsets = 200;
  o.seed = 5;
  const SpanVariability r = CalcSpanVariability(s.fn, s.v, s.mu, s.stroke, o);
  ASSERT_TRUE(r.valid) << r.why;
  EXPECT_EQ(r.strokes, 40);
  ASSERT_EQ(r.subsets.size(), 200u);
  ASSERT_EQ(r.bins.size(), 10u);
  const char* names[3] = {"b0", "b1", "b2"};
  for (int j = 0; j < 3; ++j) {
    int n_low = 0, n_high = 0;
    const double low = PooledStd(r, 0, 30, j, &n_low);
    const double high = PooledStd(r, 60, 100, j, &n_high);
    ASSERT_GE(n_low, 5) << names[j];
    ASSERT_GE(n_high, 5) << names[j];
    EXPECT_GT(low, 2.0 * high) << names[j] << ": std below 30 % span " << low
                               << ", above 60 % " << high;
  }
  // High-span estimates sit on the truth.
  const double truth[3] = {spec.b0, spec.b1, spec.b2};
  for (const SpanBin& b : r.bins) {
    if (b.span_lo_pct < 70 || b.subsets < 3) continue;
    for (int j = 0; j < 3; ++j)
      EXPECT_NEAR(b.beta_mean[j], truth[j], 0.15 * std::fabs(truth[j]))
          << names[j] << " in bin " << b.span_lo_pct;
  }
  // Deterministic for a seed.
  const SpanVariability again =
      CalcSpanVariability(s.fn, s.v, s.mu, s.stroke, o);
  EXPECT_EQ(again.subsets[17].span_pct, r.subsets[17].span_pct);
}

TEST(SpanVariability, InvalidOptionsAndDegenerateData) {
  SpanVariabilityOptions o;
  o.bin_pct = 0;
  EXPECT_THROW(CalcSpanVariability({1}, {1}, {1}, {0}, o),
               std::invalid_argument);
  EXPECT_THROW(CalcSpanVariability({1}, {1, 2}, {1}, {0}),
               std::invalid_argument);
  const SpanVariability r =
      CalcSpanVariability({1, 2, 3}, {1, 2, 3}, {1, 1, 1}, {0, 0, 0});
  EXPECT_FALSE(r.valid);
  EXPECT_NE(r.why.find("area"), std::string::npos);
}

}  // namespace
}  // namespace frictiond
