#include "frictiond/proto/joint_json.h"

#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/number_text.h"

namespace frictiond {

using nlohmann::json;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

[[noreturn]] void Bad(const std::string& field, const std::string& why) {
  throw FieldError::Because(field, why);
}

// Reads an optional number at j[key] into *x (kept when absent).
void Number(const json& j,
            const char* key,
            const std::string& where,
            double* x) {
  if (!j.contains(key)) return;
  const json& v = j.at(key);
  if (!v.is_number()) Bad(where + key, "must be a number");
  *x = v.get<double>();
  if (!std::isfinite(*x)) Bad(where + key, "must be finite");
}

double RequireNumber(const json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) Bad(where + key, "is missing");
  double x = 0;
  Number(j, key, where, &x);
  return x;
}

// Re-throws a validator's error with a prefix ("surface." etc). An error
// without a field names the prefix's object ("surface: ...").
template <typename F>
void Prefixed(const std::string& prefix, F&& f) {
  try {
    f();
  } catch (const FieldError& e) {
    throw e.Prefixed(prefix);
  } catch (const std::invalid_argument& e) {
    std::string object = prefix;
    if (!object.empty() && object.back() == '.') object.pop_back();
    throw FieldError::Because(object, e.what());
  }
}

json FitToJson(const JointFitResult& r, const JointModelScore* score) {
  json theta = json::object();
  const auto names = ParameterNames(r.kind);
  for (std::size_t i = 0; i < names.size(); ++i) {
    const double x = static_cast<Eigen::Index>(i) < r.theta.size()
                         ? r.theta[static_cast<Eigen::Index>(i)]
                         : std::numeric_limits<double>::quiet_NaN();
    theta[names[i]] = std::isfinite(x) ? json(x) : json();
  }
  json cov = json::array();
  for (Eigen::Index i = 0; i < r.P_theta.rows(); ++i) {
    json row = json::array();
    for (Eigen::Index k = 0; k < r.P_theta.cols(); ++k)
      row.push_back(r.P_theta(i, k));
    cov.push_back(row);
  }
  json j = {{"status", ToString(r.status)},
            {"theta", theta},
            {"covariance", cov},
            {"residual_rms", r.residual_rms},
            {"iterations", r.iterations}};
  if (!r.why.empty()) j["why"] = r.why;
  if (score) {
    j["heldout_rmse"] =
        std::isfinite(score->heldout_rmse) ? json(score->heldout_rmse) : json();
    j["heldout_mae"] =
        std::isfinite(score->heldout_mae) ? json(score->heldout_mae) : json();
  }
  return j;
}

JointFitStatus StatusFromString(const std::string& s,
                                const std::string& where) {
  for (JointFitStatus st : {JointFitStatus::kConverged,
                            JointFitStatus::kMaxIterations,
                            JointFitStatus::kNotObservable,
                            JointFitStatus::kFailed})
    if (ToString(st) == s) return st;
  Bad(where + "status", "'" + s + "' is not a known status");
}

JointFitResult FitFromJson(const json& j,
                           JointModelKind kind,
                           const std::string& where,
                           JointModelScore* score) {
  if (!j.is_object()) Bad(where, "must be an object");
  JointFitResult r;
  r.kind = kind;
  if (!j.contains("status") || !j["status"].is_string())
    Bad(where + ".status", "must be a string");
  r.status = StatusFromString(j["status"].get<std::string>(), where + ".");
  const auto names = ParameterNames(kind);
  const int p = static_cast<int>(names.size());
  r.theta.resize(p);
  if (!j.contains("theta") || !j["theta"].is_object())
    Bad(where + ".theta", "must be an object");
  for (int i = 0; i < p; ++i) {
    const json& v = j["theta"].contains(names[static_cast<std::size_t>(i)])
                        ? j["theta"][names[static_cast<std::size_t>(i)]]
                        : json();
    if (v.is_null()) {
      r.theta[i] = std::numeric_limits<double>::quiet_NaN();
    } else if (v.is_number()) {
      r.theta[i] = v.get<double>();
    } else {
      Bad(where + ".theta." + names[static_cast<std::size_t>(i)],
          "must be a number or null");
    }
  }
  r.P_theta = Eigen::MatrixXd::Zero(p, p);
  if (j.contains("covariance")) {
    const json& c = j["covariance"];
    if (!c.is_array() || c.size() != static_cast<std::size_t>(p))
      Bad(where + ".covariance", "must be " + std::to_string(p) + " rows");
    for (int i = 0; i < p; ++i) {
      const json& row = c[static_cast<std::size_t>(i)];
      if (!row.is_array() || row.size() != static_cast<std::size_t>(p))
        Bad(where + ".covariance",
            "must be " + std::to_string(p) + " x " + std::to_string(p));
      for (int k = 0; k < p; ++k) {
        if (!row[static_cast<std::size_t>(k)].is_number())
          Bad(where + ".covariance", "must hold numbers");
        r.P_theta(i, k) = row[static_cast<std::size_t>(k)].get<double>();
      }
    }
  }
  Number(j, "residual_rms", where + ".", &r.residual_rms);
  if (j.contains("why") && j["why"].is_string())
    r.why = j["why"].get<std::string>();
  if (score) {
    score->kind = kind;
    score->heldout_rmse = score->heldout_mae =
        std::numeric_limits<double>::quiet_NaN();
    if (j.contains("heldout_rmse") && j["heldout_rmse"].is_number())
      score->heldout_rmse = j["heldout_rmse"].get<double>();
    if (j.contains("heldout_mae") && j["heldout_mae"].is_number())
      score->heldout_mae = j["heldout_mae"].get<double>();
  }
  return r;
}

