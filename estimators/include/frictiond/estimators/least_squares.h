#pragma once
/// @file
/// The one small nonlinear least-squares solver of the estimators: bounded
/// Levenberg-Marquardt with Marquardt scaling, or Gauss-Newton with step
/// halving, for problems with few parameters (fixed N, or Eigen::Dynamic)
/// and many residuals. It serves the LuGre fits (paper 001 eq. 14, both
/// steps), the joint-friction fits (paper 002) and the reciprocal form of
/// mu = f(Fn) (paper 000 Table II). In the spirit of Ceres'
/// tiny_solver.h: this header is the manual.
///
/// Problem: minimise C(x) = |r(x)|^2 over lower <= x <= upper, where the
/// caller's functor fills r (m residuals) and J = dr/dx (m x N):
///
/// @code
///   // bool f(const Eigen::Matrix<double, N, 1>& x, Eigen::VectorXd* r,
///   //        Eigen::Matrix<double, Eigen::Dynamic, N>* J);
///   // returns false when r or J is not finite (or x leaves the model's
///   // domain); the solver then treats the trial as rejected.
///   LeastSquaresWorkspace<2> ws(m);          // r, J and trial buffers
///   Eigen::Vector2d x(1.0, 0.5);             // start, inside the box
///   const LeastSquaresSummary<2> s = SolveLeastSquares<2>(
///       f, &x, lower, upper, LeastSquaresOptions(), &ws);
///   if (s.status == LeastSquaresStatus::kConverged) {
///     // x is the solution, ws.r and ws.J hold r(x) and J(x),
///     // s.JtJ_inv = (J^T J)^-1 at x (for P = s^2 (J^T J)^-1 or a sandwich).
///   }
/// @endcode
///
/// Iteration (k = 0, 1, ...): A = J^T J, g = J^T r, D = diag(A) floored at
/// options.min_diagonal. LM solves (A + lambda D + 1e-14 D) delta = -g
/// (Marquardt's scaling, paper 001 eq. 14); GN solves (A + 1e-14 D) delta
/// = -g (the 1e-14 D floor lets GN survive a singular A). The trial is
/// x + alpha delta projected onto the box. A trial is accepted when f
/// returns true and C(trial) <= C(x). On rejection LM multiplies lambda by
/// lambda_increase and GN halves alpha, up to max_step_tries times per
/// iteration; after an acceptance lambda is divided by lambda_decrease
/// (floored at 1e-12). Convergence: an accepted step lowered C by less than
/// cost_tolerance * C, or moved no entry by more than step_tolerance
/// relative to its size, or no trial was accepted (no descent left at
/// machine precision: a minimum, possibly on the box).
///
/// After the loop, J^T J is Jacobi-scaled (S = D^-1/2 A D^-1/2) and its
/// reciprocal condition number (smallest / largest eigenvalue) reported;
/// at or below min_rcond the status is kRankDeficient and JtJ_inv is NaN.
///
/// Statuses are results, not exceptions (house rule 8); only invalid
/// options, sizes or a start outside the box throw.

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>

