#include "frictiond/estimators/lugre.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/LU>

namespace frictiond {
namespace internal {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double Sign(double x) { return (x > 0) - (x < 0); }

std::string Num(double x) {
  std::ostringstream os;
  os.precision(9);
  os << x;
  return os.str();
}

// Appends "field = value (must be rule)" to *why and returns false.
bool Fail(std::string* why, const char* field, double value, const char* rule) {
  if (why)
    *why = std::string(field) + " = " + Num(value) + " (must be " + rule + ")";
  return false;
}

}  // namespace
}  // namespace internal

using internal::Fail;
using internal::Sign;

LuGreTheta MakeLuGreTheta(double mu_s,
                          double mu_c,
                          double v0_mm_s,
                          double sigma2_s_mm,
                          double sigma0_per_mm,
                          double sigma1_s_mm) {
  LuGreTheta theta;
  theta << mu_s, mu_c, v0_mm_s, sigma2_s_mm, sigma0_per_mm, sigma1_s_mm;
  return theta;
}

bool IsValidLuGreTheta(const LuGreTheta& theta, std::string* why) {
  if (!(theta[0] > 0) || !std::isfinite(theta[0]))
    return Fail(why, "theta.mu_s", theta[0], "finite and > 0");
  if (!(theta[1] > 0) || !std::isfinite(theta[1]))
    return Fail(why, "theta.mu_c", theta[1], "finite and > 0");
  if (!(theta[2] > 0) || !std::isfinite(theta[2]))
    return Fail(why, "theta.v0_mm_s", theta[2], "finite and > 0");
  if (!std::isfinite(theta[3]))
    return Fail(why, "theta.sigma2_s_mm", theta[3], "finite");
  if (!(theta[4] > 0) || !std::isfinite(theta[4]))
    return Fail(why, "theta.sigma0_per_mm", theta[4], "finite and > 0");
  if (!(theta[5] >= 0) || !std::isfinite(theta[5]))
    return Fail(why, "theta.sigma1_s_mm", theta[5], "finite and >= 0");
  return true;
}

void ValidateLuGreTheta(const LuGreTheta& theta) {
  std::string why;
  if (!IsValidLuGreTheta(theta, &why)) throw std::invalid_argument(why);
}

double CalcStribeckRatio(const LuGreTheta& theta,
                         double v_mm_s,
                         LuGreThetaRow* J_g_theta,
                         double* J_g_v) {
  const double mu_s = theta[0];
  const double mu_c = theta[1];
  const double v0 = theta[2];
  const double u = v_mm_s / v0;
  const double e = std::exp(-u * u);
  if (J_g_theta) {
    J_g_theta->setZero();
    (*J_g_theta)[0] = e;
    (*J_g_theta)[1] = 1.0 - e;
    (*J_g_theta)[2] = (mu_s - mu_c) * e * 2.0 * u * u / v0;
  }
  if (J_g_v) *J_g_v = (mu_s - mu_c) * e * (-2.0 * u / v0);
  return mu_c + (mu_s - mu_c) * e;
}

double CalcSteadyStateFrictionRatio(const LuGreTheta& theta,
                                    double v_mm_s,
                                    LuGreThetaRow* J_mu_theta) {
  const double s = Sign(v_mm_s);
  const double g = CalcStribeckRatio(theta, v_mm_s, J_mu_theta);
  if (J_mu_theta) {
    *J_mu_theta *= s;
    (*J_mu_theta)[3] = v_mm_s;
  }
  return s * g + theta[3] * v_mm_s;
}

double CalcBristleRate(const LuGreTheta& theta,
                       double v_mm_s,
                       double z_mm,
                       double* J_zdot_z,
                       LuGreThetaRow* J_zdot_theta,
                       double* J_zdot_v) {
  const double sigma0 = theta[4];
  const double abs_v = std::abs(v_mm_s);
  double g_v = 0;
  const double g = CalcStribeckRatio(theta, v_mm_s, J_zdot_theta, &g_v);
  const double inv_g = 1.0 / g;
  if (J_zdot_z) *J_zdot_z = -sigma0 * abs_v * inv_g;
  if (J_zdot_theta) {
    // d/dg of (-sigma0 |v| z / g) = sigma0 |v| z / g^2.
    *J_zdot_theta *= sigma0 * abs_v * z_mm * inv_g * inv_g;
    (*J_zdot_theta)[4] = -abs_v * z_mm * inv_g;
  }
  if (J_zdot_v) {
    *J_zdot_v = 1.0 - sigma0 * z_mm * Sign(v_mm_s) * inv_g +
                sigma0 * abs_v * z_mm * g_v * inv_g * inv_g;
  }
  return v_mm_s - sigma0 * abs_v * z_mm * inv_g;
}

