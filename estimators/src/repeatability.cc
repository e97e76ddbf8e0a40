#include "frictiond/estimators/repeatability.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/least_squares.h"
#include "frictiond/estimators/number_text.h"

namespace frictiond {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Transform of joint i at coordinate q: Rz(theta) Tz(d) Tx(a) Rx(alpha).
Eigen::Isometry3d DhTransform(const DhJoint& j, double q) {
  const double theta = j.theta_rad + (j.type == JointType::kRevolute ? q : 0);
  const double d = j.d_mm + (j.type == JointType::kPrismatic ? q : 0);
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ca = std::cos(j.alpha_rad), sa = std::sin(j.alpha_rad);
  Eigen::Matrix4d m;
  m << ct, -st * ca, st * sa, j.a_mm * ct,  //
      st, ct * ca, -ct * sa, j.a_mm * st,   //
      0, sa, ca, d,                         //
      0, 0, 0, 1;
  Eigen::Isometry3d t;
  t.matrix() = m;
  return t;
}

// Tip position x(q) and the position Jacobian *J = dx/dq
// (3 x n: axis x (tip - origin) for revolute joints, the axis for
// prismatic ones), in one pass over the chain.
template <typename JacobianMatrix>
Eigen::Vector3d CalcTipAndJacobian(const SerialArm& arm,
                                   const Eigen::Ref<const Eigen::VectorXd>& q,
                                   JacobianMatrix* J) {
  const Eigen::Index n = q.size();
  std::vector<Eigen::Vector3d> origin(static_cast<std::size_t>(n)),
      axis(static_cast<std::size_t>(n));
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (Eigen::Index i = 0; i < n; ++i) {
    origin[static_cast<std::size_t>(i)] = t.translation();
    axis[static_cast<std::size_t>(i)] = t.linear().col(2);
    t = t * DhTransform(arm.joints[static_cast<std::size_t>(i)], q[i]);
  }
  const Eigen::Vector3d tip = t.translation();
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    J->col(i) = arm.joints[k].type == JointType::kRevolute
                    ? Eigen::Vector3d(axis[k].cross(tip - origin[k]))
                    : axis[k];
  }
  return tip;
}

void CheckSize(const SerialArm& arm, Eigen::Index n) {
  if (n != static_cast<Eigen::Index>(arm.joints.size()))
    throw std::invalid_argument("q has " + std::to_string(n) +
                                " entries, the arm has " +
                                std::to_string(arm.joints.size()) + " joints");
}

// Regularised lower incomplete gamma P(r/2, x/2) for r = 1, 2, 3.
double ChiSquareCdf(int r, double x) {
  if (x <= 0) return 0.0;
  switch (r) {
    case 1:
      return std::erf(std::sqrt(x / 2));
    case 2:
      return 1.0 - std::exp(-x / 2);
    default:
      return std::erf(std::sqrt(x / 2)) -
             std::sqrt(2 * x / kPi) * std::exp(-x / 2);
  }
}

// SolvePositionIk's solve with N parameters (N = q->size() or Dynamic):
// residual r(q) = x(q) - target, J = dx/dq. Returns the iterations.
template <int N>
int RunPositionIk(const SerialArm& arm,
                  const Eigen::Vector3d& target_mm,
                  const LeastSquaresOptions& options,
                  const Eigen::VectorXd& q_lo,
                  const Eigen::VectorXd& q_hi,
                  Eigen::VectorXd* q) {
  using Vec = Eigen::Matrix<double, N, 1>;
  auto residual = [&](const Vec& qq,
                      Eigen::VectorXd* r,
                      typename LeastSquaresWorkspace<N>::Jacobian* J) {
    *r = CalcTipAndJacobian(arm, qq, J) - target_mm;
    return r->allFinite() && J->allFinite();
  };
  Vec x = *q;
  const Vec lo = q_lo, hi = q_hi;
  LeastSquaresWorkspace<N> ws(3, q->size());
  const LeastSquaresSummary<N> s =
      SolveLeastSquares<N>(residual, &x, lo, hi, options, &ws);
  *q = x;
  return s.iterations;
}

}  // namespace

void ValidateArm(const SerialArm& arm) {
  if (arm.joints.empty() || arm.joints.size() > 32)
    throw FieldError("joints",
                     "joints has " + std::to_string(arm.joints.size()) +
                         " entries (must be 1..32)");
  for (std::size_t i = 0; i < arm.joints.size(); ++i) {
    const DhJoint& j = arm.joints[i];
    const std::string at = "joints[" + std::to_string(i) + "].";
    auto finite = [&](double x, const char* f) {
      if (!std::isfinite(x))
        throw FieldError(at + f,
                         at + f + " = " + NumberText(x) + " (must be finite)");
    };
    finite(j.a_mm, "a_mm");
    finite(j.alpha_rad, "alpha");
    finite(j.d_mm, "d_mm");
    finite(j.theta_rad, "theta");
    if (!(j.stiffness > 0 && std::isfinite(j.stiffness)))
      throw FieldError(
          at + "stiffness",
          at + "stiffness = " + NumberText(j.stiffness) + " (must be > 0)");
    if (!(j.sigma_tau >= 0 && std::isfinite(j.sigma_tau)))
      throw FieldError(
          at + "sigma_tau",
          at + "sigma_tau = " + NumberText(j.sigma_tau) + " (must be >= 0)");
    if (!(j.q_min <= j.q_max))
      throw FieldError(at + "q_min",
                       at + "q_min = " + NumberText(j.q_min) +
                           " (must be <= q_max = " + NumberText(j.q_max) + ")");
  }
}

