#include "frictiond/estimators/joint_friction.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/number_text.h"

namespace frictiond {

namespace {

constexpr double kSqrt2 = 1.41421356237309504880;
constexpr double kInvSqrt2Pi = 0.39894228040143267794;

// 8-point Gauss-Legendre rule on [-1, 1] (positive half; symmetric).
constexpr double kGlNode[4] = {0.1834346424956498049,
                               0.5255324099163289858,
                               0.7966664774136267396,
                               0.9602898564975362317};
constexpr double kGlWeight[4] = {0.3626837833783619830,
                                 0.3137066458778872873,
                                 0.2223810344533744706,
                                 0.1012285362903762591};
constexpr int kGlPanels = 16;  // 16 panels x 8 nodes = 128 nodes

void Require(bool ok,
             const std::string& field,
             double value,
             const std::string& rule) {
  if (!ok)
    throw FieldError(field,
                     field + " = " + NumberText(value) + " (" + rule + ")");
}

}  // namespace

AsperitySurface MakeSurfaceFromRoughness(double r_um,
                                         double w_um,
                                         double sw_um) {
  Require(r_um > 0 && std::isfinite(r_um), "r_um", r_um, "must be > 0");
  Require(w_um >= 0 && std::isfinite(w_um), "w_um", w_um, "must be >= 0");
  Require(sw_um >= 0 && std::isfinite(sw_um), "sw_um", sw_um, "must be >= 0");
  AsperitySurface s;
  s.alt_um = 0.5 * r_um;  // eq. 3, Alt = R/2
  s.salt_um = 0.35 * std::sqrt(w_um * w_um + sw_um * sw_um);  // eq. 3
  Require(s.salt_um > 0, "salt_um", s.salt_um, "w_um or sw_um must be > 0");
  return s;
}

void ValidateSurface(const AsperitySurface& s) {
  Require(std::isfinite(s.alt_um), "alt_um", s.alt_um, "must be finite");
  Require(s.salt_um > 0 && std::isfinite(s.salt_um),
          "salt_um",
          s.salt_um,
          "must be > 0");
  Require(s.radius_log_sd >= 0 && s.radius_log_sd <= 5,
          "radius_log_sd",
          s.radius_log_sd,
          "must be in [0, 5]");
  Require(std::isfinite(s.radius_log_mean) && std::abs(s.radius_log_mean) <= 20,
          "radius_log_mean",
          s.radius_log_mean,
          "must be finite, |b| <= 20");
  Require(s.srad_um > 0 && std::isfinite(s.srad_um),
          "srad_um",
          s.srad_um,
          "must be > 0");
  Require(s.summits >= 1 && s.summits <= 1e7,
          "summits",
          s.summits,
          "must be in [1, 1e7]");
  Require(s.modulus_gpa > 0 && s.modulus_gpa <= 1e4,
          "modulus_gpa",
          s.modulus_gpa,
          "must be in (0, 1e4]");
}

void ValidateLubricant(const Lubricant& l) {
  Require(l.vogel_a_pa_s > 0 && std::isfinite(l.vogel_a_pa_s),
          "vogel_a_pa_s",
          l.vogel_a_pa_s,
          "must be > 0");
  Require(l.vogel_b_c > 0 && std::isfinite(l.vogel_b_c),
          "vogel_b_c",
          l.vogel_b_c,
          "must be > 0");
  Require(std::isfinite(l.vogel_c_c) && l.vogel_c_c > -273.15,
          "vogel_c_c",
          l.vogel_c_c,
          "must be finite and > -273.15");
}

double CalcViscosity(const Lubricant& l, double temp_c) {
  const double t = temp_c + l.vogel_c_c;
  if (!(t > 0)) return std::numeric_limits<double>::quiet_NaN();
  return l.vogel_a_pa_s * std::exp(l.vogel_b_c / t);
}

double CalcSommerfeldUm(double eta_pa_s,
                        double v_mm_s,
                        double load_n,
                        const JointContact& contact) {
  // eta [Pa s] * V [m/s] / p [Pa] = metres; * 1e6 -> um.
  // V = v_mm_s * 1e-3 m/s; p = load_n / (area_mm2 * 1e-6) Pa.
  const double p_pa = load_n / (contact.area_mm2 * 1e-6);
  return eta_pa_s * (v_mm_s * 1e-3) / p_pa * 1e6;
}

MixedFrictionTheta MakeMixedFrictionTheta(double f_s,
                                          double f_l,
                                          double d_ref_um,
                                          double n) {
  MixedFrictionTheta t;
  t << f_s, f_l, d_ref_um, n;
  return t;
}

namespace {

// The rule of IsValidMixedFrictionTheta; on failure, the field at fault
// and the message.
bool CheckTheta(const MixedFrictionTheta& t,
                std::string* field,
                std::string* why) {
  auto fail = [&](const char* f, const std::string& m) {
    *field = f;
    *why = m;
    return false;
  };
  if (!t.allFinite()) return fail("theta", "theta has a non-finite entry");
  if (!(t[1] >= 0))
    return fail("f_l", "f_l = " + NumberText(t[1]) + " (must be >= 0)");
  if (!(t[0] >= t[1]))
    return fail("f_s",
                "f_s = " + NumberText(t[0]) +
                    " (must be >= f_l = " + NumberText(t[1]) + ")");
  if (!(t[2] > 0))
    return fail("d_ref_um",
                "d_ref_um = " + NumberText(t[2]) + " (must be > 0)");
  if (!(t[3] > 0 && t[3] <= 3))
    return fail("n", "n = " + NumberText(t[3]) + " (must be in (0, 3])");
  return true;
}

void RequireValidTheta(const MixedFrictionTheta& t) {
  std::string field, why;
  if (!CheckTheta(t, &field, &why)) throw FieldError(field, why);
}

}  // namespace

bool IsValidMixedFrictionTheta(const MixedFrictionTheta& t, std::string* why) {
  std::string field, message;
  if (CheckTheta(t, &field, &message)) return true;
  if (why) *why = message;
  return false;
}

double CalcFilmThicknessUm(const MixedFrictionTheta& theta,
                           double sommerfeld_um) {
  return theta[2] * std::pow(sommerfeld_um / kSommerfeldRefUm, theta[3]);
}

SummitIntegrals CalcSummitIntegrals(double lambda) {
  SummitIntegrals out;
  if (!std::isfinite(lambda)) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    return {nan, nan, nan, nan};
  }
  // F_nu = int_0^inf t^nu phi(lambda + t) dt, t = u^2:
  //      = int 2 u^(2 nu + 1) phi(lambda + u^2) du,
  // smooth in u for every nu >= -1/2. Range: s = lambda + u^2 within
  // [-9.5, 9.5] for lambda <= 0 (phi < exp(-45) of its peak outside); for
  // lambda > 0 the integrand falls as exp(-lambda u^2 - u^4/2) relative to
  // u = 0, cut where that exponent reaches 45.
  const double u2_lo = std::max(0.0, -lambda - 9.5);
  const double u2_hi =
      lambda <= 0 ? 9.5 - lambda : -lambda + std::sqrt(lambda * lambda + 90.0);
  const double u_lo = std::sqrt(u2_lo), u_hi = std::sqrt(u2_hi);
  const double h = (u_hi - u_lo) / kGlPanels;
  for (int p = 0; p < kGlPanels; ++p) {
    const double mid = u_lo + h * (p + 0.5);
    for (int k = 0; k < 4; ++k) {
      for (double sign : {-1.0, 1.0}) {
        const double u = mid + sign * 0.5 * h * kGlNode[k];
        const double u2 = u * u;
        const double s = lambda + u2;
        // 2 phi(s) * weight * (h / 2) = weight * h * phi(s).
        const double w =
            kGlWeight[k] * h * kInvSqrt2Pi * std::exp(-0.5 * s * s);
        out.f_m12 += w;                   // 2 u^0: nu = -1/2
        out.f_12 += w * u2;               // 2 u^2: nu = 1/2
        out.f_32 += w * u2 * u2;          // 2 u^4: nu = 3/2
        out.f_3 += w * u2 * u2 * u2 * u;  // 2 u^7: nu = 3
      }
    }
  }
  return out;
}

