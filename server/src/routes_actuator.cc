// Measured actuator logs (issue 20 item 6, docs/actuator.md): the
// "actuator" model family of (robot, joint id) pairs, stored as a model
// version of the pair beside the other families (the joint id takes the
// fingertip's place, as the "joint" family does), so it is versioned like
// material models without a new table.
//
//   POST /v1/materials/{id}/actuator-logs?joint=&law=   (application/json:
//        one log object, or {"logs": [log, ...]}) -> fit and store
//   GET  /v1/materials/{id}/actuator-model?joint=&version=
//   POST /v1/materials/{id}/actuator-simulate?joint=&version=  (one log)
//   GET  /v1/materials/{id}/actuator-mjcf?joint=&version=
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "frictiond/estimators/field_error.h"
#include "frictiond/proto/actuator_json.h"
#include "frictiond/proto/actuator_report.h"
#include "frictiond/proto/sim_export.h"
#include "frictiond/server/model_lookup.h"
#include "frictiond/server/routes.h"

namespace frictiond {

using nlohmann::json;

namespace {

constexpr const char* kActuatorFamilyKey = "actuator";
constexpr std::size_t kMaxLogsPerUpload = 32;

std::string JointParam(const HttpRequest& req) {
  const std::string j = req.QueryOr("joint", "default");
  CheckId(j, "joint");
  return j;
}

void RequireJson(const HttpRequest& req) {
  const std::string ct = req.Header("Content-Type");
  if (ct.rfind("application/json", 0) != 0)
    throw HttpError(
        415,
        "Content-Type",
        "Content-Type '" + ct.substr(0, 64) + "' (must be application/json)");
}

// A log's name: its trajectory and gain, "sin_sin_kp100". The gain is
// validated (finite, > 0) but unbounded: whole gains below 2^53 print as
// integers (truncated, as stored names have always been), others in full
// (a cast of 1e308 to an integer is undefined).
std::string LogName(const std::string& trajectory, double kp) {
  if (!(kp > 0) || !std::isfinite(kp)) return trajectory;
  const std::string gain = kp < 9007199254740992.0
                               ? std::to_string(static_cast<std::int64_t>(kp))
                               : FormatRoundTrip(kp);
  return trajectory + "_kp" + gain;
}

// Parses the body: one log, or {"logs": [...]}. Nothing is stored on error.
std::vector<ActuatorLog> ParseLogs(const std::string& body) {
  std::vector<ActuatorLog> logs;
  const json j = ParseJsonBody(body);
  if (!j.is_object())
    throw RequestError(
        StatusCode::kInvalidArgument, "body", "body must be a JSON object");
  auto parse_one = [&](const json& x, const std::string& prefix) {
    try {
      ActuatorLog log = ActuatorLogFromJson(x);
      // Optional; a non-string was a 500 (json type_error) before.
      std::string trajectory;
      if (const auto t = x.find("trajectory"); t != x.end()) {
        if (!t->is_string())
          throw FieldError::Because("trajectory", "must be a string");
        trajectory = t->get<std::string>();
      }
      log.name = LogName(trajectory, log.kp);
      logs.push_back(std::move(log));
    } catch (const std::invalid_argument& e) {
      throw InvalidArgumentFrom(e, "log", prefix);
    }
  };
  if (j.contains("logs")) {
    const json& a = j["logs"];
    if (!a.is_array() || a.empty())
      throw RequestError(StatusCode::kInvalidArgument,
                         "logs",
                         "logs must be a non-empty array");
    if (a.size() > kMaxLogsPerUpload)
      throw RequestError(StatusCode::kResourceExhausted,
                         "logs",
                         "logs: " + std::to_string(a.size()) + " (limit " +
                             std::to_string(kMaxLogsPerUpload) + ")");
    for (std::size_t i = 0; i < a.size(); ++i)
      parse_one(a[i], "logs[" + std::to_string(i) + "].");
  } else {
    parse_one(j, "");
  }
  return logs;
}

struct LoadedActuator {
  std::shared_ptr<const CachedModel> model;
  json family;
  ActuatorModel actuator;
};

LoadedActuator LoadActuator(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  CheckId(id, "id");
  const std::string joint = JointParam(req);
  const json hint = {{"upload",
                      "POST /v1/materials/" + id + "/actuator-logs?joint=" +
                          joint + " (application/json logs)"}};
  std::optional<int> version;
  if (auto v = req.Query("version")) version = ParseVersionParam(*v);
  const ModelFamily found = RequireModelFamily(
      lib, id, joint, version, kActuatorFamilyKey, "actuator", hint);
  LoadedActuator out;
  out.model = found.model;
  out.family = *found.family;
  try {
    out.actuator = ActuatorModelFromJson(out.family.at("model"));
  } catch (const std::exception& e) {
    throw std::runtime_error(
        std::string("stored actuator model is malformed: ") + e.what());
  }
  return out;
}

HttpResponse HandleUpload(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  CheckId(id, "id");
  const std::string joint = JointParam(req);
  RequireJson(req);
  const std::string law_name = req.QueryOr("law", "auto");
  ActuatorFrictionLaw law;
  try {
    law = ParseActuatorFrictionLaw(
        law_name == "auto" ? ActuatorFrictionLawName(kAutoActuatorLaw)
                           : law_name);
  } catch (const std::invalid_argument& e) {
    throw RequestError(StatusCode::kInvalidArgument, "law", e.what());
  }
  const std::vector<ActuatorLog> logs = ParseLogs(req.body);
  const ActuatorFitResult fit = FitActuatorLaw(logs, law);
  if (!fit.converged)
    throw RequestError(StatusCode::kFailedPrecondition,
                       "logs",
                       "identification failed: " + fit.why);
  json family = ActuatorFitToJson(fit);
  json per_log = json::array();
  std::size_t samples = 0;
  for (const ActuatorLog& l : logs) {
    samples += l.size();
    per_log.push_back({{"name", l.name},
                       {"kp", l.kp},
                       {"trajectory", l.trajectory},
                       {"samples", l.size()},
                       {"mae_rad", SimulateActuatorLog(fit.model, l)}});
  }
  family["logs"] = per_log;
  family["samples"] = samples;
  family["law_requested"] = law_name;
  auto model = lib.AddFamilyVersion(
      id, joint, kActuatorFamilyKey, family, "actuator-logs");
  return HttpResponse::Json(201,
                            {{"material", id},
                             {"joint", joint},
                             {"version", model ? model->set.version : 0},
                             {"actuator", family}});
}

}  // namespace

void RegisterActuatorRoutes(HttpServer& http, FrictionLibrary& library) {
  http.Route("POST",
             "/v1/materials/{id}/actuator-logs",
             [&library](const HttpRequest& req) {
               return HandleUpload(library, req);
             });
  http.Route("GET",
             "/v1/materials/{id}/actuator-model",
             [&library](const HttpRequest& req) {
               const LoadedActuator a = LoadActuator(library, req);
               return HttpResponse::Json(200,
                                         {{"material", req.params.at(0)},
                                          {"joint", JointParam(req)},
                                          {"version", a.model->set.version},
                                          {"actuator", a.family}});
             });
  http.Route("POST",
             "/v1/materials/{id}/actuator-simulate",
             [&library](const HttpRequest& req) {
               RequireJson(req);
               const LoadedActuator a = LoadActuator(library, req);
               const std::vector<ActuatorLog> logs = ParseLogs(req.body);
               if (logs.size() != 1)
                 throw RequestError(StatusCode::kInvalidArgument,
                                    "logs",
                                    "simulate takes one log");
               return HttpResponse::Json(
                   200,
                   {{"mae_rad", SimulateActuatorLog(a.actuator, logs[0])},
                    {"samples", logs[0].size()},
                    {"law", ActuatorFrictionLawName(a.actuator.law)},
                    {"version", a.model->set.version}});
             });
  http.Route("GET",
             "/v1/materials/{id}/actuator-mjcf",
             [&library](const HttpRequest& req) {
               const LoadedActuator a = LoadActuator(library, req);
               HttpResponse r;
               r.status = 200;
               r.content_type = "application/xml";
               r.body = ExportActuatorMjcf(a.actuator, JointParam(req));
               return r;
             });
}

}  // namespace frictiond
