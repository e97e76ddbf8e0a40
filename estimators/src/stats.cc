#include "frictiond/estimators/stats.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace frictiond {

double NormalCdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

double NormalQuantile(double p) {
  if (!(p > 0)) return -std::numeric_limits<double>::infinity();
  if (!(p < 1)) return std::numeric_limits<double>::infinity();
  // Acklam's rational approximation, refined by one Halley step.
  static const double a[] = {-3.969683028665376e+01,
                             2.209460984245205e+02,
                             -2.759285104469687e+02,
                             1.383577518672690e+02,
                             -3.066479806614716e+01,
                             2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01,
                             1.615858368580409e+02,
                             -1.556989798598866e+02,
                             6.680131188771972e+01,
                             -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03,
                             -3.223964580411365e-01,
                             -2.400758277161838e+00,
                             -2.549732539343734e+00,
                             4.374664141464968e+00,
                             2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03,
                             3.224671290700398e-01,
                             2.445134137142996e+00,
                             3.754408661907416e+00};
  const double plow = 0.02425;
  double x;
  if (p < plow) {
    const double q = std::sqrt(-2 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  } else if (p <= 1 - plow) {
    const double q = p - 0.5;
    const double r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) *
        q / (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  } else {
    const double q = std::sqrt(-2 * std::log(1 - p));
    x = -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  const double e = NormalCdf(x) - p;
  const double u = e * std::sqrt(2 * M_PI) * std::exp(x * x / 2);
  return x - u / (1 + x * u / 2);
}

namespace {

// Continued fraction for the incomplete beta (modified Lentz).
double BetaContinuedFraction(double a, double b, double x) {
  const double tiny = 1e-300;
  double c = 1.0;
  double d = 1.0 - (a + b) * x / (a + 1.0);
  if (std::fabs(d) < tiny) d = tiny;
  d = 1.0 / d;
  double h = d;
  for (int m = 1; m <= 500; ++m) {
    const double m2 = 2.0 * m;
    double aa = m * (b - m) * x / ((a + m2 - 1) * (a + m2));
    d = 1.0 + aa * d;
    if (std::fabs(d) < tiny) d = tiny;
    c = 1.0 + aa / c;
    if (std::fabs(c) < tiny) c = tiny;
    d = 1.0 / d;
    h *= d * c;
    aa = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1));
    d = 1.0 + aa * d;
    if (std::fabs(d) < tiny) d = tiny;
    c = 1.0 + aa / c;
    if (std::fabs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::fabs(del - 1.0) < 1e-15) break;
  }
  return h;
}

}  // namespace

double RegularizedIncompleteBeta(double a, double b, double x) {
  if (!(x > 0)) return 0.0;
  if (!(x < 1)) return 1.0;
  const double log_front = std::lgamma(a + b) - std::lgamma(a) -
                           std::lgamma(b) + a * std::log(x) +
                           b * std::log1p(-x);
  if (x < (a + 1) / (a + b + 2))
    return std::exp(log_front) * BetaContinuedFraction(a, b, x) / a;
  return 1.0 - std::exp(log_front) * BetaContinuedFraction(b, a, 1 - x) / b;
}

double StudentTTwoSidedP(double t, double dof) {
  if (!std::isfinite(t)) return 0.0;
  if (!(dof > 0)) return 1.0;
  return RegularizedIncompleteBeta(dof / 2, 0.5, dof / (dof + t * t));
}

double FUpperP(double f, double d1, double d2) {
  if (!(f > 0)) return 1.0;
  if (!std::isfinite(f)) return 0.0;
  return RegularizedIncompleteBeta(d2 / 2, d1 / 2, d2 / (d2 + d1 * f));
}

double SortedQuantile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return std::numeric_limits<double>::quiet_NaN();
  p = std::clamp(p, 0.0, 1.0);
  const double h = p * (sorted.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (h - lo) * (sorted[hi] - sorted[lo]);
}