double CalcAsperityLoadScaleN(const AsperitySurface& surface) {
  // E[sqrt R] with R = SRAD R*, ln R* ~ N(b, a^2) (eqs. 4-5): lognormal
  // moment exp(b/2 + a^2/8). Units: E* [N/mm^2], R [mm], SAlt [mm] -> N.
  const double a = surface.radius_log_sd, b = surface.radius_log_mean;
  const double mean_sqrt_r_mm =
      std::sqrt(surface.srad_um * 1e-3) * std::exp(0.5 * b + 0.125 * a * a);
  const double salt_mm = surface.salt_um * 1e-3;
  return surface.summits * (4.0 / 3.0) * (surface.modulus_gpa * 1e3) *
         mean_sqrt_r_mm * salt_mm * std::sqrt(salt_mm);
}

double CalcTouchingFraction(const AsperitySurface& surface, double film_um) {
  // int_d^inf p1(z) dz, p1 Gaussian (eq. 2) -> Q(lambda).
  const double lambda = (film_um - surface.alt_um) / surface.salt_um;
  return 0.5 * std::erfc(lambda / kSqrt2);
}

double CalcDrySeparationUm(const AsperitySurface& surface, double load_n) {
  if (!(load_n > 0) || !std::isfinite(load_n))
    return std::numeric_limits<double>::quiet_NaN();
  // Solve F_3/2(lambda) = W / K. F_3/2 falls monotonically; by Jensen
  // F_3/2(lambda) >= |lambda|^3/2 for lambda < 0, so lambda_lo = -(W/K)^2/3
  // brackets from below; F_3/2(40) < 1e-300 brackets from above.
  const double target = load_n / CalcAsperityLoadScaleN(surface);
  double lo = -std::pow(target, 2.0 / 3.0) - 1.0, hi = 40.0;
  double lambda = std::clamp(-std::pow(target, 2.0 / 3.0), lo, hi);
  for (int it = 0; it < 200 && hi - lo > 1e-13 * (1.0 + std::abs(lambda));
       ++it) {
    const SummitIntegrals f = CalcSummitIntegrals(lambda);
    if (f.f_32 > target)
      lo = lambda;
    else
      hi = lambda;
    // Newton on ln F_3/2 (d ln F / dlambda = -1.5 F_1/2 / F_3/2), kept
    // inside the bracket, else bisection.
    double next = f.f_32 > 0 ? lambda + (std::log(f.f_32) - std::log(target)) *
                                            f.f_32 / (1.5 * f.f_12)
                             : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - lambda) < 1e-14 * (1.0 + std::abs(lambda))) {
      lambda = next;
      break;
    }
    lambda = next;
  }
  return surface.alt_um + lambda * surface.salt_um;
}

