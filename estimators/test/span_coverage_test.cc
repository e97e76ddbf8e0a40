#include "frictiond/estimators/span_coverage.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/identification_memo.h"

namespace frictiond {
namespace {

const SpanRect kPlan{0.5, 4.5, 15.0, 80.0};  // paper 000 II-C span

TEST(SpanCoverage, HullAreaOfKnownShapes) {
  // Unit square with an interior point and a duplicate: area 1.
  EXPECT_DOUBLE_EQ(
      CalcConvexHullArea({{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5, 0.5}, {0, 0}}),
      1.0);
  // Triangle (0,0) (4,0) (0,3): area 6.
  EXPECT_DOUBLE_EQ(CalcConvexHullArea({{0, 0}, {4, 0}, {0, 3}, {1, 1}}), 6.0);
  // Collinear points have no area.
  EXPECT_DOUBLE_EQ(CalcConvexHullArea({{0, 0}, {1, 1}, {2, 2}}), 0.0);
}

TEST(SpanCoverage, HullPolygonDropsInteriorAndCollinearPoints) {
  using P = std::pair<double, double>;
  const std::vector<P> hull = CalcConvexHull(
      {{1, 1}, {0, 0}, {2, 0}, {1, 0}, {2, 2}, {0, 2}, {1, 1.5}, {0, 0}});
  // Counter-clockwise from the smallest point; (1,0) is collinear, (1,1)
  // and (1,1.5) are inside, the duplicate (0,0) appears once.
  const std::vector<P> expected = {{0, 0}, {2, 0}, {2, 2}, {0, 2}};
  EXPECT_EQ(hull, expected);
  EXPECT_EQ(CalcConvexHull({{0, 0}, {1, 1}, {2, 2}}).size(), 2u);
  EXPECT_TRUE(CalcConvexHull({}).empty());
}

// Andrew's monotone chain on all points, without the interior-point
// filter and the one-line shortcut CalcConvexHull takes.
std::vector<std::pair<double, double>> PlainHull(
    std::vector<std::pair<double, double>> p) {
  using P = std::pair<double, double>;
  std::sort(p.begin(), p.end());
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() < 3) return p;
  auto cross = [](const P& o, const P& a, const P& b) {
    return (a.first - o.first) * (b.second - o.second) -
           (a.second - o.second) * (b.first - o.first);
  };
  std::vector<P> h(2 * p.size());
  std::size_t k = 0;
  for (const P& q : p) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], q) <= 0) --k;
    h[k++] = q;
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  h.resize(k - 1);
  return h;
}

// The same polygon as the plain algorithm for clouds of many shapes:
// square, disk, skewed Gaussian, points clamped to a rectangle (many on its
// edges), quantised grids, and one vertical / horizontal line.
TEST(SpanCoverage, HullEqualsPlainMonotoneChain) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int shape = 0; shape < 6; ++shape) {
    for (int n : {10, 64, 65, 500, 5000}) {
      std::vector<std::pair<double, double>> p;
      for (int i = 0; i < n; ++i) {
        double x = u(rng), y = u(rng);
        switch (shape) {
          case 1: {  // disk
            const double a = 6.283185307179586 * x, r = std::sqrt(y);
            x = r * std::cos(a);
            y = r * std::sin(a);
            break;
          }
          case 2:  // skewed Gaussian
            x = g(rng);
            y = 0.3 * x + 0.1 * g(rng);
            break;
          case 3:  // clamped to a rectangle
            x = std::clamp(2.0 * g(rng), -1.0, 1.0);
            y = std::clamp(2.0 * g(rng), -1.0, 1.0);
            break;
          case 4:  // quantised grid
            x = std::floor(8 * x) / 8;
            y = std::floor(8 * y) / 8;
            break;
          default:  // a vertical line (or a horizontal one for odd n)
            if (n % 2)
              y = 0.25;
            else
              x = 4.5;
            break;
        }
        p.emplace_back(x, y);
      }
      EXPECT_EQ(CalcConvexHull(p), PlainHull(p))
          << "shape " << shape << " n " << n;
    }
  }
}

