#include "frictiond/client/joint_client.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace frictiond {

using nlohmann::json;

namespace {

std::string Num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.17g", x);
  return buf;
}

void CheckPositive(const char* name, double x) {
  if (!(x > 0) || !std::isfinite(x))
    throw std::invalid_argument(std::string(name) + " = " + Num(x) +
                                " (must be finite and > 0)");
}

void CheckFinite(const char* name, double x) {
  if (!std::isfinite(x))
    throw std::invalid_argument(std::string(name) + " = " + Num(x) +
                                " (must be finite)");
}

}  // namespace

json UploadJointData(
    FrictionClient& client,
    const std::string& material,
    const std::string& joint,
    const std::string& csv,
    const std::vector<std::pair<std::string, std::string>>& params) {
  std::string path = "/v1/materials/" + UrlEncode(material) +
                     "/joint-data?joint=" + UrlEncode(joint);
  for (const auto& [k, v] : params)
    path += "&" + UrlEncode(k) + "=" + UrlEncode(v);
  return client.SendJson("POST", path, csv, "text/csv");
}

JointFrictionReply FetchJointFriction(FrictionClient& client,
                                      const std::string& material,
                                      const std::string& joint,
                                      double v_mm_s,
                                      double load_n,
                                      double temp_c) {
  CheckPositive("v_mm_s", v_mm_s);
  CheckPositive("load_n", load_n);
  CheckFinite("temp_c", temp_c);
  JointFrictionReply r;
  r.body = client.GetJson("/v1/materials/" + UrlEncode(material) +
                          "/joint-friction?joint=" + UrlEncode(joint) +
                          "&v_mm_s=" + Num(v_mm_s) + "&load_n=" + Num(load_n) +
                          "&temp_c=" + Num(temp_c));
  if (!r.body.is_object() || !r.body.contains("mu") ||
      !r.body["mu"].is_number())
    throw ClientError(200, "joint-friction: expected {\"mu\": ...}", r.body);
  r.mu = r.body["mu"].get<double>();
  r.sigma = r.body.value("sigma", 0.0);
  r.sommerfeld_um = r.body.value("sommerfeld_um", 0.0);
  r.regime = r.body.value("regime", "");
  r.version = r.body.value("version", 0);
  return r;
}

json PutRobot(FrictionClient& client,
              const std::string& robot,
              const json& description) {
  return client.SendJson(
      "PUT", "/v1/robots/" + UrlEncode(robot), description.dump());
}

RepeatabilityReply FetchRepeatability(FrictionClient& client,
                                      const std::string& robot,
                                      double x_mm,
                                      double y_mm,
                                      double z_mm,
                                      double probability) {
  CheckFinite("x_mm", x_mm);
  CheckFinite("y_mm", y_mm);
  CheckFinite("z_mm", z_mm);
  if (!(probability > 0 && probability < 1))
    throw std::invalid_argument("probability = " + Num(probability) +
                                " (must be in (0, 1))");
  RepeatabilityReply r;
  r.body =
      client.GetJson("/v1/robots/" + UrlEncode(robot) +
                     "/repeatability?x_mm=" + Num(x_mm) + "&y_mm=" + Num(y_mm) +
                     "&z_mm=" + Num(z_mm) + "&probability=" + Num(probability));
  const json& a =
      r.body.is_object() ? r.body.value("semi_axes_um", json()) : json();
  if (!a.is_array() || a.size() != 3)
    throw ClientError(200, "repeatability: expected semi_axes_um", r.body);
  for (int i = 0; i < 3; ++i) r.semi_axes_um[i] = a[i].get<double>();
  r.probability = r.body.value("probability", probability);
  return r;
}

std::optional<JointFamily> JointFamilyFromModel(const ModelSet& set) {
  auto it = set.other.find(kJointFamilyKey);
  if (it == set.other.end() || it->is_null()) return std::nullopt;
  return JointFamilyFromJson(*it);
}

}  // namespace frictiond
