// LuGre feature (paper 001, issue 5 item 6): the "lugre" model family,
// identified on every stroke upload from the pair's low- and high-
// acceleration strokes (IdentifyLuGreFromStrokes in
// estimators/lugre_identification.h holds the stroke recognition rule and
// the two-step fit) and stored beside the stochastic model, and the
// break-away friction ratio route GET /v1/materials/{id}/breakaway.
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "frictiond/estimators/breakaway.h"
#include "frictiond/estimators/lugre_identification.h"
#include "frictiond/estimators/number_text.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/server/routes.h"

namespace frictiond {

using nlohmann::json;

namespace {

double PositiveParam(const HttpRequest& req,
                     const std::string& name,
                     const std::string& unit) {
  const double x = req.RequireNumber(name);
  if (!(x > 0))
    throw RequestError(
        StatusCode::kInvalidArgument,
        name,
        name + " = " + NumberText(x) + " (must be > 0" + unit + ")");
  return x;
}

HttpResponse HandleBreakaway(FrictionLibrary& lib, const HttpRequest& req) {
  const double rho = PositiveParam(req, "rho", " [1/s]");
  const double fn_n = PositiveParam(req, "fn_n", " [N]");
  ForceDrivenOptions options;
  if (req.Query("mass_kg")) {
    options.mass_kg = PositiveParam(req, "mass_kg", " [kg]");
    if (!(options.mass_kg <= 1e4))
      throw RequestError(StatusCode::kInvalidArgument,
                         "mass_kg",
                         "mass_kg = " + NumberText(options.mass_kg) +
                             " (must be <= 10000 [kg])");
  }
  const auto model = ModelFor(lib, req);
  const std::string& id = model->set.material;
  auto it = model->set.other.find(kLuGreFamilyKey);
  if (it == model->set.other.end() || it->is_null()) {
    throw RequestError(
        StatusCode::kFailedPrecondition,
        kLuGreFamilyKey,
        "model version " + std::to_string(model->set.version) + " of '" + id +
            "' has no LuGre family (lugre): upload a low-acceleration "
            "(<= 3 mm/s^2) and a high-acceleration (>= 5 mm/s^2) stroke",
        json{{"material", id}, {"version", model->set.version}});
  }
  LuGreFamily family;
  try {
    family = LuGreFromJson(*it);
  } catch (const std::invalid_argument& e) {
    // The store holds it: a server-side fault, not the caller's.
    throw std::runtime_error(std::string("stored LuGre family is malformed: ") +
                             e.what());
  }
  // With the measured drag ratio (and slip velocity), the prediction starts
  // from the state they imply (paper 001 eq. (16), breakaway.h
  // PredictBreakawayRatioFromState); otherwise from rest as in Table II.
  std::optional<double> mu_applied;
  double v_mm_s = 0.0;
  if (req.Query("mu_applied")) {
    mu_applied = req.RequireNumber("mu_applied");
    if (!(*mu_applied >= 0))
      throw RequestError(
          StatusCode::kInvalidArgument,
          "mu_applied",
          "mu_applied = " + NumberText(*mu_applied) + " (must be >= 0)");
  }
  if (req.Query("v_mm_s")) {
    if (!mu_applied)
      throw RequestError(StatusCode::kInvalidArgument,
                         "v_mm_s",
                         "v_mm_s is the measured slip velocity of the state "
                         "mu_applied names: give mu_applied too");
    v_mm_s = req.RequireNumber("v_mm_s");
  }
  ForceDrivenResult r;
  if (mu_applied) {
    try {
      r = PredictBreakawayRatioFromState(
          family.theta, *mu_applied, v_mm_s, rho, fn_n, options);
    } catch (const std::invalid_argument& e) {
      // E.g. sigma1 |v| >= g(v): no bristle state holds that ratio.
      throw RequestError(
          StatusCode::kFailedPrecondition,
          "mu_applied",
          std::string("mu_applied = ") + NumberText(*mu_applied) +
              ", v_mm_s = " + NumberText(v_mm_s) +
              ": no state of the stored LuGre model: " + e.what());
    }
  } else {
    r = PredictBreakawayRatio(family.theta, rho, fn_n, options);
  }
  auto finite = [](double x) { return std::isfinite(x) ? json(x) : json(); };
  json body = {{"material", id},
               {"fingertip", model->set.fingertip},
               {"version", model->set.version},
               {"bf_ratio", finite(r.bf_ratio)},
               {"t_breakaway_s", finite(r.t_breakaway_s)},
               {"mu_applied", finite(r.mu_applied)},
               {"rho", rho},
               {"fn_n", fn_n},
               {"mass_kg", options.mass_kg},
               {"status", ToString(r.status)},
               {"steps", r.steps},
               {"from_measured_state", mu_applied.has_value()}};
  if (mu_applied) body["v_mm_s"] = v_mm_s;
  if (!r.why.empty()) body["why"] = r.why;
  return HttpResponse::Json(200, body);
}

}  // namespace

void RegisterLuGreFeature(HttpServer& http, FrictionLibrary& library) {
  // The LuGre family is identified on upload by IdentifyMaterial
  // (FrictionLibrary::FitModelSet); these routes only read it.
  http.Route("GET",
             "/v1/materials/{id}/breakaway",
             [&library](const HttpRequest& req) {
               return HandleBreakaway(library, req);
             });
}

}  // namespace frictiond
