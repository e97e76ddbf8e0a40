#pragma once
/// @file
/// The query parameters of the daemon's `/v1` routes: one table, the one
/// place that says which names a route takes. Two readers:
/// - the OpenAPI description (openapi.h) documents them, so a generated
///   client sends exactly these names;
/// - the HTTP server rejects any other name before the route's handler runs
///   (InstallQueryCheck), so a typo such as `?fn=5` or `?fingertips=a` is a
///   400 naming it instead of being ignored silently, and so is a name
///   given twice (`?fn_n=1&fn_n=2`).
///
/// A route that also takes the stored model's further inputs (covariates
/// such as `temp_c`, by their own names; kModelInputsParameter in the
/// table) leaves the names the table does not list to its handler, which
/// knows the model's inputs (ModelInputParams, routes.h). Routes outside
/// `/v1` (console files, /healthz, /metrics) are not checked.

#include <string>
#include <vector>

#include "frictiond/server/http_server.h"
#include "frictiond/server/request_error.h"

namespace frictiond {

/// One documented query parameter (units in the name, as in CONTRACT.md).
struct QueryParameter {
  const char* name;
  const char* type;  ///< OpenAPI schema type: string, number, integer, ...
  bool required;
  const char* description;
};

/// The name under which a route that takes the stored model's further
/// inputs documents them: one OpenAPI object parameter (style form,
/// explode), not a query key.
inline constexpr char kModelInputsParameter[] = "inputs";

/// The table's entry for a route, e.g. fn_n, v_mm_s, fingertip, ... for
/// `GET /v1/materials/{id}/predict`; empty when the route takes none.
const std::vector<QueryParameter>& QueryParametersOf(
    const std::string& method, const std::string& pattern);

/// The names of QueryParametersOf(method, pattern), in table order.
std::vector<std::string> DocumentedQueryParameters(const std::string& method,
                                                   const std::string& pattern);

/// Every (method, pattern) the table names.
std::vector<RouteKey> RoutesWithDocumentedQueries();

/// True when the table lists `name` for the route.
bool TakesQueryParameter(const std::string& method,
                         const std::string& pattern,
                         const std::string& name);

/// True when the route takes the stored model's further inputs.
bool TakesModelInputs(const std::string& method, const std::string& pattern);

/// The error for a query name the request may not carry:
/// RequestError(kInvalidArgument), the name (shown printable, at most 64
/// characters) as its field, and "query parameter 'name' `why`".
RequestError QueryParameterError(const std::string& name,
                                 const std::string& why);

/// Rejects, with RequestError(kInvalidArgument) and the name as its field,
/// a query name given more than once ("query parameter 'x' is given 2 times
/// (give it once)": each parameter is one value), then the first name the
/// table does not list for `request`'s route (`pattern`): "query parameter
/// 'x' is not known here (allowed: a, b)" ("allowed: none" for a route that
/// takes none; a route that TakesModelInputs leaves unlisted names to its
/// handler). Does nothing for a route outside `/v1`.
void CheckQueryParameters(const HttpRequest& request,
                          const std::string& pattern);

/// Makes `http` run CheckQueryParameters on every request it admits, before
/// the body is read (HttpServer::SetQueryCheck).
void InstallQueryCheck(HttpServer& http);

}  // namespace frictiond
