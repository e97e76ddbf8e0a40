#include "frictiond/client/lugre_client.h"

#include <cmath>
#include <cstdio>
#include <limits>
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

double NumberOrNaN(const json& j, const char* key) {
  auto it = j.find(key);
  return (it != j.end() && it->is_number())
             ? it->get<double>()
             : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

BreakawayReply FetchBreakaway(FrictionClient& client,
                              const std::string& material,
                              double rho_per_s,
                              double fn_n,
                              std::optional<double> mass_kg,
                              const std::string& fingertip) {
  CheckPositive("rho", rho_per_s);
  CheckPositive("fn_n", fn_n);
  if (mass_kg) CheckPositive("mass_kg", *mass_kg);
  std::string path =
      "/v1/materials/" + UrlEncode(material) +
      "/breakaway?rho=" + Num(rho_per_s) + "&fn_n=" + Num(fn_n) +
      "&fingertip=" +
      UrlEncode(fingertip.empty() ? client.options().fingertip : fingertip);
  if (mass_kg) path += "&mass_kg=" + Num(*mass_kg);
  BreakawayReply r;
  r.body = client.GetJson(path);
  if (!r.body.is_object())
    throw ClientError(200, "breakaway: expected a JSON object", r.body);
  r.material = r.body.value("material", material);
  r.version = r.body.value("version", 0);
  r.bf_ratio = NumberOrNaN(r.body, "bf_ratio");
  r.t_breakaway_s = NumberOrNaN(r.body, "t_breakaway_s");
  r.rho_per_s = NumberOrNaN(r.body, "rho");
  r.fn_n = NumberOrNaN(r.body, "fn_n");
  r.mass_kg = NumberOrNaN(r.body, "mass_kg");
  r.status = r.body.value("status", "");
  return r;
}

std::optional<LuGreFamily> LuGreFamilyFromModel(const ModelSet& set) {
  auto it = set.other.find(kLuGreFamilyKey);
  if (it == set.other.end() || it->is_null()) return std::nullopt;
  return LuGreFromJson(*it);
}

std::optional<LuGreTheta> LuGreFromModel(const ModelSet& set) {
  if (auto family = LuGreFamilyFromModel(set)) return family->theta;
  return std::nullopt;
}

}  // namespace frictiond
