#include <cmath>

#include "frictiond/estimators/number_text.h"
#include "frictiond/server/auth.h"
#include "frictiond/server/identification_json.h"
#include "frictiond/server/metrics.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/server/routes.h"
#include "frictiond/server/text.h"

namespace frictiond {

using nlohmann::json;

json MaterialToJson(const Material& m) {
  return json{{"id", m.id},
              {"name", m.name},
              {"description", m.description},
              {"tags", m.tags},
              {"created_at", m.created_at},
              {"updated_at", m.updated_at}};
}

namespace {

// The body of a PUT: empty (= {}) or a JSON object.
json JsonObjectBody(const std::string& body, const std::string& shape) {
  const json j = body.empty() ? json::object() : ParseJsonBody(body);
  if (!j.is_object())
    throw RequestError(StatusCode::kInvalidArgument,
                       "body",
                       "body: expected a JSON object " + shape);
  return j;
}

std::string StringField(const json& value, const std::string& field) {
  if (!value.is_string())
    throw RequestError(
        StatusCode::kInvalidArgument, field, field + ": expected a string");
  return value.get<std::string>();
}

RequestError UnknownField(const std::string& key, const std::string& allowed) {
  return RequestError(StatusCode::kInvalidArgument,
                      key,
                      "body: unknown field '" + ShownText(key, 64) +
                          "' (allowed: " + allowed + ")");
}

}  // namespace

std::string FingertipParam(const HttpRequest& req) {
  const std::string f = req.QueryOr("fingertip", "default");
  CheckId(f, "fingertip");
  return f;
}

std::string Requester(const HttpRequest& req) {
  if (auto robot = req.Query("robot")) {
    CheckText(*robot, "robot", 128);
    if (!robot->empty()) return *robot;
  }
  std::string who = req.Header("X-Robot-Id");
  CheckText(who, "X-Robot-Id", 128);
  if (who.empty()) who = "http:" + req.remote_addr;
  return who;
}

std::shared_ptr<const CachedModel> ModelFor(FrictionLibrary& lib,
                                            const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  const std::string fingertip = FingertipParam(req);
  if (auto v = req.Query("version")) {
    CheckId(id, "id");
    auto m = lib.FindModelVersion(id, fingertip, ParseVersionParam(*v));
    if (!m)
      throw RequestError(StatusCode::kNotFound,
                         "version",
                         "material '" + id + "' has no model version " + *v);
    return m;
  }
  return lib.RequireModel(id, fingertip, Requester(req));
}

InputValues ModelInputParams(const HttpRequest& req,
                             const StochasticFrictionModel& m) {
  InputValues out;
  for (const auto& [k, val] : req.query) {
    if (TakesQueryParameter(req.method, req.route, k)) continue;
    if (m.inputs.count(k) == 0 || k == "fn_n" || k == "v_mm_s")
      throw QueryParameterError(
          k, "is not known here and not an input of this model");
    out.emplace_back(k, ParseNumberParam(k, val));
  }
  return out;
}

const StochasticFrictionModel& Stochastic(const CachedModel& m) {
  if (!m.set.stochastic) {
    throw RequestError(StatusCode::kFailedPrecondition,
                       "model",
                       "model version " + std::to_string(m.set.version) +
                           " has no stochastic model");
  }
  return *m.set.stochastic;
}

namespace {

// grip-force's and slip-likelihood's grasp state: hold_s in [0, 3600] s
// (default 0: one instant), v_mm_s finite and >= 0 (default 0: at rest).
GripForceOptions GraspStateParams(const HttpRequest& req) {
  GripForceOptions options;
  if (req.Query("hold_s")) options.hold_s = req.RequireNumber("hold_s");
  if (req.Query("v_mm_s")) options.v_mm_s = req.RequireNumber("v_mm_s");
  if (!(options.hold_s >= 0 && options.hold_s <= 3600))
    throw RequestError(StatusCode::kInvalidArgument,
                       "hold_s",
                       "hold_s = " + std::to_string(options.hold_s) +
                           " (must be in [0, 3600] s)");
  if (!(options.v_mm_s >= 0) || !std::isfinite(options.v_mm_s))
    throw RequestError(StatusCode::kInvalidArgument,
                       "v_mm_s",
                       "v_mm_s = " + std::to_string(options.v_mm_s) +
                           " (must be finite and >= 0)");
  return options;
}

}  // namespace

void RequireServable(const MeanMuCheck& check,
                     const InputValues& inputs,
                     const std::string& what) {
  if (check.admissible) return;
  json given = json::object();
  for (const auto& [name, value] : inputs) given[name] = value;
  throw RequestError(StatusCode::kFailedPrecondition,
                     check.field.empty() ? "model" : check.field,
                     (what.empty() ? "" : what + ": ") + check.why,
                     json{{"inputs", given}});
}

namespace {

bool IsCsvContentType(const std::string& ct) {
  const std::string base = ct.substr(0, ct.find(';'));
  return base.empty() || base == "text/csv" || base == "application/csv" ||
         base == "text/plain";
}

}  // namespace

void RegisterCoreRoutes(HttpServer& http, FrictionLibrary& lib) {
  http.Route("GET", "/healthz", [&lib](const HttpRequest&) {
    return HttpResponse::Json(
        200, {{"status", "ok"}, {"backend", lib.store().BackendName()}});
  });
  http.Route("GET", "/metrics", [&http, &lib](const HttpRequest&) {
    const Ingestor& ingestor = lib.ingestor();
    std::string text =
        http.metrics().Render() + RenderHeapGauges() +
        RenderSeries("frictiond_stroke_cache_samples",
                     "gauge",
                     "Parsed stroke samples the ingestor keeps "
                     "(IngestorOptions::cache_sample_cap).",
                     ingestor.cached_samples()) +
        RenderSeries("frictiond_stroke_cache_store_reads_total",
                     "counter",
                     "Uploads read back from the store one at a time by the "
                     "ingestor.",
                     ingestor.store_reads());
    return HttpResponse{200, "text/plain; version=0.0.4", std::move(text), {}};
  });

  // --- materials
  // ---------------------------------------------------------------
  http.Route("GET", "/v1/materials", [&lib](const HttpRequest& req) {
    const std::string q = req.QueryOr("q", "");
    json list = json::array();
    for (const Material& m : lib.ListMaterials()) {
      if (!q.empty() && m.id.find(q) == std::string::npos &&
          m.name.find(q) == std::string::npos)
        continue;
      json j = MaterialToJson(m);
      auto model = lib.FindModel(m.id, "default");
      j["latest_version"] = model ? json(model->set.version) : json(nullptr);
      list.push_back(j);
    }
    return HttpResponse::Json(200, {{"materials", list}});
  });
  http.Route("GET", "/v1/materials/{id}", [&lib](const HttpRequest& req) {
    const std::string& id = req.params[0];
    CheckId(id, "id");
    auto m = lib.store().GetMaterial(id);
    if (!m) {
      json extra = {{"material", id}, {"known_material", false}};
      extra["identification"] = IdentificationRequestToJson(
          lib.RequestIdentification(id, "default", Requester(req)));
      throw RequestError(
          StatusCode::kNotFound,
          "id",
          "unknown material '" + id + "': an identification was requested",
          extra);
    }
    json j = MaterialToJson(*m);
    json models = json::array();
    for (const Fingertip& f : lib.store().ListFingertips()) {
      const auto versions = lib.store().ListModels(id, f.id);
      if (!versions.empty()) {
        models.push_back({{"fingertip", f.id},
                          {"latest_version", versions.back().version},
                          {"versions", versions.size()}});
      }
    }
    j["models"] = models;
    return HttpResponse::Json(200, j);
  });
  http.Route("PUT", "/v1/materials/{id}", [&lib](const HttpRequest& req) {
    const std::string& id = req.params[0];
    MaterialUpdate update;
    const json body = JsonObjectBody(req.body, "{name, description, tags}");
    for (auto it = body.begin(); it != body.end(); ++it) {
      const std::string& k = it.key();
      if (k == "name") {
        update.name = StringField(*it, k);
      } else if (k == "description") {
        update.description = StringField(*it, k);
      } else if (k == "tags") {
        if (!it->is_array())
          throw RequestError(StatusCode::kInvalidArgument,
                             k,
                             "tags: expected an array of strings");
        std::vector<std::string> tags;
        for (const json& t : *it) {
          if (!t.is_string())
            throw RequestError(StatusCode::kInvalidArgument,
                               k,
                               "tags: expected an array of strings");
          tags.push_back(t.get<std::string>());
        }
        update.tags = std::move(tags);
      } else {
        throw UnknownField(k, "name, description, tags");
      }
    }
    const bool created = lib.PutMaterial(id, update);
    return HttpResponse::Json(created ? 201 : 200,
                              MaterialToJson(lib.GetMaterial(id)));
  });
  http.Route("DELETE", "/v1/materials/{id}", [&lib](const HttpRequest& req) {
    const std::string& id = req.params[0];
    if (!lib.DeleteMaterial(id))
      throw RequestError(
          StatusCode::kNotFound, "id", "unknown material '" + id + "'");
    return HttpResponse::Json(200, {{"deleted", id}});
  });

  // --- fingertips
  // --------------------------------------------------------------
  http.Route("GET", "/v1/fingertips", [&lib](const HttpRequest&) {
    json list = json::array();
    for (const Fingertip& f : lib.store().ListFingertips()) {
      list.push_back({{"id", f.id},
                      {"name", f.name},
                      {"description", f.description},
                      {"created_at", f.created_at}});
    }
    return HttpResponse::Json(200, {{"fingertips", list}});
  });
  http.Route("PUT", "/v1/fingertips/{id}", [&lib](const HttpRequest& req) {
    const std::string& id = req.params[0];
    // A PUT replaces the fingertip: fields not given are reset (the name
    // to the id).
    Fingertip f{id, id, "", ""};
    const json body = JsonObjectBody(req.body, "{name, description}");
    for (auto it = body.begin(); it != body.end(); ++it) {
      if (it.key() == "name")
        f.name = StringField(*it, "name");
      else if (it.key() == "description")
        f.description = StringField(*it, "description");
      else
        throw UnknownField(it.key(), "name, description");
    }
    const bool created = lib.PutFingertip(f);
    return HttpResponse::Json(
        created ? 201 : 200,
        {{"id", f.id}, {"name", f.name}, {"description", f.description}});
  });

  // --- models
  // ------------------------------------------------------------------
  http.Route("GET", "/v1/materials/{id}/model", [&lib](const HttpRequest& req) {
    return HttpResponse::RawJson(200, ModelFor(lib, req)->json_text);
  });
  http.Route(
      "GET", "/v1/materials/{id}/models", [&lib](const HttpRequest& req) {
        const std::string& id = req.params[0];
        CheckId(id, "id");
        const std::string fingertip = FingertipParam(req);
        json list = json::array();
        for (const ModelRecord& r : lib.store().ListModels(id, fingertip)) {
          list.push_back({{"version", r.version},
                          {"created_at", r.created_at},
                          {"reason", r.reason},
                          {"stroke_id", r.stroke_id}});
        }
        if (list.empty() && !lib.store().GetMaterial(id))
          throw RequestError(
              StatusCode::kNotFound, "id", "unknown material '" + id + "'");
        return HttpResponse::Json(
            200,
            {{"material", id}, {"fingertip", fingertip}, {"versions", list}});
      });

  // --- strokes
  // -----------------------------------------------------------------
  http.Route(
      "POST", "/v1/materials/{id}/strokes", [&lib](const HttpRequest& req) {
        const std::string& id = req.params[0];
        CheckId(id, "id");
        const std::string ct = req.Header("Content-Type");
        if (!IsCsvContentType(ct)) {
          throw HttpError(
              415,
              "Content-Type",
              "Content-Type '" + ct.substr(0, 64) + "' (must be text/csv)");
        }
        IngestOptions options;
        options.fingertip = FingertipParam(req);
        options.robot = req.QueryOr("robot", req.Header("X-Robot-Id"));
        options.labelling = ParseLabelling(
            [&req](const std::string& n) { return req.Query(n); },
            SlipLabelOptions{});
        // The audit entry goes into the upload's transaction: one flush per
        // upload instead of two, and no upload without its entry.
        if (!req.audit_action.empty()) options.audit = HttpAuditEntry(req, 201);
        const IngestResult r = lib.IngestStrokes(id, req.body, options);
        const StochasticFrictionModel& m = *r.model->set.stochastic;
        json coef = json::object();
        for (std::size_t k = 0; k < m.mu.terms.size(); ++k)
          coef[m.mu.terms[k].Name()] = m.mu.beta(k);
        json body = {{"material", id},
                     {"fingertip", options.fingertip},
                     {"version", r.version},
                     {"stroke_id", r.stroke_id},
                     {"samples", r.samples},
                     {"material_created", r.material_created},
                     {"fit_status", r.fit_status},
                     {"coefficients", coef},
                     {"sigma_eps", m.mu.sigma_eps},
                     {"r2", m.mu.r2},
                     {"slip_samples", m.samples_slip}};
        if (!r.fit_note.empty()) body["note"] = r.fit_note;
        HttpResponse out = HttpResponse::Json(201, body);
        out.audit_committed = options.audit.has_value();
        out.headers.emplace("Location",
                            "/v1/materials/" + id +
                                "/model?version=" + std::to_string(r.version) +
                                "&fingertip=" + options.fingertip);
        return out;
      });
  http.Route(
      "GET", "/v1/materials/{id}/strokes", [&lib](const HttpRequest& req) {
        const std::string& id = req.params[0];
        CheckId(id, "id");
        const std::string fingertip = FingertipParam(req);
        json list = json::array();
        for (const StrokeRecord& s : lib.store().ListStrokes(id, fingertip)) {
          list.push_back({{"id", s.id},
                          {"robot", s.robot},
                          {"received_at", s.received_at},
                          {"samples", s.samples}});
        }
        return HttpResponse::Json(
            200,
            {{"material", id}, {"fingertip", fingertip}, {"strokes", list}});
      });

  // --- evaluation
  // --------------------------------------------------------------
  http.Route(
      "GET", "/v1/materials/{id}/predict", [&lib](const HttpRequest& req) {
        const double fn = req.RequireNumber("fn_n");
        const double v = req.RequireNumber("v_mm_s");
        if (!(fn > 0))
          throw RequestError(StatusCode::kInvalidArgument,
                             "fn_n",
                             "fn_n = " + std::to_string(fn) + " (must be > 0)");
        if (!(v >= 0))
          throw RequestError(
              StatusCode::kInvalidArgument,
              "v_mm_s",
              "v_mm_s = " + std::to_string(v) + " (must be >= 0)");
        auto model = ModelFor(lib, req);
        const StochasticFrictionModel& m = Stochastic(*model);
        InputValues inputs{{"fn_n", fn}, {"v_mm_s", v}};
        for (auto& input : ModelInputParams(req, m))
          inputs.push_back(std::move(input));
        MuPrediction p = PredictMu(m, inputs);
        RequireServable(CheckServableMu(m, inputs, p), inputs);
        const bool floored = FloorAtZero(&p);
        return HttpResponse::Json(
            200,
            {{"material", model->set.material},
             {"version", model->set.version},
             {"mu", p.mu},
             {"sigma", p.sigma},
             {"interval95", {p.lo95, p.hi95}},
             {"floored_at_zero", floored},
             {"extrapolated", p.extrapolated},
             {"extrapolated_inputs", p.extrapolated_inputs},
             {"mu_coulomb", m.mu_coulomb}});
      });
  http.Route(
      "GET",
      "/v1/materials/{id}/slip-likelihood",
      [&lib](const HttpRequest& req) {
        const double fn = req.RequireNumber("fn_n");
        const double ft = req.RequireNumber("ft_n");
        if (!(fn > 0))
          throw RequestError(StatusCode::kInvalidArgument,
                             "fn_n",
                             "fn_n = " + std::to_string(fn) + " (must be > 0)");
        if (!(ft >= 0))
          throw RequestError(
              StatusCode::kInvalidArgument,
              "ft_n",
              "ft_n = " + std::to_string(ft) + " (must be >= 0)");
        // Given the grasp's state (v_mm_s and/or hold_s, as
        // grip-force takes them), the answer is grip-force's forward
        // model, eq. (1) with eps over the hold; without, the paper's
        // speed-free likelihood (section III-A / III-C).
        const bool at_state = req.Query("v_mm_s") || req.Query("hold_s");
        const GripForceOptions state = GraspStateParams(req);
        auto model = ModelFor(lib, req);
        const StochasticFrictionModel& m = Stochastic(*model);
        const double r = ft / fn;
        if (!std::isfinite(r))
          throw RequestError(StatusCode::kFailedPrecondition,
                             "ft_n",
                             "ft_n / fn_n = " + NumberText(ft) + " / " +
                                 NumberText(fn) + " is not finite");
        // Outside the fitted range: flagged as predict flags it.
        MuPrediction at;
        double L = 0.0;
        if (at_state) {
          // The served forward model (mu_admissibility.h, CalcServedHoldSlip):
          // a servable mean mu at the state, then P(slip in the hold).
          ServedHoldSlip s;
          try {
            s = CalcServedHoldSlip(m, fn, ft, state);
          } catch (const std::invalid_argument& e) {
            // The one input left that the model can refuse.
            throw RequestError(
                StatusCode::kFailedPrecondition, "hold_s", e.what());
          }
          RequireServable(s.check, s.inputs);
          at = std::move(s.at);
          L = s.probability;
        } else {
          at = PredictMu(m, InputValues{{"fn_n", fn}});
          L = CalcSlipLikelihood(m, fn, ft);
        }
        json out{{"material", model->set.material},
                 {"version", model->set.version},
                 {"likelihood", L},
                 {"ratio", r},
                 {"method",
                  at_state ? "eq1_hold"
                           : (m.likelihood.valid ? "sigmoid" : "eps_cdf")},
                 {"coulomb_slips", r >= m.mu_coulomb},
                 {"extrapolated", at.extrapolated},
                 {"extrapolated_inputs", at.extrapolated_inputs}};
        if (at_state) {
          out["v_mm_s"] = state.v_mm_s;
          out["hold_s"] = state.hold_s;
        }
        return HttpResponse::Json(200, out);
      });
  http.Route(
      "GET", "/v1/materials/{id}/grip-force", [&lib](const HttpRequest& req) {
        const double load = req.RequireNumber("load_n");
        const double risk = req.RequireNumber("risk");
        if (!(load > 0))
          throw RequestError(
              StatusCode::kInvalidArgument,
              "load_n",
              "load_n = " + std::to_string(load) + " (must be > 0)");
        if (!(risk > 0 && risk < 1))
          throw RequestError(
              StatusCode::kInvalidArgument,
              "risk",
              "risk = " + std::to_string(risk) + " (must be in (0, 1))");
        // hold_s (default 0 = one instant) and v_mm_s (default 0 = at
        // rest): CONTRACT.md; grip_force.h for the risk's meaning.
        const GripForceOptions options = GraspStateParams(req);
        auto model = ModelFor(lib, req);
        const GripForce g =
            CalcGripForce(Stochastic(*model), load, risk, options);
        if (g.status == GripForceStatus::kUnsupportedRisk) {
          throw RequestError(StatusCode::kFailedPrecondition,
                             "risk",
                             g.why,
                             {{"min_supported_risk", g.min_supported_risk},
                              {"hold_s", options.hold_s}});
        }
        if (g.status == GripForceStatus::kNoTimeModel)
          throw RequestError(StatusCode::kFailedPrecondition, "hold_s", g.why);
        if (!g.attainable) {
          throw RequestError(
              StatusCode::kFailedPrecondition,
              "load_n",
              "no grip force holds load_n = " + std::to_string(load) +
                  " N at risk " + std::to_string(risk) + ": " + g.why);
        }
        if (!std::isfinite(g.fn_n) || !std::isfinite(g.fn_n_sd)) {
          const bool at_speed = req.Query("v_mm_s").has_value();
          throw RequestError(
              StatusCode::kFailedPrecondition,
              at_speed ? "v_mm_s" : "load_n",
              "no finite grip force holds load_n = " + NumberText(load) +
                  " N at v_mm_s = " + NumberText(options.v_mm_s) +
                  ": the model's terms overflow there");
        }
        const double half = 1.959963984540054 * g.fn_n_sd;
        return HttpResponse::Json(
            200,
            {{"material", model->set.material},
             {"version", model->set.version},
             {"fn_n", g.fn_n},
             {"fn_n_sd", g.fn_n_sd},
             {"fn_n_interval95", {g.fn_n - half, g.fn_n + half}},
             {"mu_used", g.mu_used},
             {"load_n", load},
             {"risk", risk},
             {"hold_s", options.hold_s},
             {"v_mm_s", options.v_mm_s},
             {"instant_risk", g.instant_risk},
             {"hold_samples", g.hold_samples},
             {"min_supported_risk", g.min_supported_risk},
             {"extrapolated", g.extrapolated}});
      });

  // --- identification jobs
  // ----------------------------------------------------------
  // Pages newest first: ?limit= (1..1000, default 100) and ?after= (the
  // "next_after" of the previous page); "next_after" is null on the last.
  http.Route("GET", "/v1/identifications", [&lib](const HttpRequest& req) {
    const std::string open = req.QueryOr("open", "0");
    if (open != "0" && open != "1" && open != "true" && open != "false")
      throw RequestError(StatusCode::kInvalidArgument,
                         "open",
                         "open: must be 1, 0, true or false");
    const bool open_only = open == "1" || open == "true";
    int limit = 100;
    if (auto v = req.Query("limit")) {
      const double x = ParseNumberParam("limit", *v);
      if (!(x >= 1 && x <= 1000 && x == std::floor(x)))
        throw RequestError(
            StatusCode::kInvalidArgument,
            "limit",
            "limit = " + *v + " (must be an integer in 1..1000)");
      limit = static_cast<int>(x);
    }
    std::int64_t after = 0;
    if (auto v = req.Query("after")) {
      const double x = ParseNumberParam("after", *v);
      if (!(x >= 1 && x < 9e15 && x == std::floor(x)))
        throw RequestError(StatusCode::kInvalidArgument,
                           "after",
                           "after = " + *v + " (must be a positive job id)");
      after = static_cast<std::int64_t>(x);
    }
    json list = json::array();
    std::vector<IdentificationJob> page =
        lib.store().ListJobsPage(open_only, after, limit + 1);
    const bool more = static_cast<int>(page.size()) > limit;
    if (more) page.resize(static_cast<std::size_t>(limit));
    for (const IdentificationJob& j : page) {
      json plan =
          json::parse(j.plan_json.empty() ? "{}" : j.plan_json, nullptr, false);
      list.push_back({{"id", j.id},
                      {"material", j.material},
                      {"fingertip", j.fingertip},
                      {"state", j.state},
                      {"detail", j.detail},
                      {"requested_by", j.requested_by},
                      {"created_at", j.created_at},
                      {"updated_at", j.updated_at},
                      {"stroke", plan}});
    }
    return HttpResponse::Json(
        200,
        {{"identifications", list},
         {"next_after", more ? json(page.back().id) : json(nullptr)}});
  });
}

}  // namespace frictiond