namespace {

// Separation d = d_film + min(0, d_dry) and its lambda (file comment).
double SeparationLambda(const AsperitySurface& surface,
                        double film_um,
                        double load_n,
                        double k_n) {
  double d = film_um;
  // d_dry < 0 exactly when W > K F_3/2(-Alt/SAlt).
  if (load_n >
      k_n * CalcSummitIntegrals(-surface.alt_um / surface.salt_um).f_32) {
    d += std::min(0.0, CalcDrySeparationUm(surface, load_n));
  }
  return (d - surface.alt_um) / surface.salt_um;
}

}  // namespace

double CalcSolidFraction(const AsperitySurface& surface,
                         double film_um,
                         double load_n,
                         double* J_alpha_d) {
  if (!(load_n > 0) || !std::isfinite(load_n)) {
    if (J_alpha_d) *J_alpha_d = 0;
    return std::numeric_limits<double>::quiet_NaN();
  }
  // alpha = W_solid / W = K F_3/2(lambda) / W (eqs. 1, 6, 7; file comment).
  const double k_n = CalcAsperityLoadScaleN(surface);
  const double lambda = SeparationLambda(surface, film_um, load_n, k_n);
  const SummitIntegrals f = CalcSummitIntegrals(lambda);
  const double ratio = k_n * f.f_32 / load_n;
  if (ratio >= 1.0) {
    if (J_alpha_d) *J_alpha_d = 0;
    return 1.0;
  }
  if (J_alpha_d) *J_alpha_d = -1.5 * k_n * f.f_12 / (load_n * surface.salt_um);
  return ratio;
}

