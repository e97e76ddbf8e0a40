#pragma once
/// @file
/// Distribution functions used by the estimators' tests of significance.

#include <vector>

namespace frictiond {

/// Standard normal CDF Phi(x).
double NormalCdf(double x);
/// Standard normal quantile Phi^-1(p), p in (0, 1); +-inf at 0 and 1.
double NormalQuantile(double p);
/// Regularised incomplete beta function I_x(a, b), a, b > 0, x in [0, 1].
double RegularizedIncompleteBeta(double a, double b, double x);
/// Two-sided p-value of Student's t statistic with `dof` degrees of freedom.
double StudentTTwoSidedP(double t, double dof);
/// Upper-tail p-value P(F > f) of Fisher's F with (d1, d2) degrees of freedom.
double FUpperP(double f, double d1, double d2);
/// Empirical quantile of `sorted` (ascending) at probability p in [0, 1],
/// linear interpolation between order statistics (type 7).
double SortedQuantile(const std::vector<double>& sorted, double p);
/// The same quantiles as SortedQuantile of sorted(x) at each of `levels`
/// (ascending, in [0, 1]), found by selection (expected O(n) for a handful
/// of levels) instead of a sort. `x` is scratch space: its contents
/// afterwards are unspecified.
std::vector<double> SelectQuantiles(std::vector<double>* x,
                                    const std::vector<double>& levels);

}  // namespace frictiond
