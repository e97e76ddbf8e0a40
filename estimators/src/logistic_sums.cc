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
// exp(x) for x clamped to [-limit, limit]: x = k ln2 + r with |r| <= ln2/2
// (Cody-Waite, k rounded by the 1.5 * 2^mantissa trick), exp(r) by its
// Taylor series, times 2^k built in the exponent bits. Double: to r^13
// (truncation < 4e-18); float: to r^7 (relative error ~2e-7).
template <class T>
struct ExpConstants;

template <>
struct ExpConstants<double> {
  using Bits = std::int64_t;
  static constexpr double kLog2e = 1.4426950408889634;
  static constexpr double kLn2Hi = 6.93147180369123816490e-01;
  static constexpr double kLn2Lo = 1.90821492927058770002e-10;
  static constexpr double kMagic = 6755399441055744.0;  // 1.5 * 2^52
  static constexpr double kLimit = 708.0;
  static constexpr int kBias = 1023, kMantissa = 52;
  static constexpr int kTerms = 14;
  static constexpr double kInvFactorial[kTerms] = {1.0 / 6227020800.0,
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
};

template <>
struct ExpConstants<float> {
  using Bits = std::int32_t;
  static constexpr float kLog2e = 1.44269504f;
  static constexpr float kLn2Hi = 0.693145751953125f;
  static constexpr float kLn2Lo = 1.428606765330187e-06f;
  static constexpr float kMagic = 12582912.0f;  // 1.5 * 2^23
  static constexpr float kLimit = 87.0f;
  static constexpr int kBias = 127, kMantissa = 23;
  static constexpr int kTerms = 8;
  static constexpr float kInvFactorial[kTerms] = {1.0f / 5040.0f,
                                                  1.0f / 720.0f,
                                                  1.0f / 120.0f,
                                                  1.0f / 24.0f,
                                                  1.0f / 6.0f,
                                                  0.5f,
                                                  1.0f,
                                                  1.0f};
};

// GCC vector extensions: W values of T per vector, compiled for AVX2 + FMA
// or AVX-512 inside the target functions below. Nothing here is passed by
// value across a call, so the ABI of wide vectors does not matter.
template <class T, int W>
struct Lanes {
  typedef T V __attribute__((vector_size(sizeof(T) * W)));
  typedef typename ExpConstants<T>::Bits B
      __attribute__((vector_size(sizeof(T) * W)));
  typedef int I __attribute__((vector_size(4 * W)));
  typedef double D __attribute__((vector_size(8 * W)));
};

template <class T, int W>
inline __attribute__((always_inline)) void ExpSimd(
    const typename Lanes<T, W>::V& x_in, typename Lanes<T, W>::V* out) {
  using V = typename Lanes<T, W>::V;
  using B = typename Lanes<T, W>::B;
  using C = ExpConstants<T>;
  const V lo = V{} - C::kLimit;
  const V hi = V{} + C::kLimit;
  V x = x_in > lo ? x_in : lo;
  x = x < hi ? x : hi;
  const V t = x * C::kLog2e + C::kMagic;
  const V k = t - C::kMagic;
  const V r = (x - k * C::kLn2Hi) - k * C::kLn2Lo;
  V p = r * C::kInvFactorial[0] + C::kInvFactorial[1];
  for (int j = 2; j < C::kTerms; ++j) p = p * r + C::kInvFactorial[j];
  typename C::Bits magic_bits;
  std::memcpy(&magic_bits, &C::kMagic, sizeof magic_bits);
  B t_bits;
  std::memcpy(&t_bits, &t, sizeof t_bits);
  const B e = (t_bits - magic_bits + C::kBias) << C::kMantissa;
  V scale;
  std::memcpy(&scale, &e, sizeof scale);
  *out = p * scale;
}

// The sums with W lanes of T: probabilities in T, partial sums in T over
// blocks of 64 vectors, then in double (for T = float this keeps the
// relative error of the sums near 1e-6 rather than growing with n).
template <class T, int W>
inline __attribute__((always_inline)) LogisticSums SumsSimd(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  using V = typename Lanes<T, W>::V;
  using I = typename Lanes<T, W>::I;
  using D = typename Lanes<T, W>::D;
  const V floor_w = V{} + static_cast<T>(1e-12);
  const T center = static_cast<T>(at.center);
  const T scale = static_cast<T>(at.scale);
  const T a = static_cast<T>(at.a), b = static_cast<T>(at.b);
  LogisticSums s;
  std::size_t i = 0;
  constexpr std::size_t kBlock = 64 * W;
  while (i + W <= n) {
    V g0 = V{}, g1 = V{}, h00 = V{}, h01 = V{}, h11 = V{};
    const std::size_t end = std::min(n, i + kBlock);
    for (; i + W <= end; i += W) {
      D rd;
      std::memcpy(&rd, r + i, sizeof rd);
      I yi;
      std::memcpy(&yi, y + i, sizeof yi);
      const V yv = -__builtin_convertvector(yi != 0, V);  // (0 or -1)
      const V z = (__builtin_convertvector(rd, V) - center) * scale;
      V e;
      ExpSimd<T, W>(-(a + b * z), &e);
      const V p = 1 / (1 + e);
      V w = p * (1 - p);
      w = w > floor_w ? w : floor_w;
      const V res = yv - p;
      g0 += res;
      g1 += res * z;
      h00 += w;
      h01 += w * z;
      h11 += w * z * z;
    }
    for (int l = 0; l < W; ++l) {
      s.g0 += g0[l];
      s.g1 += g1[l];
      s.h00 += h00[l];
      s.h01 += h01[l];
      s.h11 += h11[l];
    }
  }
  for (; i < n; ++i) AddSample(r[i], y[i], at, &s);
  return s;
}

__attribute__((target("avx2,fma"))) LogisticSums SumsAvx2(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  return SumsSimd<double, 4>(r, y, n, at);
}

__attribute__((target("avx512f,avx512dq,avx2,fma"))) LogisticSums SumsAvx512(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  return SumsSimd<double, 8>(r, y, n, at);
}

__attribute__((target("avx2,fma"))) LogisticSums SumsAvx2Float(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  return SumsSimd<float, 8>(r, y, n, at);
}

__attribute__((target("avx512f,avx512dq,avx2,fma"))) LogisticSums
SumsAvx512Float(const double* r,
                const int* y,
                std::size_t n,
                const LogisticPoint& at) {
  return SumsSimd<float, 16>(r, y, n, at);
}
#endif

}  // namespace

SimdLevel LogisticSumsLevel(SimdLevel max_level) {
  return std::min(max_level, CpuSimdLevel());
}

LogisticSums CalcLogisticSums(const double* r,
                              const int* y,
                              std::size_t n,
                              const LogisticPoint& at,
                              SimdLevel max_level,
                              bool single_precision) {
#if defined(__GNUC__) && defined(__x86_64__)
  switch (LogisticSumsLevel(max_level)) {
    case SimdLevel::kAvx512:
      return single_precision ? SumsAvx512Float(r, y, n, at)
                              : SumsAvx512(r, y, n, at);
    case SimdLevel::kAvx2:
      return single_precision ? SumsAvx2Float(r, y, n, at)
                              : SumsAvx2(r, y, n, at);
    default:
      break;
  }
#endif
  return SumsBaseline(r, y, n, at);
}

}  // namespace frictiond