double CalcMixedFriction(const MixedFrictionTheta& theta,
                         const AsperitySurface& surface,
                         double sommerfeld_um,
                         double load_n,
                         MixedFrictionThetaRow* J_f_theta,
                         double* J_f_s) {
  const double f_s = theta[0], f_l = theta[1];
  if (!(sommerfeld_um > 0)) {  // no film: dry contact
    const double alpha = CalcSolidFraction(surface, 0.0, load_n);
    if (J_f_theta) *J_f_theta << alpha, 1.0 - alpha, 0.0, 0.0;
    if (J_f_s) *J_f_s = 0.0;
    return alpha * f_s + (1.0 - alpha) * f_l;
  }
  const bool want_j = J_f_theta || J_f_s;
  const double log_ratio = std::log(sommerfeld_um / kSommerfeldRefUm);
  const double scale = std::exp(theta[3] * log_ratio);  // (S/S_ref)^n
  const double d = theta[2] * scale;
  double J_alpha_d = 0;
  const double alpha =
      CalcSolidFraction(surface, d, load_n, want_j ? &J_alpha_d : nullptr);
  const double f = alpha * f_s + (1.0 - alpha) * f_l;  // eq. 1
  if (J_f_theta) {
    const double J_f_d = (f_s - f_l) * J_alpha_d;
    *J_f_theta << alpha, 1.0 - alpha, J_f_d * scale, J_f_d * d * log_ratio;
  }
  if (J_f_s) {
    *J_f_s = (f_s - f_l) * J_alpha_d * theta[3] * d / sommerfeld_um;
  }
  return f;
}

double CalcMixedFrictionDispersion(const MixedFrictionTheta& theta,
                                   const AsperitySurface& surface,
                                   double sommerfeld_um,
                                   double load_n) {
  const double d =
      sommerfeld_um > 0 ? CalcFilmThicknessUm(theta, sommerfeld_um) : 0.0;
  const double alpha = CalcSolidFraction(surface, d, load_n);
  if (!(alpha < 1.0)) return alpha == 1.0 ? 0.0 : alpha;  // dry or NaN
  // Var(alpha) = (K/W)^2 (exp(a^2/4) F_3 - F_3/2^2) / N (file comment),
  // written without dividing by F_3/2 so that full film stays finite.
  const double k_n = CalcAsperityLoadScaleN(surface);
  const SummitIntegrals f =
      CalcSummitIntegrals(SeparationLambda(surface, d, load_n, k_n));
  const double a = surface.radius_log_sd;
  const double kw = k_n / load_n;
  const double var_alpha =
      std::max(0.0,
               kw * kw * (std::exp(0.25 * a * a) * f.f_3 - f.f_32 * f.f_32) /
                   surface.summits);
  return (theta[0] - theta[1]) * std::sqrt(var_alpha);
}

double SampleContactFriction(const MixedFrictionTheta& theta,
                             const AsperitySurface& surface,
                             double sommerfeld_um,
                             double load_n,
                             std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const double film =
      sommerfeld_um > 0 ? CalcFilmThicknessUm(theta, sommerfeld_um) : 0.0;
  const double k_n = CalcAsperityLoadScaleN(surface);
  const double d =
      surface.alt_um +
      surface.salt_um * SeparationLambda(surface, film, load_n, k_n);
  const long n = std::max(1L, std::lround(surface.summits));
  const double e_star = surface.modulus_gpa * 1e3;  // N/mm^2
  double w_solid = 0;
  for (long i = 0; i < n; ++i) {
    const double z = surface.alt_um + surface.salt_um * normal(*rng);  // eq. 2
    // R = SRAD R*, log R* ~ N(b, a^2) (eqs. 4-5).
    const double r_um =
        surface.srad_um * std::exp(surface.radius_log_mean +
                                   surface.radius_log_sd * normal(*rng));
    if (z > d) {
      // Hertz: P = 4/3 E* R^1/2 delta^3/2 (eq. 6, elastic term), mm units.
      const double delta_mm = (z - d) * 1e-3;
      w_solid += (4.0 / 3.0) * e_star * std::sqrt(r_um * 1e-3) * delta_mm *
                 std::sqrt(delta_mm);
    }
  }
  const double alpha = std::min(1.0, w_solid / load_n);
  return alpha * theta[0] + (1.0 - alpha) * theta[1];
}