namespace {

// Ascending sort of doubles (no NaN) by LSD radix on their order-preserving
// 64-bit keys, 11 bits per pass; passes whose digit is the same for every
// key are skipped (typically the sign and exponent ones).
void RadixSort(std::vector<double>* values) {
  std::vector<double>& x = *values;
  const std::size_t n = x.size();
  std::vector<std::uint64_t> key(n), tmp(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t u;
    std::memcpy(&u, &x[i], sizeof u);
    // Negative: flip all bits; positive: flip the sign bit.
    key[i] = (u >> 63) ? ~u : (u | (std::uint64_t{1} << 63));
  }
  constexpr int kBits = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kBits;
  std::vector<std::size_t> count(kBuckets);
  for (int shift = 0; shift < 64; shift += kBits) {
    std::fill(count.begin(), count.end(), 0);
    for (std::uint64_t k : key) ++count[(k >> shift) & (kBuckets - 1)];
    if (count[(key[0] >> shift) & (kBuckets - 1)] == n) continue;
    std::size_t total = 0;
    for (std::size_t& c : count) {
      const std::size_t here = c;
      c = total;
      total += here;
    }
    for (std::uint64_t k : key) tmp[count[(k >> shift) & (kBuckets - 1)]++] = k;
    key.swap(tmp);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t k = key[i];
    const std::uint64_t u = (k >> 63) ? (k & ~(std::uint64_t{1} << 63)) : ~k;
    std::memcpy(&x[i], &u, sizeof u);
  }
}

}  // namespace

std::vector<double> SelectQuantiles(std::vector<double>* x,
                                    const std::vector<double>& levels) {
  std::vector<double> out;
  std::vector<double>& e = *x;
  if (e.empty()) {
    out.assign(levels.size(), std::numeric_limits<double>::quiet_NaN());
    return out;
  }
  // The order statistics the quantiles interpolate between, placed by
  // recursive multiple selection: select the middle one, then the ones
  // below it in the left part and the ones above in the right part
  // (O(n log k) for k order statistics, where one nth_element per statistic
  // on the remaining tail would be O(n k)).
  std::vector<std::size_t> order;
  for (double p : levels) {
    const double h = std::clamp(p, 0.0, 1.0) * (e.size() - 1);
    order.push_back(static_cast<std::size_t>(std::floor(h)));
    order.push_back(std::min(order.back() + 1, e.size() - 1));
  }
  std::sort(order.begin(), order.end());
  order.erase(std::unique(order.begin(), order.end()), order.end());
  const bool any_nan =
      std::any_of(e.begin(), e.end(), [](double v) { return std::isnan(v); });
  if (order.size() > 16 && e.size() > 4096 && !any_nan) {
    // Many order statistics of a large set: a radix sort is cheaper than
    // O(n log k) selection.
    RadixSort(&e);
    order.clear();
  }
  struct Range {
    std::size_t lo, hi;           // elements [lo, hi)
    std::size_t first_k, last_k;  // order statistics order[first_k, last_k)
  };
  std::vector<Range> todo = {{0, e.size(), 0, order.size()}};
  while (!todo.empty()) {
    const Range r = todo.back();
    todo.pop_back();
    if (r.first_k >= r.last_k || r.hi - r.lo <= 1) continue;
    const std::size_t mid = r.first_k + (r.last_k - r.first_k) / 2;
    const std::size_t k = order[mid];
    std::nth_element(e.begin() + r.lo, e.begin() + k, e.begin() + r.hi);
    todo.push_back({r.lo, k, r.first_k, mid});
    todo.push_back({k + 1, r.hi, mid + 1, r.last_k});
  }
  for (double p : levels) {
    const double h = std::clamp(p, 0.0, 1.0) * (e.size() - 1);
    const std::size_t a = static_cast<std::size_t>(std::floor(h));
    const std::size_t b = std::min(a + 1, e.size() - 1);
    out.push_back(e[a] + (h - a) * (e[b] - e[a]));
  }
  return out;
}

}  // namespace frictiond
