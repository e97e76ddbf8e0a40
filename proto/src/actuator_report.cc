#include "frictiond/proto/actuator_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <Eigen/Dense>

#include "frictiond/proto/actuator_json.h"

namespace frictiond {

using json = nlohmann::json;

const ActuatorFrictionLaw kAutoActuatorLaw = ActuatorFrictionLaw::kExtended;

ActuatorVariant AutoActuatorVariant() {
  return {"extended+current_limit+delay+backlash+r_temp",
          ActuatorFrictionLaw::kExtended,
          {ActuatorParam::kCurrentLimit,
           ActuatorParam::kCommandDelay,
           ActuatorParam::kBacklash,
           ActuatorParam::kRTempCoeff}};
}

ActuatorVariant LawVariant(ActuatorFrictionLaw law) {
  return {ActuatorFrictionLawName(law), law, {}};
}

namespace {

std::vector<const ActuatorLog*> Pointers(const std::vector<ActuatorLog>& logs) {
  std::vector<const ActuatorLog*> p;
  for (const ActuatorLog& l : logs) p.push_back(&l);
  return p;
}

// Start values of the extras when they are first freed.
void SeedExtra(ActuatorModel* m, ActuatorParam p) {
  switch (p) {
    case ActuatorParam::kCurrentLimit:
      if (!(m->current_limit_a > 0)) m->current_limit_a = 1.75;
      break;
    case ActuatorParam::kBacklash:
      if (!(m->backlash_rad > 0)) m->backlash_rad = 0.01;
      break;
    case ActuatorParam::kCommandDelay:
      if (!(m->command_delay_s > 0)) m->command_delay_s = 0.01;
      break;
    default:
      break;
  }
}

std::string Fmt(const char* f, double a, double b = 0) {
  char buf[200];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

// Exact paired sign-flip test (two-sided) of mean(d) != 0; Monte Carlo
// with a fixed seed above 16 folds.
double SignFlipPValue(const std::vector<double>& d) {
  const std::size_t n = d.size();
  if (n == 0) return 1.0;
  double observed = 0;
  for (double x : d) observed += x;
  observed = std::abs(observed);
  long extreme = 0, total = 0;
  if (n <= 16) {
    for (unsigned long mask = 0; mask < (1ul << n); ++mask) {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) s += (mask >> i & 1) ? -d[i] : d[i];
      if (std::abs(s) >= observed - 1e-15) ++extreme;
      ++total;
    }
  } else {
    unsigned long long state = 12345;
    for (int r = 0; r < 20000; ++r) {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        s += (state >> 63) ? -d[i] : d[i];
      }
      if (std::abs(s) >= observed - 1e-15) ++extreme;
      ++total;
    }
  }
  return static_cast<double>(extreme) / static_cast<double>(total);
}

double Mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

}  // namespace

ActuatorFitResult FitActuatorVariant(
    const std::vector<const ActuatorLog*>& logs,
    const ActuatorVariant& variant,
    const ActuatorFitOptions& options,
    const ActuatorModel* warm) {
  ActuatorModel start;
  if (warm) {
    start = *warm;
    // Keep the warm motor constants and shared friction; seed the law's own.
    const ActuatorModel d = MakeDefaultActuatorModel(variant.law);
    if (warm->law != variant.law && variant.law_free) {
      for (ActuatorParam p : ActuatorLawParams(variant.law)) {
        const double w = ActuatorParamValue(*warm, p);
        if (w == 0.0) ActuatorParamRef(start, p) = ActuatorParamValue(d, p);
      }
    }
    start.law = variant.law;
  } else if (variant.extra.size() > 1) {
    // Three stages: the law alone (from Coulomb-viscous), then the extras.
    ActuatorVariant law_only = variant;
    law_only.extra.clear();
    ActuatorFitOptions o = options;
    o.bootstrap = 0;
    o.lm_iterations = 2;
    start = FitActuatorVariant(logs, law_only, o).model;
  } else {
    const ActuatorModel cv_start =
        MakeDefaultActuatorModel(ActuatorFrictionLaw::kCoulombViscous);
    if (variant.law == ActuatorFrictionLaw::kCoulombViscous) {
      start = cv_start;
    } else {
      ActuatorFitOptions o = options;
      o.bootstrap = 0;
      o.lm_iterations = 2;
      const ActuatorFitResult cv = FitActuatorModel(
          logs,
          cv_start,
          ActuatorLawParams(ActuatorFrictionLaw::kCoulombViscous),
          o);
      start = MakeDefaultActuatorModel(variant.law);
      for (ActuatorParam p :
           ActuatorLawParams(ActuatorFrictionLaw::kCoulombViscous))
        ActuatorParamRef(start, p) = ActuatorParamValue(cv.model, p);
      if (variant.law == ActuatorFrictionLaw::kMixedLubrication)
        start.friction.mixed_load_base = cv.model.friction.friction_base;
    }
  }
  std::vector<ActuatorParam> free = ActuatorLawParams(
      variant.law_free ? variant.law : ActuatorFrictionLaw::kCoulombViscous);
  for (ActuatorParam p : variant.extra) {
    SeedExtra(&start, p);
    if (std::find(free.begin(), free.end(), p) == free.end()) free.push_back(p);
  }
  return FitActuatorModel(logs, start, free, options);
}