// The covered extent and the hull percentage against their definitions:
// odd and even counts, spread and one-line sets, points outside the span.
TEST(SpanCoverage, CoveredExtentAndPercentMatchDefinitions) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int n : {1, 2, 3, 1000, 1001}) {
    for (bool one_line : {false, true}) {
      std::vector<double> fn(n), v(n);
      std::vector<std::pair<double, double>> clamped;
      SpanRect want{INFINITY, -INFINITY, INFINITY, -INFINITY};
      for (int i = 0; i < n; ++i) {
        fn[i] = one_line ? 5.0 : 5.0 * u(rng);
        v[i] = 100.0 * u(rng);
        const double f = std::clamp(fn[i], kPlan.fn_min_n, kPlan.fn_max_n);
        const double s = std::clamp(v[i], kPlan.v_min_mm_s, kPlan.v_max_mm_s);
        clamped.emplace_back(f, s);
        want = {std::min(want.fn_min_n, f),
                std::max(want.fn_max_n, f),
                std::min(want.v_min_mm_s, s),
                std::max(want.v_max_mm_s, s)};
      }
      const SpanCoverage c = CalcSpanCoverage(fn, v, kPlan);
      EXPECT_EQ(c.covered.fn_min_n, want.fn_min_n) << n;
      EXPECT_EQ(c.covered.fn_max_n, want.fn_max_n) << n;
      EXPECT_EQ(c.covered.v_min_mm_s, want.v_min_mm_s) << n;
      EXPECT_EQ(c.covered.v_max_mm_s, want.v_max_mm_s) << n;
      EXPECT_NEAR(
          c.span_pct, 100.0 * CalcConvexHullArea(clamped) / kPlan.Area(), 1e-9)
          << n;
      if (one_line) {
        EXPECT_EQ(c.span_pct, 0.0);
      }
    }
  }
}

TEST(SpanCoverage, FullSweepCoversEverything) {
  const std::vector<double> fn = {0.5, 4.5, 4.5, 0.5, 2.0};
  const std::vector<double> v = {15, 15, 80, 80, 40};
  const SpanCoverage c = CalcSpanCoverage(fn, v, kPlan);
  EXPECT_NEAR(c.span_pct, 100.0, 1e-9);
  EXPECT_EQ(c.samples, 5);
}

TEST(SpanCoverage, PointsOutsideAreClamped) {
  // A square far bigger than the plan still covers exactly 100 %.
  const std::vector<double> fn = {0.0, 9.0, 9.0, 0.0};
  const std::vector<double> v = {0, 0, 300, 300};
  EXPECT_NEAR(CalcSpanCoverage(fn, v, kPlan).span_pct, 100.0, 1e-9);
}

TEST(SpanCoverage, LowForceStrokeAsksForHighForce) {
  // Covers fn 0.5..1.5 N (25 % of the Fn range), full speed range: 25 %.
  const std::vector<double> fn = {0.5, 1.5, 1.5, 0.5};
  const std::vector<double> v = {15, 15, 80, 80};
  const SpanCoverage c = CalcSpanCoverage(fn, v, kPlan);
  EXPECT_NEAR(c.span_pct, 25.0, 1e-9);
  EXPECT_DOUBLE_EQ(c.missing.fn_min_n, 1.5);
  EXPECT_DOUBLE_EQ(c.missing.fn_max_n, 4.5);
  // The speed range was covered, so it stays the whole plan's range.
  EXPECT_DOUBLE_EQ(c.missing.v_min_mm_s, 15.0);
  EXPECT_DOUBLE_EQ(c.missing.v_max_mm_s, 80.0);
}

TEST(SpanCoverage, NothingCoveredMeansWholePlanMissing) {
  const SpanCoverage c = CalcSpanCoverage({}, {}, kPlan);
  EXPECT_EQ(c.span_pct, 0.0);
  EXPECT_EQ(c.samples, 0);
  EXPECT_DOUBLE_EQ(c.missing.fn_min_n, kPlan.fn_min_n);
  EXPECT_DOUBLE_EQ(c.missing.v_max_mm_s, kPlan.v_max_mm_s);
}

