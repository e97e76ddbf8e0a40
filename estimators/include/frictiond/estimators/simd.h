#pragma once

namespace frictiond {

/// Instruction sets the vector kernels (FitOls moments, logistic sums) are
/// compiled for and chosen between at run time, narrowest first.
enum class SimdLevel { kScalar = 0, kAvx2 = 1, kAvx512 = 2 };

/// The widest level this CPU has: AVX-512 needs AVX-512F/DQ plus AVX2 and
/// FMA, AVX2 needs AVX2 and FMA (x86-64 with GCC/Clang; kScalar elsewhere).
SimdLevel CpuSimdLevel();

/// "AVX-512", "AVX2+FMA" or "scalar".
const char* SimdLevelName(SimdLevel level);

}  // namespace frictiond
