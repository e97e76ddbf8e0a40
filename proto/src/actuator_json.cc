#include "frictiond/proto/actuator_json.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "frictiond/estimators/actuator_friction.h"
#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/number_text.h"
#include "frictiond/proto/json_parse.h"

namespace frictiond {

using json = nlohmann::json;

namespace {

constexpr int kMaxDepth = 8;

json ParseBounded(std::string_view text, const char* what) {
  if (text.size() > kMaxActuatorLogBytes)
    throw FieldError::Because(what,
                              std::to_string(text.size()) + " bytes (limit " +
                                  std::to_string(kMaxActuatorLogBytes) + ")");
  if (text.empty()) throw FieldError::Because(what, "empty");
  return ParseJson(text, what, kMaxDepth);
}

double Number(const json& obj,
              const std::string& key,
              const std::string& field) {
  const auto it = obj.find(key);
  if (it == obj.end()) throw FieldError::Because(field, "missing");
  if (!it->is_number()) throw FieldError::Because(field, "must be a number");
  const double v = it->get<double>();
  if (!std::isfinite(v))
    throw FieldError(field,
                     field + " = " + NumberText(v) + " (must be finite)");
  return v;
}

std::string Text(const json& obj, const std::string& key) {
  const auto it = obj.find(key);
  if (it == obj.end() || !it->is_string()) return "";
  std::string s = it->get<std::string>();
  if (s.size() > 200) s.resize(200);
  return s;
}

}  // namespace

ActuatorLog ParseActuatorLog(std::string_view text, const std::string& name) {
  return ActuatorLogFromJson(ParseBounded(text, "log"), name);
}

ActuatorLog ActuatorLogFromJson(const json& j, const std::string& name) {
  if (!j.is_object()) throw FieldError::Because("log", "must be a JSON object");
  ActuatorLog log;
  log.name = name;
  log.motor = Text(j, "motor");
  log.trajectory = Text(j, "trajectory");
  log.mass_kg = Number(j, "mass", "mass");
  log.length_m = Number(j, "length", "length");
  log.kp = Number(j, "kp", "kp");
  log.vin_v = Number(j, "vin", "vin");
  const bool has_dt = j.contains("dt");
  if (has_dt) log.dt_s = Number(j, "dt", "dt");
  const auto e = j.find("entries");
  if (e == j.end()) throw FieldError::Because("entries", "missing");
  if (!e->is_array()) throw FieldError::Because("entries", "must be an array");
  const std::size_t n = e->size();
  if (n == 0) throw FieldError::Because("entries", "empty");
  if (n > kMaxActuatorLogEntries)
    throw FieldError::Because("entries",
                              std::to_string(n) + " (limit " +
                                  std::to_string(kMaxActuatorLogEntries) + ")");
  log.t_s.reserve(n);
  log.q_rad.reserve(n);
  log.dq_rad_s.reserve(n);
  log.goal_rad.reserve(n);
  log.temp_c.reserve(n);
  log.torque_enable.reserve(n);
  bool has_speed = true;
  for (std::size_t i = 0; i < n; ++i) {
    const json& x = (*e)[i];
    const std::string f = "entries[" + std::to_string(i) + "]";
    if (!x.is_object()) throw FieldError::Because(f, "must be an object");
    log.t_s.push_back(Number(x, "timestamp", f + ".timestamp"));
    log.q_rad.push_back(Number(x, "position", f + ".position"));
    log.goal_rad.push_back(Number(x, "goal_position", f + ".goal_position"));
    const auto te = x.find("torque_enable");
    if (te == x.end())
      throw FieldError::Because(f + ".torque_enable", "missing");
    if (!te->is_boolean())
      throw FieldError::Because(f + ".torque_enable", "must be true or false");
    log.torque_enable.push_back(te->get<bool>() ? 1 : 0);
    if (i == 0) has_speed = x.contains("speed");
    log.dq_rad_s.push_back(has_speed ? Number(x, "speed", f + ".speed") : 0.0);
    log.temp_c.push_back(x.contains("temp") ? Number(x, "temp", f + ".temp")
                                            : 30.0);
  }
  for (std::size_t i = 1; i < n; ++i)
    if (!(log.t_s[i] > log.t_s[i - 1]))
      throw FieldError("entries[" + std::to_string(i) + "].timestamp",
                       "entries[" + std::to_string(i) +
                           "].timestamp = " + NumberText(log.t_s[i]) +
                           " (must be > the previous " +
                           NumberText(log.t_s[i - 1]) + ")");
  if (!has_dt && n >= 2) {
    std::vector<double> steps(n - 1);
    for (std::size_t i = 1; i < n; ++i)
      steps[i - 1] = log.t_s[i] - log.t_s[i - 1];
    std::nth_element(
        steps.begin(), steps.begin() + steps.size() / 2, steps.end());
    log.dt_s = steps[steps.size() / 2];
  }
  if (!has_speed && n >= 2) {
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t a = i == 0 ? 0 : i - 1, b = std::min(n - 1, i + 1);
      log.dq_rad_s[i] =
          (log.q_rad[b] - log.q_rad[a]) / (log.t_s[b] - log.t_s[a]);
    }
  }
  ValidateActuatorLog(log);
  return log;
}