json Span(double lo, double hi) { return json::array({lo, hi}); }

void SpanFromJson(const json& j, const char* key, double* lo, double* hi) {
  if (!j.contains(key)) return;
  const json& s = j[key];
  if (!s.is_array() || s.size() != 2 || !s[0].is_number() || !s[1].is_number())
    Bad(std::string("joint.span.") + key, "must be [lo, hi]");
  *lo = s[0].get<double>();
  *hi = s[1].get<double>();
}

}  // namespace

json JointConfigToJson(const JointConfig& c, const WearParams& w) {
  return json{
      {"surface",
       {{"alt_um", c.surface.alt_um},
        {"salt_um", c.surface.salt_um},
        {"radius_log_sd", c.surface.radius_log_sd},
        {"radius_log_mean", c.surface.radius_log_mean},
        {"srad_um", c.surface.srad_um},
        {"summits", c.surface.summits},
        {"modulus_gpa", c.surface.modulus_gpa}}},
      {"contact", {{"area_mm2", c.contact.area_mm2}}},
      {"lubricant",
       {{"vogel_a_pa_s", c.lubricant.vogel_a_pa_s},
        {"vogel_b_c", c.lubricant.vogel_b_c},
        {"vogel_c_c", c.lubricant.vogel_c_c}}},
      {"wear", {{"k_solid", w.k_solid}, {"hardness_mpa", w.hardness_mpa}}}};
}

void JointConfigFromJson(const json& j, JointConfig* c, WearParams* w) {
  if (!j.is_object()) Bad("config", "must be an object");
  if (j.contains("surface")) {
    const json& s = j["surface"];
    if (!s.is_object()) Bad("surface", "must be an object");
    Number(s, "alt_um", "surface.", &c->surface.alt_um);
    Number(s, "salt_um", "surface.", &c->surface.salt_um);
    Number(s, "radius_log_sd", "surface.", &c->surface.radius_log_sd);
    Number(s, "radius_log_mean", "surface.", &c->surface.radius_log_mean);
    Number(s, "srad_um", "surface.", &c->surface.srad_um);
    Number(s, "summits", "surface.", &c->surface.summits);
    Number(s, "modulus_gpa", "surface.", &c->surface.modulus_gpa);
  }
  Prefixed("surface.", [&] { ValidateSurface(c->surface); });
  if (j.contains("contact")) {
    if (!j["contact"].is_object()) Bad("contact", "must be an object");
    Number(j["contact"], "area_mm2", "contact.", &c->contact.area_mm2);
  }
  if (!(c->contact.area_mm2 > 0))
    throw FieldError("contact.area_mm2",
                     "contact.area_mm2 = " + NumberText(c->contact.area_mm2) +
                         " (must be > 0)");
  if (j.contains("lubricant")) {
    const json& l = j["lubricant"];
    if (!l.is_object()) Bad("lubricant", "must be an object");
    Number(l, "vogel_a_pa_s", "lubricant.", &c->lubricant.vogel_a_pa_s);
    Number(l, "vogel_b_c", "lubricant.", &c->lubricant.vogel_b_c);
    Number(l, "vogel_c_c", "lubricant.", &c->lubricant.vogel_c_c);
  }
  Prefixed("lubricant.", [&] { ValidateLubricant(c->lubricant); });
  if (j.contains("wear")) {
    const json& x = j["wear"];
    if (!x.is_object()) Bad("wear", "must be an object");
    Number(x, "k_solid", "wear.", &w->k_solid);
    Number(x, "hardness_mpa", "wear.", &w->hardness_mpa);
  }
  if (!(w->k_solid >= 0))
    throw FieldError(
        "wear.k_solid",
        "wear.k_solid = " + NumberText(w->k_solid) + " (must be >= 0)");
  if (!(w->hardness_mpa > 0))
    throw FieldError("wear.hardness_mpa",
                     "wear.hardness_mpa = " + NumberText(w->hardness_mpa) +
                         " (must be > 0)");
}

