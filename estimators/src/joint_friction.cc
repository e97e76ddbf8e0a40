#include "frictiond/estimators/joint_friction.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace frictiond {

namespace {

constexpr double kSqrt2 = 1.41421356237309504880;
constexpr double kInvSqrt2Pi = 0.39894228040143267794;

std::string Num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", x);
  return buf;
}

void Require(bool ok,
             const std::string& field,
             double value,
             const std::string& rule) {
  if (!ok)
    throw std::invalid_argument(field + " = " + Num(value) + " (" + rule + ")");
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

bool IsValidMixedFrictionTheta(const MixedFrictionTheta& t, std::string* why) {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!t.allFinite()) return fail("theta has a non-finite entry");
  if (!(t[1] >= 0)) return fail("f_l = " + Num(t[1]) + " (must be >= 0)");
  if (!(t[0] >= t[1]))
    return fail("f_s = " + Num(t[0]) + " (must be >= f_l = " + Num(t[1]) + ")");
  if (!(t[2] > 0)) return fail("d_ref_um = " + Num(t[2]) + " (must be > 0)");
  if (!(t[3] > 0 && t[3] <= 3))
    return fail("n = " + Num(t[3]) + " (must be in (0, 3])");
  return true;
}

double CalcFilmThicknessUm(const MixedFrictionTheta& theta,
                           double sommerfeld_um) {
  return theta[2] * std::pow(sommerfeld_um / kSommerfeldRefUm, theta[3]);
}

double CalcSolidFraction(const AsperitySurface& surface,
                         double film_um,
                         double* J_alpha_d) {
  // alpha = int_d^inf p1(z) dz, p1 Gaussian (eq. 2) -> Q(lambda).
  const double lambda = (film_um - surface.alt_um) / surface.salt_um;
  if (J_alpha_d) {
    *J_alpha_d =
        -kInvSqrt2Pi * std::exp(-0.5 * lambda * lambda) / surface.salt_um;
  }
  return 0.5 * std::erfc(lambda / kSqrt2);
}

double CalcMixedFriction(const MixedFrictionTheta& theta,
                         const AsperitySurface& surface,
                         double sommerfeld_um,
                         MixedFrictionThetaRow* J_f_theta,
                         double* J_f_s) {
  const double f_s = theta[0], f_l = theta[1];
  if (!(sommerfeld_um > 0)) {  // no film: d = 0
    const double alpha = CalcSolidFraction(surface, 0.0);
    if (J_f_theta) *J_f_theta << alpha, 1.0 - alpha, 0.0, 0.0;
    if (J_f_s) *J_f_s = 0.0;
    return alpha * f_s + (1.0 - alpha) * f_l;
  }
  const bool want_j = J_f_theta || J_f_s;
  // (S/S_ref)^n: one pow when no Jacobian is asked for (the hot path).
  const double log_ratio =
      want_j ? std::log(sommerfeld_um / kSommerfeldRefUm) : 0.0;
  const double scale =
      want_j ? std::exp(theta[3] * log_ratio)
             : std::pow(sommerfeld_um / kSommerfeldRefUm, theta[3]);
  const double d = theta[2] * scale;
  double J_alpha_d = 0;
  const double alpha =
      CalcSolidFraction(surface, d, want_j ? &J_alpha_d : nullptr);
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
                                   double sommerfeld_um) {
  const double d =
      sommerfeld_um > 0 ? CalcFilmThicknessUm(theta, sommerfeld_um) : 0.0;
  const double alpha = CalcSolidFraction(surface, d);
  const double a = surface.radius_log_sd;
  const double var_alpha =
      alpha * (1.0 - alpha) * std::exp(0.25 * a * a) / surface.summits;
  return (theta[0] - theta[1]) * std::sqrt(var_alpha);
}

double SampleContactFriction(const MixedFrictionTheta& theta,
                             const AsperitySurface& surface,
                             double sommerfeld_um,
                             std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const double d =
      sommerfeld_um > 0 ? CalcFilmThicknessUm(theta, sommerfeld_um) : 0.0;
  const long n = std::max(1L, std::lround(surface.summits));
  double w_solid = 0, w_all = 0;
  for (long i = 0; i < n; ++i) {
    const double z = surface.alt_um + surface.salt_um * normal(*rng);  // eq. 2
    // R = SRAD R*, log R* ~ N(b, a^2) (eqs. 4-5); load weight sqrt(R).
    const double r_um =
        surface.srad_um * std::exp(surface.radius_log_mean +
                                   surface.radius_log_sd * normal(*rng));
    const double w = std::sqrt(r_um);
    w_all += w;
    if (z > d) w_solid += w;
  }
  const double alpha = w_solid / w_all;
  return alpha * theta[0] + (1.0 - alpha) * theta[1];
}