json ActuatorModelToJson(const ActuatorModel& model) {
  json params = json::object();
  for (int i = 0; i < static_cast<int>(ActuatorParam::kCount); ++i) {
    const auto p = static_cast<ActuatorParam>(i);
    params[GetActuatorParamInfo(p).name] = ActuatorParamValue(model, p);
  }
  return {{"format", "frictiond-actuator-model"},
          {"version", 1},
          {"law", ActuatorFrictionLawName(model.law)},
          {"params", params}};
}

ActuatorModel ActuatorModelFromJson(const json& j) {
  if (!j.is_object()) throw FieldError::Because("model", "must be an object");
  const auto law = j.find("law");
  if (law == j.end() || !law->is_string())
    throw FieldError::Because("law", "missing or not a string");
  ActuatorModel m = MakeDefaultActuatorModel(
      ParseActuatorFrictionLaw(law->get<std::string>()));
  const auto params = j.find("params");
  if (params == j.end() || !params->is_object())
    throw FieldError::Because("params", "missing or not an object");
  for (int i = 0; i < static_cast<int>(ActuatorParam::kCount); ++i) {
    const auto p = static_cast<ActuatorParam>(i);
    const ActuatorParamInfo& info = GetActuatorParamInfo(p);
    if (!params->contains(info.name)) continue;
    const double v =
        Number(*params, info.name, std::string("params.") + info.name);
    if (!(v >= info.lo && v <= info.hi))
      throw FieldError(std::string("params.") + info.name,
                       std::string("params.") + info.name + " = " +
                           NumberText(v) + " (must be in [" +
                           NumberText(info.lo) + ", " + NumberText(info.hi) +
                           "])");
    ActuatorParamRef(m, p) = v;
  }
  return m;
}

ActuatorModel ParseBamParams(std::string_view text) {
  const json j = ParseBounded(text, "params");
  if (!j.is_object()) throw FieldError::Because("params", "must be an object");
  const std::string model = Text(j, "model");
  ActuatorFrictionLaw law;
  if (model == "m1")
    law = ActuatorFrictionLaw::kCoulombViscous;
  else if (model == "m2")
    law = ActuatorFrictionLaw::kStribeck;
  else if (model == "m3" || model == "m4")
    law = ActuatorFrictionLaw::kLoadDependent;
  else if (model == "m5")
    law = ActuatorFrictionLaw::kDirectional;
  else if (model == "m6")
    law = ActuatorFrictionLaw::kBamM6;
  else
    throw FieldError(
        "model",
        "model = '" + model + "' (must be one of m1, m2, m3, m4, m5, m6)");
  ActuatorModel m = MakeDefaultActuatorModel(law);
  // Zero every friction term first: a BAM file lists only its model's.
  m.friction = ActuatorFrictionParams{};
  m.friction.friction_base = 0;
  m.friction.friction_viscous = 0;
  m.q_offset_rad = 0;
  for (int i = 0; i < static_cast<int>(ActuatorParam::kCount); ++i) {
    const auto p = static_cast<ActuatorParam>(i);
    const char* name = GetActuatorParamInfo(p).name;
    if (!j.contains(name)) continue;
    const double v = Number(j, name, name);
    ActuatorParamRef(m, p) = v;
  }
  if (!(m.kt > 0))
    throw FieldError("kt", "kt = " + NumberText(m.kt) + " (must be > 0)");
  if (!(m.r_ohm > 0))
    throw FieldError("R", "R = " + NumberText(m.r_ohm) + " (must be > 0)");
  if (!(m.armature_kg_m2 >= 0))
    throw FieldError(
        "armature",
        "armature = " + NumberText(m.armature_kg_m2) + " (must be >= 0)");
  if (model == "m3" || model == "m4") {
    // BAM's M3 has no Stribeck term; M4 does (load_friction_stribeck).
    if (model == "m3") m.friction.friction_stribeck = 0;
  }
  return m;
}

std::string ExportActuatorMjcf(const ActuatorModel& model,
                               const std::string& joint_name) {
  const ActuatorFrictionBudget rest =
      CalcActuatorFrictionBudget(model.law, model.friction, {0, 0, 0, 30});
  const double back_emf = model.kt * model.kt / model.r_ohm;
  std::string name;
  for (char c : joint_name)
    name +=
        (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-')
            ? c
            : '_';
  if (name.empty()) name = "joint";
  char buf[1024];
  std::snprintf(
      buf,
      sizeof buf,
      "<!-- frictiond actuator model, law %s. MJCF holds a constant "
      "frictionloss and a linear damping only; not exported: %s -->\n"
      "<joint name=\"%s\" type=\"hinge\" frictionloss=\"%.9g\" "
      "damping=\"%.9g\" armature=\"%.9g\"/>\n"
      "<!-- damping = friction_viscous %.9g + back-EMF kt^2/R %.9g (motor "
      "powered); with the motor released use damping=\"%.9g\" -->\n",
      ActuatorFrictionLawName(model.law).c_str(),
      model.law == ActuatorFrictionLaw::kCoulombViscous
          ? "nothing (the law is Coulomb-viscous)"
          : "the Stribeck peak (frictionloss is the budget at rest, zero "
            "load), the load-dependent and directional terms, the "
            "temperature slope, LuGre bristles and the mixed-lubrication "
            "film law (apply them as a joint torque, "
            "estimators/actuator_friction.h)",
      name.c_str(),
      rest.frictionloss_nm,
      model.friction.friction_viscous + back_emf,
      model.armature_kg_m2,
      model.friction.friction_viscous,
      back_emf,
      model.friction.friction_viscous);
  return buf;
}

}  // namespace frictiond