double CalcFrictionRatio(const LuGreTheta& theta,
                         double v_mm_s,
                         double z_mm,
                         double* J_mu_z,
                         LuGreThetaRow* J_mu_theta,
                         double* J_mu_v) {
  const double sigma0 = theta[4];
  const double sigma1 = theta[5];
  const double sigma2 = theta[3];
  double J_zdot_z = 0;
  double J_zdot_v = 0;
  const double zdot = CalcBristleRate(
      theta, v_mm_s, z_mm, &J_zdot_z, J_mu_theta, J_mu_v ? &J_zdot_v : nullptr);
  if (J_mu_z) *J_mu_z = sigma0 + sigma1 * J_zdot_z;
  if (J_mu_theta) {
    *J_mu_theta *= sigma1;
    (*J_mu_theta)[3] += v_mm_s;
    (*J_mu_theta)[4] += z_mm;
    (*J_mu_theta)[5] += zdot;
  }
  if (J_mu_v) *J_mu_v = sigma1 * J_zdot_v + sigma2;
  return sigma0 * z_mm + sigma1 * zdot + sigma2 * v_mm_s;
}

double CalcBristleStep(const LuGreTheta& theta,
                       double v_mid_mm_s,
                       double dt_s,
                       double z_mm,
                       double* J_z1_z,
                       LuGreThetaRow* J_z1_theta) {
  const double abs_v = std::abs(v_mid_mm_s);
  if (abs_v == 0.0 || dt_s == 0.0) {
    if (J_z1_z) *J_z1_z = 1.0;
    if (J_z1_theta) J_z1_theta->setZero();
    return z_mm;
  }
  const double sigma0 = theta[4];
  const double s = Sign(v_mid_mm_s);
  const double g = CalcStribeckRatio(theta, v_mid_mm_s, J_z1_theta);
  const double a = sigma0 * abs_v / g;
  const double z_ss = s * g / sigma0;
  const double e = std::exp(-a * dt_s);
  const double dz = z_mm - z_ss;
  if (J_z1_z) *J_z1_z = e;
  if (J_z1_theta) {
    const double J_z1_a = -dz * dt_s * e;
    const double J_z1_zss = 1.0 - e;
    const double J_z1_g =
        J_z1_zss * s / sigma0 + J_z1_a * (-sigma0 * abs_v / (g * g));
    *J_z1_theta *= J_z1_g;
    (*J_z1_theta)[4] =
        J_z1_zss * (-s * g / (sigma0 * sigma0)) + J_z1_a * (abs_v / g);
  }
  return z_ss + dz * e;
}

double CalcDampingGain(double mass_kg, double fn_n, double damping_ratio) {
  if (!(mass_kg > 0) || !std::isfinite(mass_kg))
    throw std::invalid_argument("mass_kg = " + internal::Num(mass_kg) +
                                " (must be finite and > 0)");
  if (!(fn_n > 0) || !std::isfinite(fn_n))
    throw std::invalid_argument("fn_n = " + internal::Num(fn_n) +
                                " (must be finite and > 0)");
  if (!(damping_ratio > 0) || !std::isfinite(damping_ratio))
    throw std::invalid_argument(
        "damping_ratio = " + internal::Num(damping_ratio) +
        " (must be finite and > 0)");
  return 2.0 * damping_ratio * std::sqrt(mass_kg / (1000.0 * fn_n));
}

const char* ToString(SimulationStatus status) {
  switch (status) {
    case SimulationStatus::kOk:
      return "ok";
    case SimulationStatus::kStepTooSmall:
      return "step_too_small";
    case SimulationStatus::kMaxSteps:
      return "max_steps";
    case SimulationStatus::kNonFinite:
      return "non_finite";
    case SimulationStatus::kNoBreakaway:
      return "no_breakaway";
  }
  return "unknown";
}

