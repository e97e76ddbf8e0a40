#include "frictiond/estimators/logistic_sums.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

// The sums written out with std::exp and long double accumulators.
LogisticSums NaiveSums(const std::vector<double>& r,
                       const std::vector<int>& y,
                       const LogisticPoint& at) {
  long double g0 = 0, g1 = 0, h00 = 0, h01 = 0, h11 = 0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double z = (r[i] - at.center) * at.scale;
    const double p = 1.0 / (1.0 + std::exp(-(at.a + at.b * z)));
    const double w = std::max(p * (1.0 - p), 1e-12);
    const double res = (y[i] ? 1.0 : 0.0) - p;
    g0 += res;
    g1 += res * z;
    h00 += w;
    h01 += w * z;
    h11 += w * z * z;
  }
  return {double(g0), double(g1), double(h00), double(h01), double(h11)};
}

// Every sum within `tol` (absolute).
void ExpectNear(const LogisticSums& a,
                const LogisticSums& b,
                double tol,
                const std::string& what) {
  EXPECT_NEAR(a.g0, b.g0, tol) << what;
  EXPECT_NEAR(a.g1, b.g1, tol) << what;
  EXPECT_NEAR(a.h00, b.h00, tol) << what;
  EXPECT_NEAR(a.h01, b.h01, tol) << what;
  EXPECT_NEAR(a.h11, b.h11, tol) << what;
}

// The AVX-512 and AVX2 paths (polynomial exp, 8 and 4 lanes) and the
// scalar one give the sums of the formula to rounding, for moderate and for
// saturating linear predictors (|a + b z| up to ~2000, where exp is clamped),
// odd lengths (the vector tail) and slip flags other than 0/1.
TEST(LogisticSums, EveryPathMatchesTheFormula) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> ratio(0.6, 0.25);
  std::uniform_int_distribution<int> flag(-2, 3);
  for (std::size_t n : {1u, 3u, 4u, 7u, 1001u, 40000u}) {
    std::vector<double> r(n);
    std::vector<int> y(n);
    for (std::size_t i = 0; i < n; ++i) {
      r[i] = ratio(rng);
      y[i] = flag(rng) > 0 ? flag(rng) : 0;
    }
    for (const LogisticPoint at : {LogisticPoint{-0.4, 1.3, 0.6, 4.0},
                                   LogisticPoint{2.0, -25.0, 0.6, 4.0},
                                   LogisticPoint{0.0, 400.0, 0.6, 4.0}}) {
      const LogisticSums want = NaiveSums(r, y, at);
      const std::string what =
          "n " + std::to_string(n) + " b " + std::to_string(at.b);
      const double scale = static_cast<double>(n) * (1.0 + std::fabs(at.b));
      for (SimdLevel level :
           {SimdLevel::kScalar, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
        ExpectNear(CalcLogisticSums(r.data(), y.data(), n, at, level),
                   want,
                   1e-12 * scale,
                   what + " " + SimdLevelName(LogisticSumsLevel(level)));
      }
    }
  }
  EXPECT_EQ(LogisticSumsLevel(SimdLevel::kScalar), SimdLevel::kScalar);
  EXPECT_LE(LogisticSumsLevel(SimdLevel::kAvx2), SimdLevel::kAvx2);
  std::printf("CalcLogisticSums runs %s here\n",
              SimdLevelName(LogisticSumsLevel()));
}

// Single precision (for the first Newton steps): sums within 5e-8 of the
// formula's, relative to their scale, on every path (the scalar path
// ignores the flag and stays exact).
TEST(LogisticSums, SinglePrecisionIsCloseNotExact) {
  std::mt19937_64 rng(4);
  std::normal_distribution<double> ratio(0.6, 0.25);
  std::uniform_int_distribution<int> coin(0, 1);
  for (std::size_t n : {5u, 17u, 1030u, 40001u}) {
    std::vector<double> r(n);
    std::vector<int> y(n);
    for (std::size_t i = 0; i < n; ++i) {
      r[i] = ratio(rng);
      y[i] = coin(rng);
    }
    for (const LogisticPoint at : {LogisticPoint{-0.4, 1.3, 0.6, 4.0},
                                   LogisticPoint{2.0, -25.0, 0.6, 4.0}}) {
      const LogisticSums want = NaiveSums(r, y, at);
      for (SimdLevel level :
           {SimdLevel::kScalar, SimdLevel::kAvx2, SimdLevel::kAvx512}) {
        const LogisticSums got =
            CalcLogisticSums(r.data(), y.data(), n, at, level, true);
        const std::string what = "n " + std::to_string(n) + " " +
                                 SimdLevelName(LogisticSumsLevel(level));
        const double scale = static_cast<double>(n) * (1.0 + std::fabs(at.b));
        ExpectNear(got,
                   want,
                   LogisticSumsLevel(level) == SimdLevel::kScalar
                       ? 1e-12 * scale
                       : 5e-8 * scale,
                   what);
      }
    }
  }
}

// A broken vector exp would show as a wrong probability: the gradient sum
// at a = ln(3), b = 0 is n (0.75 - 0.75) for three slips in four.
TEST(LogisticSums, InterceptOnlyProbability) {
  const std::size_t n = 4000;
  std::vector<double> r(n, 1.0);
  std::vector<int> y(n);
  for (std::size_t i = 0; i < n; ++i) y[i] = i % 4 != 0;
  const LogisticSums s =
      CalcLogisticSums(r.data(), y.data(), n, {std::log(3.0), 0.0, 0.0, 1.0});
  EXPECT_NEAR(s.g0, 0.0, 1e-10);
  EXPECT_NEAR(s.h00, n * 0.75 * 0.25, 1e-9);
}

}  // namespace
}  // namespace frictiond
