#include "frictiond/estimators/lugre_identification.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <Eigen/Eigenvalues>

#include "frictiond/estimators/least_squares.h"

namespace frictiond {
namespace internal {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string Num(double x) {
  std::ostringstream os;
  os.precision(9);
  os << x;
  return os.str();
}

bool Fail(std::string* why,
          const std::string& field,
          double value,
          const char* rule) {
  if (why) *why = field + " = " + Num(value) + " (must be " + rule + ")";
  return false;
}

// Settings shared by the LM/GN fits.
struct SolverSettings {
  int max_iterations;
  double cost_tolerance;
  double initial_lambda;
  double min_rcond;
  bool gauss_newton;
};

template <int N>
struct SolverSummary {
  LuGreFitStatus status = LuGreFitStatus::kFailed;
  int iterations = 0;
  double cost = 0.0;
  double rcond = 0.0;
  Eigen::Matrix<double, N, N> P = Eigen::Matrix<double, N, N>::Zero();
  std::string why;
};

// Minimises |r(x)|^2 within [lower, upper] by SolveLeastSquares (LM with
// Marquardt scaling, paper eq. 14, or Gauss-Newton with step halving) and
// maps its outcome to a LuGre status and P = s^2 (J^T J)^-1 with
// s^2 = cost / (m - N).
template <int N, typename Eval>
SolverSummary<N> Solve(Eval&& eval,
                       Eigen::Matrix<double, N, 1>* x,
                       const Eigen::Matrix<double, N, 1>& lower,
                       const Eigen::Matrix<double, N, 1>& upper,
                       const SolverSettings& settings,
                       LeastSquaresWorkspace<N>* ws) {
  LeastSquaresOptions options;
  options.method = settings.gauss_newton
                       ? LeastSquaresMethod::kGaussNewton
                       : LeastSquaresMethod::kLevenbergMarquardt;
  options.max_iterations = settings.max_iterations;
  options.cost_tolerance = settings.cost_tolerance;
  options.initial_lambda = settings.initial_lambda;
  options.min_rcond = settings.min_rcond;
  const LeastSquaresSummary<N> s =
      SolveLeastSquares<N>(eval, x, lower, upper, options, ws);
  SolverSummary<N> out;
  out.iterations = s.iterations;
  out.cost = s.cost;
  out.rcond = s.rcond;
  out.why = s.why;
  const Eigen::Index m = ws->r.size();
  switch (s.status) {
    case LeastSquaresStatus::kNotEnoughData:
      out.status = LuGreFitStatus::kNotEnoughData;
      return out;
    case LeastSquaresStatus::kFailed:
      out.status = LuGreFitStatus::kFailed;
      return out;
    case LeastSquaresStatus::kRankDeficient:
      out.status = LuGreFitStatus::kNotObservable;
      out.why = "scaled J^T J is rank deficient (rcond = " + Num(s.rcond) +
                " <= min_rcond = " + Num(settings.min_rcond) + ")";
      break;
    case LeastSquaresStatus::kConverged:
      out.status = LuGreFitStatus::kConverged;
      break;
    case LeastSquaresStatus::kMaxIterations:
      out.status = LuGreFitStatus::kMaxIterations;
      break;
  }
  const double s2 = m > N ? s.cost / static_cast<double>(m - N) : kNaN;
  out.P = s2 * s.JtJ_inv;
  return out;
}

bool CheckFraction(std::string* why,
                   const char* field,
                   double value,
                   bool closed_low) {
  const bool ok = (closed_low ? value >= 0 : value > 0) && value < 1;
  if (!ok)
    return Fail(why, field, value, closed_low ? "in [0, 1)" : "in (0, 1)");
  return true;
}

}  // namespace
}  // namespace internal

using internal::Fail;
using internal::kNaN;
using internal::Num;

