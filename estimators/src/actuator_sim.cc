#include "frictiond/estimators/actuator_sim.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/least_squares.h"
#include "frictiond/estimators/number_text.h"

namespace frictiond {

namespace {

constexpr double kDivergedMaeRad = 10.0;
constexpr int kLuGreSubsteps = 10;

double Clip(double x, double lo, double hi) {
  return x < lo ? lo : (x > hi ? hi : x);
}

constexpr ActuatorParamInfo kParamInfo[] = {
    {"kt", 0.05, 3.0},
    {"R", 0.5, 10.0},
    {"armature", 1e-5, 0.02},
    {"q_offset", -0.1, 0.1},
    {"gain_scale", 0.3, 3.0},
    {"r_temp_coeff", -0.02, 0.05},
    {"backlash", 0.0, 0.1},
    {"current_limit", 0.0, 5.0},
    {"command_delay", 0.0, 0.05},
    {"friction_base", 0.0, 0.3},
    {"friction_viscous", 0.0, 0.2},
    {"friction_stribeck", 0.0, 0.3},
    {"dtheta_stribeck", 0.02, 5.0},
    {"alpha", 0.5, 5.0},
    {"load_friction_base", 0.0, 1.0},
    {"load_friction_stribeck", 0.0, 1.0},
    {"load_friction_motor", 0.0, 1.0},
    {"load_friction_external", 0.0, 1.0},
    {"load_friction_motor_stribeck", 0.0, 1.0},
    {"load_friction_external_stribeck", 0.0, 1.0},
    {"load_friction_motor_quad", 0.0, 0.05},
    {"load_friction_external_quad", 0.0, 0.05},
    {"friction_temp_coeff", -0.1, 0.1},
    {"lugre_sigma0", 10.0, 5000.0},
    {"lugre_sigma1", 0.0, 0.5},
    {"mixed_load_base", 0.0, 0.3},
    {"mixed_load_gain", 0.0, 1.0},
    {"mixed_fluid_ratio", 0.0, 1.0},
    {"mixed_film_ref_um", 0.01, 10.0},
    {"mixed_film_power", 0.1, 3.0},
};
static_assert(sizeof(kParamInfo) / sizeof(kParamInfo[0]) ==
                  static_cast<std::size_t>(ActuatorParam::kCount),
              "one ActuatorParamInfo per ActuatorParam");

// Bounded <-> unbounded coordinates: p = lo + (hi - lo) / (1 + exp(-u)).
double ToBounded(double u, const ActuatorParamInfo& info) {
  return info.lo + (info.hi - info.lo) / (1.0 + std::exp(-u));
}
double ToUnbounded(double p, const ActuatorParamInfo& info) {
  const double w = info.hi - info.lo;
  const double x = Clip((p - info.lo) / w, 1e-6, 1.0 - 1e-6);
  return std::log(x / (1.0 - x));
}
double DBoundedDu(double u, const ActuatorParamInfo& info) {
  const double s = 1.0 / (1.0 + std::exp(-u));
  return (info.hi - info.lo) * s * (1.0 - s);
}

// Motor torque tau_m (DC motor with back-EMF) for the controller state.
struct MotorConsts {
  double gain;  // kp g_e s_g
  double vin, kt;
};

}  // namespace

ActuatorModel MakeDefaultActuatorModel(ActuatorFrictionLaw law) {
  ActuatorModel m;
  m.law = law;
  m.kt = 0.3;
  m.r_ohm = 4.0;
  m.armature_kg_m2 = 0.0018;
  m.q_offset_rad = 0.02;
  ActuatorFrictionParams& f = m.friction;
  f.friction_base = 0.005;
  f.friction_viscous = 0.01;
  if (law != ActuatorFrictionLaw::kCoulombViscous) {
    f.friction_stribeck = 0.004;
    f.dtheta_stribeck = 1.0;
    f.alpha = 1.7;
  }
  if (law == ActuatorFrictionLaw::kLoadDependent) {
    f.load_friction_base = 0.05;
    f.load_friction_stribeck = 0.05;
  }
  if (law == ActuatorFrictionLaw::kDirectional ||
      law == ActuatorFrictionLaw::kBamM6 ||
      law == ActuatorFrictionLaw::kExtended) {
    f.load_friction_motor = 0.1;
    f.load_friction_external = 0.1;
    f.load_friction_motor_stribeck = 0.02;
    f.load_friction_external_stribeck = 0.05;
  }
  if (law == ActuatorFrictionLaw::kBamM6) {
    f.load_friction_motor_quad = 0.005;
    f.load_friction_external_quad = 0.005;
  }
  if (law == ActuatorFrictionLaw::kMixedLubrication) {
    f.mixed_load_base = 0.01;
    f.mixed_load_gain = 0.1;
  }
  return m;
}

void ValidateActuatorLog(const ActuatorLog& log) {
  auto positive = [](const char* field, double v) {
    if (!(v > 0) || !std::isfinite(v))
      throw FieldError(field,
                       std::string(field) + " = " + NumberText(v) +
                           " (must be finite and > 0)");
  };
  positive("mass", log.mass_kg);
  positive("length", log.length_m);
  positive("kp", log.kp);
  positive("vin", log.vin_v);
  positive("dt", log.dt_s);
  const std::size_t n = log.q_rad.size();
  if (n < 2)
    throw FieldError::Because("entries",
                              std::to_string(n) + " (must hold at least 2)");
  auto same = [&](const char* field, std::size_t m) {
    if (m != n)
      throw FieldError::Because(
          std::string("entries.") + field,
          std::to_string(m) + " values for " + std::to_string(n) + " entries");
  };
  same("timestamp", log.t_s.size());
  same("speed", log.dq_rad_s.size());
  same("goal_position", log.goal_rad.size());
  same("temp", log.temp_c.size());
  same("torque_enable", log.torque_enable.size());
  auto finite = [&](const char* field, const std::vector<double>& v) {
    for (std::size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(v[i]))
        throw FieldError("entries[" + std::to_string(i) + "]." + field,
                         "entries[" + std::to_string(i) + "]." + field + " = " +
                             NumberText(v[i]) + " (must be finite)");
  };
  finite("timestamp", log.t_s);
  finite("position", log.q_rad);
  finite("speed", log.dq_rad_s);
  finite("goal_position", log.goal_rad);
  finite("temp", log.temp_c);
  for (std::size_t i = 1; i < n; ++i)
    if (!(log.t_s[i] > log.t_s[i - 1]))
      throw FieldError("entries[" + std::to_string(i) + "].timestamp",
                       "entries[" + std::to_string(i) +
                           "].timestamp = " + NumberText(log.t_s[i]) +
                           " (must be > the previous " +
                           NumberText(log.t_s[i - 1]) + ")");
}

ActuatorCommand CalcActuatorCommand(const ActuatorModel& m,
                                    const ActuatorLog& log,
                                    std::size_t k,
                                    double q_rad,
                                    double motor_speed_rad_s) {
  const std::size_t n = log.size();
  ActuatorCommand out;
  out.r_ohm = std::max(
      1e-3,
      m.r_ohm *
          (1.0 + m.r_temp_coeff_per_c * (log.temp_c[k] - kResistanceRefTempC)));
  out.enabled = log.torque_enable[k] != 0;
  const double delay_steps = std::max(0.0, m.command_delay_s / log.dt_s);
  double goal = log.goal_rad[k];
  if (delay_steps > 0) {
    const double back = static_cast<double>(k) - delay_steps;
    if (back <= 0) {
      goal = log.goal_rad[0];
    } else {
      const std::size_t i = static_cast<std::size_t>(back);
      const double w = back - static_cast<double>(i);
      goal = log.goal_rad[i] +
             w * (log.goal_rad[std::min(i + 1, n - 1)] - log.goal_rad[i]);
    }
  }
  const double gain = log.kp * kXl330ErrorGain * m.gain_scale;
  double duty = gain * (goal - q_rad);
  if (m.current_limit_a > 0) {
    const double center = m.kt * motor_speed_rad_s / log.vin_v;
    const double span = out.r_ohm * m.current_limit_a / log.vin_v;
    duty = Clip(duty, center - span, center + span);
  }
  out.duty = Clip(duty, -1.0, 1.0);
  return out;
}

double SimulateActuatorLog(const ActuatorModel& m,
                           const ActuatorLog& log,
                           ActuatorRolloutTrace* trace) {
  const std::size_t n = log.size();
  const double dt = log.dt_s;
  const double ml2 = log.mass_kg * log.length_m * log.length_m;
  const double inertia = ml2 + m.armature_kg_m2;
  const double mgl = log.mass_kg * kGravityM_s2 * log.length_m;
  const double kt = m.kt;
  const ActuatorFrictionParams& fp = m.friction;
  const bool lugre = m.law == ActuatorFrictionLaw::kLuGre;
  const double half_gap = 0.5 * m.backlash_rad;
  const bool backlash = half_gap > 0 && m.armature_kg_m2 > 0;
  if (trace) {
    // Emptied, keeping capacity (a reused trace does not reallocate).
    for (std::vector<double>* v : {&trace->q_rad,
                                   &trace->dq_rad_s,
                                   &trace->motor_torque_nm,
                                   &trace->external_torque_nm,
                                   &trace->friction_torque_nm})
      v->clear();
    trace->q_rad.reserve(n);
    trace->dq_rad_s.reserve(n);
    trace->motor_torque_nm.reserve(n);
    trace->external_torque_nm.reserve(n);
    trace->friction_torque_nm.reserve(n);
  }
  double q = log.q_rad[0], dq = log.dq_rad_s[0];
  double qm = q, dqm = dq;  // motor side (backlash only)
  double z = 0;             // LuGre bristles
  double err = 0;
  for (std::size_t k = 0; k < n; ++k) {
    err += std::abs(q - log.q_rad[k]);
    if (trace) trace->q_rad.push_back(q);
    const ActuatorCommand command =
        CalcActuatorCommand(m, log, k, q, backlash ? dqm : dq);
    const double r = command.r_ohm;
    const bool enabled = command.enabled;
    const double volts = log.vin_v * command.duty;
    auto motor_torque = [&](double speed) {
      return enabled ? kt * (volts - kt * speed) / r : 0.0;
    };
    double tau_m = 0, tau_e = 0, tau_f = 0;
    if (lugre) {
      const double h = dt / kLuGreSubsteps;
      for (int s = 0; s < kLuGreSubsteps; ++s) {
        tau_m = motor_torque(dq);
        tau_e = -mgl * std::sin(q + m.q_offset_rad);
        tau_f = CalcLuGreJointTorque(fp, dq, h, &z);
        dq += (tau_m + tau_e + tau_f) / inertia * h;
        q += dq * h;
      }
      qm = q;
      dqm = dq;
    } else if (!backlash) {
      tau_m = motor_torque(dq);
      tau_e = -mgl * std::sin(q + m.q_offset_rad);
      const ActuatorFrictionBudget b = CalcActuatorFrictionBudget(
          m.law, fp, {dq, tau_m, tau_e, log.temp_c[k]});
      tau_f = CalcBudgetFrictionTorque(b, inertia, dt, dq, tau_m + tau_e);
      dq += (tau_m + tau_e + tau_f) / inertia * dt;
      q += dq * dt;
    } else {
      tau_m = motor_torque(dqm);
      tau_e = -mgl * std::sin(q + m.q_offset_rad);
      const ActuatorFrictionBudget b = CalcActuatorFrictionBudget(
          m.law, fp, {dq, tau_m, tau_e, log.temp_c[k]});
      const double gap = qm - q;
      bool together = false;
      if (std::abs(gap) >= half_gap * (1.0 - 1e-9)) {
        // Gap closed: the pair moves as one body if the motor side pushes
        // the output (contact torque along the gap's side).
        const double f_c =
            CalcBudgetFrictionTorque(b, inertia, dt, dq, tau_m + tau_e);
        const double a_c = (tau_m + tau_e + f_c) / inertia;
        const double contact = ml2 * a_c - tau_e - f_c;
        if ((gap > 0) == (contact > 0) && std::abs(dqm - dq) < 1e-9) {
          together = true;
          tau_f = f_c;
          dq += a_c * dt;
          q += dq * dt;
          dqm = dq;
          qm = q + (gap > 0 ? half_gap : -half_gap);
        }
      }
      if (!together) {
        tau_f = CalcBudgetFrictionTorque(b, ml2, dt, dq, tau_e);
        dq += (tau_e + tau_f) / ml2 * dt;
        q += dq * dt;
        dqm += tau_m / m.armature_kg_m2 * dt;
        qm += dqm * dt;
        const double g = qm - q;
        if (std::abs(g) > half_gap) {  // contact: inelastic, momentum kept
          const double v = (ml2 * dq + m.armature_kg_m2 * dqm) / inertia;
          dq = dqm = v;
          qm = q + (g > 0 ? half_gap : -half_gap);
        }
      }
    }
    if (trace) {
      trace->dq_rad_s.push_back(dq);
      trace->motor_torque_nm.push_back(tau_m);
      trace->external_torque_nm.push_back(tau_e);
      trace->friction_torque_nm.push_back(tau_f);
    }
    if (!std::isfinite(q) || !std::isfinite(dq)) {
      if (trace) trace->q_rad.resize(n, std::nan(""));
      return kDivergedMaeRad;
    }
  }
  return err / static_cast<double>(n);
}

const ActuatorParamInfo& GetActuatorParamInfo(ActuatorParam p) {
  return kParamInfo[static_cast<int>(p)];
}

double& ActuatorParamRef(ActuatorModel& m, ActuatorParam p) {
  ActuatorFrictionParams& f = m.friction;
  switch (p) {
    case ActuatorParam::kKt:
      return m.kt;
    case ActuatorParam::kR:
      return m.r_ohm;
    case ActuatorParam::kArmature:
      return m.armature_kg_m2;
    case ActuatorParam::kQOffset:
      return m.q_offset_rad;
    case ActuatorParam::kGainScale:
      return m.gain_scale;
    case ActuatorParam::kRTempCoeff:
      return m.r_temp_coeff_per_c;
    case ActuatorParam::kBacklash:
      return m.backlash_rad;
    case ActuatorParam::kCurrentLimit:
      return m.current_limit_a;
    case ActuatorParam::kCommandDelay:
      return m.command_delay_s;
    case ActuatorParam::kFrictionBase:
      return f.friction_base;
    case ActuatorParam::kFrictionViscous:
      return f.friction_viscous;
    case ActuatorParam::kFrictionStribeck:
      return f.friction_stribeck;
    case ActuatorParam::kDthetaStribeck:
      return f.dtheta_stribeck;
    case ActuatorParam::kAlpha:
      return f.alpha;
    case ActuatorParam::kLoadFrictionBase:
      return f.load_friction_base;
    case ActuatorParam::kLoadFrictionStribeck:
      return f.load_friction_stribeck;
    case ActuatorParam::kLoadFrictionMotor:
      return f.load_friction_motor;
    case ActuatorParam::kLoadFrictionExternal:
      return f.load_friction_external;
    case ActuatorParam::kLoadFrictionMotorStribeck:
      return f.load_friction_motor_stribeck;
    case ActuatorParam::kLoadFrictionExternalStribeck:
      return f.load_friction_external_stribeck;
    case ActuatorParam::kLoadFrictionMotorQuad:
      return f.load_friction_motor_quad;
    case ActuatorParam::kLoadFrictionExternalQuad:
      return f.load_friction_external_quad;
    case ActuatorParam::kFrictionTempCoeff:
      return f.friction_temp_coeff;
    case ActuatorParam::kLuGreSigma0:
      return f.lugre_sigma0;
    case ActuatorParam::kLuGreSigma1:
      return f.lugre_sigma1;
    case ActuatorParam::kMixedLoadBase:
      return f.mixed_load_base;
    case ActuatorParam::kMixedLoadGain:
      return f.mixed_load_gain;
    case ActuatorParam::kMixedFluidRatio:
      return f.mixed_fluid_ratio;
    case ActuatorParam::kMixedFilmRef:
      return f.mixed_film_ref_um;
    case ActuatorParam::kMixedFilmPower:
      return f.mixed_film_power;
    case ActuatorParam::kCount:
      break;
  }
  throw std::invalid_argument("ActuatorParam out of range");
}

double ActuatorParamValue(const ActuatorModel& m, ActuatorParam p) {
  return ActuatorParamRef(const_cast<ActuatorModel&>(m), p);
}

std::vector<ActuatorParam> ActuatorLawParams(ActuatorFrictionLaw law) {
  using P = ActuatorParam;
  std::vector<P> v = {P::kKt,
                      P::kR,
                      P::kArmature,
                      P::kQOffset,
                      P::kFrictionBase,
                      P::kFrictionViscous};
  const std::vector<P> stribeck = {
      P::kFrictionStribeck, P::kDthetaStribeck, P::kAlpha};
  const std::vector<P> directional = {P::kLoadFrictionMotor,
                                      P::kLoadFrictionExternal,
                                      P::kLoadFrictionMotorStribeck,
                                      P::kLoadFrictionExternalStribeck};
  auto add = [&](const std::vector<P>& w) {
    v.insert(v.end(), w.begin(), w.end());
  };
  switch (law) {
    case ActuatorFrictionLaw::kCoulombViscous:
      break;
    case ActuatorFrictionLaw::kStribeck:
      add(stribeck);
      break;
    case ActuatorFrictionLaw::kLoadDependent:
      add(stribeck);
      add({P::kLoadFrictionBase, P::kLoadFrictionStribeck});
      break;
    case ActuatorFrictionLaw::kDirectional:
      add(stribeck);
      add(directional);
      break;
    case ActuatorFrictionLaw::kBamM6:
      add(stribeck);
      add(directional);
      add({P::kLoadFrictionMotorQuad, P::kLoadFrictionExternalQuad});
      break;
    case ActuatorFrictionLaw::kExtended:
      add(stribeck);
      add(directional);
      add({P::kFrictionTempCoeff});
      break;
    case ActuatorFrictionLaw::kLuGre:
      add({P::kFrictionStribeck,
           P::kDthetaStribeck,
           P::kLuGreSigma0,
           P::kLuGreSigma1});
      break;
    case ActuatorFrictionLaw::kMixedLubrication:
      v.erase(std::find(v.begin(), v.end(), P::kFrictionBase));
      add({P::kMixedLoadBase,
           P::kMixedLoadGain,
           P::kMixedFluidRatio,
           P::kMixedFilmRef,
           P::kMixedFilmPower});
      break;
  }
  return v;
}

double CalcActuatorSetMae(const ActuatorModel& model,
                          const std::vector<const ActuatorLog*>& logs) {
  double sum = 0;
  std::size_t count = 0;
  for (const ActuatorLog* log : logs) {
    sum += SimulateActuatorLog(model, *log) * static_cast<double>(log->size());
    count += log->size();
  }
  return count ? sum / static_cast<double>(count) : 0.0;
}

namespace {

class SetObjective {
 public:
  SetObjective(const std::vector<const ActuatorLog*>& logs,
               const ActuatorModel& start,
               const std::vector<ActuatorParam>& free)
      : logs_(logs), model_(start), free_(free) {}

