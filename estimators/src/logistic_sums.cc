#include "frictiond/estimators/logistic_sums.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace frictiond {

namespace {

// One sample's contribution (the baseline path and the tail of the vector
// path).
inline void AddSample(double r,
                      int y,
                      const LogisticPoint& at,
                      LogisticSums* s) {
  const double z = (r - at.center) * at.scale;
  const double p = 1.0 / (1.0 + std::exp(-(at.a + at.b * z)));
  const double w = std::max(p * (1.0 - p), 1e-12);
  const double res = (y != 0 ? 1.0 : 0.0) - p;
  s->g0 += res;
  s->g1 += res * z;
  s->h00 += w;
  s->h01 += w * z;
  s->h11 += w * z * z;
}

LogisticSums SumsBaseline(const double* r,
                          const int* y,
                          std::size_t n,
                          const LogisticPoint& at) {
  LogisticSums s;
  for (std::size_t i = 0; i < n; ++i) AddSample(r[i], y[i], at, &s);
  return s;
}

#if defined(__GNUC__) && defined(__x86_64__)
// GCC vector extensions: 4 doubles, compiled for AVX2 + FMA inside the
// target function below (nothing here is passed by value across a call, so
// the ABI of 32-byte vectors does not matter).
typedef double V4d __attribute__((vector_size(32)));
typedef long long V4l __attribute__((vector_size(32)));
typedef int V4i __attribute__((vector_size(16)));

// exp(x) for x clamped to [-708, 708]: x = k ln2 + r with |r| <= ln2/2
// (Cody-Waite, k rounded by the 1.5 * 2^52 trick), exp(r) by its Taylor
// series to r^13 (truncation < 4e-18), times 2^k built in the exponent bits.
inline __attribute__((always_inline)) void Exp4(const V4d& x_in, V4d* out) {
  constexpr double kLog2e = 1.4426950408889634;
  constexpr double kLn2Hi = 6.93147180369123816490e-01;
  constexpr double kLn2Lo = 1.90821492927058770002e-10;
  constexpr double kMagic = 6755399441055744.0;  // 1.5 * 2^52
  const V4d lo = {-708.0, -708.0, -708.0, -708.0};
  const V4d hi = {708.0, 708.0, 708.0, 708.0};
  V4d x = x_in > lo ? x_in : lo;
  x = x < hi ? x : hi;
  const V4d t = x * kLog2e + kMagic;
  const V4d k = t - kMagic;
  const V4d r = (x - k * kLn2Hi) - k * kLn2Lo;
  static constexpr double kInvFactorial[] = {1.0 / 6227020800.0,
                                             1.0 / 479001600.0,
                                             1.0 / 39916800.0,
                                             1.0 / 3628800.0,
                                             1.0 / 362880.0,
                                             1.0 / 40320.0,
                                             1.0 / 5040.0,
                                             1.0 / 720.0,
                                             1.0 / 120.0,
                                             1.0 / 24.0,
                                             1.0 / 6.0,
                                             0.5,
                                             1.0,
                                             1.0};
  V4d p = r * kInvFactorial[0] + kInvFactorial[1];
  for (int j = 2; j < 14; ++j) p = p * r + kInvFactorial[j];
  std::int64_t magic_bits;
  std::memcpy(&magic_bits, &kMagic, sizeof magic_bits);
  V4l t_bits;
  std::memcpy(&t_bits, &t, sizeof t_bits);
  const V4l e = (t_bits - magic_bits + 1023) << 52;
  V4d scale;
  std::memcpy(&scale, &e, sizeof scale);
  *out = p * scale;
}

__attribute__((target("avx2,fma"))) LogisticSums SumsAvx2(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  const V4d zero = {0.0, 0.0, 0.0, 0.0};
  const V4d floor_w = {1e-12, 1e-12, 1e-12, 1e-12};
  V4d g0 = zero, g1 = zero, h00 = zero, h01 = zero, h11 = zero;
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    V4d rv;
    std::memcpy(&rv, r + i, sizeof rv);
    V4i yi;
    std::memcpy(&yi, y + i, sizeof yi);
    const V4d yv = -__builtin_convertvector(yi != 0, V4d);  // (0 or -1)
    const V4d z = (rv - at.center) * at.scale;
    V4d e;
    Exp4(-(at.a + at.b * z), &e);
    const V4d p = 1.0 / (1.0 + e);
    V4d w = p * (1.0 - p);
    w = w > floor_w ? w : floor_w;
    const V4d res = yv - p;
    g0 += res;
    g1 += res * z;
    h00 += w;
    h01 += w * z;
    h11 += w * z * z;
  }
  LogisticSums s;
  for (int l = 0; l < 4; ++l) {
    s.g0 += g0[l];
    s.g1 += g1[l];
    s.h00 += h00[l];
    s.h01 += h01[l];
    s.h11 += h11[l];
  }
  for (; i < n; ++i) AddSample(r[i], y[i], at, &s);
  return s;
}
#endif

bool CpuHasAvx2Fma() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const bool has =
      __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
#else
  return false;
#endif
}

}  // namespace

bool LogisticSumsUseAvx2(bool allow_avx2) {
  return allow_avx2 && CpuHasAvx2Fma();
}

LogisticSums CalcLogisticSums(const double* r,
                              const int* y,
                              std::size_t n,
                              const LogisticPoint& at,
                              bool allow_avx2) {
#if defined(__GNUC__) && defined(__x86_64__)
  if (LogisticSumsUseAvx2(allow_avx2)) return SumsAvx2(r, y, n, at);
#endif
  return SumsBaseline(r, y, n, at);
}

}  // namespace frictiond
