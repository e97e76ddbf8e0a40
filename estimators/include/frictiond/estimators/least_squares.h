#pragma once
/// @file
/// The one small nonlinear least-squares solver of the estimators: bounded
/// Levenberg-Marquardt with Marquardt scaling, or Gauss-Newton with step
/// halving, for problems with few parameters (fixed N, or Eigen::Dynamic)
/// and many residuals. It serves the LuGre fits (paper 001 eq. 14, both
/// steps), the joint-friction fits (paper 002) and the reciprocal form of
/// mu = f(Fn) (paper 000 Table II), and through the extensions below the
/// actuator identification (smoothed-L1 rollout residuals, issue 20) and
/// the position inverse kinematics of the repeatability ellipsoids (paper
/// 002, Section 6). In the spirit of Ceres' tiny_solver.h: this header is
/// the manual.
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
///
/// Extensions (all off by default, so the above is exactly the default
/// behaviour):
/// - options.damping = kLevenberg damps with lambda * (trace(A) / n) * I
///   instead of lambda * D (the damped least-norm step of inverse
///   kinematics: (A + mu I)^-1 J^T = J^T (J J^T + mu I)^-1);
///   options.allow_underdetermined lets m < n (LM only: the damping makes
///   the system solvable); options.target_cost stops as soon as
///   C(x) <= target_cost; options.min_lambda floors lambda; and
///   options.strict_decrease accepts a trial only when C(trial) < C(x);
///   options.compute_covariance = false skips the final rcond/JtJ_inv.
/// - The split overload SolveLeastSquares(residual, jacobian, x, ...) is
///   for problems whose Jacobian is dear (finite differences over a
///   simulation) or whose steps are judged by a criterion other than
///   |r|^2: trials evaluate only residual(x, &r, &cost), which fills r and
///   the cost C compared for acceptance (|r|^2 for plain least squares;
///   e.g. a mean absolute error for smoothed-L1 residuals), and
///   jacobian(x, r, &J) runs once per accepted point. The steps still come
///   from r and J (Gauss-Newton model of |r|^2); summary.cost and
///   initial_cost are then that criterion.

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

