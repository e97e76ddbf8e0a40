#pragma once
/// @file
/// Route sets of the HTTP API (CONTRACT.md, "HTTP API"). Each feature
/// registers its routes on the server against the shared library core.

#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"

namespace frictiond {

/// /healthz, /metrics, materials CRUD, fingertips, model lookup and versions,
/// stroke upload, predict, slip-likelihood, grip-force, identifications.
void RegisterCoreRoutes(HttpServer& http, FrictionLibrary& library);

/// Feature modules (each in server/src/routes_<feature>.cc). Each may also
/// register family fitters and model listeners on the library.
void RegisterPaper000Routes(
    HttpServer& http,
    FrictionLibrary& library);  // coverage, control, likelihood extras
void RegisterLuGreFeature(
    HttpServer& http, FrictionLibrary& library);  // LuGre family + /breakaway
void RegisterDiagnosisRoutes(HttpServer& http,
                             FrictionLibrary& library);  // /diagnose
void RegisterRecognitionRoutes(
    HttpServer& http, FrictionLibrary& library);  // /images, /recognize
/// GET /v1/materials/{id}/export (simulator formats) and
/// GET /v1/pairs/{fingertip}/{object}/friction (pair-level answer); see
/// docs/export.md.
void RegisterExportRoutes(HttpServer& http, FrictionLibrary& library);

/// Material JSON as served.
nlohmann::json MaterialToJson(const Material& m);

/// The fingertip named by ?fingertip= (default "default"), validated.
std::string FingertipParam(const HttpRequest& req);

}  // namespace frictiond