namespace {

constexpr double kF32TableLo = -8.0, kF32TableHi = 12.0;
constexpr int kF32Nodes = 4096;
constexpr double kDryDecadesLn = 16.0;  // ln(W / capacity) tabulated
constexpr int kDryNodes = 4096;

// Cubic Hermite on a uniform grid: node values y, slopes s (per unit x),
// x0 the first node, h the spacing; x inside [x0, x0 + (n-1) h].
double Hermite(const std::vector<double>& y,
               const std::vector<double>& s,
               double x0,
               double h,
               double x) {
  const double q = (x - x0) / h;
  const std::size_t i =
      std::min(static_cast<std::size_t>(std::max(q, 0.0)), y.size() - 2);
  const double t = q - static_cast<double>(i);
  const double t2 = t * t, t3 = t2 * t;
  const double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + t;
  const double h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
  return h00 * y[i] + h10 * h * s[i] + h01 * y[i + 1] + h11 * h * s[i + 1];
}

// F_3/2(lambda) for lambda <= -8: E[(L + Z)^3/2], L = -lambda, expanded in
// the even moments of Z: L^3/2 sum_k C(3/2, 2k) (2k-1)!! L^-2k (the part of
// Z below -L, weight phi(8) ~ 5e-15, is dropped). 12 terms: relative error
// below 1e-13 at L = 8 (tested against the quadrature).
double AsymptoticF32(double lambda) {
  const double l = -lambda, inv_l2 = 1.0 / (l * l);
  double sum = 1.0, binom = 1.0, power = 1.0, dfact = 1.0;
  for (int k = 1; k <= 12; ++k) {
    const double j = 2.0 * k;
    binom *= (1.5 - j + 2) * (1.5 - j + 1) / ((j - 1) * j);  // C(3/2, 2k)
    power *= inv_l2;                                         // L^-2k
    dfact *= j - 1;                                          // (2k-1)!!
    sum += binom * dfact * power;
  }
  return l * std::sqrt(l) * sum;
}

}  // namespace