json JointFamilyToJson(const JointFamily& f) {
  const JointModelScore* s[3] = {nullptr, nullptr, nullptr};
  for (const JointModelScore& sc : f.scores) s[static_cast<int>(sc.kind)] = &sc;
  return json{{"config", JointConfigToJson(f.config, f.wear)},
              {"samples", f.samples},
              {"span",
               {{"v_mm_s", Span(f.v_min_mm_s, f.v_max_mm_s)},
                {"load_n", Span(f.load_min_n, f.load_max_n)},
                {"sommerfeld_um", Span(f.s_min_um, f.s_max_um)}}},
              {"models",
               {{ToString(JointModelKind::kMixed), FitToJson(f.mixed, s[0])},
                {ToString(JointModelKind::kStribeckViscous),
                 FitToJson(f.stribeck, s[1])},
                {ToString(JointModelKind::kLuGreSteadyState),
                 FitToJson(f.lugre, s[2])}}}};
}

JointFamily JointFamilyFromJson(const json& j) {
  if (!j.is_object()) Bad("joint", "must be an object");
  JointFamily f;
  if (!j.contains("config")) Bad("joint.config", "is missing");
  Prefixed("joint.config.",
           [&] { JointConfigFromJson(j["config"], &f.config, &f.wear); });
  if (j.contains("samples") && j["samples"].is_number_unsigned())
    f.samples = j["samples"].get<std::size_t>();
  if (j.contains("span") && j["span"].is_object()) {
    SpanFromJson(j["span"], "v_mm_s", &f.v_min_mm_s, &f.v_max_mm_s);
    SpanFromJson(j["span"], "load_n", &f.load_min_n, &f.load_max_n);
    SpanFromJson(j["span"], "sommerfeld_um", &f.s_min_um, &f.s_max_um);
  }
  if (!j.contains("models") || !j["models"].is_object())
    Bad("joint.models", "must be an object");
  const json& m = j["models"];
  JointFitResult* fits[3] = {&f.mixed, &f.stribeck, &f.lugre};
  for (JointModelKind kind : {JointModelKind::kMixed,
                              JointModelKind::kStribeckViscous,
                              JointModelKind::kLuGreSteadyState}) {
    const std::string key = ToString(kind);
    if (!m.contains(key)) Bad("joint.models." + key, "is missing");
    JointModelScore score;
    *fits[static_cast<int>(kind)] =
        FitFromJson(m[key], kind, "joint.models." + key, &score);
    f.scores.push_back(score);
  }
  return f;
}