namespace frictiond {

/// Step rule of SolveLeastSquares.
enum class LeastSquaresMethod {
  kLevenbergMarquardt,  ///< damped, Marquardt-scaled steps
  kGaussNewton,         ///< undamped steps, halved until accepted
};

/// Outcome of SolveLeastSquares.
enum class LeastSquaresStatus {
  kConverged,      ///< cost or step change fell below tolerance
  kMaxIterations,  ///< max_iterations used up; x is the last iterate
  kRankDeficient,  ///< rcond of the scaled J^T J <= min_rcond at the end
  kNotEnoughData,  ///< fewer residuals than parameters; x unchanged
  kFailed,         ///< f returned false at the start; x unchanged
};

/// Short name ("converged", "max_iterations", "rank_deficient",
/// "not_enough_data", "failed").
inline const char* ToString(LeastSquaresStatus status) {
  switch (status) {
    case LeastSquaresStatus::kConverged:
      return "converged";
    case LeastSquaresStatus::kMaxIterations:
      return "max_iterations";
    case LeastSquaresStatus::kRankDeficient:
      return "rank_deficient";
    case LeastSquaresStatus::kNotEnoughData:
      return "not_enough_data";
    case LeastSquaresStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

/// Options of SolveLeastSquares; the defaults are those of the LuGre fits.
/// Copyable value type.
struct LeastSquaresOptions {
  LeastSquaresMethod method = LeastSquaresMethod::kLevenbergMarquardt;
  /// Iteration limit, > 0.
  int max_iterations = 100;
  /// Converged when an accepted step lowers the cost by less than this
  /// fraction of it, in [0, 1).
  double cost_tolerance = 1e-12;
  /// Converged when an accepted step moves no entry by more than this
  /// fraction of |x_i| (+1e-12), >= 0.
  double step_tolerance = 1e-12;
  /// Initial LM damping, > 0 (unused by GN).
  double initial_lambda = 1e-3;
  /// LM damping factor after a rejected trial, > 1.
  double lambda_increase = 10.0;
  /// LM damping divisor after an accepted step, > 1.
  double lambda_decrease = 10.0;
  /// Trials per iteration before the solver stops at the current x, > 0.
  int max_step_tries = 30;
  /// Floor of diag(J^T J) in the scaling, > 0.
  double min_diagonal = 1e-300;
  /// rcond of the scaled J^T J at or below this: kRankDeficient, in [0, 1).
  double min_rcond = 1e-12;

  /// True if every field satisfies its rule; otherwise *why (if not null)
  /// names the field, its value and the rule.
  bool IsValid(std::string* why) const {
    auto fail = [why](const char* field, double value, const char* rule) {
      if (why)
        *why = std::string(field) + " = " + std::to_string(value) +
               " (must be " + rule + ")";
      return false;
    };
    if (!(max_iterations > 0))
      return fail("max_iterations", max_iterations, "> 0");
    if (!(cost_tolerance >= 0 && cost_tolerance < 1))
      return fail("cost_tolerance", cost_tolerance, "in [0, 1)");
    if (!(step_tolerance >= 0) || !std::isfinite(step_tolerance))
      return fail("step_tolerance", step_tolerance, "finite and >= 0");
    if (!(initial_lambda > 0) || !std::isfinite(initial_lambda))
      return fail("initial_lambda", initial_lambda, "finite and > 0");
    if (!(lambda_increase > 1) || !std::isfinite(lambda_increase))
      return fail("lambda_increase", lambda_increase, "finite and > 1");
    if (!(lambda_decrease > 1) || !std::isfinite(lambda_decrease))
      return fail("lambda_decrease", lambda_decrease, "finite and > 1");
    if (!(max_step_tries > 0))
      return fail("max_step_tries", max_step_tries, "> 0");
    if (!(min_diagonal > 0) || !std::isfinite(min_diagonal))
      return fail("min_diagonal", min_diagonal, "finite and > 0");
    if (!(min_rcond >= 0 && min_rcond < 1))
      return fail("min_rcond", min_rcond, "in [0, 1)");
    return true;
  }
};

/// Buffers of one problem size: the residuals and Jacobian at the current x
/// (r, J; valid after SolveLeastSquares returns anything but kFailed or
/// kNotEnoughData) and at the trial. Reuse it across solves of the same
/// size to avoid allocation. Copyable, movable.
template <int N>
struct LeastSquaresWorkspace {
  using Jacobian = Eigen::Matrix<double, Eigen::Dynamic, N>;
  /// m residuals; n parameters (must be N unless N is Eigen::Dynamic).
  explicit LeastSquaresWorkspace(Eigen::Index m, Eigen::Index n = N)
      : r(m), r_try(m), J(m, n), J_try(m, n) {}
  Eigen::VectorXd r;
  Eigen::VectorXd r_try;
  Jacobian J;
  Jacobian J_try;
};

/// What SolveLeastSquares did.
template <int N>
struct LeastSquaresSummary {
  using Matrix = Eigen::Matrix<double, N, N>;
  LeastSquaresStatus status = LeastSquaresStatus::kFailed;
  int iterations = 0;  ///< iterations run (accepted steps + the last try)
  double initial_cost = 0.0;  ///< |r|^2 at the start
  double cost = 0.0;          ///< |r|^2 at the returned x
  double rcond = 0.0;         ///< of the Jacobi-scaled J^T J at x
  /// (J^T J)^-1 at x (inverted in scaled form); NaN when kRankDeficient,
  /// empty when kFailed or kNotEnoughData.
  Matrix JtJ_inv;
  std::string why;  ///< reason for any status other than kConverged
};

/// Minimises |r(x)|^2 within [lower, upper] (see the file comment).
/// @param f      functor bool(const VecN& x, VectorXd* r, Matrix<-1,N>* J)
/// @param x      in: the start (inside the box); out: the solution
/// @param ws     buffers sized for m residuals (ws->r.size() = m)
/// @throws std::invalid_argument for invalid options, mismatched sizes or a
/// start outside the box.
template <int N, typename Residual>
LeastSquaresSummary<N> SolveLeastSquares(
    Residual&& f,
    Eigen::Matrix<double, N, 1>* x,
    const Eigen::Matrix<double, N, 1>& lower,
    const Eigen::Matrix<double, N, 1>& upper,
    const LeastSquaresOptions& options,
    LeastSquaresWorkspace<N>* ws) {
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  std::string error;
  if (!options.IsValid(&error))
    throw std::invalid_argument("LeastSquaresOptions." + error);
  const Eigen::Index n = x->size();
  const Eigen::Index m = ws->r.size();
  if (lower.size() != n || upper.size() != n || ws->J.cols() != n ||
      ws->J.rows() != m || ws->r_try.size() != m || ws->J_try.rows() != m ||
      ws->J_try.cols() != n) {
    throw std::invalid_argument(
        "SolveLeastSquares: x has " + std::to_string(n) + " entries, bounds " +
        std::to_string(lower.size()) + " and " + std::to_string(upper.size()) +
        ", workspace " + std::to_string(m) + " x " +
        std::to_string(ws->J.cols()) + " (must agree)");
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!((*x)[i] >= lower[i] && (*x)[i] <= upper[i]))
      throw std::invalid_argument(
          "SolveLeastSquares: x[" + std::to_string(i) +
          "] = " + std::to_string((*x)[i]) + " (must be within [" +
          std::to_string(lower[i]) + ", " + std::to_string(upper[i]) + "])");
  }
  LeastSquaresSummary<N> out;
  if (m < n) {
    out.status = LeastSquaresStatus::kNotEnoughData;
    out.why = std::to_string(m) + " residuals for " + std::to_string(n) +
              " parameters";
    return out;
  }
  if (!f(*x, &ws->r, &ws->J)) {
    out.status = LeastSquaresStatus::kFailed;
    out.why = "model not finite at the initial guess";
    return out;
  }
  const bool gauss_newton = options.method == LeastSquaresMethod::kGaussNewton;
  double cost = ws->r.squaredNorm();
  out.initial_cost = cost;
  double lambda = options.initial_lambda;
  Mat A(n, n), M(n, n);
  Vec g(n), delta(n), x_try(n), diag(n);
  bool converged = false;
  int it = 0;
  for (; it < options.max_iterations && !converged; ++it) {
    A.noalias() = ws->J.transpose() * ws->J;
    g.noalias() = ws->J.transpose() * ws->r;
    diag = A.diagonal().cwiseMax(options.min_diagonal);
    bool accepted = false;
    double cost_try = cost;
    double alpha = 1.0;
    for (int tries = 0; tries < options.max_step_tries && !accepted; ++tries) {
      M = A;
      if (!gauss_newton) M.diagonal() += lambda * diag;
      M.diagonal() += 1e-14 * diag;
      delta = M.ldlt().solve(-g);
      x_try = (*x + alpha * delta).cwiseMax(lower).cwiseMin(upper);
      if (f(x_try, &ws->r_try, &ws->J_try)) {
        cost_try = ws->r_try.squaredNorm();
        if (cost_try <= cost) accepted = true;
      }
      if (!accepted) {
        if (gauss_newton) {
          alpha *= 0.5;
        } else {
          lambda *= options.lambda_increase;
        }
      }
    }
    if (!accepted) {
      // No descent direction left at machine precision: a minimum.
      converged = true;
      break;
    }
    const double decrease = (cost - cost_try) / std::max(cost, 1e-300);
    const double step =
        ((x_try - *x).cwiseAbs().array() / (x->cwiseAbs().array() + 1e-12))
            .maxCoeff();
    *x = x_try;
    std::swap(ws->r, ws->r_try);
    ws->J.swap(ws->J_try);
    cost = cost_try;
    lambda = std::max(lambda / options.lambda_decrease, 1e-12);
    if (decrease < options.cost_tolerance || step < options.step_tolerance)
      converged = true;
  }
  out.iterations = it;
  out.cost = cost;
  A.noalias() = ws->J.transpose() * ws->J;
  const Vec d =
      A.diagonal().cwiseMax(options.min_diagonal).cwiseSqrt().cwiseInverse();
  const Mat S = d.asDiagonal() * A * d.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Mat> es(S, Eigen::EigenvaluesOnly);
  const double ev_max = es.eigenvalues().maxCoeff();
  out.rcond =
      ev_max > 0 ? std::max(0.0, es.eigenvalues().minCoeff()) / ev_max : 0.0;
  if (out.rcond > options.min_rcond) {
    out.JtJ_inv =
        d.asDiagonal() * S.ldlt().solve(Mat::Identity(n, n)) * d.asDiagonal();
  } else {
    out.JtJ_inv = Mat::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
  }
  if (out.rcond <= options.min_rcond) {
    out.status = LeastSquaresStatus::kRankDeficient;
    out.why =
        "scaled J^T J is rank deficient (rcond = " + std::to_string(out.rcond) +
        " <= min_rcond = " + std::to_string(options.min_rcond) + ")";
  } else if (converged) {
    out.status = LeastSquaresStatus::kConverged;
  } else {
    out.status = LeastSquaresStatus::kMaxIterations;
    out.why = "max_iterations = " + std::to_string(options.max_iterations) +
              " reached";
  }
  return out;
}

}  // namespace frictiond