ActuatorFitResult FitActuatorLaw(const std::vector<ActuatorLog>& logs,
                                 ActuatorFrictionLaw law,
                                 const ActuatorFitOptions& options) {
  const ActuatorVariant v =
      law == kAutoActuatorLaw ? AutoActuatorVariant() : LawVariant(law);
  return FitActuatorVariant(Pointers(logs), v, options);
}

std::vector<double> CalcHeldOutMae(const std::vector<ActuatorLog>& logs,
                                   const ActuatorVariant& variant,
                                   const std::vector<int>& group,
                                   const ActuatorFitOptions& options,
                                   const ActuatorModel* warm) {
  std::vector<double> out(logs.size(), 0.0);
  std::vector<int> groups = group;
  std::sort(groups.begin(), groups.end());
  groups.erase(std::unique(groups.begin(), groups.end()), groups.end());
  for (int g : groups) {
    std::vector<const ActuatorLog*> train;
    for (std::size_t i = 0; i < logs.size(); ++i)
      if (group[i] != g) train.push_back(&logs[i]);
    if (train.empty()) continue;
    const ActuatorFitResult fit =
        FitActuatorVariant(train, variant, options, warm);
    for (std::size_t i = 0; i < logs.size(); ++i)
      if (group[i] == g) out[i] = SimulateActuatorLog(fit.model, logs[i]);
  }
  return out;
}

json ActuatorFitToJson(const ActuatorFitResult& fit) {
  json params = json::array();
  for (std::size_t i = 0; i < fit.free.size(); ++i) {
    json p = {{"name", GetActuatorParamInfo(fit.free[i]).name},
              {"value", ActuatorParamValue(fit.model, fit.free[i])},
              {"stderr", i < fit.stderr_.size() ? fit.stderr_[i] : 0.0}};
    if (i < fit.boot_lo.size()) {
      p["boot_lo"] = fit.boot_lo[i];
      p["boot_hi"] = fit.boot_hi[i];
    }
    params.push_back(p);
  }
  return {{"model", ActuatorModelToJson(fit.model)},
          {"mae_rad", fit.mae_rad},
          {"converged", fit.converged},
          {"why", fit.why},
          {"evaluations", fit.evaluations},
          {"params", params}};
}