bool VelocityDrivenOptions::IsValid(std::string* why) const {
  if (!(rel_tol > 0) || !std::isfinite(rel_tol))
    return Fail(why, "rel_tol", rel_tol, "finite and > 0");
  if (!(abs_tol_mm > 0) || !std::isfinite(abs_tol_mm))
    return Fail(why, "abs_tol_mm", abs_tol_mm, "finite and > 0");
  if (!(max_step_s > 0) || !std::isfinite(max_step_s))
    return Fail(why, "max_step_s", max_step_s, "finite and > 0");
  if (!(min_step_s > 0) || !(min_step_s <= max_step_s))
    return Fail(why, "min_step_s", min_step_s, "> 0 and <= max_step_s");
  if (!(max_steps > 0)) return Fail(why, "max_steps", max_steps, "> 0");
  return true;
}

namespace {

// Dormand-Prince 4(5) coefficients (Dormand & Prince 1980; Hairer, Norsett,
// Wanner, Solving ODEs I, Table 5.2).
constexpr double kC2 = 1.0 / 5, kC3 = 3.0 / 10, kC4 = 4.0 / 5, kC5 = 8.0 / 9;
constexpr double kA21 = 1.0 / 5;
constexpr double kA31 = 3.0 / 40, kA32 = 9.0 / 40;
constexpr double kA41 = 44.0 / 45, kA42 = -56.0 / 15, kA43 = 32.0 / 9;
constexpr double kA51 = 19372.0 / 6561, kA52 = -25360.0 / 2187,
                 kA53 = 64448.0 / 6561, kA54 = -212.0 / 729;
constexpr double kA61 = 9017.0 / 3168, kA62 = -355.0 / 33,
                 kA63 = 46732.0 / 5247, kA64 = 49.0 / 176,
                 kA65 = -5103.0 / 18656;
constexpr double kB1 = 35.0 / 384, kB3 = 500.0 / 1113, kB4 = 125.0 / 192,
                 kB5 = -2187.0 / 6784, kB6 = 11.0 / 84;
// Difference between the 5th- and 4th-order weights.
constexpr double kE1 = 71.0 / 57600, kE3 = -71.0 / 16695, kE4 = 71.0 / 1920,
                 kE5 = -17253.0 / 339200, kE6 = 22.0 / 525, kE7 = -1.0 / 40;

void CheckSeries(const Eigen::Ref<const Eigen::VectorXd>& t_s,
                 const Eigen::Ref<const Eigen::VectorXd>& v_mm_s) {
  if (t_s.size() != v_mm_s.size()) {
    throw std::invalid_argument(
        "v_mm_s.size() = " + std::to_string(v_mm_s.size()) +
        " (must equal t_s.size() = " + std::to_string(t_s.size()) + ")");
  }
  if (t_s.size() < 1)
    throw std::invalid_argument("t_s.size() = 0 (must be >= 1)");
  for (Eigen::Index k = 0; k < t_s.size(); ++k) {
    if (!std::isfinite(t_s[k]) || (k > 0 && !(t_s[k] > t_s[k - 1]))) {
      throw std::invalid_argument("t_s[" + std::to_string(k) +
                                  "] = " + internal::Num(t_s[k]) +
                                  " (must be finite and > t_s[k-1])");
    }
    if (!std::isfinite(v_mm_s[k])) {
      throw std::invalid_argument("v_mm_s[" + std::to_string(k) +
                                  "] = " + internal::Num(v_mm_s[k]) +
                                  " (must be finite)");
    }
  }
}

}  // namespace