bool LuGreStroke::IsValid(std::string* why) const {
  if (v_mm_s.size() != t_s.size() || mu.size() != t_s.size()) {
    if (why) {
      *why = "stroke sizes differ: t_s " + std::to_string(t_s.size()) +
             ", v_mm_s " + std::to_string(v_mm_s.size()) + ", mu " +
             std::to_string(mu.size());
    }
    return false;
  }
  for (Eigen::Index k = 0; k < t_s.size(); ++k) {
    const std::string row = "[" + std::to_string(k) + "]";
    if (!std::isfinite(t_s[k]) || (k > 0 && !(t_s[k] > t_s[k - 1])))
      return Fail(why, "t_s" + row, t_s[k], "finite and > t_s[k-1]");
    if (!std::isfinite(v_mm_s[k]))
      return Fail(why, "v_mm_s" + row, v_mm_s[k], "finite");
    if (!std::isfinite(mu[k])) return Fail(why, "mu" + row, mu[k], "finite");
  }
  return true;
}

const char* ToString(LuGreFitStatus status) {
  switch (status) {
    case LuGreFitStatus::kConverged:
      return "converged";
    case LuGreFitStatus::kMaxIterations:
      return "max_iterations";
    case LuGreFitStatus::kNotObservable:
      return "not_observable";
    case LuGreFitStatus::kNotEnoughData:
      return "not_enough_data";
    case LuGreFitStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

namespace {

void ValidateStroke(const LuGreStroke& stroke) {
  std::string why;
  if (!stroke.IsValid(&why)) throw std::invalid_argument("stroke." + why);
}

template <int N>
bool CheckBounds(std::string* why,
                 const Eigen::Matrix<double, N, 1>& lower,
                 const Eigen::Matrix<double, N, 1>& upper) {
  for (int i = 0; i < N; ++i) {
    if (!std::isfinite(lower[i]) || !std::isfinite(upper[i]) ||
        !(lower[i] < upper[i])) {
      return Fail(why,
                  "lower_bounds[" + std::to_string(i) + "]",
                  lower[i],
                  ("finite and < upper_bounds[i] = " + Num(upper[i])).c_str());
    }
  }
  return true;
}

}  // namespace

bool QuasiStaticFitOptions::IsValid(std::string* why) const {
  if (!internal::CheckFraction(
          why, "min_speed_fraction", min_speed_fraction, true))
    return false;
  if (!(num_speed_bins >= 0))
    return Fail(why, "num_speed_bins", num_speed_bins, ">= 0");
  if (!(max_iterations > 0))
    return Fail(why, "max_iterations", max_iterations, "> 0");
  if (!internal::CheckFraction(why, "cost_tolerance", cost_tolerance, false))
    return false;
  if (!(initial_lambda > 0) || !std::isfinite(initial_lambda))
    return Fail(why, "initial_lambda", initial_lambda, "finite and > 0");
  if (!internal::CheckFraction(why, "min_rcond", min_rcond, true)) return false;
  return CheckBounds<4>(why, lower_bounds, upper_bounds);
}

LuGreFitResult FitLuGreQuasiStatic(const LuGreStroke& stroke,
                                   const Eigen::Vector4d& initial_guess,
                                   const QuasiStaticFitOptions& options) {
  ValidateStroke(stroke);
  std::string why;
  if (!options.IsValid(&why))
    throw std::invalid_argument("QuasiStaticFitOptions." + why);
  for (int i = 0; i < 4; ++i) {
    if (!(initial_guess[i] >= options.lower_bounds[i] &&
          initial_guess[i] <= options.upper_bounds[i])) {
      throw std::invalid_argument("initial_guess[" + std::to_string(i) +
                                  "] = " + Num(initial_guess[i]) +
                                  " (must be within [" +
                                  Num(options.lower_bounds[i]) + ", " +
                                  Num(options.upper_bounds[i]) + "])");
    }
  }
  LuGreFitResult result;
  result.theta << initial_guess, kNaN, kNaN;
  result.z0_mm = kNaN;
  result.z0_std_mm = kNaN;

  // Fold onto |v| (the model is odd in v) and drop the slowest samples.
  const Eigen::Index n = stroke.size();
  const double v_max = n > 0 ? stroke.v_mm_s.cwiseAbs().maxCoeff() : 0.0;
  const double v_min = options.min_speed_fraction * v_max;
  Eigen::Index used = 0;
  for (Eigen::Index k = 0; k < n; ++k)
    used += std::abs(stroke.v_mm_s[k]) > v_min ? 1 : 0;
  Eigen::VectorXd speed(used);
  Eigen::VectorXd ratio(used);
  Eigen::VectorXd weight(used);
  {
    Eigen::Index j = 0;
    for (Eigen::Index k = 0; k < n; ++k) {
      const double v = stroke.v_mm_s[k];
      if (std::abs(v) > v_min) {
        speed[j] = std::abs(v);
        ratio[j] = v > 0 ? stroke.mu[k] : -stroke.mu[k];
        weight[j] = 1.0;
        ++j;
      }
    }
  }
  if (options.num_speed_bins > 0 && used > 0) {
    // Average increasing and decreasing branches in equal-width speed bins;
    // weights sqrt(count) keep the cost equal to the per-sample one.
    const int nb = options.num_speed_bins;
    Eigen::VectorXd sum_v = Eigen::VectorXd::Zero(nb);
    Eigen::VectorXd sum_mu = Eigen::VectorXd::Zero(nb);
    Eigen::VectorXd count = Eigen::VectorXd::Zero(nb);
    const double width = (v_max - v_min) / nb;
    for (Eigen::Index j = 0; j < used; ++j) {
      const int b =
          std::clamp(static_cast<int>((speed[j] - v_min) / width), 0, nb - 1);
      sum_v[b] += speed[j];
      sum_mu[b] += ratio[j];
      count[b] += 1.0;
    }
    const Eigen::Index filled = (count.array() > 0).count();
    speed.resize(filled);
    ratio.resize(filled);
    weight.resize(filled);
    Eigen::Index j = 0;
    for (int b = 0; b < nb; ++b) {
      if (count[b] > 0) {
        speed[j] = sum_v[b] / count[b];
        ratio[j] = sum_mu[b] / count[b];
        weight[j] = std::sqrt(count[b]);
        ++j;
      }
    }
  }
  const Eigen::Index m = speed.size();
  LuGreTheta theta = LuGreTheta::Zero();
  auto eval = [&](const Eigen::Vector4d& p,
                  Eigen::VectorXd* r,
                  Eigen::Matrix<double, Eigen::Dynamic, 4>* J) {
    theta.head<4>() = p;
    LuGreThetaRow J_mu_theta;
    for (Eigen::Index i = 0; i < m; ++i) {
      const double mu =
          CalcSteadyStateFrictionRatio(theta, speed[i], &J_mu_theta);
      (*r)[i] = weight[i] * (mu - ratio[i]);
      J->row(i) = weight[i] * J_mu_theta.head<4>();
    }
    return r->allFinite() && J->allFinite();
  };
  LeastSquaresWorkspace<4> ws(m);
  Eigen::Vector4d p = initial_guess;
  const internal::SolverSettings settings{
      options.max_iterations,
      options.cost_tolerance,
      options.initial_lambda,
      options.min_rcond,
      options.solver == QuasiStaticSolver::kGaussNewton};
  const internal::SolverSummary<4> s = internal::Solve<4>(
      eval, &p, options.lower_bounds, options.upper_bounds, settings, &ws);
  result.status = s.status;
  result.why = s.why;
  result.iterations = s.iterations;
  result.rcond = s.rcond;
  result.theta.head<4>() = p;
  result.P_theta.topLeftCorner<4, 4>() = s.P;
  // Per-sample RMS over the used samples.
  theta.head<4>() = p;
  double sse = 0;
  Eigen::Index cnt = 0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double v = stroke.v_mm_s[k];
    if (std::abs(v) > v_min) {
      const double e = CalcSteadyStateFrictionRatio(theta, v) - stroke.mu[k];
      sse += e * e;
      ++cnt;
    }
  }
  result.residual_rms = cnt > 0 ? std::sqrt(sse / cnt) : kNaN;
  return result;
}

bool DynamicFitOptions::IsValid(std::string* why) const {
  if (!(damping_gain > 0) || !std::isfinite(damping_gain))
    return Fail(why, "damping_gain", damping_gain, "finite and > 0");
  if (!(max_iterations > 0))
    return Fail(why, "max_iterations", max_iterations, "> 0");
  if (!internal::CheckFraction(why, "cost_tolerance", cost_tolerance, false))
    return false;
  if (!(initial_lambda > 0) || !std::isfinite(initial_lambda))
    return Fail(why, "initial_lambda", initial_lambda, "finite and > 0");
  if (!internal::CheckFraction(
          why, "excitation_fraction", excitation_fraction, false))
    return false;
  if (!(min_excited_samples >= 1))
    return Fail(why, "min_excited_samples", min_excited_samples, ">= 1");
  if (!internal::CheckFraction(why, "min_rcond", min_rcond, true)) return false;
  return CheckBounds<7>(why, lower_bounds, upper_bounds);
}

void CalcLuGreDiscreteResponse(const LuGreTheta& theta,
                               double z0_mm,
                               const Eigen::Ref<const Eigen::VectorXd>& t_s,
                               const Eigen::Ref<const Eigen::VectorXd>& v_mm_s,
                               Eigen::VectorXd* mu,
                               Eigen::Matrix<double, Eigen::Dynamic, 7>* J_mu_x,
                               Eigen::VectorXd* z_mm) {
  ValidateLuGreTheta(theta);
  if (t_s.size() != v_mm_s.size()) {
    throw std::invalid_argument(
        "v_mm_s.size() = " + std::to_string(v_mm_s.size()) +
        " (must equal t_s.size() = " + std::to_string(t_s.size()) + ")");
  }
  const Eigen::Index n = t_s.size();
  if (mu && mu->size() != n) mu->resize(n);
  if (J_mu_x && J_mu_x->rows() != n) J_mu_x->resize(n, 7);
  if (z_mm && z_mm->size() != n) z_mm->resize(n);
  double z = z0_mm;
  Eigen::Matrix<double, 1, 7> J_z_x = Eigen::Matrix<double, 1, 7>::Zero();
  J_z_x[6] = 1.0;
  LuGreThetaRow J_step_theta;
  LuGreThetaRow J_mu_theta;
  for (Eigen::Index k = 0; k < n; ++k) {
    if (k > 0) {
      const double dt = t_s[k] - t_s[k - 1];
      const double v_mid = 0.5 * (v_mm_s[k - 1] + v_mm_s[k]);
      double J_step_z = 1.0;
      z = CalcBristleStep(
          theta, v_mid, dt, z, &J_step_z, J_mu_x ? &J_step_theta : nullptr);
      if (J_mu_x) {
        J_z_x *= J_step_z;
        J_z_x.head<6>() += J_step_theta;
      }
    }
    double J_mu_z = 0.0;
    const double m = CalcFrictionRatio(
        theta, v_mm_s[k], z, &J_mu_z, J_mu_x ? &J_mu_theta : nullptr);
    if (mu) (*mu)[k] = m;
    if (z_mm) (*z_mm)[k] = z;
    if (J_mu_x) {
      J_mu_x->row(k) = J_mu_z * J_z_x;
      J_mu_x->row(k).head<6>() += J_mu_theta;
    }
  }
}

int CountExcitedSamples(const LuGreTheta& theta,
                        double z0_mm,
                        const Eigen::Ref<const Eigen::VectorXd>& t_s,
                        const Eigen::Ref<const Eigen::VectorXd>& v_mm_s,
                        double excitation_fraction) {
  Eigen::VectorXd z;
  CalcLuGreDiscreteResponse(theta, z0_mm, t_s, v_mm_s, nullptr, nullptr, &z);
  const double v_max = v_mm_s.size() > 0 ? v_mm_s.cwiseAbs().maxCoeff() : 0.0;
  const double threshold = excitation_fraction * v_max;
  int count = 0;
  for (Eigen::Index k = 0; k < z.size(); ++k) {
    if (std::abs(CalcBristleRate(theta, v_mm_s[k], z[k])) > threshold) ++count;
  }
  return count;
}

namespace {

// Free parameters of one variant: x (N entries) <-> [theta, z0] (7 entries).
template <int N>
struct VariantMap {
  DynamicFitVariant variant;
  double gain;

  // Writes theta and z0 from x; the fixed entries of theta are left alone.
  void ToFull(const Eigen::Matrix<double, N, 1>& x,
              LuGreTheta* theta,
              double* z0) const {
    if constexpr (N == 2) {
      (*theta)[4] = x[0];
      (*theta)[5] = gain * std::sqrt(std::max(x[0], 0.0));
      *z0 = x[1];
    } else if constexpr (N == 3) {
      (*theta)[4] = x[0];
      (*theta)[5] = x[1];
      *z0 = x[2];
    } else {
      theta->head<6>() = x.template head<6>();
      *z0 = x[6];
    }
  }
  Eigen::Matrix<double, N, 1> FromFull(const LuGreTheta& theta,
                                       double z0) const {
    Eigen::Matrix<double, N, 1> x;
    if constexpr (N == 2) {
      x << theta[4], z0;
    } else if constexpr (N == 3) {
      x << theta[4], theta[5], z0;
    } else {
      x << theta, z0;
    }
    return x;
  }
  // d[theta, z0]/dx, 7 x N.
  Eigen::Matrix<double, 7, N> Chain(
      const Eigen::Matrix<double, N, 1>& x) const {
    Eigen::Matrix<double, 7, N> M = Eigen::Matrix<double, 7, N>::Zero();
    if constexpr (N == 2) {
      M(4, 0) = 1.0;
      M(5, 0) = gain / (2.0 * std::sqrt(std::max(x[0], 1e-300)));
      M(6, 1) = 1.0;
    } else if constexpr (N == 3) {
      M(4, 0) = 1.0;
      M(5, 1) = 1.0;
      M(6, 2) = 1.0;
    } else {
      M.setIdentity();
    }
    return M;
  }
  // Indices of x within [theta, z0].
  static int FullIndex(int i) {
    if constexpr (N == 2) {
      return i == 0 ? 4 : 6;
    } else if constexpr (N == 3) {
      return i + 4;
    } else {
      return i;
    }
  }
};

template <int N>
LuGreFitResult RunDynamicFit(const LuGreStroke& stroke,
                             const LuGreTheta& initial_theta,
                             double z0_guess_mm,
                             const DynamicFitOptions& options) {
  const VariantMap<N> map{options.variant, options.damping_gain};
  Eigen::Matrix<double, N, 1> lower, upper;
  for (int i = 0; i < N; ++i) {
    lower[i] = options.lower_bounds[VariantMap<N>::FullIndex(i)];
    upper[i] = options.upper_bounds[VariantMap<N>::FullIndex(i)];
  }
  Eigen::Matrix<double, N, 1> x = map.FromFull(initial_theta, z0_guess_mm);
  for (int i = 0; i < N; ++i) {
    if (!(x[i] >= lower[i] && x[i] <= upper[i])) {
      const int f = VariantMap<N>::FullIndex(i);
      throw std::invalid_argument(
          std::string(f == 6 ? "z0_guess_mm" : "initial_theta[") +
          (f == 6 ? "" : std::to_string(f) + "]") + " = " + Num(x[i]) +
          " (must be within [" + Num(lower[i]) + ", " + Num(upper[i]) + "])");
    }
  }
  const Eigen::Index n = stroke.size();
  LuGreTheta theta = initial_theta;
  double z0 = z0_guess_mm;
  Eigen::VectorXd mu_model(n);
  Eigen::Matrix<double, Eigen::Dynamic, 7> J_full(n, 7);
  auto eval = [&](const Eigen::Matrix<double, N, 1>& xx,
                  Eigen::VectorXd* r,
                  Eigen::Matrix<double, Eigen::Dynamic, N>* J) {
    map.ToFull(xx, &theta, &z0);
    if (!IsValidLuGreTheta(theta)) return false;
    CalcLuGreDiscreteResponse(
        theta, z0, stroke.t_s, stroke.v_mm_s, &mu_model, &J_full);
    r->noalias() = mu_model - stroke.mu;
    J->noalias() = J_full * map.Chain(xx);
    return r->allFinite() && J->allFinite();
  };
  LeastSquaresWorkspace<N> ws(n);
  const internal::SolverSettings settings{options.max_iterations,
                                          options.cost_tolerance,
                                          options.initial_lambda,
                                          options.min_rcond,
                                          false};
  const internal::SolverSummary<N> s =
      internal::Solve<N>(eval, &x, lower, upper, settings, &ws);

  LuGreFitResult result;
  result.theta = initial_theta;
  map.ToFull(x, &result.theta, &result.z0_mm);
  result.status = s.status;
  result.why = s.why;
  result.iterations = s.iterations;
  result.rcond = s.rcond;
  result.residual_rms = n > 0 ? std::sqrt(s.cost / n) : kNaN;
  // P of [theta, z0] = M P_x M^T.
  const Eigen::Matrix<double, 7, N> M = map.Chain(x);
  const Eigen::Matrix<double, 7, 7> P_full = M * s.P * M.transpose();
  result.P_theta = P_full.topLeftCorner<6, 6>();
  result.z0_std_mm = std::sqrt(P_full(6, 6));
  if (IsValidLuGreTheta(result.theta)) {
    result.excited_samples = CountExcitedSamples(result.theta,
                                                 result.z0_mm,
                                                 stroke.t_s,
                                                 stroke.v_mm_s,
                                                 options.excitation_fraction);
  }
  if (result.status == LuGreFitStatus::kConverged &&
      result.excited_samples < options.min_excited_samples) {
    result.status = LuGreFitStatus::kNotObservable;
    result.why = "only " + std::to_string(result.excited_samples) +
                 " samples with |dz/dt| > " + Num(options.excitation_fraction) +
                 " * max|v| (min_excited_samples = " +
                 std::to_string(options.min_excited_samples) +
                 "): sigma0, sigma1 are not observable from this stroke";
  }
  return result;
}

}  // namespace

LuGreFitResult FitLuGreDynamic(const LuGreStroke& stroke,
                               const LuGreTheta& initial_theta,
                               double z0_guess_mm,
                               const DynamicFitOptions& options) {
  ValidateStroke(stroke);
  std::string why;
  if (!options.IsValid(&why))
    throw std::invalid_argument("DynamicFitOptions." + why);
  LuGreTheta theta = initial_theta;
  if (options.variant == DynamicFitVariant::kLm1 && theta[4] > 0)
    theta[5] = options.damping_gain * std::sqrt(theta[4]);
  if (!IsValidLuGreTheta(theta, &why))
    throw std::invalid_argument("initial_" + why);
  if (!std::isfinite(z0_guess_mm))
    throw std::invalid_argument("z0_guess_mm = " + Num(z0_guess_mm) +
                                " (must be finite)");
  switch (options.variant) {
    case DynamicFitVariant::kLm1:
      return RunDynamicFit<2>(stroke, theta, z0_guess_mm, options);
    case DynamicFitVariant::kLm2:
      return RunDynamicFit<3>(stroke, theta, z0_guess_mm, options);
    case DynamicFitVariant::kLm6:
      return RunDynamicFit<7>(stroke, theta, z0_guess_mm, options);
  }
  throw std::invalid_argument(
      "DynamicFitOptions.variant = " +
      std::to_string(static_cast<int>(options.variant)) +
      " (must be kLm1, kLm2 or kLm6)");
}

bool LuGreEkfOptions::IsValid(std::string* why) const {
  if (!(damping_gain > 0) || !std::isfinite(damping_gain))
    return Fail(why, "damping_gain", damping_gain, "finite and > 0");
  if (!(x0[0] > 0) || !std::isfinite(x0[0]))
    return Fail(why, "x0[0] (sigma0)", x0[0], "finite and > 0");
  if (!std::isfinite(x0[1])) return Fail(why, "x0[1] (z)", x0[1], "finite");
  if (!P0.allFinite() || !(P0(0, 1) == P0(1, 0)) || !(P0(0, 0) > 0) ||
      !(P0.determinant() > 0))
    return Fail(why,
                "P0(0, 0)",
                P0(0, 0),
                "part of a finite symmetric positive definite matrix");
  if (!Q.allFinite() || !(Q(0, 1) == Q(1, 0)) || !(Q(0, 0) >= 0) ||
      !(Q(1, 1) >= 0) || !(Q.determinant() >= 0))
    return Fail(why,
                "Q(0, 0)",
                Q(0, 0),
                "part of a finite symmetric positive semi-definite matrix");
  if (!(R > 0) || !std::isfinite(R)) return Fail(why, "R", R, "finite and > 0");
  if (!(min_sigma0 > 0) || !std::isfinite(min_sigma0))
    return Fail(why, "min_sigma0", min_sigma0, "finite and > 0");
  if (!internal::CheckFraction(
          why, "excitation_fraction", excitation_fraction, false))
    return false;
  if (!(min_excited_samples >= 1))
    return Fail(why, "min_excited_samples", min_excited_samples, ">= 1");
  if (!(max_relative_std > 0 && max_relative_std <= 1))
    return Fail(why, "max_relative_std", max_relative_std, "in (0, 1]");
  return true;
}

LuGreStiffnessEkf::LuGreStiffnessEkf(const LuGreTheta& theta,
                                     const LuGreEkfOptions& options)
    : theta_work_(theta),
      damping_gain_(options.damping_gain),
      R_(options.R),
      min_sigma0_(options.min_sigma0),
      Q_(options.Q),
      x_(options.x0),
      P_(options.P0) {
  std::string why;
  if (!options.IsValid(&why))
    throw std::invalid_argument("LuGreEkfOptions." + why);
  theta_work_[LuGreIndex::kStiffness] = options.x0[0];
  theta_work_[LuGreIndex::kDamping] = damping_gain_ * std::sqrt(options.x0[0]);
  if (!IsValidLuGreTheta(theta_work_, &why)) throw std::invalid_argument(why);
  Phi_.setIdentity();
  PPhiT_.setZero();
  IKH_.setIdentity();
  H_.setZero();
  PHt_.setZero();
  K_.setZero();
}

LuGreFitResult FitLuGreEkf(const LuGreStroke& stroke,
                           const LuGreTheta& quasi_static_theta,
                           const LuGreEkfOptions& options) {
  ValidateStroke(stroke);
  LuGreStiffnessEkf ekf(quasi_static_theta, options);
  const Eigen::Index n = stroke.size();
  double sse = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    if (k > 0) {
      ekf.Predict(stroke.t_s[k] - stroke.t_s[k - 1],
                  0.5 * (stroke.v_mm_s[k - 1] + stroke.v_mm_s[k]));
    }
    const double innovation = ekf.Update(stroke.v_mm_s[k], stroke.mu[k]);
    sse += innovation * innovation;
  }
  LuGreFitResult result;
  result.iterations = static_cast<int>(n);
  result.rcond = 1.0;
  result.theta = quasi_static_theta;
  const double sigma0 = ekf.state()[0];
  result.theta[LuGreIndex::kStiffness] = sigma0;
  result.theta[LuGreIndex::kDamping] = ekf.sigma1();
  const double J_s1_s0 = options.damping_gain / (2.0 * std::sqrt(sigma0));
  const double var0 = ekf.P_x()(0, 0);
  result.P_theta(4, 4) = var0;
  result.P_theta(4, 5) = result.P_theta(5, 4) = J_s1_s0 * var0;
  result.P_theta(5, 5) = J_s1_s0 * J_s1_s0 * var0;
  result.z0_mm = ekf.state()[1];
  result.z0_std_mm = std::sqrt(ekf.P_x()(1, 1));
  result.residual_rms = n > 0 ? std::sqrt(sse / n) : kNaN;
  if (!ekf.state().allFinite() || !ekf.P_x().allFinite()) {
    result.status = LuGreFitStatus::kFailed;
    result.why = "EKF state or covariance became non-finite";
    return result;
  }
  // Observability along the filtered trajectory (z0 taken as the filter's
  // initial z).
  result.excited_samples = CountExcitedSamples(result.theta,
                                               options.x0[1],
                                               stroke.t_s,
                                               stroke.v_mm_s,
                                               options.excitation_fraction);
  const double rel_std = std::sqrt(var0) / sigma0;
  if (result.excited_samples < options.min_excited_samples) {
    result.status = LuGreFitStatus::kNotObservable;
    result.why = "only " + std::to_string(result.excited_samples) +
                 " samples with |dz/dt| > " + Num(options.excitation_fraction) +
                 " * max|v| (min_excited_samples = " +
                 std::to_string(options.min_excited_samples) + ")";
  } else if (!(rel_std <= options.max_relative_std)) {
    result.status = LuGreFitStatus::kNotObservable;
    result.why = "std(sigma0) / sigma0 = " + Num(rel_std) +
                 " > max_relative_std = " + Num(options.max_relative_std);
  } else {
    result.status = LuGreFitStatus::kConverged;
  }
  return result;
}

}  // namespace frictiond