// The per-stroke form (IdentifyMaterial's, with the refit's memo) against
// the plain form on data wider than the strokes a robot makes: points far
// outside the plan, non-finite ones, strokes on one line, single points,
// convex arcs (every point a vertex of the stroke's hull, as a smooth
// stroke's slipping samples often are) partly outside the plan.
// The memo is reused across calls whose strokes overlap
// (a bounded refit), so later calls are mostly memo hits.
TEST(SpanCoverage, PerStrokeFormWithMemoEqualsThePlainForm) {
  std::mt19937_64 rng(20261128);
  std::uniform_real_distribution<double> u(-1.0, 6.0), w(-20.0, 120.0);
  struct Stroke {
    std::vector<double> fn, v;
  };
  auto make_stroke = [&](int kind) {
    Stroke s;
    const int n = kind == 0 ? 1 : 1 + static_cast<int>(rng() % 300);
    const double c = u(rng), d = w(rng);
    for (int i = 0; i < n; ++i) {
      double fn = u(rng), v = w(rng);
      if (kind == 1) fn = c;            // constant load: a vertical line
      if (kind == 2) v = d;             // constant speed
      if (kind == 3) v = d + 3.0 * fn;  // a sloped line
      if (kind == 4 && i % 17 == 5) fn = NAN;
      if (kind == 4 && i % 29 == 7) v = INFINITY;
      if (kind >= 6) {  // an arc about (c, d), angles in order
        const double a = 3.0 * i / n + (kind == 7 ? 2.0 : 0.0);
        fn = c + 2.0 * std::cos(a);
        v = d + 50.0 * std::sin(a);
      }
      s.fn.push_back(fn);
      s.v.push_back(v);
    }
    return s;
  };
  IdentificationMemo memo;
  std::vector<Stroke> window;  // the refit's strokes, oldest first
  int hits_expected = 0;
  for (int call = 0; call < 200; ++call) {
    window.push_back(make_stroke(static_cast<int>(rng() % 8)));
    if (window.size() > 12) window.erase(window.begin());
    std::vector<double> fn, v;
    std::vector<int> id;
    for (std::size_t k = 0; k < window.size(); ++k) {
      // Ids as a refit numbers them: the position in the window.
      for (std::size_t i = 0; i < window[k].fn.size(); ++i) {
        fn.push_back(window[k].fn[i]);
        v.push_back(window[k].v[i]);
        id.push_back(static_cast<int>(k));
      }
    }
    const SpanRect plan =
        call % 5 == 0 ? SpanRect{0.0, 5.0, 0.0, 100.0} : kPlan;
    const SpanCoverage plain = CalcSpanCoverage(fn, v, plan);
    const SpanCoverage per = CalcSpanCoverage(fn, v, plan, id, &memo);
    const SpanCoverage no_memo = CalcSpanCoverage(fn, v, plan, id, nullptr);
    for (const SpanCoverage* c : {&per, &no_memo}) {
      EXPECT_NEAR(c->span_pct, plain.span_pct, 1e-9 * (1.0 + plain.span_pct))
          << call;
      EXPECT_EQ(c->samples, plain.samples) << call;
      EXPECT_EQ(c->covered.fn_min_n, plain.covered.fn_min_n) << call;
      EXPECT_EQ(c->covered.fn_max_n, plain.covered.fn_max_n) << call;
      EXPECT_EQ(c->covered.v_min_mm_s, plain.covered.v_min_mm_s) << call;
      EXPECT_EQ(c->covered.v_max_mm_s, plain.covered.v_max_mm_s) << call;
      EXPECT_EQ(c->missing.fn_min_n, plain.missing.fn_min_n) << call;
      EXPECT_EQ(c->missing.fn_max_n, plain.missing.fn_max_n) << call;
      EXPECT_EQ(c->missing.v_min_mm_s, plain.missing.v_min_mm_s) << call;
      EXPECT_EQ(c->missing.v_max_mm_s, plain.missing.v_max_mm_s) << call;
    }
    if (call > 0 && call % 5 != 0 && (call - 1) % 5 != 0)
      hits_expected += static_cast<int>(window.size()) - 1;
    memo.Sweep();
  }
  // The older strokes came from the memo (same points, same plan).
  EXPECT_GE(memo.stroke_hulls.hits(),
            static_cast<std::uint64_t>(hits_expected));
  // Empty ids: the plain form; mismatched ids: refused.
  EXPECT_EQ(
      CalcSpanCoverage({1.0, 2.0}, {20.0, 70.0}, kPlan, {}, &memo).samples, 2);
  EXPECT_THROW(CalcSpanCoverage({1.0, 2.0}, {20.0, 70.0}, kPlan, {0}, &memo),
               std::invalid_argument);
}

TEST(SpanCoverage, RejectsBadInput) {
  EXPECT_THROW(CalcSpanCoverage({1.0}, {}, kPlan), std::invalid_argument);
  EXPECT_THROW(CalcSpanCoverage({}, {}, SpanRect{1, 1, 0, 10}),
               std::invalid_argument);
}