MixedFrictionTable::MixedFrictionTable(const MixedFrictionTheta& theta,
                                       const AsperitySurface& surface,
                                       const Lubricant& lubricant,
                                       const JointContact& contact)
    : theta_(theta), surface_(surface) {
  RequireValidTheta(theta);
  ValidateSurface(surface);
  ValidateLubricant(lubricant);
  Require(contact.area_mm2 > 0 && std::isfinite(contact.area_mm2),
          "area_mm2",
          contact.area_mm2,
          "must be > 0");
  log_a_ = std::log(lubricant.vogel_a_pa_s);
  b_ = lubricant.vogel_b_c;
  c_ = lubricant.vogel_c_c;
  // S [um] = eta * v_mm_s * 1e-3 / (load / (area * 1e-6)) * 1e6
  //        = eta * v * area * 1e-3 / load.
  log_const_ = std::log(contact.area_mm2 * 1e-3);
  const double k_n = CalcAsperityLoadScaleN(surface);
  // Loads up to the Hertz capacity of the summits at the mean line have
  // d_dry >= 0 and alpha = min(1, G(u) / W) (class comment).
  w_table_max_ =
      k_n * CalcSummitIntegrals(-surface.alt_um / surface.salt_um).f_32;
  // Grid in u = ln S where d runs from 1e-9 SAlt (G within 1e-8 relative of
  // its d = 0 limit) to Alt + 12 SAlt (G < 1e-30 K beyond).
  const double d_lo = 1e-9 * surface.salt_um;
  const double d_hi = std::max(surface.alt_um, 0.0) + 12.0 * surface.salt_um;
  auto u_of_d = [&](double d) {
    return std::log(kSommerfeldRefUm) + std::log(d / theta[2]) / theta[3];
  };
  u_min_ = u_of_d(d_lo);
  u_max_ = u_of_d(d_hi);
  constexpr int kNodes = 8192;
  du_ = (u_max_ - u_min_) / (kNodes - 1);
  inv_du_ = 1.0 / du_;
  g_.resize(kNodes);
  slope_.resize(kNodes);
  auto node = [&](double u, double* slope) {
    const double d =
        theta[2] * std::exp(theta[3] * (u - std::log(kSommerfeldRefUm)));
    const SummitIntegrals f =
        CalcSummitIntegrals((d - surface.alt_um) / surface.salt_um);
    // dG/du = K dF_3/2/dlambda dlambda/dd dd/du = -1.5 K F_1/2 / SAlt * n d.
    if (slope) *slope = -1.5 * k_n * f.f_12 / surface.salt_um * theta[3] * d;
    return k_n * f.f_32;
  };
  for (int i = 0; i < kNodes; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    g_[k] = node(u_min_ + du_ * i, &slope_[k]);
  }
  g_low_ = w_table_max_;  // the d -> 0 limit
  g_high_ = g_.back();
  // Heavy loads: lambda_dry(ln(W/K)) and F_3/2(lambda) tables.
  k_n_ = k_n;
  log_k_ = std::log(k_n);
  y_lo_ = std::log(w_table_max_ / k_n);
  y_hi_ = y_lo_ + kDryDecadesLn;
  dy_ = (y_hi_ - y_lo_) / (kDryNodes - 1);
  lam_dry_.resize(kDryNodes);
  lam_dry_slope_.resize(kDryNodes);
  for (int i = 0; i < kDryNodes; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const double w = k_n * std::exp(y_lo_ + dy_ * i);
    const double lam =
        (CalcDrySeparationUm(surface, w) - surface.alt_um) / surface.salt_um;
    const SummitIntegrals f = CalcSummitIntegrals(lam);
    lam_dry_[k] = lam;
    // F_3/2(lambda) = e^y: dlambda/dy = F_3/2 / F_3/2' = -F_3/2 / (1.5 F_1/2).
    lam_dry_slope_[k] = -f.f_32 / (1.5 * f.f_12);
  }
  f32_.resize(kF32Nodes);
  f32_slope_.resize(kF32Nodes);
  const double h = (kF32TableHi - kF32TableLo) / (kF32Nodes - 1);
  for (int i = 0; i < kF32Nodes; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const SummitIntegrals f = CalcSummitIntegrals(kF32TableLo + h * i);
    f32_[k] = f.f_32;
    f32_slope_[k] = -1.5 * f.f_12;
  }
}

double MixedFrictionTable::HeavyLoad(double u, double load_n) const {
  const double y = std::log(load_n) - log_k_;
  if (!(y < y_hi_))
    return CalcMixedFriction(theta_, surface_, std::exp(u), load_n);
  const double lam_dry = y <= y_lo_
                             ? lam_dry_.front()
                             : Hermite(lam_dry_, lam_dry_slope_, y_lo_, dy_, y);
  const double d_film =
      theta_[2] * std::exp(theta_[3] * (u - std::log(kSommerfeldRefUm)));
  const double lambda = lam_dry + d_film / surface_.salt_um;
  double f32 = 0;
  if (lambda < kF32TableLo) {
    f32 = AsymptoticF32(lambda);
  } else if (lambda < kF32TableHi) {
    f32 = Hermite(f32_,
                  f32_slope_,
                  kF32TableLo,
                  (kF32TableHi - kF32TableLo) / (kF32Nodes - 1),
                  lambda);
  }
  return std::min(1.0, k_n_ * f32 / load_n);
}

double MixedFrictionTable::EvalLog(double u, double load_n) const {
  if (!(load_n > 0)) return std::numeric_limits<double>::quiet_NaN();
  if (!(load_n <= w_table_max_)) {
    const double alpha = HeavyLoad(u, load_n);
    return alpha * theta_[0] + (1.0 - alpha) * theta_[1];
  }
  double g;
  if (!(u > u_min_)) {
    g = g_low_;
  } else if (!(u < u_max_)) {
    g = g_high_;
  } else {
    g = Hermite(g_, slope_, u_min_, du_, u);
  }
  const double alpha = std::min(1.0, g / load_n);        // eq. 6 load fraction
  return alpha * theta_[0] + (1.0 - alpha) * theta_[1];  // eq. 1
}

