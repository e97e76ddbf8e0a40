#pragma once

#include <cstddef>

#include "frictiond/estimators/simd.h"

namespace frictiond {

/// Where a Newton (IRLS) step of the logistic fit is taken: the model is
/// L = 1/(1 + exp(-(a + b z))) with the standardised ratio
/// z = (r - center) * scale (paper 000, III-A, after standardising r).
struct LogisticPoint {
  double a = 0.0;
  double b = 0.0;
  double center = 0.0;
  double scale = 1.0;
};

/// One pass of sums over (r, y) pairs at a LogisticPoint: the gradient of
/// the log-likelihood (g0 = sum (y - p), g1 = sum (y - p) z) and the Fisher
/// information (h00 = sum w, h01 = sum w z, h11 = sum w z^2), with
/// p = L(z) and w = max(p (1 - p), 1e-12).
struct LogisticSums {
  double g0 = 0.0;
  double g1 = 0.0;
  double h00 = 0.0;
  double h01 = 0.0;
  double h11 = 0.0;
};

/// The sums over n pairs (y: 0 = stick, anything else = slip), with the
/// widest instruction set up to `max_level` that the CPU has: AVX-512 (8
/// samples per instruction) or AVX2 + FMA (4) with a polynomial exp
/// (relative error < 5e-16), else one sample at a time with std::exp. All
/// agree to rounding. With `single_precision`, the vector paths compute
/// the probabilities in float (twice the lanes; sums of relative error
/// ~1e-6): for Newton steps far from the optimum, never for the last one
/// (the scalar path ignores the flag).
LogisticSums CalcLogisticSums(const double* r,
                              const int* y,
                              std::size_t n,
                              const LogisticPoint& at,
                              SimdLevel max_level = SimdLevel::kAvx512,
                              bool single_precision = false);

/// The instruction set CalcLogisticSums(..., max_level) uses here.
SimdLevel LogisticSumsLevel(SimdLevel max_level = SimdLevel::kAvx512);

}  // namespace frictiond
