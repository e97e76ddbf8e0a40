#pragma once
/// @file
/// Route sets of the HTTP API (CONTRACT.md, "HTTP API"). Each feature
/// registers its routes on the server against the shared library core.

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/estimators/mu_admissibility.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/recognition_hook.h"

namespace frictiond {

/// /healthz, /metrics, materials CRUD, fingertips, model lookup and versions,
/// stroke upload, predict, slip-likelihood, grip-force, identifications.
void RegisterCoreRoutes(HttpServer& http, FrictionLibrary& library);

/// Feature modules (each in server/src/routes_<feature>.cc). Each may also
/// register family fitters and model listeners on the library.
/// Queries of a stored stochastic model (docs/paper000.md):
/// /target-force (eq. 3), /sliding-speed (eq. 4),
/// /conditional-slip-likelihood (eq. 2, family "slip_likelihood_fn"),
/// /forms, /mu-spread, /span-variability.
void RegisterModelQueryRoutes(HttpServer& http, FrictionLibrary& library);
void RegisterLuGreFeature(
    HttpServer& http, FrictionLibrary& library);  // LuGre family + /breakaway
void RegisterDiagnosisRoutes(HttpServer& http,
                             FrictionLibrary& library);  // /diagnose
/// Joint friction (paper 002): /joint-data, /joint-friction, /joint-wear,
/// /v1/robots/{id}, /repeatability, /repeatability-grid (docs/joint.md).
void RegisterJointRoutes(HttpServer& http, FrictionLibrary& library);
/// Measured actuator logs (issue 20): /actuator-logs, /actuator-model,
/// /actuator-simulate, /actuator-mjcf (docs/actuator.md).
void RegisterActuatorRoutes(HttpServer& http, FrictionLibrary& library);

/// /images, /recognize. Returns the recognition hook over the same
/// registered references (for the LCM endpoint), or an empty function when
/// built without OpenCV. `operating_point`: the calibrated score a candidate
/// needs to be accepted, in [0, 1]; negative = the calibrated default
/// (RecognizerOptions::kDefaultOperatingPoint, docs/recognition.md).
/// @throws std::invalid_argument for an operating point above 1 or NaN.
RecognizeImageFn RegisterRecognitionRoutes(HttpServer& http,
                                           FrictionLibrary& library,
                                           double operating_point = -1.0);
/// GET /v1/materials/{id}/export (simulator formats) and
/// GET /v1/pairs/{fingertip}/{object}/friction (pair-level answer); see
/// docs/export.md.
void RegisterExportRoutes(HttpServer& http, FrictionLibrary& library);

/// Operator console: GET / and /console/{file} (static files compiled into
/// the daemon) and GET /v1/materials/{id}/samples (decimated slipping
/// samples, their Fn-v hull and span coverage); see docs/console.md.
void RegisterConsoleRoutes(HttpServer& http, FrictionLibrary& library);

/// Material JSON as served.
nlohmann::json MaterialToJson(const Material& m);

/// The fingertip named by ?fingertip= (default "default"), validated.
std::string FingertipParam(const HttpRequest& req);

/// Who asks, for identification requests: ?robot=, else X-Robot-Id, else
/// "http:<remote address>" (at most 128 characters).
std::string Requester(const HttpRequest& req);

/// The model a read route serves: ?version= (400 when not a positive
/// integer, 404 when absent) or the newest, whose absence is a 404 that
/// records an identification request (FrictionLibrary::RequireModel).
std::shared_ptr<const CachedModel> ModelFor(FrictionLibrary& lib,
                                            const HttpRequest& req);

/// The further inputs of model `m` a route that takes them
/// (TakesModelInputs, query_parameters.h) was given: every query name its
/// table entry does not list, parsed as a number. A name that is not an
/// input of `m` (or is fn_n or v_mm_s, which the route sets itself) is a
/// 400 naming it.
InputValues ModelInputParams(const HttpRequest& req,
                             const StochasticFrictionModel& m);

/// The stochastic family of a served model; 422 (field "model") when the
/// version has none.
const StochasticFrictionModel& Stochastic(const CachedModel& m);

/// 422 naming the input at fault when a model's answer at `inputs` may not
/// be served (`check`: CheckServableMu, mu_admissibility.h: mu below 0 or
/// not finite). `what` names the side in the message ("material 'a'")
/// when a route serves more than one model; empty otherwise.
void RequireServable(const MeanMuCheck& check,
                     const InputValues& inputs,
                     const std::string& what = "");

}  // namespace frictiond
