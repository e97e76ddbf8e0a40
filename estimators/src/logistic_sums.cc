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
// GCC vector extensions: W doubles per vector, compiled for AVX2 + FMA
// (W = 4) or AVX-512 (W = 8) inside the target functions below. Nothing
// here is passed by value across a call, so the ABI of wide vectors does
// not matter.
template <int W>
struct Simd {
  typedef double D __attribute__((vector_size(8 * W)));
  typedef long long L __attribute__((vector_size(8 * W)));
  typedef int I __attribute__((vector_size(4 * W)));
};

// exp(x) for x clamped to [-708, 708]: x = k ln2 + r with |r| <= ln2/2
// (Cody-Waite, k rounded by the 1.5 * 2^52 trick), exp(r) by its Taylor
// series to r^13 (truncation < 4e-18), times 2^k built in the exponent bits.
template <int W>
inline __attribute__((always_inline)) void ExpSimd(
    const typename Simd<W>::D& x_in, typename Simd<W>::D* out) {
  using D = typename Simd<W>::D;
  using L = typename Simd<W>::L;
  constexpr double kLog2e = 1.4426950408889634;
  constexpr double kLn2Hi = 6.93147180369123816490e-01;
  constexpr double kLn2Lo = 1.90821492927058770002e-10;
  constexpr double kMagic = 6755399441055744.0;  // 1.5 * 2^52
  const D lo = D{} - 708.0;
  const D hi = D{} + 708.0;
  D x = x_in > lo ? x_in : lo;
  x = x < hi ? x : hi;
  const D t = x * kLog2e + kMagic;
  const D k = t - kMagic;
  const D r = (x - k * kLn2Hi) - k * kLn2Lo;
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
  D p = r * kInvFactorial[0] + kInvFactorial[1];
  for (int j = 2; j < 14; ++j) p = p * r + kInvFactorial[j];
  std::int64_t magic_bits;
  std::memcpy(&magic_bits, &kMagic, sizeof magic_bits);
  L t_bits;
  std::memcpy(&t_bits, &t, sizeof t_bits);
  const L e = (t_bits - magic_bits + 1023) << 52;
  D scale;
  std::memcpy(&scale, &e, sizeof scale);
  *out = p * scale;
}

template <int W>
inline __attribute__((always_inline)) LogisticSums SumsSimd(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  using D = typename Simd<W>::D;
  using I = typename Simd<W>::I;
  const D zero = D{};
  const D floor_w = D{} + 1e-12;
  D g0 = zero, g1 = zero, h00 = zero, h01 = zero, h11 = zero;
  std::size_t i = 0;
  for (; i + W <= n; i += W) {
    D rv;
    std::memcpy(&rv, r + i, sizeof rv);
    I yi;
    std::memcpy(&yi, y + i, sizeof yi);
    const D yv = -__builtin_convertvector(yi != 0, D);  // (0 or -1)
    const D z = (rv - at.center) * at.scale;
    D e;
    ExpSimd<W>(-(at.a + at.b * z), &e);
    const D p = 1.0 / (1.0 + e);
    D w = p * (1.0 - p);
    w = w > floor_w ? w : floor_w;
    const D res = yv - p;
    g0 += res;
    g1 += res * z;
    h00 += w;
    h01 += w * z;
    h11 += w * z * z;
  }
  LogisticSums s;
  for (int l = 0; l < W; ++l) {
    s.g0 += g0[l];
    s.g1 += g1[l];
    s.h00 += h00[l];
    s.h01 += h01[l];
    s.h11 += h11[l];
  }
  for (; i < n; ++i) AddSample(r[i], y[i], at, &s);
  return s;
}

// The same sums from single-precision probabilities: W floats per vector
// (twice the lanes of double), exp(x) for x clamped to [-87, 87] by
// Cody-Waite and a Taylor series to r^7 (relative error ~2e-7), sums in
// float over blocks of 64 vectors, then in double. The relative error of
// the sums stays of order 1e-6: enough for a Newton step far from the
// optimum, not for the last one.
template <int W>
struct SimdF {
  typedef float F __attribute__((vector_size(4 * W)));
  typedef int I __attribute__((vector_size(4 * W)));
  typedef double D __attribute__((vector_size(8 * W)));
};