double MixedFrictionTable::EvalSommerfeld(double sommerfeld_um,
                                          double load_n) const {
  return EvalLog(std::log(sommerfeld_um), load_n);
}

double MixedFrictionTable::Eval(double v_mm_s,
                                double load_n,
                                double temp_c) const {
  const double t = temp_c + c_;
  if (!(t > 0)) return std::numeric_limits<double>::quiet_NaN();
  return EvalLog(log_a_ + b_ / t + std::log(v_mm_s / load_n) + log_const_,
                 load_n);
}

double CalcWearCoefficient(const MixedFrictionTheta& theta,
                           const AsperitySurface& surface,
                           const WearParams& wear,
                           double sommerfeld_um,
                           double load_n) {
  const double d =
      sommerfeld_um > 0 ? CalcFilmThicknessUm(theta, sommerfeld_um) : 0.0;
  return wear.k_solid * CalcSolidFraction(surface, d, load_n);
}

std::vector<WearPoint> PredictWearDrift(const MixedFrictionTheta& theta,
                                        const AsperitySurface& surface,
                                        const WearParams& wear,
                                        const JointContact& contact,
                                        double sommerfeld_um,
                                        double load_n,
                                        double distance_mm,
                                        int points) {
  RequireValidTheta(theta);
  ValidateSurface(surface);
  Require(wear.k_solid >= 0 && std::isfinite(wear.k_solid),
          "k_solid",
          wear.k_solid,
          "must be >= 0");
  Require(wear.hardness_mpa > 0 && std::isfinite(wear.hardness_mpa),
          "hardness_mpa",
          wear.hardness_mpa,
          "must be > 0");
  Require(contact.area_mm2 > 0 && std::isfinite(contact.area_mm2),
          "area_mm2",
          contact.area_mm2,
          "must be > 0");
  Require(sommerfeld_um >= 0 && std::isfinite(sommerfeld_um),
          "sommerfeld_um",
          sommerfeld_um,
          "must be >= 0");
  Require(load_n > 0 && std::isfinite(load_n), "load_n", load_n, "must be > 0");
  Require(distance_mm > 0 && std::isfinite(distance_mm),
          "distance_mm",
          distance_mm,
          "must be > 0");
  Require(points >= 2 && points <= 100000,
          "points",
          points,
          "must be in [2, 100000]");
  const double p_mpa = load_n / contact.area_mm2;  // N/mm^2
  std::vector<WearPoint> out;
  out.reserve(static_cast<std::size_t>(points));
  AsperitySurface worn = surface;
  double h_um = 0;
  const double ds = distance_mm / (points - 1);
  // Substeps of the worn-height ODE per output interval (midpoint rule).
  constexpr int kSubsteps = 20;
  for (int i = 0; i < points; ++i) {
    if (i > 0) {
      for (int k = 0; k < kSubsteps; ++k) {
        const double step = ds / kSubsteps;
        // dh/ds [mm/mm] = K p / H; h in um -> * 1e3.
        auto rate = [&](double h) {
          AsperitySurface s = surface;
          s.alt_um = std::max(0.0, surface.alt_um - h);
          return CalcWearCoefficient(theta, s, wear, sommerfeld_um, load_n) *
                 p_mpa / wear.hardness_mpa * 1e3;
        };
        const double mid = h_um + 0.5 * step * rate(h_um);
        h_um += step * rate(mid);
      }
    }
    worn.alt_um = std::max(0.0, surface.alt_um - h_um);
    WearPoint p;
    p.distance_mm = ds * i;
    p.worn_um = h_um;
    p.friction = CalcMixedFriction(theta, worn, sommerfeld_um, load_n);
    p.wear_coefficient =
        CalcWearCoefficient(theta, worn, wear, sommerfeld_um, load_n);
    out.push_back(p);
  }
  return out;
}

}  // namespace frictiond
