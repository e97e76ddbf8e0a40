#pragma once
/// OpenAPI 3 description of the daemon's `/v1` routes, served at
/// `GET /v1/openapi.json` (CONTRACT.md), so that clients in any language
/// can be generated from it.
///
/// The paths and methods are generated from the routes the HttpServer has
/// registered when the document is asked for, so a route cannot be served
/// without being described; path parameters come from the `{name}` segments
/// of each pattern, and the role a route needs from `RequiredRole` (the one
/// policy table, server/src/auth.cc). Query parameters are listed in one
/// table in openapi.cc; a test (tests/auth_test.cc) checks that every
/// registered `/v1` route is described and that the table names no route
/// that is not registered.

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/server/http_server.h"

namespace frictiond {

/// The OpenAPI 3.0.3 document for `routes` (those outside `/v1` are left
/// out). `version` goes to `info.version`.
nlohmann::json BuildOpenApi(const std::vector<RouteKey>& routes,
                            const std::string& version);

/// The name under which a route that takes the stored model's further
/// inputs (covariates such as `temp_c`, by their own names) documents them:
/// one OpenAPI object parameter (style form, explode), not a query key.
inline constexpr char kModelInputsParameter[] = "inputs";

/// The documented query parameters of a route, e.g. {"fn_n", "v_mm_s"}
/// for `GET /v1/materials/{id}/predict` (with kModelInputsParameter for a
/// route that takes the model's further inputs); empty when it takes none.
std::vector<std::string> DocumentedQueryParameters(const std::string& method,
                                                   const std::string& pattern);

/// Every (method, pattern) the query-parameter table names.
std::vector<RouteKey> RoutesWithDocumentedQueries();

/// Registers `GET /v1/openapi.json`, built from `http.Routes()` on each
/// request. Register it after every other route module.
void RegisterOpenApiRoute(HttpServer& http);

}  // namespace frictiond
