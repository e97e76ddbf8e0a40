#include "frictiond/estimators/simd.h"

namespace frictiond {

SimdLevel CpuSimdLevel() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const SimdLevel level = [] {
    const bool avx2 =
        __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    if (avx2 && __builtin_cpu_supports("avx512f") &&
        __builtin_cpu_supports("avx512dq"))
      return SimdLevel::kAvx512;
    return avx2 ? SimdLevel::kAvx2 : SimdLevel::kScalar;
  }();
  return level;
#else
  return SimdLevel::kScalar;
#endif
}

const char* SimdLevelName(SimdLevel level) {
  switch (level) {
    case SimdLevel::kAvx512:
      return "AVX-512";
    case SimdLevel::kAvx2:
      return "AVX2+FMA";
    default:
      return "scalar";
  }
}

}  // namespace frictiond