VelocityDrivenResult SimulateVelocityDriven(
    const LuGreTheta& theta,
    const Eigen::Ref<const Eigen::VectorXd>& t_s,
    const Eigen::Ref<const Eigen::VectorXd>& v_mm_s,
    double z0_mm,
    const VelocityDrivenOptions& options) {
  ValidateLuGreTheta(theta);
  std::string why;
  if (!options.IsValid(&why))
    throw std::invalid_argument("VelocityDrivenOptions." + why);
  CheckSeries(t_s, v_mm_s);
  if (!std::isfinite(z0_mm))
    throw std::invalid_argument("z0_mm = " + internal::Num(z0_mm) +
                                " (must be finite)");

  const Eigen::Index n = t_s.size();
  VelocityDrivenResult result;
  result.mu.setConstant(n, internal::kNaN);
  result.z_mm.setConstant(n, internal::kNaN);

  double z = z0_mm;
  result.z_mm[0] = z;
  result.mu[0] = CalcFrictionRatio(theta, v_mm_s[0], z);
  double h = options.max_step_s;
  bool have_k1 = false;
  double k1 = 0;
  int total = 0;
  for (Eigen::Index k = 0; k + 1 < n; ++k) {
    const double ta = t_s[k];
    const double tb = t_s[k + 1];
    const double va = v_mm_s[k];
    const double slope = (v_mm_s[k + 1] - va) / (tb - ta);
    auto rate = [&](double t, double zz) {
      return CalcBristleRate(theta, va + slope * (t - ta), zz);
    };
    double t = ta;
    if (!have_k1) {
      k1 = rate(t, z);
      have_k1 = true;
    }
    while (t < tb) {
      if (++total > options.max_steps) {
        result.status = SimulationStatus::kMaxSteps;
        result.why = "max_steps = " + std::to_string(options.max_steps) +
                     " used up at t = " + internal::Num(t) + " s";
        return result;
      }
      const double remaining = tb - t;
      bool last = false;
      double hh = std::min(h, options.max_step_s);
      if (hh >= remaining * (1 - 1e-12)) {
        hh = remaining;
        last = true;
      }
      const double k2 = rate(t + kC2 * hh, z + hh * kA21 * k1);
      const double k3 = rate(t + kC3 * hh, z + hh * (kA31 * k1 + kA32 * k2));
      const double k4 =
          rate(t + kC4 * hh, z + hh * (kA41 * k1 + kA42 * k2 + kA43 * k3));
      const double k5 =
          rate(t + kC5 * hh,
               z + hh * (kA51 * k1 + kA52 * k2 + kA53 * k3 + kA54 * k4));
      const double k6 = rate(
          t + hh,
          z + hh * (kA61 * k1 + kA62 * k2 + kA63 * k3 + kA64 * k4 + kA65 * k5));
      const double z_new =
          z + hh * (kB1 * k1 + kB3 * k3 + kB4 * k4 + kB5 * k5 + kB6 * k6);
      const double t_new = last ? tb : t + hh;
      const double k7 = rate(t_new, z_new);
      const double err_abs = std::abs(hh * (kE1 * k1 + kE3 * k3 + kE4 * k4 +
                                            kE5 * k5 + kE6 * k6 + kE7 * k7));
      const double scale =
          options.abs_tol_mm +
          options.rel_tol * std::max(std::abs(z), std::abs(z_new));
      const double err = err_abs / scale;
      if (!std::isfinite(z_new) || !std::isfinite(err)) {
        result.status = SimulationStatus::kNonFinite;
        result.why = "non-finite state at t = " + internal::Num(t) + " s";
        return result;
      }
      const double factor =
          err == 0 ? 5.0 : std::clamp(0.9 * std::pow(err, -0.2), 0.2, 5.0);
      if (err <= 1.0) {
        t = t_new;
        z = z_new;
        k1 = k7;
        ++result.steps;
        // Keep the controller's step when this one was clipped to the sample.
        if (!last || factor < 1.0) h = hh * factor;
      } else {
        ++result.rejected_steps;
        h = hh * factor;
        if (h < options.min_step_s) {
          result.status = SimulationStatus::kStepTooSmall;
          result.why = "step " + internal::Num(h) + " s < min_step_s = " +
                       internal::Num(options.min_step_s) +
                       " at t = " + internal::Num(t) + " s";
          return result;
        }
      }
    }
    result.z_mm[k + 1] = z;
    result.mu[k + 1] = CalcFrictionRatio(theta, v_mm_s[k + 1], z);
  }
  return result;
}