json DiagnoseActuatorLogs(const std::vector<ActuatorLog>& logs) {
  if (logs.size() < 3)
    throw std::invalid_argument("logs: " + std::to_string(logs.size()) +
                                " (diagnosis needs at least 3)");
  const std::vector<const ActuatorLog*> all = Pointers(logs);
  ActuatorFitOptions full;
  full.nm_max_evaluations = 1500;
  full.lm_iterations = 3;
  ActuatorFitOptions fold = full;
  fold.nm_max_evaluations = 300;
  fold.nm_restarts = 0;
  fold.lm_iterations = 1;
  std::vector<int> loo(logs.size());
  for (std::size_t i = 0; i < logs.size(); ++i) loo[i] = static_cast<int>(i);

  const ActuatorVariant base = LawVariant(ActuatorFrictionLaw::kCoulombViscous);
  const ActuatorFitResult cv = FitActuatorVariant(all, base, full);
  const std::vector<double> base_ho =
      CalcHeldOutMae(logs, base, loo, fold, &cv.model);
  const double base_cv = Mean(base_ho);
  json out;
  out["baseline"] = {{"model", "coulomb_viscous"},
                     {"cv_mae", base_cv},
                     {"in_sample_mae", cv.mae_rad},
                     {"unit", "rad"},
                     {"held_out", "leave-one-log-out"}};

  // Where and when the baseline departs; phase vs shape.
  json departures = json::array();
  for (const ActuatorLog& log : logs) {
    ActuatorRolloutTrace tr;
    const double mae = SimulateActuatorLog(cv.model, log, &tr);
    std::size_t first = log.size();
    for (std::size_t k = 0; k < log.size(); ++k)
      if (std::abs(tr.q_rad[k] - log.q_rad[k]) > 0.05) {
        first = k;
        break;
      }
    // Error while the motor is released vs powered, moving vs near rest.
    double off = 0, on = 0;
    std::size_t n_off = 0, n_on = 0;
    for (std::size_t k = 0; k < log.size(); ++k) {
      const double e = std::abs(tr.q_rad[k] - log.q_rad[k]);
      if (log.torque_enable[k]) {
        on += e;
        ++n_on;
      } else {
        off += e;
        ++n_off;
      }
    }
    const PhaseShapeSplit ps = CalcPhaseShapeSplit(tr.q_rad, log, 0.1);
    departures.push_back(
        {{"log", log.name},
         {"kp", log.kp},
         {"trajectory", log.trajectory},
         {"mae_rad", mae},
         {"first_departure_s",
          first < log.size() ? json(log.t_s[first] - log.t_s[0]) : json()},
         {"mae_powered_rad", n_on ? on / n_on : 0.0},
         {"mae_released_rad", n_off ? off / n_off : 0.0},
         {"best_shift_s", ps.shift_s},
         {"phase_share_pct",
          mae > 0 ? 100.0 * (mae - ps.mae_shifted_rad) / mae : 0.0},
         {"shape_mae_rad", ps.mae_shifted_rad}});
  }
  out["departures"] = departures;

  // Candidate causes, each added alone to the baseline, scored held out.
  struct Candidate {
    const char* cause;
    ActuatorVariant variant;
    const char* effect;
  };
  using P = ActuatorParam;
  using L = ActuatorFrictionLaw;
  const std::vector<Candidate> candidates = {
      {"stribeck",
       {"stribeck", L::kStribeck, {}},
       "static friction above Coulomb near rest"},
      {"gearbox_load",
       {"load_dependent", L::kLoadDependent, {}},
       "friction grows with the gearbox torque |tau_e - tau_m|"},
      {"direction_drive_vs_backdrive",
       {"directional", L::kDirectional, {}},
       "load friction differs when the motor drives vs the load back-drives"},
      {"temperature_friction",
       {"coulomb_viscous+temp", L::kExtended, {P::kFrictionTempCoeff}, false},
       "Coulomb friction changes with motor temperature (confounded with kp)"},
      {"gain_scale",
       {"coulomb_viscous+gain_scale", L::kCoulombViscous, {P::kGainScale}},
       "controller gain differs from upstream's empirical 1/256 divisor"},
      {"resistance_temperature",
       {"coulomb_viscous+r_temp", L::kCoulombViscous, {P::kRTempCoeff}},
       "winding resistance rises with temperature (confounded with kp)"},
      {"backlash",
       {"coulomb_viscous+backlash", L::kCoulombViscous, {P::kBacklash}},
       "gearbox play between motor and output"},
      {"current_limit",
       {"coulomb_viscous+current_limit",
        L::kCoulombViscous,
        {P::kCurrentLimit}},
       "firmware current limit saturates the motor torque"},
      {"command_delay",
       {"coulomb_viscous+command_delay",
        L::kCoulombViscous,
        {P::kCommandDelay}},
       "the goal reaches the controller late (bus and firmware latency)"},
  };
  json findings = json::array();
  for (const Candidate& c : candidates) {
    const ActuatorVariant& v = c.variant;
    ActuatorModel warm = cv.model;
    const ActuatorFitResult fit = FitActuatorVariant(all, v, full, &warm);
    const std::vector<double> ho =
        CalcHeldOutMae(logs, v, loo, fold, &fit.model);
    std::vector<double> d(ho.size());
    for (std::size_t i = 0; i < ho.size(); ++i) d[i] = base_ho[i] - ho[i];
    const double m = Mean(ho);
    const double gain = base_cv > 0 ? 100.0 * (base_cv - m) / base_cv : 0.0;
    const double p_value = SignFlipPValue(d);
    std::string summary = std::string(c.cause) + ": held-out MAE " +
                          Fmt("%.4f rad (baseline %.4f rad)", m, base_cv) +
                          Fmt(", gain %.1f%%, p = %.3g", gain, p_value);
    findings.push_back({{"cause", c.cause},
                        {"kind", "cause"},
                        {"model", v.name},
                        {"p_value", p_value},
                        {"cv_mae", m},
                        {"cv_mae_gain_pct", gain},
                        {"effect", c.effect},
                        {"summary", summary}});
  }

  // Residual friction torque from the measured motion against covariates.
  {
    std::vector<double> y, speed, load, dir, back, temp, kp;
    for (const ActuatorLog& log : logs) {
      const std::vector<double> tau = CalcMeasuredFrictionTorque(cv.model, log);
      const double ml2 = log.mass_kg * log.length_m * log.length_m;
      (void)ml2;
      for (std::size_t k = 2; k + 2 < log.size(); k += 2) {
        const double v = log.dq_rad_s[k];
        if (std::abs(v) < 0.2 || !log.torque_enable[k]) continue;
        const double s = v > 0 ? 1.0 : -1.0;
        const double predicted =
            cv.model.friction.friction_base +
            cv.model.friction.friction_viscous * std::abs(v);
        // Friction magnitude along -sign(v), minus the Coulomb-viscous law.
        y.push_back(-s * tau[k] - predicted);
        const double mgl = log.mass_kg * kGravityM_s2 * log.length_m;
        const double tau_e =
            -mgl * std::sin(log.q_rad[k] + cv.model.q_offset_rad);
        speed.push_back(std::abs(v));
        load.push_back(std::abs(tau_e));
        dir.push_back(v > 0 ? 1.0 : 0.0);
        back.push_back(tau_e * v > 0 ? 1.0 : 0.0);
        temp.push_back(log.temp_c[k]);
        kp.push_back(log.kp);
      }
    }
    struct Cov {
      const char* name;
      const std::vector<double>* x;
      const char* unit;
    };
    const std::vector<Cov> covs = {
        {"residual_vs_speed", &speed, "N m per rad/s"},
        {"residual_vs_gravity_load", &load, "N m per N m"},
        {"residual_vs_direction", &dir, "N m (positive minus negative)"},
        {"residual_vs_backdriven", &back, "N m (back-driven minus driven)"},
        {"residual_vs_temperature", &temp, "N m per C"},
        {"residual_vs_kp", &kp, "N m per gain unit"}};
    const std::size_t n = y.size();
    for (const Cov& c : covs) {
      if (n < 10) break;
      const std::vector<double>& x = *c.x;
      double mx = Mean(x), my = Mean(y), sxx = 0, sxy = 0;
      for (std::size_t i = 0; i < n; ++i) {
        sxx += (x[i] - mx) * (x[i] - mx);
        sxy += (x[i] - mx) * (y[i] - my);
      }
      if (!(sxx > 0)) continue;
      const double slope = sxy / sxx;
      double sse = 0, r1num = 0;
      std::vector<double> res(n);
      for (std::size_t i = 0; i < n; ++i) {
        res[i] = y[i] - my - slope * (x[i] - mx);
        sse += res[i] * res[i];
        if (i) r1num += res[i] * res[i - 1];
      }
      const double r1 = std::clamp(r1num / std::max(1e-300, sse), 0.0, 0.99);
      const double n_eff = n * (1 - r1) / (1 + r1);
      const double se = std::sqrt(sse / std::max(1.0, n - 2.0) / sxx) *
                        std::sqrt(n / std::max(3.0, n_eff));
      const double z = std::abs(slope) / std::max(1e-300, se);
      const double p_value = std::erfc(z / std::sqrt(2.0));
      findings.push_back(
          {{"cause", c.name},
           {"kind", "covariate"},
           {"p_value", p_value},
           {"cv_mae_gain_pct", 0.0},
           {"effect", Fmt("residual friction slope %.4g ", slope) + c.unit},
           {"summary",
            std::string(c.name) +
                Fmt(": slope %.4g, p = %.3g", slope, p_value) + " (" + c.unit +
                ", samples moving > 0.2 rad/s)"}});
    }
  }
  std::stable_sort(
      findings.begin(), findings.end(), [](const json& a, const json& b) {
        return a.at("cv_mae_gain_pct").get<double>() >
               b.at("cv_mae_gain_pct").get<double>();
      });
  out["findings"] = findings;

  // The extended (auto) model, held out the same way.
  const ActuatorVariant ext = AutoActuatorVariant();
  const ActuatorFitResult ef = FitActuatorVariant(all, ext, full, &cv.model);
  const std::vector<double> ext_ho =
      CalcHeldOutMae(logs, ext, loo, fold, &ef.model);
  const double ext_cv = Mean(ext_ho);
  out["extended"] = {
      {"model", ext.name},
      {"cv_mae", ext_cv},
      {"gain_pct", base_cv > 0 ? 100.0 * (base_cv - ext_cv) / base_cv : 0.0},
      {"p_value", [&] {
         std::vector<double> d(ext_ho.size());
         for (std::size_t i = 0; i < d.size(); ++i)
           d[i] = base_ho[i] - ext_ho[i];
         return SignFlipPValue(d);
       }()}};
  out["confounding"] =
      "temperature rises with kp across the session (kp order), so a "
      "temperature effect and a gain effect cannot be told apart from these "
      "logs; only a within-log temperature drift (at most 2 C) separates "
      "them, which is too small to resolve";
  return out;
}

}  // namespace frictiond