  ActuatorModel ModelAt(const Eigen::VectorXd& u) const {
    ActuatorModel m = model_;
    for (std::size_t i = 0; i < free_.size(); ++i)
      ActuatorParamRef(m, free_[i]) =
          ToBounded(u[i], GetActuatorParamInfo(free_[i]));
    return m;
  }
  Eigen::VectorXd UAt(const ActuatorModel& m) const {
    Eigen::VectorXd u(free_.size());
    for (std::size_t i = 0; i < free_.size(); ++i)
      u[i] = ToUnbounded(ActuatorParamValue(m, free_[i]),
                         GetActuatorParamInfo(free_[i]));
    return u;
  }
  double Mae(const Eigen::VectorXd& u) {
    ++evaluations_;
    const double f = CalcActuatorSetMae(ModelAt(u), logs_);
    return std::isfinite(f) ? f : kDivergedMaeRad;
  }
  // Entries of all logs (the number of residuals).
  Eigen::Index Entries() const {
    std::size_t total = 0;
    for (const ActuatorLog* log : logs_) total += log->size();
    return static_cast<Eigen::Index>(total);
  }
  // One rollout of the set at u: fills *r (Entries() entries) with the
  // smoothed-L1 residuals e / sqrt(|e| + delta), e = q_sim - q (an entry
  // that diverged counts as e = kDivergedMaeRad), and returns the set's
  // mean absolute error exactly as Mae(u) does (the criterion).
  double Residuals(const Eigen::VectorXd& u, double delta, Eigen::VectorXd* r) {
    ++evaluations_;
    const ActuatorModel m = ModelAt(u);
    r->resize(Entries());
    Eigen::Index at = 0;
    double sum = 0;
    std::size_t count = 0;
    for (const ActuatorLog* log : logs_) {
      sum += SimulateActuatorLog(m, *log, &trace_) *
             static_cast<double>(log->size());
      count += log->size();
      for (std::size_t k = 0; k < log->size(); ++k) {
        double e = trace_.q_rad[k] - log->q_rad[k];
        if (!std::isfinite(e)) e = kDivergedMaeRad;
        (*r)[at++] = e / std::sqrt(std::abs(e) + delta);
      }
    }
    const double f = count ? sum / static_cast<double>(count) : 0.0;
    return std::isfinite(f) ? f : kDivergedMaeRad;
  }
  int evaluations() const { return evaluations_; }