bool ForceDrivenOptions::IsValid(std::string* why) const {
  if (!(mass_kg > 0) || !std::isfinite(mass_kg))
    return Fail(why, "mass_kg", mass_kg, "finite and > 0");
  if (!(mu_applied0 >= 0) || !std::isfinite(mu_applied0))
    return Fail(why, "mu_applied0", mu_applied0, "finite and >= 0");
  if (!std::isfinite(initial_v_mm_s))
    return Fail(why, "initial_v_mm_s", initial_v_mm_s, "finite");
  if (!std::isfinite(initial_z_mm))
    return Fail(why, "initial_z_mm", initial_z_mm, "finite");
  if (!(t_end_s > 0) || !std::isfinite(t_end_s))
    return Fail(why, "t_end_s", t_end_s, "finite and > 0");
  if (!(breakaway_speed_factor > 0) || !std::isfinite(breakaway_speed_factor))
    return Fail(why,
                "breakaway_speed_factor",
                breakaway_speed_factor,
                "finite and > 0");
  if (!(rel_tol > 0) || !std::isfinite(rel_tol))
    return Fail(why, "rel_tol", rel_tol, "finite and > 0");
  if (!(abs_tol > 0) || !std::isfinite(abs_tol))
    return Fail(why, "abs_tol", abs_tol, "finite and > 0");
  if (!(max_step_s > 0) || !std::isfinite(max_step_s))
    return Fail(why, "max_step_s", max_step_s, "finite and > 0");
  if (!(min_step_s > 0) || !(min_step_s <= max_step_s))
    return Fail(why, "min_step_s", min_step_s, "> 0 and <= max_step_s");
  if (!(max_steps > 0)) return Fail(why, "max_steps", max_steps, "> 0");
  return true;
}

namespace {

// Right-hand side of eqs. 19-20 for y = [v, z] with optional Jacobian.
struct ForceDrivenRhs {
  const LuGreTheta& theta;
  double mu_applied0;
  double rho;
  double k_acc;  // 1000 Fn / m [mm/s^2 per unit ratio]

  // Returns dy/dt; *mu gets the friction ratio; J (if set) gets df/dy.
  Eigen::Vector2d operator()(double t,
                             const Eigen::Vector2d& y,
                             double* mu,
                             Eigen::Matrix2d* J) const {
    double J_zdot_z = 0, J_zdot_v = 0;
    const double zdot = CalcBristleRate(
        theta, y[0], y[1], &J_zdot_z, nullptr, J ? &J_zdot_v : nullptr);
    const double mu_f = theta[4] * y[1] + theta[5] * zdot + theta[3] * y[0];
    if (mu) *mu = mu_f;
    if (J) {
      const double J_mu_v = theta[5] * J_zdot_v + theta[3];
      const double J_mu_z = theta[4] + theta[5] * J_zdot_z;
      (*J) << -k_acc * J_mu_v, -k_acc * J_mu_z, J_zdot_v, J_zdot_z;
    }
    return Eigen::Vector2d(k_acc * (mu_applied0 + rho * t - mu_f), zdot);
  }
};

}  // namespace

