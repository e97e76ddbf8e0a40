#include "frictiond/server/openapi.h"

#include <algorithm>
#include <cctype>
#include <map>
#include <utility>

#include "frictiond/server/auth.h"

namespace frictiond {
namespace {

struct QueryParam {
  const char* name;
  const char* type;  // OpenAPI schema type
  bool required;
  const char* description;
};

using RouteQueries =
    std::map<std::pair<std::string, std::string>, std::vector<QueryParam>>;

// The one table of documented query parameters (units in the names, as in
// CONTRACT.md). Routes absent here take none, or only ones for the console.
const RouteQueries& QueryTable() {
  static const RouteQueries table = {
      {{"GET", "/v1/materials/{id}/model"},
       {{"fingertip", "string", false, "fingertip id (default: default)"},
        {"version", "integer", false, "model version (default: latest)"},
        {"robot", "string", false, "requesting robot, for the stroke plan"}}},
      {{"GET", "/v1/materials/{id}/models"},
       {{"fingertip", "string", false, "fingertip id"}}},
      {{"POST", "/v1/materials/{id}/strokes"},
       {{"fingertip", "string", false, "fingertip id"},
        {"robot", "string", false, "robot that measured the strokes"},
        {"slip_peak_mm_s", "number", false, "slip threshold [mm/s]"},
        {"slip_floor_mm_s", "number", false, "rest threshold [mm/s]"},
        {"median_window_s", "number", false, "median filter window [s]"},
        {"max_fn_n", "number", false, "largest plausible Fn [N]"},
        {"max_v_mm_s", "number", false, "largest plausible speed [mm/s]"}}},
      {{"GET", "/v1/materials/{id}/predict"},
       {{"fn_n", "number", true, "normal force [N], > 0"},
        {"v_mm_s", "number", true, "sliding speed [mm/s], >= 0"},
        {"fingertip", "string", false, "fingertip id"},
        {"version", "integer", false, "model version"}}},
      {{"GET", "/v1/materials/{id}/slip-likelihood"},
       {{"fn_n", "number", true, "normal force [N], > 0"},
        {"ft_n", "number", true, "tangential force [N], >= 0"},
        {"fingertip", "string", false, "fingertip id"},
        {"version", "integer", false, "model version"}}},
      {{"GET", "/v1/materials/{id}/grip-force"},
       {{"load_n", "number", true, "tangential load to hold [N], > 0"},
        {"risk", "number", true, "P(any slip during the hold), in (0, 1)"},
        {"hold_s",
         "number",
         false,
         "hold duration [s] (default 0: one instant)"},
        {"v_mm_s",
         "number",
         false,
         "sliding speed of the grasp [mm/s] (default 0)"},
        {"fingertip", "string", false, "fingertip id"},
        {"version", "integer", false, "model version"}}},
      {{"GET", "/v1/materials/{id}/breakaway"},
       {{"rho", "number", true, "drag-ratio rate [1/s], > 0"},
        {"fn_n", "number", true, "normal force [N], > 0"},
        {"mass_kg", "number", false, "object mass [kg] (default 0.2)"},
        {"mu_applied",
         "number",
         false,
         "measured Ft/Fn now: predict from the state it implies"},
        {"v_mm_s",
         "number",
         false,
         "measured slip velocity [mm/s] with mu_applied (default 0)"},
        {"fingertip", "string", false, "fingertip id"},
        {"version", "integer", false, "model version"}}},
      {{"GET", "/v1/identifications"},
       {{"open", "boolean", false, "only open jobs"},
        {"limit", "integer", false, "page size (default 100, at most 1000)"},
        {"after", "integer", false, "job id after which the page starts"}}},
      {{"GET", "/v1/materials/{id}/export"},
       {{"format", "string", true, "mjcf, sdf, urdf, usd or isaac"},
        {"risk", "number", false, "slip risk the exported mu holds at"},
        {"fn_n", "number", false, "normal force [N] the mu is taken at"},
        {"v_mm_s", "number", false, "sliding speed [mm/s]"},
        {"version", "integer", false, "model version"}}},
      {{"POST", "/v1/materials/{id}/diagnose"},
       {{"store", "boolean", false, "store the extended model as a version"},
        {"seed", "integer", false, "fold seed"}}},
      {{"GET", "/v1/materials/{id}/joint-friction"},
       {{"v_mm_s", "number", true, "sliding speed [mm/s]"},
        {"load_n", "number", true, "load [N]"},
        {"temp_c", "number", false, "temperature [degC]"},
        {"eta_pa_s", "number", false, "lubricant viscosity [Pa s]"},
        {"joint", "string", false, "joint id"}}},
      {{"POST", "/v1/materials/{id}/joint-data"},
       {{"joint", "string", false, "joint id"}}},
      {{"POST", "/v1/materials/{id}/actuator-logs"},
       {{"joint", "string", false, "joint id"},
        {"law", "string", false, "friction law (default auto)"}}},
      {{"GET", "/v1/materials/{id}/actuator-model"},
       {{"joint", "string", false, "joint id"},
        {"version", "integer", false, "model version"}}},
      {{"GET", "/v1/robots/{id}/repeatability"},
       {{"x_mm", "number", true, "target x [mm]"},
        {"y_mm", "number", true, "target y [mm]"},
        {"z_mm", "number", true, "target z [mm]"}}},
  };
  return table;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(c));
  return s;
}

std::vector<std::string> PathParameters(const std::string& pattern) {
  std::vector<std::string> out;
  std::size_t pos = 0;
  while ((pos = pattern.find('{', pos)) != std::string::npos) {
    const std::size_t end = pattern.find('}', pos);
    if (end == std::string::npos) break;
    out.push_back(pattern.substr(pos + 1, end - pos - 1));
    pos = end + 1;
  }
  return out;
}

nlohmann::json ErrorResponse(const char* what) {
  return {{"description", what},
          {"content",
           {{"application/json",
             {{"schema", {{"$ref", "#/components/schemas/Error"}}}}}}}};
}

}  // namespace