 private:
  const std::vector<const ActuatorLog*>& logs_;
  ActuatorModel model_;
  std::vector<ActuatorParam> free_;
  ActuatorRolloutTrace trace_;  // reused by Residuals
  int evaluations_ = 0;
};

// Nelder-Mead on f(u) (standard coefficients 1, 2, 1/2, 1/2).
template <typename F>
Eigen::VectorXd NelderMead(F&& f,
                           const Eigen::VectorXd& u0,
                           double step,
                           int max_evaluations,
                           double* f_best,
                           int* used) {
  const int n = static_cast<int>(u0.size());
  std::vector<Eigen::VectorXd> x(n + 1, u0);
  std::vector<double> fx(n + 1);
  for (int i = 0; i < n; ++i) x[i + 1][i] += step;
  int evals = 0;
  for (int i = 0; i <= n; ++i, ++evals) fx[i] = f(x[i]);
  std::vector<int> order(n + 1);
  while (evals < max_evaluations) {
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      return fx[a] < fx[b];
    });
    const int best = order[0], worst = order[n], second = order[n - 1];
    if (fx[worst] - fx[best] < 1e-9 * (1.0 + fx[best])) break;
    Eigen::VectorXd centroid = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < n; ++i) centroid += x[order[i]];
    centroid /= n;
    const Eigen::VectorXd xr = centroid + (centroid - x[worst]);
    const double fr = f(xr);
    ++evals;
    if (fr < fx[best]) {
      const Eigen::VectorXd xe = centroid + 2.0 * (centroid - x[worst]);
      const double fe = f(xe);
      ++evals;
      if (fe < fr) {
        x[worst] = xe;
        fx[worst] = fe;
      } else {
        x[worst] = xr;
        fx[worst] = fr;
      }
    } else if (fr < fx[second]) {
      x[worst] = xr;
      fx[worst] = fr;
    } else {
      const bool outside = fr < fx[worst];
      const Eigen::VectorXd xc =
          outside ? Eigen::VectorXd(centroid + 0.5 * (xr - centroid))
                  : Eigen::VectorXd(centroid + 0.5 * (x[worst] - centroid));
      const double fc = f(xc);
      ++evals;
      if (fc < (outside ? fr : fx[worst])) {
        x[worst] = xc;
        fx[worst] = fc;
      } else {
        for (int i = 1; i <= n; ++i) {
          const int j = order[i];
          x[j] = x[best] + 0.5 * (x[j] - x[best]);
          fx[j] = f(x[j]);
          ++evals;
        }
      }
    }
  }
  const int best =
      static_cast<int>(std::min_element(fx.begin(), fx.end()) - fx.begin());
  *f_best = fx[best];
  *used = evals;
  return x[best];
}

}  // namespace

