// FitOls (eq. 1 of paper 000) against known truth, including the cases the
// one-pass blocked moments must get right: columns with a large offset
// (epoch-like time stamps), no intercept, constant and collinear columns,
// non-finite input, and sizes that are not a multiple of the block.
#include "frictiond/estimators/regression.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/stats.h"

namespace frictiond {
namespace {

struct Data {
  Eigen::MatrixXd X;
  Eigen::VectorXd y;
};

// y = 0.9 + 0.004 v - 0.06 fn + 2e-4 (t - t0) + N(0, 0.05).
Data MakeData(int n, double t0, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> v_u(5.0, 80.0), fn_u(0.5, 4.5),
      t_u(0.0, 300.0);
  std::normal_distribution<double> eps(0.0, 0.05);
  Data d{Eigen::MatrixXd(n, 4), Eigen::VectorXd(n)};
  for (int i = 0; i < n; ++i) {
    const double v = v_u(rng), fn = fn_u(rng), t = t_u(rng);
    d.X.row(i) << 1.0, v, fn, t0 + t;
    d.y(i) = 0.9 + 0.004 * v - 0.06 * fn + 2e-4 * t + eps(rng);
  }
  return d;
}

// Reference solution by a QR of the (column-centred) design.
Eigen::VectorXd QrBeta(const Data& d) {
  return d.X.colPivHouseholderQr().solve(d.y);
}

TEST(FitOls, RecoversTruthWithinStandardErrorsAtOddSizes) {
  for (int n : {7, 2047, 2049, 10001}) {
    const Data d = MakeData(n, 0.0, 1 + n);
    const OlsResult r = FitOls(d.X, d.y);
    ASSERT_EQ(r.status, FitStatus::kOk) << n << ": " << r.why;
    const Eigen::VectorXd ref = QrBeta(d);
    for (int k = 0; k < 4; ++k)
      EXPECT_NEAR(r.beta(k), ref(k), 1e-9 * (1 + std::abs(ref(k))))
          << "n " << n << " k " << k;
    if (n >= 2047) {
      EXPECT_NEAR(r.beta(1), 0.004, 4 * r.std_err(1)) << n;
      EXPECT_NEAR(r.beta(2), -0.06, 4 * r.std_err(2)) << n;
      EXPECT_NEAR(r.sigma_eps, 0.05, 0.005) << n;
    }
    EXPECT_NEAR(r.residuals.squaredNorm(),
                (d.y - d.X * ref).squaredNorm(),
                1e-9 * (d.y - d.X * ref).squaredNorm());
  }
}

// Every design shape the moment kernels distinguish: intercept first or in
// the middle, none, a column whose first block is all ones but not the rest
// (must not be taken for the intercept), and a design wider than the
// unrolled kernels. Statistics with and without the residual vector agree.
TEST(FitOls, KernelsAndStatisticsWithoutResidualsMatchQr) {
  EXPECT_FALSE(OlsUsesAvx2(OlsOptions{true, false}));
  std::cout << "FitOls kernels here: "
            << (OlsUsesAvx2(OlsOptions{}) ? "AVX2+FMA" : "SSE2")
            << " (baseline SSE2 also tested)\n";
  for (int n : {9, 4097, 10001}) {
    const Data base = MakeData(n, 0.0, 20 + n);
    std::vector<std::pair<std::string, Data>> cases;
    cases.push_back({"intercept first", base});
    Data middle = base;
    middle.X.col(0).swap(middle.X.col(2));
    cases.push_back({"intercept in the middle", middle});
    Data none = base;
    none.X = base.X.rightCols(3).eval();
    cases.push_back({"no intercept", none});
    Data almost = base;
    almost.X.col(0).setOnes();
    almost.X(n - 1, 0) = 2.0;  // not a column of ones after all
    almost.X.col(2).setOnes();
    cases.push_back({"ones only at first", almost});
    Data wide = base;
    wide.X.conservativeResize(n, 7);
    std::mt19937_64 rng(n);
    std::normal_distribution<double> z(0.0, 1.0);
    for (int k = 4; k < 7; ++k)
      for (int i = 0; i < n; ++i) wide.X(i, k) = z(rng) + k;
    cases.push_back({"wide", wide});
    for (const auto& [name, d] : cases) {
      const OlsResult with = FitOls(d.X, d.y);
      const OlsResult without = FitOls(d.X, d.y, OlsOptions{false});
      // The baseline (SSE2) kernels, whichever the CPU would choose.
      const OlsResult baseline = FitOls(d.X, d.y, OlsOptions{true, false});
      ASSERT_EQ(baseline.status, FitStatus::kOk) << name << " n " << n;
      ASSERT_EQ(with.status, FitStatus::kOk) << name << " n " << n;
      ASSERT_EQ(without.status, FitStatus::kOk) << name << " n " << n;
      EXPECT_EQ(without.residuals.size(), 0) << name;
      const Eigen::VectorXd ref = QrBeta(d);
      const double rss = (d.y - d.X * ref).squaredNorm();
      for (int k = 0; k < d.X.cols(); ++k) {
        EXPECT_NEAR(with.beta(k), ref(k), 1e-9 * (1 + std::abs(ref(k))))
            << name << " n " << n << " k " << k;
        EXPECT_NEAR(
            without.beta(k), with.beta(k), 1e-12 * (1 + std::abs(ref(k))))
            << name << " n " << n << " k " << k;
        EXPECT_NEAR(without.std_err(k), with.std_err(k), 1e-9 * with.std_err(k))
            << name << " n " << n << " k " << k;
      }
      EXPECT_NEAR(with.residuals.squaredNorm(), rss, 1e-9 * rss) << name;
      for (int k = 0; k < d.X.cols(); ++k) {
        EXPECT_NEAR(baseline.beta(k), ref(k), 1e-9 * (1 + std::abs(ref(k))))
            << "baseline kernels: " << name << " n " << n << " k " << k;
        EXPECT_NEAR(
            baseline.std_err(k), with.std_err(k), 1e-9 * with.std_err(k))
            << "baseline kernels: " << name << " n " << n << " k " << k;
      }
      EXPECT_NEAR(baseline.sigma_eps, with.sigma_eps, 1e-9 * with.sigma_eps)
          << "baseline kernels: " << name;
      EXPECT_NEAR(without.sigma_eps, with.sigma_eps, 1e-9 * with.sigma_eps)
          << name << " n " << n;
      EXPECT_NEAR(without.r2, with.r2, 1e-9) << name << " n " << n;
      EXPECT_NEAR(without.p_value, with.p_value, 1e-9) << name;
    }
  }
}

TEST(FitOls, LargeOffsetColumnKeepsItsPrecision) {
  // Time stamps around 1.7e9 s with a 300 s spread: raw second moments
  // would cancel catastrophically (1e21 against 1e5).
  const Data d = MakeData(50000, 1.7e9, 3);
  const OlsResult r = FitOls(d.X, d.y);
  ASSERT_EQ(r.status, FitStatus::kOk) << r.why;
  EXPECT_NEAR(r.beta(3), 2e-4, 4 * r.std_err(3));
  EXPECT_NEAR(r.beta(1), 0.004, 4 * r.std_err(1));
  EXPECT_GT(r.r2, 0.5);
  EXPECT_NEAR(r.sigma_eps, 0.05, 0.002);
}

TEST(FitOls, WithoutInterceptMatchesQr) {
  Data d = MakeData(5000, 0.0, 4);
  d.X = d.X.rightCols(3).eval();  // v, fn, t: no column of ones
  const OlsResult r = FitOls(d.X, d.y);
  ASSERT_EQ(r.status, FitStatus::kOk) << r.why;
  const Eigen::VectorXd ref = QrBeta(d);
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(r.beta(k), ref(k), 1e-9 * (1 + std::abs(ref(k)))) << k;
}

TEST(FitOls, ConstantAndCollinearColumnsAreNotIdentified) {
  Data d = MakeData(3000, 0.0, 5);
  d.X.col(2).setConstant(5.0);           // constant load: fn not identified
  d.X.col(3) = 2.0 * d.X.col(1).eval();  // collinear with v
  const OlsResult r = FitOls(d.X, d.y);
  EXPECT_EQ(r.status, FitStatus::kPartial) << r.why;
  EXPECT_FALSE(r.identified[2]);
  EXPECT_EQ(r.identified[1] + r.identified[3], 1);
  EXPECT_EQ(r.beta(2), 0.0);
}

TEST(FitOls, NonFiniteInputFailsNamingIt) {
  Data d = MakeData(4000, 0.0, 6);
  d.X(3500, 1) = std::nan("");
  OlsResult r = FitOls(d.X, d.y);
  EXPECT_EQ(r.status, FitStatus::kFailed);
  EXPECT_NE(r.why.find("not finite"), std::string::npos) << r.why;
  EXPECT_EQ(r.nonfinite_column, 1) << r.why;
  d = MakeData(4000, 0.0, 6);
  d.y(10) = INFINITY;
  r = FitOls(d.X, d.y);
  EXPECT_EQ(r.status, FitStatus::kFailed);
  EXPECT_EQ(r.nonfinite_column, d.X.cols()) << r.why;  // y
  // Finite values whose squares overflow.
  d = MakeData(4000, 0.0, 6);
  d.X.col(2) *= 1e200;
  r = FitOls(d.X, d.y);
  EXPECT_EQ(r.status, FitStatus::kFailed);
  EXPECT_EQ(r.nonfinite_column, 2) << r.why;
  EXPECT_NE(r.why.find("too large"), std::string::npos) << r.why;
  // A fit that succeeds names no column.
  d = MakeData(4000, 0.0, 6);
  EXPECT_EQ(FitOls(d.X, d.y).nonfinite_column, -1);
}

// SelectQuantiles (used for the eps distribution and the span checks)
// gives exactly SortedQuantile's values, with ties, tiny and odd sizes.
TEST(SelectQuantiles, EqualsSortedQuantile) {
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> coarse(0, 9);
  std::normal_distribution<double> fine(0.0, 1.0);
  std::vector<double> levels = {0.0, 0.001, 0.05, 0.25, 0.5, 0.5, 0.75, 1.0};
  for (int k = 1; k <= 99; k += 7) levels.push_back(k / 100.0);
  std::sort(levels.begin(), levels.end());
  for (int n : {1, 2, 3, 17, 1000, 20001}) {
    for (bool ties : {false, true}) {
      std::vector<double> x(n);
      for (double& v : x) v = ties ? coarse(rng) : fine(rng);
      std::vector<double> sorted = x;
      std::sort(sorted.begin(), sorted.end());
      const std::vector<double> q = SelectQuantiles(&x, levels);
      ASSERT_EQ(q.size(), levels.size());
      for (std::size_t j = 0; j < levels.size(); ++j)
        EXPECT_EQ(q[j], SortedQuantile(sorted, levels[j]))
            << "n " << n << " ties " << ties << " p " << levels[j];
    }
  }
}

// The many-level path (distribution into buckets from a sample's range)
// with values the sample does not see: heavy tails, infinities, a spike of
// equal values, a sample without spread, and most values in one bucket.
TEST(SelectQuantiles, ManyLevelsWithOutliersAndTies) {
  std::mt19937_64 rng(12);
  std::cauchy_distribution<double> heavy(0.0, 1.0);
  std::normal_distribution<double> fine(0.0, 1.0);
  std::vector<double> levels;
  for (int k = 0; k <= 100; ++k) levels.push_back(k / 100.0);
  // 257 and 4097: just above the size where the distribution path starts
  // (every value is in the range sample there) and the size it used to
  // start at.
  for (int n : {257, 1000, 4097, 30011})
    for (int kind = 0; kind < 5; ++kind) {
      std::vector<double> x(n);
      for (int i = 0; i < n; ++i) {
        switch (kind) {
          case 0:
            x[i] = heavy(rng);
            break;
          case 1:  // infinities off the sample's stride
            x[i] = i % 58 != 0 && i % 997 == 1 ? (i % 2 ? INFINITY : -INFINITY)
                                               : fine(rng);
            break;
          case 2:  // 60 % one value
            x[i] = i % 5 < 3 ? 0.25 : fine(rng);
            break;
          case 3:  // every sampled value equal, the rest spread
            x[i] = i % 58 == 0 ? 1.0 : fine(rng);
            break;
          default:  // distinct values packed into one bucket by outliers
            x[i] = i % 100 == 0 ? 1e3 * fine(rng) : 1e-6 * fine(rng);
            break;
        }
      }
      std::vector<double> sorted = x;
      std::sort(sorted.begin(), sorted.end());
      const std::vector<double> q = SelectQuantiles(&x, levels);
      for (std::size_t j = 0; j < levels.size(); ++j) {
        const double want = SortedQuantile(sorted, levels[j]);
        if (std::isnan(want)) {  // -inf + 0 * inf at p = 0 and 1
          EXPECT_TRUE(std::isnan(q[j]))
              << "n " << n << " kind " << kind << " p " << levels[j];
        } else {
          EXPECT_EQ(q[j], want)
              << "n " << n << " kind " << kind << " p " << levels[j];
        }
      }
    }
}

}  // namespace
}  // namespace frictiond