// Paper 000 III-C-2: coverage relative to the hull of all of the
// material's data, not to the plan's rectangle.
TEST(HullSpanCoverage, IsRelativeToTheMaterialsHull) {
  // The material's data: a triangle (0,0), (4,0), (0,80) of area 160.
  const std::vector<double> all_fn = {0, 4, 0, 1};
  const std::vector<double> all_v = {0, 0, 80, 10};
  // A stroke over the square (0,0)-(2,40) inside it: area 80 = 50 %.
  const std::vector<double> fn = {0, 2, 2, 0};
  const std::vector<double> v = {0, 0, 40, 40};
  const HullSpanCoverage c = CalcHullSpanCoverage(fn, v, all_fn, all_v);
  EXPECT_NEAR(c.hull_area, 80.0, 1e-12);
  EXPECT_NEAR(c.material_hull_area, 160.0, 1e-12);
  EXPECT_NEAR(c.span_pct, 50.0, 1e-12);
  EXPECT_TRUE(c.reliable);  // the 50 % rule, on the paper's reference
  EXPECT_EQ(c.samples, 4);
  EXPECT_EQ(c.material_samples, 8);
  // The same stroke against the plan's rectangle gives another number: the
  // two references differ (the rectangle stays what the robot is asked).
  const SpanRect rect{0.0, 4.0, 0.0, 80.0};
  EXPECT_NEAR(CalcSpanCoverage(fn, v, rect).span_pct, 25.0, 1e-12);
  // A stroke reaching beyond the material's old data enlarges the
  // reference (its points are part of the material's data): (0,0)-(8,40)
  // over the union hull (0,0),(8,0),(8,40),(0,80): 320 / 480.
  const HullSpanCoverage wide =
      CalcHullSpanCoverage({0, 8, 8, 0}, {0, 0, 40, 40}, all_fn, all_v);
  EXPECT_NEAR(wide.span_pct, 100.0 * 320.0 / 480.0, 1e-12);
  EXPECT_TRUE(wide.reliable);
  // A thin stroke is not reliable; non-finite points are ignored.
  const HullSpanCoverage thin =
      CalcHullSpanCoverage({0, 1, 1, NAN}, {0, 0, 10, 5}, all_fn, all_v);
  EXPECT_NEAR(thin.span_pct, 100.0 * 5.0 / 160.0, 1e-12);
  EXPECT_FALSE(thin.reliable);
  EXPECT_EQ(thin.samples, 3);
  // No material area: 0 %, not a division by zero.
  EXPECT_EQ(CalcHullSpanCoverage({1}, {1}, {1, 2}, {1, 2}).span_pct, 0.0);
  EXPECT_THROW(CalcHullSpanCoverage({1, 2}, {1}, {}, {}),
               std::invalid_argument);
  EXPECT_THROW(CalcHullSpanCoverage({}, {}, {1}, {}), std::invalid_argument);
}