ActuatorFitResult FitActuatorModel(const std::vector<const ActuatorLog*>& logs,
                                   const ActuatorModel& start,
                                   const std::vector<ActuatorParam>& free,
                                   const ActuatorFitOptions& options) {
  ActuatorFitResult result;
  result.free = free;
  result.model = start;
  if (logs.empty() || free.empty()) {
    result.why = logs.empty() ? "no logs" : "no free parameters";
    return result;
  }
  SetObjective obj(logs, start, free);
  auto mae = [&](const Eigen::VectorXd& u) { return obj.Mae(u); };
  Eigen::VectorXd u = obj.UAt(start);
  double f_best = obj.Mae(u);
  bool budget_left = false;
  // Stage 1: derivative-free (the rollout error is non-smooth in the
  // friction parameters: stick/slip switches).
  for (int r = 0; r <= options.nm_restarts; ++r) {
    int used = 0;
    double f = 0;
    const double step = r == 0 ? 0.7 : 0.25;
    const int budget =
        r == 0 ? options.nm_max_evaluations : options.nm_max_evaluations / 2;
    const Eigen::VectorXd un = NelderMead(mae, u, step, budget, &f, &used);
    budget_left = used < budget;
    if (f <= f_best) {
      f_best = f;
      u = un;
    }
  }
  // Stage 2: Levenberg-Marquardt (least_squares.h, split form) on the
  // smoothed-L1 residuals e / sqrt(|e| + delta) (their squares sum to
  // ~sum |e|, a smooth stand-in for the L1 criterion), with forward-
  // difference Jacobians (step h in u), accepting a step only when the mean
  // absolute error (the criterion, the solver's cost) falls strictly. The
  // parameters are unbounded in u (logistic map), so the box is infinite.
  const int p = static_cast<int>(free.size());
  const double h = 1e-3;
  LeastSquaresWorkspace<Eigen::Dynamic> ws(obj.Entries(), p);
  Eigen::VectorXd r_h;
  auto residual =
      [&](const Eigen::VectorXd& uc, Eigen::VectorXd* r, double* criterion) {
        *criterion = obj.Residuals(uc, options.huber_rad, r);
        return true;
      };
  auto jacobian = [&](const Eigen::VectorXd& uc,
                      const Eigen::VectorXd& rc,
                      Eigen::MatrixXd* J) {
    for (int j = 0; j < p; ++j) {
      Eigen::VectorXd up = uc;
      up[j] += h;
      obj.Residuals(up, options.huber_rad, &r_h);
      J->col(j) = (r_h - rc) / h;
    }
    return J->allFinite();
  };
  bool have_jacobian = false;
  if (options.lm_iterations > 0) {
    LeastSquaresOptions lm;
    lm.max_iterations = options.lm_iterations;
    lm.cost_tolerance = 0.0;  // run the iterations while the MAE falls
    lm.step_tolerance = 0.0;
    lm.initial_lambda = 1e-2;
    lm.lambda_increase = 10.0;
    lm.lambda_decrease = 1.0 / 0.3;
    lm.min_lambda = 1e-6;
    lm.max_step_tries = 6;
    lm.min_diagonal = 1e-12;
    lm.strict_decrease = true;
    const Eigen::VectorXd inf =
        Eigen::VectorXd::Constant(p, std::numeric_limits<double>::infinity());
    Eigen::VectorXd u_lm = u;
    const LeastSquaresSummary<Eigen::Dynamic> s =
        SolveLeastSquares<Eigen::Dynamic>(
            residual, jacobian, &u_lm, Eigen::VectorXd(-inf), inf, lm, &ws);
    // s.cost <= f_best: the solver starts at u and only accepts steps
    // that lower the MAE. ws.r and ws.J are those at u_lm.
    if (s.status != LeastSquaresStatus::kFailed) {
      u = u_lm;
      f_best = s.cost;
      have_jacobian = true;
    }
  }
  result.model = obj.ModelAt(u);
  result.mae_rad = f_best;
  // Standard errors: Gauss-Newton covariance of the smoothed-L1 residuals
  // in u, mapped through dp/du, inflated by sqrt(N / N_eff) with N_eff from
  // the lag-1 autocorrelation of the residuals (rollout errors are smooth
  // in time, so the entries are far from independent).
  if (!have_jacobian) {
    double criterion = 0;
    residual(u, &ws.r, &criterion);
    jacobian(u, ws.r, &ws.J);
  }
  const Eigen::VectorXd& r = ws.r;
  const Eigen::MatrixXd& J = ws.J;
  const double n = static_cast<double>(r.size());
  const double s2 = r.squaredNorm() / std::max(1.0, n - p);
  double r1 = 0;
  if (r.size() > 2) {
    const double num = r.head(r.size() - 1).dot(r.tail(r.size() - 1));
    r1 = Clip(num / std::max(1e-300, r.squaredNorm()), 0.0, 0.999);
  }
  const double inflation = std::sqrt((1.0 + r1) / (1.0 - r1));
  Eigen::MatrixXd A = J.transpose() * J;
  A.diagonal().array() += 1e-12 * (1.0 + A.diagonal().maxCoeff());
  const Eigen::MatrixXd P_u =
      s2 * A.ldlt().solve(Eigen::MatrixXd::Identity(p, p));
  result.stderr_.resize(p);
  for (int i = 0; i < p; ++i)
    result.stderr_[i] = inflation *
                        DBoundedDu(u[i], GetActuatorParamInfo(free[i])) *
                        std::sqrt(std::max(0.0, P_u(i, i)));
  // Bootstrap over logs (resample logs with replacement, refit from the
  // optimum with a quarter of the derivative-free budget).
  if (options.bootstrap > 0) {
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<std::size_t> pick(0, logs.size() - 1);
    std::vector<std::vector<double>> draws(p);
    for (int b = 0; b < options.bootstrap; ++b) {
      std::vector<const ActuatorLog*> sample(logs.size());
      for (auto& s : sample) s = logs[pick(rng)];
      SetObjective bobj(sample, result.model, free);
      int used = 0;
      double f = 0;
      const Eigen::VectorXd ub =
          NelderMead([&](const Eigen::VectorXd& x) { return bobj.Mae(x); },
                     u,
                     0.25,
                     std::max(50, options.nm_max_evaluations / 4),
                     &f,
                     &used);
      for (int i = 0; i < p; ++i)
        draws[i].push_back(ToBounded(ub[i], GetActuatorParamInfo(free[i])));
    }
    result.boot_lo.resize(p);
    result.boot_hi.resize(p);
    for (int i = 0; i < p; ++i) {
      std::sort(draws[i].begin(), draws[i].end());
      const std::size_t m = draws[i].size();
      result.boot_lo[i] = draws[i][static_cast<std::size_t>(0.05 * (m - 1))];
      result.boot_hi[i] =
          draws[i][static_cast<std::size_t>(0.95 * (m - 1) + 0.5)];
    }
  }
  result.evaluations = obj.evaluations();
  result.converged = std::isfinite(f_best) && f_best < kDivergedMaeRad;
  if (!result.converged) result.why = "rollout diverged at every tried point";
  (void)budget_left;
  return result;
}

