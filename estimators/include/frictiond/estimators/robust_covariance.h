#pragma once
/// @file
/// Cluster-robust (stroke-grouped) covariance of least-squares coefficients.
///
/// The OLS covariance P_beta = sigma^2 (X'X)^-1 of regression.h assumes
/// i.i.d. eps. Real strokes violate that: eps is autocorrelated within a
/// stroke (AR(1)-like) and strokes carry their own offsets, so samples of a
/// stroke are not independent and the OLS standard errors of eq. (1) are too
/// small (the intervals under-cover; see robust_covariance_test.cc, which
/// plants AR(1) noise and per-stroke offsets). The sandwich estimator with
/// strokes as clusters (Liang-Zeger, with the usual small-sample factor)
///   P = c (X'X)^-1 [sum_g X_g' u_g u_g' X_g] (X'X)^-1,
///   c = G/(G-1) * (N-1)/(N-K)
/// stays valid under any within-stroke correlation when strokes are
/// independent and there are enough of them (say >= 10).
///
/// Usage:
/// @code
///   OlsResult ols = FitOls(X, y);
///   Eigen::MatrixXd P = CalcClusterRobustCovariance(X, ols.residuals, stroke);
/// @endcode

#include <vector>

#include <Eigen/Dense>

namespace frictiond {

/// Stroke-clustered covariance of the coefficients of y = X beta + u, given
/// the residuals u of the fit. Returns a K x K matrix; all zeros when there
/// are fewer than 2 clusters or X'X is singular.
/// @throws std::invalid_argument when the row counts differ.
Eigen::MatrixXd CalcClusterRobustCovariance(
    const Eigen::Ref<const Eigen::MatrixXd>& X,
    const Eigen::Ref<const Eigen::VectorXd>& residuals,
    const std::vector<int>& cluster);

}  // namespace frictiond