Eigen::Vector3d CalcEndEffectorPosition(
    const SerialArm& arm, const Eigen::Ref<const Eigen::VectorXd>& q) {
  CheckSize(arm, q.size());
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < arm.joints.size(); ++i)
    t = t * DhTransform(arm.joints[i], q[static_cast<Eigen::Index>(i)]);
  return t.translation();
}

Eigen::Matrix<double, 3, Eigen::Dynamic> CalcPositionJacobian(
    const SerialArm& arm, const Eigen::Ref<const Eigen::VectorXd>& q) {
  CheckSize(arm, q.size());
  Eigen::Matrix<double, 3, Eigen::Dynamic> J(3, q.size());
  CalcTipAndJacobian(arm, q, &J);
  return J;
}

Eigen::Matrix3d CalcPositionCovariance(
    const SerialArm& arm, const Eigen::Ref<const Eigen::VectorXd>& q) {
  const Eigen::Matrix<double, 3, Eigen::Dynamic> J =
      CalcPositionJacobian(arm, q);
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < J.cols(); ++i) {
    const DhJoint& j = arm.joints[static_cast<std::size_t>(i)];
    const double sd_q = j.sigma_tau / j.stiffness;  // joint deflection sd
    P.noalias() += (sd_q * sd_q) * J.col(i) * J.col(i).transpose();
  }
  return P;
}