JointData ParseJointCsv(const std::string& text,
                        const Lubricant& lubricant,
                        std::size_t max_rows) {
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  std::vector<std::string> header;
  auto split = [](const std::string& s) {
    std::vector<std::string> out;
    std::string cell;
    std::istringstream ss(s);
    while (std::getline(ss, cell, ',')) {
      const auto b = cell.find_first_not_of(" \t\r");
      const auto e = cell.find_last_not_of(" \t\r");
      out.push_back(b == std::string::npos ? "" : cell.substr(b, e - b + 1));
    }
    if (!s.empty() && s.back() == ',') out.push_back("");
    return out;
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (line[line.find_first_not_of(" \t\r")] == '#') continue;
    header = split(line);
    break;
  }
  if (header.empty()) throw FieldError("header", "no header row");
  auto col = [&](const char* name) -> int {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    return -1;
  };
  const int c_v = col("v_mm_s"), c_load = col("load_n"), c_mu = col("mu"),
            c_t = col("temp_c"), c_eta = col("eta_pa_s");
  for (auto [c, name] : {std::pair<int, const char*>{c_v, "v_mm_s"},
                         {c_load, "load_n"},
                         {c_mu, "mu"}})
    if (c < 0)
      throw FieldError(name,
                       std::string(name) + ": required column is missing");
  if (c_t < 0 && c_eta < 0)
    throw FieldError(
        "temp_c", "temp_c: column is missing (temp_c or eta_pa_s is required)");
  ValidateLubricant(lubricant);
  JointData d;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    if (d.size() >= max_rows)
      throw FieldError("body",
                       "more than " + std::to_string(max_rows) + " rows");
    const auto cells = split(line);
    if (cells.size() != header.size())
      throw FieldError("body",
                       "line " + std::to_string(line_no) + ": " +
                           std::to_string(cells.size()) +
                           " cells, header has " +
                           std::to_string(header.size()));
    auto cell = [&](int c) {
      const std::string& s = cells[static_cast<std::size_t>(c)];
      char* end = nullptr;
      const double x = std::strtod(s.c_str(), &end);
      if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(x))
        throw FieldError(header[static_cast<std::size_t>(c)],
                         "line " + std::to_string(line_no) + ": " +
                             header[static_cast<std::size_t>(c)] + " = '" +
                             s.substr(0, 32) + "' (must be a finite number)");
      return x;
    };
    auto positive = [&](int c) {
      const double x = cell(c);
      if (!(x > 0))
        throw FieldError(header[static_cast<std::size_t>(c)],
                         "line " + std::to_string(line_no) + ": " +
                             header[static_cast<std::size_t>(c)] + " = " +
                             NumberText(x) + " (must be > 0)");
      return x;
    };
    d.v_mm_s.push_back(positive(c_v));
    d.load_n.push_back(positive(c_load));
    d.mu.push_back(cell(c_mu));
    if (c_t >= 0) d.temp_c.push_back(cell(c_t));
    if (c_eta >= 0) {
      d.eta_pa_s.push_back(positive(c_eta));
    } else {
      const double eta = CalcViscosity(lubricant, d.temp_c.back());
      if (!(eta > 0 && std::isfinite(eta)))
        throw FieldError("temp_c",
                         "line " + std::to_string(line_no) +
                             ": temp_c = " + NumberText(d.temp_c.back()) +
                             " (outside the lubricant's Vogel range)");
      d.eta_pa_s.push_back(eta);
    }
  }
  if (d.size() == 0) throw FieldError("body", "no data rows");
  return d;
}

