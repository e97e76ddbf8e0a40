#pragma once
/// OpenAPI 3 description of the daemon's `/v1` routes, served at
/// `GET /v1/openapi.json` (CONTRACT.md), so that clients in any language
/// can be generated from it.
///
/// The paths and methods are generated from the routes the HttpServer has
/// registered when the document is asked for, so a route cannot be served
/// without being described; path parameters come from the `{name}` segments
/// of each pattern, and the role a route needs from `RequiredRole` (the one
/// policy table, server/src/auth.cc). Query parameters come from the one
/// table the server also enforces (query_parameters.h); a test
/// (tests/auth_test.cc) checks that every registered `/v1` route is
/// described and that the table names no route that is not registered.

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/server/http_server.h"

namespace frictiond {

/// The OpenAPI 3.0.3 document for `routes` (those outside `/v1` are left
/// out). `version` goes to `info.version`.
nlohmann::json BuildOpenApi(const std::vector<RouteKey>& routes,
                            const std::string& version);

/// Registers `GET /v1/openapi.json`, built from `http.Routes()` on each
/// request. Register it after every other route module.
void RegisterOpenApiRoute(HttpServer& http);

}  // namespace frictiond