std::vector<std::string> DocumentedQueryParameters(const std::string& method,
                                                   const std::string& pattern) {
  std::vector<std::string> out;
  const auto it = QueryTable().find({method, pattern});
  if (it == QueryTable().end()) return out;
  for (const QueryParam& q : it->second) out.emplace_back(q.name);
  return out;
}

std::vector<RouteKey> RoutesWithDocumentedQueries() {
  std::vector<RouteKey> out;
  for (const auto& [key, params] : QueryTable()) {
    (void)params;
    out.push_back({key.first, key.second});
  }
  return out;
}

nlohmann::json BuildOpenApi(const std::vector<RouteKey>& routes,
                            const std::string& version) {
  nlohmann::json doc;
  doc["openapi"] = "3.0.3";
  doc["info"] = {
      {"title", "frictiond"},
      {"version", version},
      {"description",
       "Friction material library for robots (CONTRACT.md). Errors are "
       "JSON {error, detail, field} with a 4xx status for the caller's "
       "mistakes."}};
  doc["components"]["securitySchemes"]["bearer"] = {{"type", "http"},
                                                    {"scheme", "bearer"}};
  doc["components"]["schemas"]["Error"] = {{"type", "object"},
                                           {"properties",
                                            {{"error", {{"type", "string"}}},
                                             {"detail", {{"type", "string"}}},
                                             {"field", {{"type", "string"}}}}},
                                           {"required", {"error", "detail"}}};
  nlohmann::json paths = nlohmann::json::object();
  for (const RouteKey& r : routes) {
    if (r.pattern.rfind("/v1/", 0) != 0) continue;
    nlohmann::json op;
    const Role role = RequiredRole(r.method, r.pattern);
    op["operationId"] = Lower(r.method) + r.pattern;
    op["summary"] = r.method + " " + r.pattern;
    op["x-frictiond-role"] = RoleName(role);
    if (role == Role::kPublic) {
      op["security"] = nlohmann::json::array();
    } else {
      // Readers may be open without a token on loopback (--open-reads).
      op["security"] = {{{"bearer", nlohmann::json::array()}}};
    }
    nlohmann::json params = nlohmann::json::array();
    for (const std::string& p : PathParameters(r.pattern)) {
      params.push_back({{"name", p},
                        {"in", "path"},
                        {"required", true},
                        {"schema", {{"type", "string"}}}});
    }
    const auto q = QueryTable().find({r.method, r.pattern});
    if (q != QueryTable().end()) {
      for (const QueryParam& qp : q->second) {
        params.push_back({{"name", qp.name},
                          {"in", "query"},
                          {"required", qp.required},
                          {"description", qp.description},
                          {"schema", {{"type", qp.type}}}});
      }
    }
    if (!params.empty()) op["parameters"] = params;
    if (r.method == "POST" || r.method == "PUT") {
      op["requestBody"] = {
          {"required", false},
          {"content",
           {{"application/json", nlohmann::json::object()},
            {"text/csv", nlohmann::json::object()},
            {"application/octet-stream", nlohmann::json::object()}}}};
    }
    op["responses"] = {
        {"200", {{"description", "OK (JSON)"}}},
        {"400", ErrorResponse("invalid argument, naming the field")},
        {"401", ErrorResponse("missing or invalid token")},
        {"403", ErrorResponse("role too low")},
        {"404", ErrorResponse("not found")},
        {"413", ErrorResponse("body too large")},
        {"422", ErrorResponse("valid but cannot be answered")},
        {"503", ErrorResponse("store unavailable")}};
    if (r.method == "POST" || r.method == "PUT")
      op["responses"]["201"] = {{"description", "created"}};
    paths[r.pattern][Lower(r.method)] = op;
  }
  doc["paths"] = paths;
  return doc;
}

void RegisterOpenApiRoute(HttpServer& http) {
  http.Route("GET", "/v1/openapi.json", [&http](const HttpRequest&) {
    HttpResponse res;
    res.status = 200;
    res.body = BuildOpenApi(http.Routes(), "1").dump();
    return res;
  });
}

}  // namespace frictiond