/// Damping of the LM normal equations.
enum class LeastSquaresDamping {
  kMarquardt,  ///< lambda * diag(J^T J) (floored): scale invariant
  kLevenberg,  ///< lambda * (trace(J^T J) / n) * I: least-norm steps
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
  /// LM damping matrix (see LeastSquaresDamping).
  LeastSquaresDamping damping = LeastSquaresDamping::kMarquardt;
  /// Floor of lambda after an accepted step, > 0 and <= initial_lambda.
  double min_lambda = 1e-12;
  /// Converged as soon as the cost is at or below this, >= 0 (0: off).
  double target_cost = 0.0;
  /// Accept a trial only when it lowers the cost strictly (default: or
  /// keeps it equal).
  bool strict_decrease = false;
  /// Allow fewer residuals than parameters (LM only); the final rcond is
  /// then 0 and the status kRankDeficient unless target_cost was reached,
  /// which counts as kConverged.
  bool allow_underdetermined = false;
  /// After the loop, compute rcond and JtJ_inv (and report kRankDeficient);
  /// false skips that work for callers that need only x (rcond is then
  /// NaN, JtJ_inv not set, and the status never kRankDeficient).
  bool compute_covariance = true;

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
    if (!(min_lambda > 0 && min_lambda <= initial_lambda))
      return fail("min_lambda", min_lambda, "> 0 and <= initial_lambda");
    if (!(target_cost >= 0) || !std::isfinite(target_cost))
      return fail("target_cost", target_cost, "finite and >= 0");
    if (allow_underdetermined && method == LeastSquaresMethod::kGaussNewton)
      return fail("allow_underdetermined", 1.0, "false for Gauss-Newton");
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

namespace internal {

// The iteration of the file comment, shared by both overloads. `trial`
// evaluates r (and J when `eager_jacobian`) and the cost at a point into
// the trial buffers; `jacobian` fills ws->J at an accepted x from ws->r
// (called only when !eager_jacobian).
template <int N, bool eager_jacobian, typename Trial, typename Jacobian>
LeastSquaresSummary<N> RunLeastSquares(Trial&& trial,
                                       Jacobian&& jacobian,
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
  if (m < n && !options.allow_underdetermined) {
    out.status = LeastSquaresStatus::kNotEnoughData;
    out.why = std::to_string(m) + " residuals for " + std::to_string(n) +
              " parameters";
    return out;
  }
  double cost = 0.0;
  if (!trial(*x, &ws->r, &ws->J, &cost) ||
      (!eager_jacobian && !jacobian(*x, ws->r, &ws->J))) {
    out.status = LeastSquaresStatus::kFailed;
    out.why = "model not finite at the initial guess";
    return out;
  }
  const bool gauss_newton = options.method == LeastSquaresMethod::kGaussNewton;
  const bool levenberg = options.damping == LeastSquaresDamping::kLevenberg;
  const bool use_target = options.target_cost > 0;
  out.initial_cost = cost;
  double lambda = options.initial_lambda;
  Mat A(n, n), M(n, n);
  Vec g(n), delta(n), x_try(n), diag(n);
  bool converged = false;
  bool reached_target = use_target && cost <= options.target_cost;
  int it = 0;
  for (; it < options.max_iterations && !converged && !reached_target; ++it) {
    A.noalias() = ws->J.transpose() * ws->J;
    g.noalias() = ws->J.transpose() * ws->r;
    if (levenberg) {
      diag.setConstant(
          std::max(A.trace() / static_cast<double>(n), options.min_diagonal));
    } else {
      diag = A.diagonal().cwiseMax(options.min_diagonal);
    }
    bool accepted = false;
    double cost_try = cost;
    double alpha = 1.0;
    for (int tries = 0; tries < options.max_step_tries && !accepted; ++tries) {
      M = A;
      if (!gauss_newton) M.diagonal() += lambda * diag;
      M.diagonal() += 1e-14 * diag;
      delta = M.ldlt().solve(-g);
      x_try = (*x + alpha * delta).cwiseMax(lower).cwiseMin(upper);
      if (x_try.allFinite() && trial(x_try, &ws->r_try, &ws->J_try, &cost_try))
        accepted = options.strict_decrease ? cost_try < cost : cost_try <= cost;
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
    if (eager_jacobian) {
      ws->J.swap(ws->J_try);
    } else if (!jacobian(*x, ws->r, &ws->J)) {
      out.status = LeastSquaresStatus::kFailed;
      out.iterations = it + 1;
      out.cost = cost_try;
      out.why = "Jacobian not finite at an accepted point";
      return out;
    }
    cost = cost_try;
    lambda = std::max(lambda / options.lambda_decrease, options.min_lambda);
    if (decrease < options.cost_tolerance || step < options.step_tolerance)
      converged = true;
    if (use_target && cost <= options.target_cost) reached_target = true;
  }
  out.iterations = it;
  out.cost = cost;
  if (!options.compute_covariance) {
    out.rcond = std::numeric_limits<double>::quiet_NaN();
    if (reached_target || converged) {
      out.status = LeastSquaresStatus::kConverged;
    } else {
      out.status = LeastSquaresStatus::kMaxIterations;
      out.why = "max_iterations = " + std::to_string(options.max_iterations) +
                " reached";
    }
    return out;
  }
  A.noalias() = ws->J.transpose() * ws->J;
  const Vec d =
      A.diagonal().cwiseMax(options.min_diagonal).cwiseSqrt().cwiseInverse();
  const Mat S = d.asDiagonal() * A * d.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Mat> es(S, Eigen::EigenvaluesOnly);
  const double ev_max = es.eigenvalues().maxCoeff();
  out.rcond =
      ev_max > 0 ? std::max(0.0, es.eigenvalues().minCoeff()) / ev_max : 0.0;
  if (m < n) out.rcond = 0.0;  // underdetermined: J^T J is singular
  if (out.rcond > options.min_rcond) {
    out.JtJ_inv =
        d.asDiagonal() * S.ldlt().solve(Mat::Identity(n, n)) * d.asDiagonal();
  } else {
    out.JtJ_inv = Mat::Constant(n, n, std::numeric_limits<double>::quiet_NaN());
  }
  if (reached_target) {
    out.status = LeastSquaresStatus::kConverged;
  } else if (out.rcond <= options.min_rcond) {
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

}  // namespace internal

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
  using Jac = typename LeastSquaresWorkspace<N>::Jacobian;
  auto trial = [&f](const Eigen::Matrix<double, N, 1>& at,
                    Eigen::VectorXd* r,
                    Jac* J,
                    double* cost) {
    if (!f(at, r, J)) return false;
    *cost = r->squaredNorm();
    return true;
  };
  auto no_jacobian = [](const Eigen::Matrix<double, N, 1>&,
                        const Eigen::VectorXd&,
                        Jac*) { return true; };
  return internal::RunLeastSquares<N, /*eager_jacobian=*/true>(
      trial, no_jacobian, x, lower, upper, options, ws);
}

/// The split form (file comment, "Extensions"): minimises the cost that
/// `residual` reports, with Gauss-Newton/LM steps from r and J.
/// @param residual  bool(const VecN& x, VectorXd* r, double* cost): fills
///                  r (m entries) and the cost at x (finite); false when
///                  either is not finite (the trial is rejected)
/// @param jacobian  bool(const VecN& x, const VectorXd& r, Matrix<-1,N>* J):
///                  fills J = dr/dx at x, given r = r(x) (e.g. forward
///                  differences need it); called at the start and once per
///                  accepted step; false when J is not finite (the solver
///                  then stops with kFailed at that x)
/// Everything else as the functor form (ws->J_try is unused).
template <int N, typename Residual, typename JacobianFn>
LeastSquaresSummary<N> SolveLeastSquares(
    Residual&& residual,
    JacobianFn&& jacobian,
    Eigen::Matrix<double, N, 1>* x,
    const Eigen::Matrix<double, N, 1>& lower,
    const Eigen::Matrix<double, N, 1>& upper,
    const LeastSquaresOptions& options,
    LeastSquaresWorkspace<N>* ws) {
  using Jac = typename LeastSquaresWorkspace<N>::Jacobian;
  auto trial = [&residual](const Eigen::Matrix<double, N, 1>& at,
                           Eigen::VectorXd* r,
                           Jac*,
                           double* cost) {
    return residual(at, r, cost) && std::isfinite(*cost);
  };
  return internal::RunLeastSquares<N, /*eager_jacobian=*/false>(
      trial, jacobian, x, lower, upper, options, ws);
}

}  // namespace frictiond