double CalcChiSquareQuantile(int r, double c) {
  if (r < 1 || r > 3)
    throw std::invalid_argument("r = " + std::to_string(r) + " (must be 1..3)");
  if (!(c > 0 && c < 1))
    throw std::invalid_argument("probability = " + NumberText(c) +
                                " (must be in (0, 1))");
  double lo = 0, hi = 1;
  while (ChiSquareCdf(r, hi) < c) hi *= 2;
  for (int i = 0; i < 200 && hi - lo > 1e-13 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (ChiSquareCdf(r, mid) < c ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Ellipsoid CalcRepeatabilityEllipsoid(const SerialArm& arm,
                                     const Eigen::Ref<const Eigen::VectorXd>& q,
                                     double probability) {
  if (!(probability > 0 && probability < 1))
    throw std::invalid_argument("probability = " + NumberText(probability) +
                                " (must be in (0, 1))");
  Ellipsoid e;
  e.P_x = CalcPositionCovariance(arm, q);
  e.probability = probability;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(e.P_x);
  const Eigen::Vector3d lam = es.eigenvalues().cwiseMax(0.0);
  const double lam_max = lam.maxCoeff();
  e.rank = 0;
  for (int i = 0; i < 3; ++i)
    if (lam_max > 0 && lam[i] > 1e-12 * lam_max) ++e.rank;
  e.axes = es.eigenvectors();
  e.chi2 = e.rank > 0 ? CalcChiSquareQuantile(e.rank, probability) : 0.0;
  for (int i = 0; i < 3; ++i)
    e.semi_axes_mm[i] =
        lam[i] > 1e-12 * lam_max ? std::sqrt(e.chi2 * lam[i]) : 0.0;
  return e;
}

IkResult SolvePositionIk(const SerialArm& arm,
                         const Eigen::Vector3d& target_mm,
                         const Eigen::Ref<const Eigen::VectorXd>& q_start,
                         double tolerance_mm,
                         int max_iterations) {
  CheckSize(arm, q_start.size());
  IkResult out;
  const Eigen::Index n = q_start.size();
  Eigen::VectorXd q = q_start;
  Eigen::VectorXd q_lo(n), q_hi(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    q_lo[i] = arm.joints[static_cast<std::size_t>(i)].q_min;
    q_hi[i] = arm.joints[static_cast<std::size_t>(i)].q_max;
  }
  q = q.cwiseMax(q_lo).cwiseMin(q_hi);
  // Damped least squares (Levenberg damping, least_squares.h): residual
  // r(q) = x(q) - target (3 entries), J = dx/dq; the step
  // (J^T J + mu I)^-1 J^T e = J^T (J J^T + mu I)^-1 e is the damped
  // least-norm step, mu = lambda trace(J^T J) / n, so lambda = lambda2 n / 3
  // with lambda2 the damping relative to trace(J J^T) / 3 (start 1e-4).
  // Steps are accepted when |e| falls; the solve stops once |e| <=
  // tolerance_mm, or when no damping finds descent.
  const double n3 = static_cast<double>(n) / 3.0;
  LeastSquaresOptions lm;
  lm.damping = LeastSquaresDamping::kLevenberg;
  lm.allow_underdetermined = true;
  lm.initial_lambda = 1e-4 * n3;
  lm.min_lambda = 1e-12 * n3;
  lm.min_diagonal = 1e-12 / n3;
  lm.max_step_tries = 20;  // from the lambda floor up to ~1e6 trace / 3
  lm.cost_tolerance = 0.0;
  lm.step_tolerance = 0.0;
  lm.strict_decrease = true;
  lm.compute_covariance = false;  // only q is wanted
  lm.target_cost = tolerance_mm > 0 && std::isfinite(tolerance_mm)
                       ? tolerance_mm * tolerance_mm
                       : 0.0;
  int it = 0;
  const bool in_limits =
      ((q.array() >= q_lo.array()) && (q.array() <= q_hi.array())).all();
  if (max_iterations > 0 && in_limits) {
    lm.max_iterations = max_iterations;
    // Fixed sizes for the common 3- and 6-joint arms (no heap in the loop).
    if (n == 3) {
      it = RunPositionIk<3>(arm, target_mm, lm, q_lo, q_hi, &q);
    } else if (n == 6) {
      it = RunPositionIk<6>(arm, target_mm, lm, q_lo, q_hi, &q);
    } else {
      it = RunPositionIk<Eigen::Dynamic>(arm, target_mm, lm, q_lo, q_hi, &q);
    }
  }
  const Eigen::Vector3d err = target_mm - CalcEndEffectorPosition(arm, q);
  out.q = q;
  out.error_mm = err.norm();
  out.iterations = it;
  out.converged = out.error_mm <= tolerance_mm;
  if (!out.converged)
    out.why = "target not reached (remaining error " +
              NumberText(out.error_mm) +
              " mm): outside the workspace or joint limits";
  return out;
}

double CalcMonteCarloContainment(const SerialArm& arm,
                                 const Eigen::Ref<const Eigen::VectorXd>& q,
                                 const Ellipsoid& e,
                                 int samples,
                                 std::mt19937_64* rng) {
  if (samples <= 0 || e.rank == 0) return 0.0;
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d x0 = CalcEndEffectorPosition(arm, q);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(e.P_x);
  const Eigen::Vector3d lam = es.eigenvalues();
  const double lam_max = lam.maxCoeff();
  Eigen::VectorXd dq(q.size());
  int inside = 0;
  for (int s = 0; s < samples; ++s) {
    for (Eigen::Index i = 0; i < q.size(); ++i) {
      const DhJoint& j = arm.joints[static_cast<std::size_t>(i)];
      dq[i] = normal(*rng) * j.sigma_tau / j.stiffness;
    }
    const Eigen::Vector3d dx = es.eigenvectors().transpose() *
                               (CalcEndEffectorPosition(arm, q + dq) - x0);
    double m2 = 0;
    for (int i = 0; i < 3; ++i)
      if (lam[i] > 1e-12 * lam_max) m2 += dx[i] * dx[i] / lam[i];
    if (m2 <= e.chi2) ++inside;
  }
  return static_cast<double>(inside) / samples;
}

std::vector<GridEllipsoid> CalcEllipsoidGrid(
    const SerialArm& arm,
    double x0_mm,
    double y0_mm,
    double size_x_mm,
    double size_y_mm,
    double z_mm,
    int nx,
    int ny,
    const Eigen::Ref<const Eigen::VectorXd>& q_start,
    double probability) {
  if (nx < 1 || ny < 1 || nx > 1000 || ny > 1000)
    throw std::invalid_argument("grid " + std::to_string(nx) + " x " +
                                std::to_string(ny) + " (must be 1..1000 each)");
  std::vector<GridEllipsoid> out(static_cast<std::size_t>(nx) *
                                 static_cast<std::size_t>(ny));
  Eigen::VectorXd q = q_start;
  const double dx = nx > 1 ? size_x_mm / (nx - 1) : 0.0;
  const double dy = ny > 1 ? size_y_mm / (ny - 1) : 0.0;
  for (int iy = 0; iy < ny; ++iy) {
    for (int k = 0; k < nx; ++k) {
      const int ix = (iy % 2 == 0) ? k : nx - 1 - k;  // serpentine
      GridEllipsoid& g =
          out[static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx) +
              static_cast<std::size_t>(ix)];
      g.target_mm = Eigen::Vector3d(x0_mm + dx * ix, y0_mm + dy * iy, z_mm);
      IkResult ik = SolvePositionIk(arm, g.target_mm, q);
      if (!ik.converged) ik = SolvePositionIk(arm, g.target_mm, q_start);
      g.reachable = ik.converged;
      if (!g.reachable) continue;
      q = ik.q;
      g.semi_axes_mm =
          CalcRepeatabilityEllipsoid(arm, q, probability).semi_axes_mm;
    }
  }
  return out;
}

}  // namespace frictiond
