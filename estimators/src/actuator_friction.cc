#include "frictiond/estimators/actuator_friction.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/joint_friction.h"

namespace frictiond {

namespace {

struct LawName {
  ActuatorFrictionLaw law;
  const char* name;
};
constexpr LawName kLawNames[] = {
    {ActuatorFrictionLaw::kCoulombViscous, "coulomb_viscous"},
    {ActuatorFrictionLaw::kStribeck, "stribeck"},
    {ActuatorFrictionLaw::kLoadDependent, "load_dependent"},
    {ActuatorFrictionLaw::kDirectional, "directional"},
    {ActuatorFrictionLaw::kBamM6, "m6"},
    {ActuatorFrictionLaw::kLuGre, "lugre"},
    {ActuatorFrictionLaw::kMixedLubrication, "mixed"},
    {ActuatorFrictionLaw::kExtended, "extended"},
};

double Sign(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

// Stribeck factor s(dq) = exp(-|dq / dtheta_s|^alpha).
double StribeckFactor(const ActuatorFrictionParams& p, double dq) {
  const double r = std::abs(dq) / p.dtheta_stribeck;
  if (p.alpha == 2.0) return std::exp(-r * r);
  return std::exp(-std::pow(r, p.alpha));
}

}  // namespace

std::string ActuatorFrictionLawName(ActuatorFrictionLaw law) {
  for (const LawName& n : kLawNames)
    if (n.law == law) return n.name;
  return "unknown";
}

ActuatorFrictionLaw ParseActuatorFrictionLaw(const std::string& name) {
  for (const LawName& n : kLawNames)
    if (name == n.name) return n.law;
  std::string all;
  for (const LawName& n : kLawNames)
    all += std::string(all.empty() ? "" : ", ") + n.name;
  throw FieldError("law", "law = '" + name + "' (must be one of " + all + ")");
}

double ActuatorFrictionBudget::TotalNm(double dq_rad_s) const {
  return frictionloss_nm + damping_nm_s_rad * std::abs(dq_rad_s);
}

ActuatorFrictionBudget CalcActuatorFrictionBudget(
    ActuatorFrictionLaw law,
    const ActuatorFrictionParams& p,
    const ActuatorFrictionInput& in) {
  ActuatorFrictionBudget b;
  b.damping_nm_s_rad = p.friction_viscous;
  const double tm = in.motor_torque_nm, te = in.external_torque_nm;
  switch (law) {
    case ActuatorFrictionLaw::kCoulombViscous:
      b.frictionloss_nm = p.friction_base;
      break;
    case ActuatorFrictionLaw::kStribeck:
      b.frictionloss_nm = p.friction_base +
                          StribeckFactor(p, in.dq_rad_s) * p.friction_stribeck;
      break;
    case ActuatorFrictionLaw::kLoadDependent: {
      const double g = std::abs(te - tm);
      b.frictionloss_nm =
          p.friction_base + p.load_friction_base * g +
          StribeckFactor(p, in.dq_rad_s) *
              (p.friction_stribeck + p.load_friction_stribeck * g);
      break;
    }
    case ActuatorFrictionLaw::kDirectional:
    case ActuatorFrictionLaw::kBamM6:
    case ActuatorFrictionLaw::kExtended: {
      const double g =
          std::abs(p.load_friction_external * te - p.load_friction_motor * tm);
      const double g_s = std::abs(p.load_friction_external_stribeck * te -
                                  p.load_friction_motor_stribeck * tm);
      double extra = 0;
      if (law == ActuatorFrictionLaw::kBamM6 && Sign(te) != Sign(tm)) {
        // Quadratic term when motor and load oppose each other: the larger
        // of the two drives the gearbox (BAM M6).
        if (std::abs(te) < std::abs(tm))
          extra = p.load_friction_external_quad * te * te;
        else if (std::abs(te) > std::abs(tm))
          extra = p.load_friction_motor_quad * tm * tm;
      }
      double base = p.friction_base;
      if (law == ActuatorFrictionLaw::kExtended)
        base *= std::max(
            0.0, 1.0 + p.friction_temp_coeff * (in.temp_c - kFrictionRefTempC));
      b.frictionloss_nm =
          base + g +
          StribeckFactor(p, in.dq_rad_s) * (p.friction_stribeck + g_s + extra);
      break;
    }
    case ActuatorFrictionLaw::kLuGre:
      b.frictionloss_nm = p.friction_base +
                          p.friction_stribeck *
                              std::exp(-(in.dq_rad_s * in.dq_rad_s) /
                                       (p.dtheta_stribeck * p.dtheta_stribeck));
      break;
    case ActuatorFrictionLaw::kMixedLubrication: {
      // Paper 002 eq. 1 through the project's joint_friction API: normal
      // load N = torque / r, speed V = r |dq|, S = eta(T) V / p.
      static const AsperitySurface surface;
      static const Lubricant oil;
      static const JointContact contact;
      const double r_mm = kMixedContactRadiusMm;
      const double torque =
          p.mixed_load_base + p.mixed_load_gain * std::abs(te - tm);
      const double load_n = torque / (r_mm * 1e-3);
      double f = 1.0;
      if (load_n > 0) {
        const double eta = CalcViscosity(oil, in.temp_c);
        const double s = CalcSommerfeldUm(
            eta, r_mm * std::abs(in.dq_rad_s), load_n, contact);
        const MixedFrictionTheta theta = MakeMixedFrictionTheta(
            1.0, p.mixed_fluid_ratio, p.mixed_film_ref_um, p.mixed_film_power);
        f = CalcMixedFriction(
            theta, surface, std::isfinite(s) ? s : 0.0, load_n);
      }
      b.frictionloss_nm = std::max(0.0, torque) * f;
      break;
    }
  }
  return b;
}

double CalcBudgetFrictionTorque(const ActuatorFrictionBudget& budget,
                                double inertia_kg_m2,
                                double dt_s,
                                double dq_rad_s,
                                double net_torque_nm) {
  const double tau_stop = inertia_kg_m2 / dt_s * dq_rad_s + net_torque_nm;
  const double limit = budget.TotalNm(dq_rad_s);
  return -Sign(tau_stop) * std::min(std::abs(tau_stop), limit);
}

double CalcLuGreJointTorque(const ActuatorFrictionParams& p,
                            double dq_rad_s,
                            double dt_s,
                            double* z_rad) {
  // g(v) (paper 001 eq. 2, torque form) and dz/dt = v - sigma0 |v| z / g
  // (eq. 1): linear in z at constant v, so z relaxes exponentially towards
  // z_ss = g sign(v) / sigma0 with rate k = sigma0 |v| / g.
  const double v = dq_rad_s;
  const double g = std::max(
      1e-9,
      p.friction_base +
          p.friction_stribeck *
              std::exp(-(v * v) / (p.dtheta_stribeck * p.dtheta_stribeck)));
  const double k = p.lugre_sigma0 * std::abs(v) / g;
  const double z0 = *z_rad;
  double z1;
  if (k * dt_s < 1e-12) {
    z1 = z0 + v * dt_s;
  } else {
    const double z_ss = v / k;
    z1 = z_ss + (z0 - z_ss) * std::exp(-k * dt_s);
  }
  const double dz = (z1 - z0) / dt_s;
  *z_rad = z1;
  // eq. 3: F = sigma0 z + sigma1 dz/dt + sigma2 v (sigma2 = f_v).
  return -(p.lugre_sigma0 * z1 + p.lugre_sigma1 * dz + p.friction_viscous * v);
}

}  // namespace frictiond
