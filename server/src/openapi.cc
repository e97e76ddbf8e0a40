#include "frictiond/server/openapi.h"

#include <algorithm>
#include <cctype>
#include <utility>

#include "frictiond/server/auth.h"
#include "frictiond/server/query_parameters.h"

namespace frictiond {
namespace {

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
    for (const QueryParameter& qp : QueryParametersOf(r.method, r.pattern)) {
      nlohmann::json p = {{"name", qp.name},
                          {"in", "query"},
                          {"required", qp.required},
                          {"description", qp.description},
                          {"schema", {{"type", qp.type}}}};
      if (std::string(qp.name) == kModelInputsParameter) {
        // Free-form key=value pairs (OpenAPI 3.0 "form", exploded).
        p["style"] = "form";
        p["explode"] = true;
        p["schema"]["additionalProperties"] = {{"type", "number"}};
      }
      params.push_back(std::move(p));
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