TEST(MaterialHullCoverage, EqualsTheOneStrokeFunctionForEveryStroke) {
  // 30 strokes of random extent (seed 9) plus a NaN and a degenerate one.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> fn, v;
  std::vector<int> stroke;
  for (int k = 0; k < 30; ++k) {
    const double f0 = 0.5 + 3 * u(rng), v0 = 15 + 50 * u(rng);
    const double df = 0.1 + u(rng), dv = 1 + 20 * u(rng);
    for (int i = 0; i < 40; ++i) {
      fn.push_back(f0 + df * u(rng));
      v.push_back(v0 + dv * u(rng));
      stroke.push_back(100 + 3 * k);
    }
  }
  fn.push_back(NAN);
  v.push_back(20);
  stroke.push_back(100);
  fn.push_back(1.0);
  v.push_back(20);
  stroke.push_back(7);  // a one-point stroke: 0 %
  const MaterialHullCoverage m = CalcMaterialHullCoverage(fn, v, stroke);
  EXPECT_EQ(m.samples, static_cast<int>(fn.size()) - 1);
  EXPECT_NEAR(m.hull_area,
              CalcConvexHullArea([&] {
                std::vector<std::pair<double, double>> p;
                for (std::size_t i = 0; i + 2 < fn.size(); ++i)
                  p.emplace_back(fn[i], v[i]);
                p.emplace_back(1.0, 20.0);
                return p;
              }()),
              1e-9 * m.hull_area);
  ASSERT_EQ(m.strokes.size(), 31u);
  EXPECT_EQ(m.strokes.front().stroke, 7);
  EXPECT_EQ(m.strokes.front().coverage.span_pct, 0.0);
  for (const StrokeHullCoverage& s : m.strokes) {
    std::vector<double> sf, sv;
    for (std::size_t i = 0; i < fn.size(); ++i)
      if (stroke[i] == s.stroke) {
        sf.push_back(fn[i]);
        sv.push_back(v[i]);
      }
    const HullSpanCoverage one = CalcHullSpanCoverage(sf, sv, fn, v);
    EXPECT_NEAR(s.coverage.span_pct, one.span_pct, 1e-9) << s.stroke;
    EXPECT_NEAR(s.coverage.hull_area, one.hull_area, 1e-12) << s.stroke;
    EXPECT_EQ(s.coverage.reliable, one.reliable) << s.stroke;
    EXPECT_EQ(s.coverage.samples, one.samples) << s.stroke;
    EXPECT_EQ(s.coverage.material_samples, m.samples);
  }
  // The newest strokes when capped; none without stroke ids.
  const MaterialHullCoverage capped =
      CalcMaterialHullCoverage(fn, v, stroke, 5);
  ASSERT_EQ(capped.strokes.size(), 5u);
  EXPECT_EQ(capped.strokes.back().stroke, 100 + 3 * 29);
  EXPECT_TRUE(CalcMaterialHullCoverage(fn, v, {}).strokes.empty());
  EXPECT_THROW(CalcMaterialHullCoverage({1, 2}, {1}, {}),
               std::invalid_argument);
  EXPECT_THROW(CalcMaterialHullCoverage({1, 2}, {1, 2}, {1}),
               std::invalid_argument);
  EXPECT_THROW(CalcMaterialHullCoverage({1}, {1}, {}, -1),
               std::invalid_argument);
}

// The material's hull is built from the strokes' hulls: it must be exactly
// the hull of all points (same vertices in the same order, same area) on
// sets wider than the bundled data: thin bands (constant load), collinear
// and one-point strokes, duplicates across strokes, strokes interleaved in
// time, 20 seeds.
TEST(MaterialHullCoverage, HullOfStrokeHullsEqualsHullOfAllPoints) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<double> fn, v;
    std::vector<int> stroke;
    const int strokes = 1 + static_cast<int>(60 * u(rng));
    for (int k = 0; k < strokes; ++k) {
      const int kind = static_cast<int>(6 * u(rng));
      const int n = kind == 4 ? 1 : 2 + static_cast<int>(300 * u(rng));
      const double f0 = 0.5 + 4 * u(rng), v0 = 80 * u(rng);
      for (int i = 0; i < n; ++i) {
        double f = f0, s = v0 + 60 * u(rng);
        if (kind == 0) f = f0 + 1e-3 * u(rng);            // thin band
        if (kind == 1) f = f0 + u(rng), s = v0;           // horizontal line
        if (kind == 2) f = f0 + 0.5 * u(rng), s = 2 * f;  // diagonal line
        if (kind == 3) f = std::round(4 * u(rng)), s = std::round(8 * u(rng));
        if (kind == 5) {  // a convex arc: every point a vertex
          const double a = 2.5 * i / n + 3.0 * f0;  // f0: a phase per stroke
          f = f0 + std::cos(a), s = v0 + 30 * std::sin(a);
        }
        fn.push_back(f);
        v.push_back(s);
        stroke.push_back(kind == 3 ? static_cast<int>(3 * u(rng)) : k + 10);
      }
    }
    std::vector<std::pair<double, double>> all;
    for (std::size_t i = 0; i < fn.size(); ++i) all.emplace_back(fn[i], v[i]);
    const std::vector<std::pair<double, double>> want = CalcConvexHull(all);
    const MaterialHullCoverage m = CalcMaterialHullCoverage(fn, v, stroke);
    EXPECT_EQ(m.hull, want) << "seed " << seed;
    EXPECT_EQ(m.hull_area, CalcConvexHullArea(all)) << "seed " << seed;
    EXPECT_EQ(m.hull, CalcMaterialHullCoverage(fn, v, {}).hull)
        << "seed " << seed;
  }
}

}  // namespace
}  // namespace frictiond