RobotDescription RobotFromJson(const json& j) {
  if (!j.is_object()) Bad("robot", "must be a JSON object");
  if (!j.contains("joints") || !j["joints"].is_array())
    Bad("joints", "must be an array");
  RobotDescription r;
  const json& joints = j["joints"];
  if (joints.empty() || joints.size() > 32)
    throw FieldError("joints",
                     "joints has " + std::to_string(joints.size()) +
                         " entries (must be 1..32)");
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const json& x = joints[i];
    const std::string at = "joints[" + std::to_string(i) + "].";
    if (!x.is_object())
      Bad("joints[" + std::to_string(i) + "]", "must be an object");
    DhJoint dh;
    const std::string type = x.contains("type") && x["type"].is_string()
                                 ? x["type"].get<std::string>()
                                 : "";
    if (type == "revolute") {
      dh.type = JointType::kRevolute;
    } else if (type == "prismatic") {
      dh.type = JointType::kPrismatic;
    } else {
      Bad(at + "type", "must be \"revolute\" or \"prismatic\"");
    }
    double alpha_deg = 0, theta_deg = 0;
    Number(x, "a_mm", at, &dh.a_mm);
    Number(x, "alpha_deg", at, &alpha_deg);
    Number(x, "d_mm", at, &dh.d_mm);
    Number(x, "theta_deg", at, &theta_deg);
    dh.alpha_rad = alpha_deg * kDeg;
    dh.theta_rad = theta_deg * kDeg;
    dh.stiffness = RequireNumber(x, "stiffness", at);
    const double q_scale = dh.type == JointType::kRevolute ? kDeg : 1.0;
    double q_min = -1e9, q_max = 1e9;
    Number(x, "q_min", at, &q_min);
    Number(x, "q_max", at, &q_max);
    dh.q_min = q_min * q_scale;
    dh.q_max = q_max * q_scale;
    const bool has_sigma = x.contains("sigma_tau");
    const bool has_friction = x.contains("friction");
    if (has_sigma == has_friction)
      Bad(at + "sigma_tau", "give exactly one of sigma_tau and friction");
    std::optional<JointFrictionRef> ref;
    if (has_sigma) {
      dh.sigma_tau = RequireNumber(x, "sigma_tau", at);
    } else {
      const json& f = x["friction"];
      const std::string fat = at + "friction.";
      if (!f.is_object()) Bad(at + "friction", "must be an object");
      JointFrictionRef fr;
      if (!f.contains("material") || !f["material"].is_string())
        Bad(fat + "material", "must be a string");
      fr.material = f["material"].get<std::string>();
      if (f.contains("joint")) {
        if (!f["joint"].is_string()) Bad(fat + "joint", "must be a string");
        fr.joint = f["joint"].get<std::string>();
      }
      Number(f, "v_mm_s", fat, &fr.v_mm_s);
      Number(f, "load_n", fat, &fr.load_n);
      Number(f, "temp_c", fat, &fr.temp_c);
      Number(f, "radius_mm", fat, &fr.radius_mm);
      for (auto [v, name] :
           {std::pair<double, const char*>{fr.v_mm_s, "v_mm_s"},
            {fr.load_n, "load_n"},
            {fr.radius_mm, "radius_mm"}})
        if (!(v > 0))
          throw FieldError(
              fat + name,
              fat + name + " = " + NumberText(v) + " (must be > 0)");
      ref = fr;
    }
    r.arm.joints.push_back(dh);
    r.friction.push_back(ref);
  }
  ValidateArm(r.arm);
  const Eigen::Index n = static_cast<Eigen::Index>(joints.size());
  r.q_home = Eigen::VectorXd::Zero(n);
  if (j.contains("q_home")) {
    const json& q = j["q_home"];
    if (!q.is_array() || q.size() != joints.size())
      Bad("q_home", "must be an array of " + std::to_string(n) + " numbers");
    for (Eigen::Index i = 0; i < n; ++i) {
      const json& v = q[static_cast<std::size_t>(i)];
      if (!v.is_number() || !std::isfinite(v.get<double>()))
        Bad("q_home[" + std::to_string(i) + "]", "must be a finite number");
      const bool rev = r.arm.joints[static_cast<std::size_t>(i)].type ==
                       JointType::kRevolute;
      r.q_home[i] = v.get<double>() * (rev ? kDeg : 1.0);
    }
  }
  return r;
}

json RobotToJson(const RobotDescription& r) {
  json joints = json::array();
  for (std::size_t i = 0; i < r.arm.joints.size(); ++i) {
    const DhJoint& dh = r.arm.joints[i];
    const bool rev = dh.type == JointType::kRevolute;
    const double qs = rev ? 1.0 / kDeg : 1.0;
    json x = {{"type", rev ? "revolute" : "prismatic"},
              {"a_mm", dh.a_mm},
              {"alpha_deg", dh.alpha_rad / kDeg},
              {"d_mm", dh.d_mm},
              {"theta_deg", dh.theta_rad / kDeg},
              {"stiffness", dh.stiffness},
              {"q_min", dh.q_min * qs},
              {"q_max", dh.q_max * qs}};
    if (i < r.friction.size() && r.friction[i]) {
      const JointFrictionRef& f = *r.friction[i];
      x["friction"] = {{"material", f.material},
                       {"joint", f.joint},
                       {"v_mm_s", f.v_mm_s},
                       {"load_n", f.load_n},
                       {"temp_c", f.temp_c},
                       {"radius_mm", f.radius_mm}};
    } else {
      x["sigma_tau"] = dh.sigma_tau;
    }
    joints.push_back(x);
  }
  json q = json::array();
  for (Eigen::Index i = 0; i < r.q_home.size(); ++i) {
    const bool rev =
        r.arm.joints[static_cast<std::size_t>(i)].type == JointType::kRevolute;
    q.push_back(r.q_home[i] * (rev ? 1.0 / kDeg : 1.0));
  }
  return json{{"joints", joints}, {"q_home", q}};
}

}  // namespace frictiond
