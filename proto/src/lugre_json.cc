#include "frictiond/proto/lugre_json.h"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace frictiond {

using nlohmann::json;

namespace {

constexpr const char* kNames[6] = {
    "mu_s", "mu_c", "v0_mm_s", "sigma2_s_mm", "sigma0_per_mm", "sigma1_s_mm"};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

json Finite(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

void RequireObject(const json& j, const std::string& where) {
  if (!j.is_object())
    throw std::invalid_argument(where + ": expected a JSON object");
}

// A number, or null (read as NaN) when allow_null.
double ReadNumber(const json& v, const std::string& where, bool allow_null) {
  if (v.is_number()) return v.get<double>();
  if (allow_null && v.is_null()) return kNaN;
  throw std::invalid_argument(where + (allow_null
                                           ? ": expected a number or null"
                                           : ": expected a number"));
}

double OptionalNumber(const json& j,
                      const char* key,
                      double fallback,
                      const std::string& where) {
  auto it = j.find(key);
  if (it == j.end()) return fallback;
  return ReadNumber(*it, where + "." + key, true);
}

int OptionalInt(const json& j,
                const char* key,
                int fallback,
                const std::string& where) {
  auto it = j.find(key);
  if (it == j.end()) return fallback;
  if (!it->is_number_integer() || it->get<long long>() < 0 ||
      it->get<long long>() > std::numeric_limits<int>::max())
    throw std::invalid_argument(where + "." + key +
                                ": expected a non-negative integer");
  return it->get<int>();
}

std::string RequireString(const json& j,
                          const char* key,
                          const std::string& where) {
  auto it = j.find(key);
  if (it == j.end())
    throw std::invalid_argument(where + "." + key + ": missing");
  if (!it->is_string())
    throw std::invalid_argument(where + "." + key + ": expected a string");
  return it->get<std::string>();
}

}  // namespace

const char* LuGreParameterName(int i) {
  if (i < 0 || i > 5)
    throw std::out_of_range("LuGre parameter index " + std::to_string(i) +
                            " (must be in 0..5)");
  return kNames[i];
}

json LuGreThetaToJson(const LuGreTheta& theta) {
  json j = json::object();
  for (int i = 0; i < 6; ++i) j[kNames[i]] = Finite(theta[i]);
  return j;
}

LuGreTheta LuGreThetaFromJson(const json& j, const std::string& where) {
  RequireObject(j, where);
  LuGreTheta theta;
  for (int i = 0; i < 6; ++i) {
    auto it = j.find(kNames[i]);
    if (it == j.end())
      throw std::invalid_argument(where + "." + kNames[i] + ": missing");
    theta[i] = ReadNumber(*it, where + "." + kNames[i], false);
  }
  std::string why;
  if (!IsValidLuGreTheta(theta, &why)) {
    // why reads "theta.v0_mm_s = -1 (must be finite and > 0)".
    if (why.rfind("theta.", 0) == 0) why = why.substr(6);
    throw std::invalid_argument(where + "." + why);
  }
  return theta;
}

json LuGreToJson(const LuGreFamily& f) {
  json j = json::object();
  j["theta"] = LuGreThetaToJson(f.theta);
  json se = json::object();
  json names = json::array();
  json cov = json::array();
  for (int a = 0; a < 6; ++a) {
    const double var = f.P_theta(a, a);
    se[kNames[a]] = Finite(var >= 0 ? std::sqrt(var) : kNaN);
    names.push_back(kNames[a]);
    json row = json::array();
    for (int b = 0; b < 6; ++b) row.push_back(Finite(f.P_theta(a, b)));
    cov.push_back(std::move(row));
  }
  j["std_errors"] = se;
  j["parameters"] = names;
  j["covariance"] = cov;
  j["status"] = f.status;
  j["variant"] = f.variant;
  j["iterations"] = f.iterations;
  j["residual_rms"] = Finite(f.residual_rms);
  j["quasi_static_residual_rms"] = Finite(f.quasi_static_residual_rms);
  j["z0_mm"] = Finite(f.z0_mm);
  j["excited_samples"] = f.excited_samples;
  j["strokes_used"] = {{"quasi_static", f.strokes_quasi_static},
                       {"dynamic", f.strokes_dynamic}};
  return j;
}

LuGreFamily LuGreFromJson(const json& j) {
  const std::string where = kLuGreFamilyKey;
  RequireObject(j, where);
  LuGreFamily f;
  auto theta = j.find("theta");
  if (theta == j.end()) throw std::invalid_argument(where + ".theta: missing");
  f.theta = LuGreThetaFromJson(*theta, where + ".theta");
  f.status = RequireString(j, "status", where);
  f.variant = RequireString(j, "variant", where);
  if (auto cov = j.find("covariance"); cov != j.end()) {
    const std::string w = where + ".covariance";
    if (!cov->is_array() || cov->size() != 6)
      throw std::invalid_argument(w + ": expected 6 rows of 6 numbers");
    for (int a = 0; a < 6; ++a) {
      const json& row = (*cov)[a];
      const std::string wr = w + "[" + std::to_string(a) + "]";
      if (!row.is_array() || row.size() != 6)
        throw std::invalid_argument(wr + ": expected 6 numbers");
      for (int b = 0; b < 6; ++b) {
        f.P_theta(a, b) =
            ReadNumber(row[b], wr + "[" + std::to_string(b) + "]", true);
      }
    }
  }
  f.iterations = OptionalInt(j, "iterations", 0, where);
  f.residual_rms = OptionalNumber(j, "residual_rms", kNaN, where);
  f.quasi_static_residual_rms =
      OptionalNumber(j, "quasi_static_residual_rms", kNaN, where);
  f.z0_mm = OptionalNumber(j, "z0_mm", 0.0, where);
  f.excited_samples = OptionalInt(j, "excited_samples", 0, where);
  if (auto used = j.find("strokes_used"); used != j.end()) {
    const std::string w = where + ".strokes_used";
    RequireObject(*used, w);
    f.strokes_quasi_static = OptionalInt(*used, "quasi_static", 0, w);
    f.strokes_dynamic = OptionalInt(*used, "dynamic", 0, w);
  }
  return f;
}

}  // namespace frictiond