template <int W>
inline __attribute__((always_inline)) void ExpSimdF(
    const typename SimdF<W>::F& x_in, typename SimdF<W>::F* out) {
  using F = typename SimdF<W>::F;
  using I = typename SimdF<W>::I;
  constexpr float kLog2e = 1.44269504f;
  constexpr float kLn2Hi = 0.693145751953125f;
  constexpr float kLn2Lo = 1.428606765330187e-06f;
  constexpr float kMagic = 12582912.0f;  // 1.5 * 2^23
  const F lo = F{} - 87.0f;
  const F hi = F{} + 87.0f;
  F x = x_in > lo ? x_in : lo;
  x = x < hi ? x : hi;
  const F t = x * kLog2e + kMagic;
  const F k = t - kMagic;
  const F r = (x - k * kLn2Hi) - k * kLn2Lo;
  static constexpr float kInvFactorial[] = {1.0f / 5040.0f,
                                            1.0f / 720.0f,
                                            1.0f / 120.0f,
                                            1.0f / 24.0f,
                                            1.0f / 6.0f,
                                            0.5f,
                                            1.0f,
                                            1.0f};
  F p = r * kInvFactorial[0] + kInvFactorial[1];
  for (int j = 2; j < 8; ++j) p = p * r + kInvFactorial[j];
  std::int32_t magic_bits;
  std::memcpy(&magic_bits, &kMagic, sizeof magic_bits);
  I t_bits;
  std::memcpy(&t_bits, &t, sizeof t_bits);
  const I e = (t_bits - magic_bits + 127) << 23;
  F scale;
  std::memcpy(&scale, &e, sizeof scale);
  *out = p * scale;
}

template <int W>
inline __attribute__((always_inline)) LogisticSums SumsSimdF(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  using F = typename SimdF<W>::F;
  using I = typename SimdF<W>::I;
  using D = typename SimdF<W>::D;
  const F floor_w = F{} + 1e-12f;
  const float center = static_cast<float>(at.center);
  const float scale = static_cast<float>(at.scale);
  const float a = static_cast<float>(at.a), b = static_cast<float>(at.b);
  LogisticSums s;
  std::size_t i = 0;
  constexpr std::size_t kBlock = 64 * W;
  while (i + W <= n) {
    F g0 = F{}, g1 = F{}, h00 = F{}, h01 = F{}, h11 = F{};
    const std::size_t end = std::min(n, i + kBlock);
    for (; i + W <= end; i += W) {
      D rd;
      std::memcpy(&rd, r + i, sizeof rd);
      I yi;
      std::memcpy(&yi, y + i, sizeof yi);
      const F yv = -__builtin_convertvector(yi != 0, F);  // (0 or -1)
      const F z = (__builtin_convertvector(rd, F) - center) * scale;
      F e;
      ExpSimdF<W>(-(a + b * z), &e);
      const F p = 1.0f / (1.0f + e);
      F w = p * (1.0f - p);
      w = w > floor_w ? w : floor_w;
      const F res = yv - p;
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
  return SumsSimd<4>(r, y, n, at);
}

__attribute__((target("avx512f,avx512dq,avx2,fma"))) LogisticSums SumsAvx512(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  return SumsSimd<8>(r, y, n, at);
}

__attribute__((target("avx2,fma"))) LogisticSums SumsAvx2Float(
    const double* r, const int* y, std::size_t n, const LogisticPoint& at) {
  return SumsSimdF<8>(r, y, n, at);
}

__attribute__((target("avx512f,avx512dq,avx2,fma"))) LogisticSums
SumsAvx512Float(const double* r,
                const int* y,
                std::size_t n,
                const LogisticPoint& at) {
  return SumsSimdF<16>(r, y, n, at);
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