PhaseShapeSplit CalcPhaseShapeSplit(const std::vector<double>& q_sim,
                                    const ActuatorLog& log,
                                    double max_shift_s) {
  PhaseShapeSplit s;
  const long n = static_cast<long>(std::min(q_sim.size(), log.size()));
  if (n < 2) return s;
  const long max_shift = static_cast<long>(std::lround(max_shift_s / log.dt_s));
  auto mae_at = [&](long shift) {
    // Compare q_sim[k + shift] with q[k] over the common range.
    double sum = 0;
    long count = 0;
    for (long k = std::max(0L, -shift); k < n && k + shift < n; ++k) {
      sum += std::abs(q_sim[k + shift] - log.q_rad[k]);
      ++count;
    }
    return count ? sum / count : 0.0;
  };
  s.mae_rad = mae_at(0);
  s.mae_shifted_rad = s.mae_rad;
  for (long shift = -max_shift; shift <= max_shift; ++shift) {
    const double m = mae_at(shift);
    if (m < s.mae_shifted_rad) {
      s.mae_shifted_rad = m;
      s.shift_s = shift * log.dt_s;
    }
  }
  return s;
}

std::vector<double> CalcMeasuredFrictionTorque(const ActuatorModel& m,
                                               const ActuatorLog& log) {
  const std::size_t n = log.size();
  std::vector<double> tau(n, 0.0);
  if (n < 7) return tau;
  std::vector<double> v(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t a = k < 2 ? 0 : k - 2, b = std::min(n - 1, k + 2);
    double s = 0;
    for (std::size_t j = a; j <= b; ++j) s += log.dq_rad_s[j];
    v[k] = s / static_cast<double>(b - a + 1);
  }
  const double ml2 = log.mass_kg * log.length_m * log.length_m;
  const double inertia = ml2 + m.armature_kg_m2;
  const double mgl = log.mass_kg * kGravityM_s2 * log.length_m;
  const double gain = log.kp * kXl330ErrorGain * m.gain_scale;
  for (std::size_t k = 1; k + 1 < n; ++k) {
    const double ddq =
        (v[k + 1] - v[k - 1]) / (log.t_s[k + 1] - log.t_s[k - 1]);
    const double r =
        std::max(1e-3,
                 m.r_ohm * (1.0 + m.r_temp_coeff_per_c *
                                      (log.temp_c[k] - kResistanceRefTempC)));
    const double duty =
        Clip(gain * (log.goal_rad[k] - log.q_rad[k]), -1.0, 1.0);
    const double tau_m = log.torque_enable[k]
                             ? m.kt * (log.vin_v * duty - m.kt * v[k]) / r
                             : 0.0;
    const double tau_e = -mgl * std::sin(log.q_rad[k] + m.q_offset_rad);
    tau[k] = inertia * ddq - tau_m - tau_e;
  }
  return tau;
}

}  // namespace frictiond
