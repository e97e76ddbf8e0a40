#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "frictiond/estimators/preprocessing.h"

namespace frictiond {
namespace {

// Reference: copy each (shrinking) window and select its upper median.
std::vector<double> NaiveMedian(const std::vector<double>& x, int kernel) {
  if (kernel <= 1 || x.size() < 3) return x;
  if (kernel % 2 == 0) ++kernel;
  const int half = kernel / 2, n = static_cast<int>(x.size());
  std::vector<double> out(x.size());
  for (int i = 0; i < n; ++i) {
    std::vector<double> w(x.begin() + std::max(0, i - half),
                          x.begin() + std::min(n - 1, i + half) + 1);
    std::nth_element(w.begin(), w.begin() + w.size() / 2, w.end());
    out[i] = w[w.size() / 2];
  }
  return out;
}

TEST(MedianFilter, SlidingWindowEqualsNaiveSelection) {
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> level(0, 5);  // many ties
  for (int kernel : {1, 2, 3, 5, 24, 25, 101}) {
    for (std::size_t n : {1u, 2u, 3u, 10u, 57u, 1000u}) {
      std::vector<double> x(n);
      for (auto& v : x) v = level(rng) * 0.5;
      EXPECT_EQ(MedianFilter(x, kernel), NaiveMedian(x, kernel))
          << "kernel " << kernel << " n " << n;
    }
  }
}

// Distinct values (every step moves the entering sample through the
// window) and the NaN rule.
TEST(MedianFilter, DistinctValuesAndNan) {
  std::mt19937 rng(43);
  std::normal_distribution<double> speed(10.0, 4.0);
  for (int kernel : {3, 11, 17}) {
    std::vector<double> x(2000);
    for (auto& v : x) v = speed(rng);
    EXPECT_EQ(MedianFilter(x, kernel), NaiveMedian(x, kernel))
        << "kernel " << kernel;
  }
  std::vector<double> x(20, 1.0);
  x[7] = NAN;
  EXPECT_THROW(MedianFilter(x, 5), std::invalid_argument);
}

// CalcMedianAbove is MedianFilter followed by "> threshold", also for
// values equal to the threshold, even kernels, shrinking ends and tiny
// inputs.
TEST(MedianFilter, MedianAboveEqualsFilterThenThreshold) {
  std::mt19937 rng(44);
  std::uniform_int_distribution<int> level(0, 6);
  for (int kernel : {0, 1, 2, 3, 4, 11, 24, 101}) {
    for (std::size_t n : {0u, 1u, 2u, 3u, 10u, 57u, 3000u}) {
      std::vector<double> x(n);
      for (auto& v : x) v = level(rng) * 0.25;
      const std::vector<double> f = MedianFilter(x, kernel);
      for (double t : {-1.0, 0.5, 0.6, 1.0, 2.0}) {
        const std::vector<unsigned char> above = CalcMedianAbove(x, kernel, t);
        ASSERT_EQ(above.size(), n);
        for (std::size_t i = 0; i < n; ++i)
          ASSERT_EQ(above[i] != 0, f[i] > t)
              << "kernel " << kernel << " n " << n << " t " << t << " i " << i;
      }
    }
  }
  EXPECT_THROW(CalcMedianAbove({1.0, NAN, 2.0}, 3, 0.5), std::invalid_argument);
}

// The median sampling interval (upper median of the positive steps) for
// quantised intervals (the counted guess), continuous ones (the selection
// over all), times computed as i / rate (steps that differ in their last
// bits), steps whose pattern repeats with the sample's stride (a sample
// that misses the median), gaps, repeated and backward time stamps.
TEST(MedianFilter, MedianDtIsTheUpperMedianOfPositiveSteps) {
  std::mt19937 rng(45);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int kind = 0; kind < 5; ++kind) {
    for (int n : {1, 2, 3, 500, 5000, 40001}) {
      std::vector<double> t(n);
      double now = 0.0;
      const int stride = std::max(1, (n - 1) / 256);
      for (int i = 0; i < n; ++i) {
        double& s = t[i];
        const double r = u(rng);
        if (kind == 3) {
          s = i / 250.0 + 1000.0;  // a clock far from zero
          continue;
        }
        if (kind == 4) {
          now += i % stride == 1 ? 0.004 : 0.004 + 1e-4 * r;
        } else if (kind == 0) {
          now += r < 0.01 ? 2.5 : 0.005;  // 200 Hz with rests
        } else if (kind == 1) {
          now += 0.004 + 0.002 * r;  // jittered clock
        } else {
          now += r < 0.2 ? 0.0 : (r < 0.25 ? -0.001 : 0.01 * r);
        }
        s = now;
      }
      std::vector<double> steps;
      for (int i = 1; i < n; ++i)
        if (t[i] - t[i - 1] > 0) steps.push_back(t[i] - t[i - 1]);
      double want = 0.0;
      if (!steps.empty()) {
        std::sort(steps.begin(), steps.end());
        want = steps[steps.size() / 2];
      }
      EXPECT_EQ(CalcMedianDt(t), want) << "kind " << kind << " n " << n;
    }
  }
}

// Strokes: a new one after each slip episode, and at a gap only when the
// current one has slipped; a slip vector of the wrong length is refused.
TEST(MedianFilter, SegmentStrokesAfterEpisodesAndGaps) {
  StrokeData d;
  std::vector<int> slip;
  for (int i = 0; i < 150; ++i) {
    d.t_s.push_back(i < 100 ? 0.01 * i : 5.0 + 0.01 * i);  // gap before 100
    d.fn_n.push_back(2.0);
    d.ft_n.push_back(1.0);
    d.v_mm_s.push_back(0.0);
    slip.push_back((i >= 10 && i < 20) || (i >= 40 && i < 50) ||
                   (i >= 110 && i < 120));
  }
  const std::vector<int> stroke = SegmentStrokes(d, slip, 3.0);
  ASSERT_EQ(stroke.size(), 150u);
  EXPECT_EQ(stroke[0], 0);
  EXPECT_EQ(stroke[19], 0);
  EXPECT_EQ(stroke[20], 1);  // rest after the first episode
  EXPECT_EQ(stroke[49], 1);
  EXPECT_EQ(stroke[50], 2);
  EXPECT_EQ(stroke[100], 2);  // gap, but stroke 2 has not slipped yet
  EXPECT_EQ(stroke[119], 2);
  EXPECT_EQ(stroke[120], 3);
  slip.pop_back();
  EXPECT_THROW(SegmentStrokes(d, slip, 3.0), std::invalid_argument);
}

// dwell_s: with the labelling options, a run above the floor that never
// reaches the peak (motion without slip) ends the rest; without them only
// slip labels do. 100 Hz: slip 0.1-0.2 s, sub-threshold motion 0.5-0.7 s
// (6 mm/s: above the 5 mm/s floor, below the 10 mm/s peak), slip from
// 1.0 s.
TEST(MedianFilter, DwellEndsAtMotionWithoutSlip) {
  StrokeData d;
  for (int i = 0; i < 130; ++i) {
    d.t_s.push_back(0.01 * i);
    d.fn_n.push_back(2.0);
    d.ft_n.push_back(1.0);
    const bool slipping = (i >= 10 && i < 20) || i >= 100;
    d.v_mm_s.push_back(slipping ? 20.0 : (i >= 50 && i < 70) ? 6.0 : 0.0);
  }
  SlipLabelOptions o;
  o.peak_mm_s = 10.0;
  o.floor_mm_s = 5.0;
  o.median_window_s = 0.0;
  EnsureLabels(&d, o);
  ASSERT_EQ(d.slip[50], 0);  // the sub-threshold run is not slip
  ASSERT_EQ(d.slip[100], 1);
  StrokeData by_labels = d;
  AddDerivedFeatures(&by_labels, o.gap_factor);
  AddDerivedFeatures(&d, o);
  const std::vector<double>& old_dwell = *by_labels.Column("dwell_s");
  const std::vector<double>& dwell = *d.Column("dwell_s");
  EXPECT_NEAR(old_dwell[100], 0.8, 1e-9);  // from the end of the first slip
  EXPECT_NEAR(dwell[100], 0.31, 1e-9);     // from the end of the motion
  EXPECT_NEAR(dwell[120], 0.31, 1e-9);     // held through the episode
  EXPECT_NEAR(dwell[60], 0.0, 1e-9);       // moving: no rest yet
  EXPECT_NEAR(dwell[40], old_dwell[40], 1e-12);  // before it: unchanged
}

TEST(MedianFilter, RemovesIsolatedSpikes) {
  std::vector<double> v(50, 20.0);
  v[10] = 500.0;
  v[30] = -400.0;
  const auto f = MedianFilter(v, 5);
  EXPECT_EQ(f, std::vector<double>(50, 20.0));
}

}  // namespace
}  // namespace frictiond