ForceDrivenResult SimulateForceDriven(
    const LuGreTheta& theta,
    double rho_per_s,
    double fn_n,
    const ForceDrivenOptions& options,
    std::vector<ForceDrivenSample>* trajectory) {
  ValidateLuGreTheta(theta);
  std::string why;
  if (!options.IsValid(&why))
    throw std::invalid_argument("ForceDrivenOptions." + why);
  if (!(rho_per_s > 0) || !std::isfinite(rho_per_s))
    throw std::invalid_argument("rho_per_s = " + internal::Num(rho_per_s) +
                                " (must be finite and > 0)");
  if (!(fn_n > 0) || !std::isfinite(fn_n))
    throw std::invalid_argument("fn_n = " + internal::Num(fn_n) +
                                " (must be finite and > 0)");

  const ForceDrivenRhs f{
      theta, options.mu_applied0, rho_per_s, 1000.0 * fn_n / options.mass_kg};
  const double v_break = options.breakaway_speed_factor * theta[2];
  // Shampine & Reichelt (1997), "The MATLAB ODE suite", modified Rosenbrock
  // formula of order 2 with an order-3 error estimate.
  const double d = 1.0 / (2.0 + std::sqrt(2.0));
  const double e32 = 6.0 + std::sqrt(2.0);
  const Eigen::Vector2d dfdt(f.k_acc * rho_per_s, 0.0);

  ForceDrivenResult result;
  double t = 0.0;
  Eigen::Vector2d y(options.initial_v_mm_s, options.initial_z_mm);
  double mu = 0.0;
  Eigen::Matrix2d J;
  Eigen::Vector2d f0 = f(t, y, &mu, &J);
  double mu_max = mu;
  if (trajectory)
    trajectory->push_back({t, options.mu_applied0, mu, y[0], y[1]});
  // First step: a fraction of the time the ramp needs to change mu by rel_tol.
  double h = std::clamp(
      options.rel_tol / rho_per_s, options.min_step_s, options.max_step_s);
  int total = 0;
  while (true) {
    if (++total > options.max_steps) {
      result.status = SimulationStatus::kMaxSteps;
      result.why = "max_steps = " + std::to_string(options.max_steps) +
                   " used up at t = " + internal::Num(t) + " s";
      break;
    }
    h = std::min(h, options.max_step_s);
    const Eigen::Matrix2d W = Eigen::Matrix2d::Identity() - (h * d) * J;
    const double det = W.determinant();
    if (!(std::abs(det) > 0) || !std::isfinite(det)) {
      result.status = SimulationStatus::kNonFinite;
      result.why =
          "singular iteration matrix at t = " + internal::Num(t) + " s";
      break;
    }
    const Eigen::Matrix2d W_inv = W.inverse();  // 2x2: closed form
    const Eigen::Vector2d k1 = W_inv * (f0 + (h * d) * dfdt);
    const Eigen::Vector2d f1 =
        f(t + 0.5 * h, y + (0.5 * h) * k1, nullptr, nullptr);
    const Eigen::Vector2d k2 = W_inv * (f1 - k1) + k1;
    const Eigen::Vector2d y_new = y + h * k2;
    double mu_new = 0;
    Eigen::Matrix2d J_new;
    const Eigen::Vector2d f2 = f(t + h, y_new, &mu_new, &J_new);
    const Eigen::Vector2d k3 =
        W_inv * (f2 - e32 * (k2 - f1) - 2.0 * (k1 - f0) + (h * d) * dfdt);
    const Eigen::Vector2d err_vec = (h / 6.0) * (k1 - 2.0 * k2 + k3);
    double err = 0;
    for (int i = 0; i < 2; ++i) {
      const double scale =
          options.abs_tol +
          options.rel_tol * std::max(std::abs(y[i]), std::abs(y_new[i]));
      err = std::max(err, std::abs(err_vec[i]) / scale);
    }
    if (!y_new.allFinite() || !std::isfinite(err)) {
      result.status = SimulationStatus::kNonFinite;
      result.why = "non-finite state at t = " + internal::Num(t) + " s";
      break;
    }
    const double factor =
        err == 0 ? 5.0 : std::clamp(0.8 * std::cbrt(1.0 / err), 0.2, 5.0);
    if (err > 1.0) {
      ++result.rejected_steps;
      h *= factor;
      if (h < options.min_step_s) {
        result.status = SimulationStatus::kStepTooSmall;
        result.why = "step " + internal::Num(h) +
                     " s < min_step_s = " + internal::Num(options.min_step_s) +
                     " at t = " + internal::Num(t) + " s";
        break;
      }
      continue;
    }
    ++result.steps;
    t += h;
    y = y_new;
    f0 = f2;
    J = J_new;
    mu = mu_new;
    mu_max = std::max(mu_max, mu);
    if (trajectory) {
      trajectory->push_back(
          {t, options.mu_applied0 + rho_per_s * t, mu, y[0], y[1]});
    }
    if (y[0] > v_break) {
      result.status = SimulationStatus::kOk;
      break;
    }
    if (t >= options.t_end_s) {
      result.status = SimulationStatus::kNoBreakaway;
      result.why = "no break-away (v = " + internal::Num(y[0]) +
                   " mm/s <= " + internal::Num(v_break) +
                   " mm/s) by t_end_s = " + internal::Num(options.t_end_s) +
                   " s";
      break;
    }
    h = std::min(h * factor, options.t_end_s - t + options.min_step_s);
  }
  result.t_breakaway_s = t;
  result.mu_applied = options.mu_applied0 + rho_per_s * t;
  result.bf_ratio =
      result.status == SimulationStatus::kOk ? mu_max : internal::kNaN;
  return result;
}

}  // namespace frictiond