MixedFrictionTable::MixedFrictionTable(const MixedFrictionTheta& theta,
                                       const AsperitySurface& surface,
                                       const Lubricant& lubricant,
                                       const JointContact& contact) {
  std::string why;
  if (!IsValidMixedFrictionTheta(theta, &why)) throw std::invalid_argument(why);
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
  // Grid in u = ln S: where d runs from 1e-6 Alt.. (Alt + 12 SAlt), beyond
  // which alpha is 1 - Q(Alt/SAlt)-limited or below 1e-30.
  const double d_lo = 1e-9 * std::max(surface.salt_um, 1e-12);
  const double d_hi = std::max(surface.alt_um, 0.0) + 12.0 * surface.salt_um;
  auto u_of_d = [&](double d) {
    return std::log(kSommerfeldRefUm) + std::log(d / theta[2]) / theta[3];
  };
  u_min_ = u_of_d(d_lo);
  u_max_ = u_of_d(d_hi);
  constexpr int kNodes = 4096;
  du_ = (u_max_ - u_min_) / (kNodes - 1);
  inv_du_ = 1.0 / du_;
  f_.resize(kNodes);
  slope_.resize(kNodes);
  for (int i = 0; i < kNodes; ++i) {
    const double s = std::exp(u_min_ + du_ * i);
    double J_f_s = 0;
    f_[static_cast<std::size_t>(i)] =
        CalcMixedFriction(theta, surface, s, nullptr, &J_f_s);
    slope_[static_cast<std::size_t>(i)] = J_f_s * s;  // df/du
  }
  f_low_ = CalcMixedFriction(theta, surface, std::exp(u_min_));
  f_high_ = CalcMixedFriction(theta, surface, std::exp(u_max_));
}

double MixedFrictionTable::EvalLog(double u) const {
  if (!(u > u_min_)) return f_low_;
  if (!(u < u_max_)) return f_high_;
  const double x = (u - u_min_) * inv_du_;
  const std::size_t i = std::min(static_cast<std::size_t>(x), f_.size() - 2);
  const double t = x - static_cast<double>(i);
  const double t2 = t * t, t3 = t2 * t;
  const double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + t;
  const double h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
  return h00 * f_[i] + h10 * du_ * slope_[i] + h01 * f_[i + 1] +
         h11 * du_ * slope_[i + 1];
}

double MixedFrictionTable::EvalSommerfeld(double sommerfeld_um) const {
  return EvalLog(std::log(sommerfeld_um));
}

double MixedFrictionTable::Eval(double v_mm_s,
                                double load_n,
                                double temp_c) const {
  const double t = temp_c + c_;
  if (!(t > 0)) return std::numeric_limits<double>::quiet_NaN();
  return EvalLog(log_a_ + b_ / t + std::log(v_mm_s / load_n) + log_const_);
}

double CalcWearCoefficient(const MixedFrictionTheta& theta,
                           const AsperitySurface& surface,
                           const WearParams& wear,
                           double sommerfeld_um) {
  const double d =
      sommerfeld_um > 0 ? CalcFilmThicknessUm(theta, sommerfeld_um) : 0.0;
  return wear.k_solid * CalcSolidFraction(surface, d);
}

std::vector<WearPoint> PredictWearDrift(const MixedFrictionTheta& theta,
                                        const AsperitySurface& surface,
                                        const WearParams& wear,
                                        const JointContact& contact,
                                        double sommerfeld_um,
                                        double load_n,
                                        double distance_mm,
                                        int points) {
  std::string why;
  if (!IsValidMixedFrictionTheta(theta, &why)) throw std::invalid_argument(why);
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
          return CalcWearCoefficient(theta, s, wear, sommerfeld_um) * p_mpa /
                 wear.hardness_mpa * 1e3;
        };
        const double mid = h_um + 0.5 * step * rate(h_um);
        h_um += step * rate(mid);
      }
    }
    worn.alt_um = std::max(0.0, surface.alt_um - h_um);
    WearPoint p;
    p.distance_mm = ds * i;
    p.worn_um = h_um;
    p.friction = CalcMixedFriction(theta, worn, sommerfeld_um);
    p.wear_coefficient = CalcWearCoefficient(theta, worn, wear, sommerfeld_um);
    out.push_back(p);
  }
  return out;
}

}  // namespace frictiond
