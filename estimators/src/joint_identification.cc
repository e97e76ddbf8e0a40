#include "frictiond/estimators/joint_identification.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/least_squares.h"
#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/number_text.h"

namespace frictiond {

namespace {

double Quantile(std::vector<double> x, double q) {
  if (x.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t k = static_cast<std::size_t>(q * (x.size() - 1));
  std::nth_element(
      x.begin(), x.begin() + static_cast<std::ptrdiff_t>(k), x.end());
  return x[k];
}

// Box bounds of each model's parameters.
void Bounds(JointModelKind kind, Eigen::VectorXd* lo, Eigen::VectorXd* hi) {
  switch (kind) {
    case JointModelKind::kMixed:
      *lo = Eigen::Vector4d(0.0, 0.0, 1e-4, 0.05);
      *hi = Eigen::Vector4d(2.0, 2.0, 1e3, 3.0);
      return;
    case JointModelKind::kStribeckViscous:
      lo->resize(5);
      hi->resize(5);
      *lo << 0.0, 0.0, 1e-3, 0.2, -1.0;
      *hi << 2.0, 2.0, 1e5, 5.0, 1.0;
      return;
    case JointModelKind::kLuGreSteadyState:
      *lo = Eigen::Vector4d(1e-4, 1e-4, 1e-3, -1.0);
      *hi = Eigen::Vector4d(2.0, 2.0, 1e5, 1.0);
      return;
  }
}

std::vector<std::size_t> AllRows(std::size_t n) {
  std::vector<std::size_t> r(n);
  std::iota(r.begin(), r.end(), std::size_t{0});
  return r;
}

Eigen::VectorXd StartGuess(JointModelKind kind,
                           const JointData& d,
                           const JointConfig& c,
                           const std::vector<std::size_t>& rows) {
  std::vector<double> mu, v, s, w;
  for (std::size_t i : rows) {
    mu.push_back(d.mu[i]);
    v.push_back(d.v_mm_s[i]);
    w.push_back(d.load_n[i]);
    s.push_back(
        CalcSommerfeldUm(d.eta_pa_s[i], d.v_mm_s[i], d.load_n[i], c.contact));
  }
  const double hi = std::max(Quantile(mu, 0.95), 1e-3);
  const double lo = std::clamp(Quantile(mu, 0.05), 0.0, hi);
  const double v_med = std::max(Quantile(v, 0.5), 1e-2);
  switch (kind) {
    case JointModelKind::kMixed: {
      // At the median S and load, the film that puts half the load on the
      // summits (alpha = 1/2): K F_3/2(lambda) = W/2, d = Alt + lambda SAlt,
      // i.e. the dry separation of half the load.
      const double n = 0.6;
      const double s_med = std::max(Quantile(s, 0.5), 1e-12);
      const double w_med = std::max(Quantile(w, 0.5), 1e-9);
      const double d_half = CalcDrySeparationUm(c.surface, 0.5 * w_med);
      const double d_ref =
          std::clamp(std::max(d_half, 0.1 * c.surface.salt_um) /
                         std::pow(s_med / kSommerfeldRefUm, n),
                     2e-4,
                     5e2);
      return Eigen::Vector4d(hi, lo, d_ref, n);
    }
    case JointModelKind::kStribeckViscous: {
      Eigen::VectorXd t(5);
      t << lo, hi, v_med, 2.0, 0.0;
      return t;
    }
    case JointModelKind::kLuGreSteadyState:
      return Eigen::Vector4d(hi, lo, v_med, 0.0);
  }
  return {};
}

}  // namespace

void ValidateJointData(const JointData& d) {
  const std::size_t n = d.mu.size();
  auto same = [&](std::size_t m, const char* name) {
    if (m != n)
      throw FieldError(name,
                       std::string(name) + " has " + std::to_string(m) +
                           " samples, mu has " + std::to_string(n));
  };
  same(d.v_mm_s.size(), "v_mm_s");
  same(d.load_n.size(), "load_n");
  same(d.eta_pa_s.size(), "eta_pa_s");
  if (!d.temp_c.empty()) same(d.temp_c.size(), "temp_c");
  for (std::size_t i = 0; i < n; ++i) {
    auto bad = [&](const char* field, double x, const char* rule) {
      throw FieldError(field,
                       "sample " + std::to_string(i) + ": " + field + " = " +
                           NumberText(x) + " (" + rule + ")");
    };
    if (!(d.v_mm_s[i] > 0 && std::isfinite(d.v_mm_s[i])))
      bad("v_mm_s", d.v_mm_s[i], "must be > 0 and finite");
    if (!(d.load_n[i] > 0 && std::isfinite(d.load_n[i])))
      bad("load_n", d.load_n[i], "must be > 0 and finite");
    if (!(d.eta_pa_s[i] > 0 && std::isfinite(d.eta_pa_s[i])))
      bad("eta_pa_s", d.eta_pa_s[i], "must be > 0 and finite");
    if (!std::isfinite(d.mu[i])) bad("mu", d.mu[i], "must be finite");
  }
}

std::string ToString(JointModelKind kind) {
  switch (kind) {
    case JointModelKind::kMixed:
      return "mixed";
    case JointModelKind::kStribeckViscous:
      return "stribeck_viscous";
    case JointModelKind::kLuGreSteadyState:
      return "lugre_steady_state";
  }
  return "?";
}

int ParameterCount(JointModelKind kind) {
  return kind == JointModelKind::kStribeckViscous ? 5 : 4;
}

std::vector<std::string> ParameterNames(JointModelKind kind) {
  switch (kind) {
    case JointModelKind::kMixed:
      return {"f_s", "f_l", "d_ref_um", "n"};
    case JointModelKind::kStribeckViscous:
      return {"f_c", "f_st", "v_s_mm_s", "delta", "k_v_s_mm"};
    case JointModelKind::kLuGreSteadyState:
      return {"mu_s", "mu_c", "v0_mm_s", "sigma2_s_mm"};
  }
  return {};
}

std::string ToString(JointFitStatus status) {
  switch (status) {
    case JointFitStatus::kConverged:
      return "converged";
    case JointFitStatus::kMaxIterations:
      return "max_iterations";
    case JointFitStatus::kNotObservable:
      return "not_observable";
    case JointFitStatus::kFailed:
      return "failed";
  }
  return "?";
}

double PredictJointFriction(JointModelKind kind,
                            const Eigen::Ref<const Eigen::VectorXd>& theta,
                            const JointConfig& config,
                            double v_mm_s,
                            double load_n,
                            double eta_pa_s,
                            Eigen::RowVectorXd* J_mu_theta) {
  switch (kind) {
    case JointModelKind::kMixed: {
      const MixedFrictionTheta t = theta.head<4>();
      const double s =
          CalcSommerfeldUm(eta_pa_s, v_mm_s, load_n, config.contact);
      MixedFrictionThetaRow J;
      const double f = CalcMixedFriction(
          t, config.surface, s, load_n, J_mu_theta ? &J : nullptr);
      if (J_mu_theta) *J_mu_theta = J;
      return f;
    }
    case JointModelKind::kStribeckViscous: {
      const double f_c = theta[0], f_st = theta[1], v_s = theta[2],
                   delta = theta[3], k_v = theta[4];
      const double x = v_mm_s / v_s;
      const double lx = std::log(x);
      const double p = std::exp(delta * lx);  // (v/v_s)^delta
      const double e = std::exp(-p);
      if (J_mu_theta) {
        J_mu_theta->resize(5);
        (*J_mu_theta)[0] = 1.0 - e;
        (*J_mu_theta)[1] = e;
        // d/dv_s of -p = delta p / v_s
        (*J_mu_theta)[2] = (f_st - f_c) * e * delta * p / v_s;
        (*J_mu_theta)[3] = -(f_st - f_c) * e * p * lx;
        (*J_mu_theta)[4] = v_mm_s;
      }
      return f_c + (f_st - f_c) * e + k_v * v_mm_s;
    }
    case JointModelKind::kLuGreSteadyState: {
      LuGreTheta t = LuGreTheta::Zero();
      t.head<4>() = theta.head<4>();
      t[LuGreIndex::kStiffness] = 1.0;  // does not enter the steady state
      LuGreThetaRow J;
      const double f =
          CalcSteadyStateFrictionRatio(t, v_mm_s, J_mu_theta ? &J : nullptr);
      if (J_mu_theta) *J_mu_theta = J.head<4>();
      return f;
    }
  }
  return std::numeric_limits<double>::quiet_NaN();
}

JointFitResult FitJointModel(JointModelKind kind,
                             const JointData& data,
                             const JointConfig& config,
                             const JointFitOptions& options,
                             const std::vector<std::size_t>& rows_in) {
  ValidateJointData(data);
  ValidateSurface(config.surface);
  ValidateLubricant(config.lubricant);
  if (!(config.contact.area_mm2 > 0 && std::isfinite(config.contact.area_mm2)))
    throw std::invalid_argument(
        "area_mm2 = " + NumberText(config.contact.area_mm2) + " (must be > 0)");
  if (!(options.max_iterations > 0))
    throw std::invalid_argument(
        "max_iterations = " + std::to_string(options.max_iterations) +
        " (must be > 0)");
  const int p = ParameterCount(kind);
  if (options.start.size() != 0 && options.start.size() != p)
    throw std::invalid_argument("start has " +
                                std::to_string(options.start.size()) +
                                " entries (must be " + std::to_string(p) + ")");
  for (std::size_t r : rows_in)
    if (r >= data.size())
      throw std::invalid_argument("row " + std::to_string(r) +
                                  " is out of range");
  const std::vector<std::size_t> rows =
      rows_in.empty() ? AllRows(data.size()) : rows_in;

  JointFitResult out;
  out.kind = kind;
  const Eigen::Index m = static_cast<Eigen::Index>(rows.size());
  if (m <= p) {
    out.status = JointFitStatus::kNotObservable;
    out.why =
        std::to_string(m) + " samples for " + std::to_string(p) + " parameters";
    out.theta =
        Eigen::VectorXd::Constant(p, std::numeric_limits<double>::quiet_NaN());
    out.P_theta = Eigen::MatrixXd::Zero(p, p);
    return out;
  }
  Eigen::VectorXd lo, hi;
  Bounds(kind, &lo, &hi);
  Eigen::VectorXd theta = options.start.size()
                              ? options.start
                              : StartGuess(kind, data, config, rows);
  theta = theta.cwiseMax(lo).cwiseMin(hi);

  LeastSquaresWorkspace<Eigen::Dynamic> ws(m, p);
  Eigen::RowVectorXd row(p);
  auto evaluate =
      [&](const Eigen::VectorXd& th, Eigen::VectorXd* r, Eigen::MatrixXd* J) {
        for (Eigen::Index i = 0; i < m; ++i) {
          const std::size_t k = rows[static_cast<std::size_t>(i)];
          const double f = PredictJointFriction(kind,
                                                th,
                                                config,
                                                data.v_mm_s[k],
                                                data.load_n[k],
                                                data.eta_pa_s[k],
                                                &row);
          (*r)[i] = f - data.mu[k];
          J->row(i) = row;
        }
        return std::isfinite(r->squaredNorm()) && J->allFinite();
      };
  LeastSquaresOptions solver;
  solver.max_iterations = options.max_iterations;
  solver.cost_tolerance = options.cost_tolerance;
  solver.min_rcond = options.min_rcond;
  solver.lambda_increase = 4.0;
  solver.lambda_decrease = 3.0;
  solver.min_diagonal = 1e-12;
  const LeastSquaresSummary<Eigen::Dynamic> s =
      SolveLeastSquares<Eigen::Dynamic>(evaluate, &theta, lo, hi, solver, &ws);
  if (s.status == LeastSquaresStatus::kFailed) {
    out.status = JointFitStatus::kFailed;
    out.why = "model is not finite at the start";
    out.theta = theta;
    out.P_theta = Eigen::MatrixXd::Zero(p, p);
    return out;
  }
  const bool converged = s.status == LeastSquaresStatus::kConverged;
  const Eigen::VectorXd& r = ws.r;
  const Eigen::MatrixXd& J = ws.J;
  out.theta = theta;
  out.iterations = s.iterations;
  out.residual_rms = std::sqrt(s.cost / static_cast<double>(m));

  // Robust (sandwich) covariance on the Jacobi-scaled normal matrix.
  out.rcond = s.rcond;
  if (s.status == LeastSquaresStatus::kRankDeficient ||
      !(out.rcond >= options.min_rcond)) {
    out.status = JointFitStatus::kNotObservable;
    out.why = "J^T J is rank deficient (rcond " + NumberText(out.rcond) +
              "): the data do not excite every parameter";
    out.P_theta = Eigen::MatrixXd::Zero(p, p);
    return out;
  }
  const Eigen::MatrixXd& A_inv = s.JtJ_inv;
  const Eigen::MatrixXd Jr = r.asDiagonal() * J;
  const Eigen::MatrixXd meat = Jr.transpose() * Jr;
  out.P_theta = A_inv * meat * A_inv *
                (static_cast<double>(m) / static_cast<double>(m - p));
  out.status =
      converged ? JointFitStatus::kConverged : JointFitStatus::kMaxIterations;
  if (!converged) out.why = "iteration limit reached";
  std::string invalid;
  if (kind == JointModelKind::kMixed &&
      !IsValidMixedFrictionTheta(theta.head<4>(), &invalid)) {
    // f_s < f_l: friction rises with S in these data, which eq. 1 with
    // solid friction above fluid friction cannot express.
    out.status = JointFitStatus::kFailed;
    out.why = "fitted parameters leave the model's domain (" + invalid +
              "): the data show no Stribeck drop of friction with S";
  }
  return out;
}

std::vector<JointModelScore> CompareJointModels(const JointData& data,
                                                const JointConfig& config,
                                                int k,
                                                const std::vector<int>& fold) {
  ValidateJointData(data);
  if (k < 2)
    throw std::invalid_argument("k = " + std::to_string(k) + " (must be >= 2)");
  if (!fold.empty() && fold.size() != data.size())
    throw std::invalid_argument("fold has " + std::to_string(fold.size()) +
                                " entries, data has " +
                                std::to_string(data.size()));
  std::vector<int> f(data.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    f[i] = fold.empty() ? static_cast<int>(i % static_cast<std::size_t>(k))
                        : fold[i];
    if (f[i] < 0 || f[i] >= k)
      throw std::invalid_argument(
          "fold[" + std::to_string(i) + "] = " + std::to_string(f[i]) +
          " (must be in [0, " + std::to_string(k - 1) + "])");
  }
  std::vector<JointModelScore> out;
  for (JointModelKind kind : {JointModelKind::kMixed,
                              JointModelKind::kStribeckViscous,
                              JointModelKind::kLuGreSteadyState}) {
    JointModelScore s;
    s.kind = kind;
    double se = 0, ae = 0;
    std::size_t count = 0;
    for (int fk = 0; fk < k; ++fk) {
      std::vector<std::size_t> train, test;
      for (std::size_t i = 0; i < f.size(); ++i)
        (f[i] == fk ? test : train).push_back(i);
      if (test.empty() || train.empty()) continue;
      const JointFitResult r = FitJointModel(kind, data, config, {}, train);
      if (r.status == JointFitStatus::kConverged ||
          r.status == JointFitStatus::kMaxIterations) {
        ++s.folds_fitted;
      }
      if (!r.theta.allFinite()) continue;
      for (std::size_t i : test) {
        const double e = PredictJointFriction(kind,
                                              r.theta,
                                              config,
                                              data.v_mm_s[i],
                                              data.load_n[i],
                                              data.eta_pa_s[i]) -
                         data.mu[i];
        se += e * e;
        ae += std::abs(e);
        ++count;
      }
    }
    s.heldout_rmse = count ? std::sqrt(se / count)
                           : std::numeric_limits<double>::quiet_NaN();
    s.heldout_mae =
        count ? ae / count : std::numeric_limits<double>::quiet_NaN();
    out.push_back(s);
  }
  return out;
}

JointData SimulateJointData(const MixedFrictionTheta& theta,
                            const JointConfig& config,
                            const std::vector<double>& v_mm_s,
                            const std::vector<double>& load_n,
                            const std::vector<double>& temp_c,
                            double noise,
                            unsigned seed) {
  if (load_n.size() != v_mm_s.size() || temp_c.size() != v_mm_s.size())
    throw std::invalid_argument("v_mm_s, load_n and temp_c differ in length");
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  JointData d;
  d.v_mm_s = v_mm_s;
  d.load_n = load_n;
  d.temp_c = temp_c;
  for (std::size_t i = 0; i < v_mm_s.size(); ++i) {
    const double eta = CalcViscosity(config.lubricant, temp_c[i]);
    const double s =
        CalcSommerfeldUm(eta, v_mm_s[i], load_n[i], config.contact);
    d.eta_pa_s.push_back(eta);
    d.mu.push_back(
        SampleContactFriction(theta, config.surface, s, load_n[i], &rng) +
        noise * normal(rng));
  }
  return d;
}

MixedFrictionPrediction PredictMixedFriction(const JointFitResult& mixed,
                                             const AsperitySurface& surface,
                                             double sommerfeld_um,
                                             double load_n) {
  MixedFrictionPrediction p;
  const MixedFrictionTheta theta = mixed.theta.head<4>();
  MixedFrictionThetaRow J;
  p.mu = CalcMixedFriction(theta, surface, sommerfeld_um, load_n, &J);
  p.sigma_contact =
      CalcMixedFrictionDispersion(theta, surface, sommerfeld_um, load_n);
  const Eigen::Matrix4d P = mixed.P_theta.topLeftCorner<4, 4>();
  p.sigma_param = std::sqrt(std::max(0.0, double(J * P * J.transpose())));
  p.sigma = std::hypot(p.sigma_contact, p.sigma_param);
  constexpr double kZ975 = 1.959964;  // standard normal 97.5 % quantile
  p.lo95 = p.mu - kZ975 * p.sigma;
  p.hi95 = p.mu + kZ975 * p.sigma;
  if (p.lo95 < 0) {
    p.lo95 = 0;
    p.floored_at_zero = true;
  }
  p.film_um =
      sommerfeld_um > 0 ? CalcFilmThicknessUm(theta, sommerfeld_um) : 0.0;
  p.alpha = CalcSolidFraction(surface, p.film_um, load_n);
  return p;
}

}  // namespace frictiond
