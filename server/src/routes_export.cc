// Friction for simulators (docs/export.md):
//   GET /v1/materials/{id}/export?format=mjcf|sdf|urdf|usd|isaac
//       [&fingertip=][&risk=][&fn_n=][&v_mm_s=][&name=][&version=]
//   GET /v1/pairs/{fingertip}/{object}/friction
//       [?fn_n=][&v_mm_s=][&rule=max|harmonic|average][&risk=][&reference=]
#include <algorithm>
#include <cmath>

#include "frictiond/estimators/contact_friction.h"
#include "frictiond/proto/sim_export.h"
#include "frictiond/server/identification_json.h"
#include "frictiond/server/routes.h"

namespace frictiond {

using nlohmann::json;

namespace {

/// Default slip risk of exported values (5 %).
constexpr double kDefaultRisk = 0.05;
/// Default combine rule: the harmonic mean is never above the average or the
/// max, so an unmeasured pair is not credited with more grip than either
/// other rule would give.
constexpr CombineRule kDefaultRule = CombineRule::kHarmonicMean;

std::string Num(double x) { return FormatRoundTrip(x); }

double RiskParam(const HttpRequest& req) {
  const auto text = req.Query("risk");
  if (!text) return kDefaultRisk;
  const double risk = ParseNumberParam("risk", *text);
  if (!(risk >= kMinSlipRisk && risk <= kMaxSlipRisk)) {
    throw RequestError(StatusCode::kInvalidArgument,
                       "risk",
                       "risk = " + Num(risk) + " (must be in [" +
                           Num(kMinSlipRisk) + ", " + Num(kMaxSlipRisk) +
                           "]: the smallest stored quantile level is 0.001, "
                           "and above 0.5 the range [Q(risk), Q(1 - risk)] "
                           "would be inverted)");
  }
  return risk;
}

/// 422 when `risk` is below the smallest per-instant risk the model's data
/// support (CalcMinSupportedRisk, grip_force.h): the same rule and answer
/// as the grip-force route, never a silent clamp.
void CheckSupportedRisk(const StochasticFrictionModel& m,
                        double risk,
                        const std::string& material) {
  const double min_risk = CalcMinSupportedRisk(m, 0.0);
  if (risk < min_risk) {
    throw RequestError(StatusCode::kFailedPrecondition,
                       "risk",
                       "risk = " + Num(risk) +
                           " is below the smallest risk the data of '" +
                           material + "' support: " + Num(min_risk),
                       {{"min_supported_risk", min_risk}, {"hold_s", 0.0}});
  }
}

/// Optional fn_n (> 0) and v_mm_s (>= 0).
struct OperatingPointParams {
  std::optional<double> fn_n;
  std::optional<double> v_mm_s;
};

OperatingPointParams OperatingPointQuery(const HttpRequest& req) {
  OperatingPointParams p;
  if (auto t = req.Query("fn_n")) {
    p.fn_n = ParseNumberParam("fn_n", *t);
    if (!(*p.fn_n > 0))
      throw RequestError(StatusCode::kInvalidArgument,
                         "fn_n",
                         "fn_n = " + Num(*p.fn_n) + " (must be > 0)");
  }
  if (auto t = req.Query("v_mm_s")) {
    p.v_mm_s = ParseNumberParam("v_mm_s", *t);
    if (!(*p.v_mm_s >= 0))
      throw RequestError(StatusCode::kInvalidArgument,
                         "v_mm_s",
                         "v_mm_s = " + Num(*p.v_mm_s) + " (must be >= 0)");
  }
  return p;
}

/// The fitted mean of an input, or 400 asking for it.
double FittedMean(const StochasticFrictionModel& m,
                  const std::string& input,
                  const std::string& material) {
  auto it = m.inputs.find(input);
  if (it == m.inputs.end()) {
    throw RequestError(StatusCode::kInvalidArgument,
                       input,
                       "query parameter " + input +
                           " is required: the model of '" + material +
                           "' stores no fitted mean of " + input);
  }
  return it->second.mean;
}

// As Stochastic (routes.h), with the material in the message: exports
// name the material they were asked for.
const StochasticFrictionModel& StochasticNamingMaterial(const CachedModel& m) {
  if (!m.set.stochastic) {
    throw RequestError(StatusCode::kFailedPrecondition,
                       "model",
                       "model version " + std::to_string(m.set.version) +
                           " of '" + m.set.material +
                           "' has no stochastic model");
  }
  return *m.set.stochastic;
}

// The distribution of a model at `x`, as served: 422 when its mean may not
// be (RequireServable), quantiles floored at 0 (*floored set when one
// was below; mu_admissibility.h).
MuDistribution ServableMuDistribution(const StochasticFrictionModel& m,
                                      const InputValues& x,
                                      const std::string& material,
                                      bool* floored) {
  MuDistribution d = CalcMuDistribution(m, x);
  RequireServable(CheckServableMu(m, x, d), x, "material '" + material + "'");
  *floored = FloorAtZero(&d) || *floored;
  return d;
}

json DistributionJson(const MuDistribution& d, double risk, bool floored) {
  const SimFrictionValues v = CalcSimFrictionValues(d, risk);
  return {{"mu", d.mean},
          {"floored_at_zero", floored},
          {"sigma", d.sigma},
          {"interval95", {d.Quantile(0.025), d.Quantile(0.975)}},
          {"risk", risk},
          {"mu_at_risk", v.sliding},
          {"quantiles", {{"levels", d.levels}, {"values", d.quantiles}}},
          {"extrapolated", d.extrapolated},
          {"extrapolated_inputs", d.extrapolated_inputs}};
}

json ModelRef(const CachedModel& m) {
  return {{"material", m.set.material},
          {"fingertip", m.set.fingertip},
          {"version", m.set.version}};
}

HttpResponse Export(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  CheckId(id, "id");
  // Every parameter is checked before the library is asked (a malformed
  // request records no identification job).
  const auto format_text = req.Query("format");
  if (!format_text) {
    throw RequestError(StatusCode::kInvalidArgument,
                       "format",
                       "query parameter format is required (one of mjcf, "
                       "sdf, urdf, usd, isaac)");
  }
  SimFormat format;
  try {
    format = ParseSimFormat(*format_text);
  } catch (const std::invalid_argument& e) {
    throw RequestError(StatusCode::kInvalidArgument, "format", e.what());
  }
  const double risk = RiskParam(req);
  const std::string fingertip = FingertipParam(req);
  const std::string name = req.QueryOr("name", id);
  CheckId(name, "name");
  const OperatingPointParams op = OperatingPointQuery(req);
  std::optional<int> version;
  if (auto v = req.Query("version")) {
    version = ParseVersionParam(*v);
  }
  std::shared_ptr<const CachedModel> model;
  if (version) {
    model = lib.FindModelVersion(id, fingertip, *version);
    if (!model)
      throw RequestError(StatusCode::kNotFound,
                         "version",
                         "material '" + id + "' has no model version " +
                             std::to_string(*version) + " for fingertip '" +
                             fingertip + "'");
  } else {
    model = lib.RequireModel(id, fingertip, Requester(req));
  }
  const StochasticFrictionModel& m = StochasticNamingMaterial(*model);
  CheckSupportedRisk(m, risk, id);
  SimExportInput in;
  in.name = name;
  in.material = id;
  in.fingertip = fingertip;
  in.version = model->set.version;
  in.fn_n = op.fn_n ? *op.fn_n : FittedMean(m, "fn_n", id);
  in.v_mm_s = op.v_mm_s ? *op.v_mm_s : FittedMean(m, "v_mm_s", id);
  in.operating_point_source =
      op.fn_n && op.v_mm_s
          ? "query"
          : (!op.fn_n && !op.v_mm_s ? "fitted means of the model's samples"
                                    : std::string(op.fn_n ? "v_mm_s" : "fn_n") +
                                          " is the fitted mean");
  in.risk = risk;
  bool floored = false;
  in.mu = ServableMuDistribution(
      m, {{"fn_n", in.fn_n}, {"v_mm_s", in.v_mm_s}}, id, &floored);
  HttpResponse out{
      200, SimFormatContentType(format), FormatSimExport(format, in), {}};
  out.headers.emplace(
      "Content-Disposition",
      "inline; filename=\"" + name + "." + SimFormatExtension(format) + "\"");
  return out;
}

HttpResponse PairFriction(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& tip = req.params.at(0);
  const std::string& object = req.params.at(1);
  CheckId(tip, "fingertip");
  CheckId(object, "object");
  const OperatingPointParams op = OperatingPointQuery(req);
  const double risk = RiskParam(req);
  CombineRule rule = kDefaultRule;
  if (auto r = req.Query("rule")) {
    try {
      rule = ParseCombineRule(*r);
    } catch (const std::invalid_argument& e) {
      throw RequestError(StatusCode::kInvalidArgument, "rule", e.what());
    }
  }
  const std::string reference = req.QueryOr("reference", "default");
  CheckId(reference, "reference");

  json body = {{"fingertip", tip}, {"object", object}};
  // Measured: a model of the object identified with this fingertip (or,
  // the same contact seen from the other side, of the fingertip material
  // identified against the object).
  auto measured = lib.FindModel(object, tip);
  if (!measured && tip != object) measured = lib.FindModel(tip, object);
  if (measured) {
    const StochasticFrictionModel& m = StochasticNamingMaterial(*measured);
    const std::string& mat = measured->set.material;
    CheckSupportedRisk(m, risk, mat);
    const double fn = op.fn_n ? *op.fn_n : FittedMean(m, "fn_n", mat);
    const double v = op.v_mm_s ? *op.v_mm_s : FittedMean(m, "v_mm_s", mat);
    bool floored = false;
    const MuDistribution d =
        ServableMuDistribution(m, {{"fn_n", fn}, {"v_mm_s", v}}, mat, &floored);
    body["measured"] = true;
    body["source"] = ModelRef(*measured);
    body["rule"] = nullptr;
    body["operating_point"] = {
        {"fn_n", fn},
        {"v_mm_s", v},
        {"defaulted", {{"fn_n", !op.fn_n}, {"v_mm_s", !op.v_mm_s}}}};
    body.update(DistributionJson(d, risk, floored));
    body["note"] =
        "measured for this fingertip-object pair; no combine rule is used, "
        "sigma and quantiles are the model's predictive distribution";
    return HttpResponse::Json(200, body);
  }
  // Not measured: combine each material's model against the reference
  // fingertip.
  auto ma = lib.FindModel(tip, reference);
  auto mb = lib.FindModel(object, reference);
  if (!ma || !mb) {
    json extra = {{"fingertip", tip},
                  {"object", object},
                  {"measured", false},
                  {"missing", json::array()}};
    if (!ma)
      extra["missing"].push_back({{"material", tip}, {"fingertip", reference}});
    if (!mb)
      extra["missing"].push_back(
          {{"material", object}, {"fingertip", reference}});
    extra["identification"] = IdentificationRequestToJson(
        lib.RequestIdentification(object, tip, Requester(req)));
    throw RequestError(
        StatusCode::kNotFound,
        !ma ? "fingertip" : "object",
        "pair (fingertip '" + tip + "', object '" + object +
            "') was not measured, and material '" + (!ma ? tip : object) +
            "' has no model for the reference fingertip '" + reference +
            "' to combine: an identification of the pair was requested",
        extra);
  }
  const StochasticFrictionModel& sa = StochasticNamingMaterial(*ma);
  const StochasticFrictionModel& sb = StochasticNamingMaterial(*mb);
  CheckSupportedRisk(sa, risk, tip);
  CheckSupportedRisk(sb, risk, object);
  // Default operating point: the mean of the two models' fitted means.
  const double fn = op.fn_n ? *op.fn_n
                            : 0.5 * (FittedMean(sa, "fn_n", tip) +
                                     FittedMean(sb, "fn_n", object));
  const double v = op.v_mm_s ? *op.v_mm_s
                             : 0.5 * (FittedMean(sa, "v_mm_s", tip) +
                                      FittedMean(sb, "v_mm_s", object));
  const InputValues x{{"fn_n", fn}, {"v_mm_s", v}};
  bool floored = false;
  const MuDistribution da = ServableMuDistribution(sa, x, tip, &floored);
  const MuDistribution db = ServableMuDistribution(sb, x, object, &floored);
  const MuDistribution d = CombineMuDistributions(da, db, rule);
  body["measured"] = false;
  body["rule"] = CombineRuleName(rule);
  body["rule_engine"] = CombineRuleEngine(rule);
  body["operating_point"] = {
      {"fn_n", fn},
      {"v_mm_s", v},
      {"defaulted", {{"fn_n", !op.fn_n}, {"v_mm_s", !op.v_mm_s}}}};
  body.update(DistributionJson(d, risk, floored));
  json sides = json::array();
  for (const auto* side : {&ma, &mb}) {
    const MuDistribution& ds = side == &ma ? da : db;
    json s = ModelRef(**side);
    s["mu"] = ds.mean;
    s["sigma"] = ds.sigma;
    s["mu_at_risk"] = ds.Quantile(risk);
    sides.push_back(s);
  }
  body["inputs"] = sides;
  json rules = json::object();
  double lo = d.mean, hi = d.mean;
  for (CombineRule r :
       {CombineRule::kMax, CombineRule::kHarmonicMean, CombineRule::kAverage}) {
    const MuDistribution c = r == rule ? d : CombineMuDistributions(da, db, r);
    rules[CombineRuleName(r)] = {{"engine", CombineRuleEngine(r)},
                                 {"mu", c.mean},
                                 {"sigma", c.sigma},
                                 {"mu_at_risk", c.Quantile(risk)}};
    lo = std::min(lo, c.mean);
    hi = std::max(hi, c.mean);
  }
  body["rules"] = rules;
  body["rule_spread"] = hi - lo;
  body["note"] =
      "not measured: combined from each material's model against fingertip '" +
      reference + "' by the " + std::string(CombineRuleName(rule)) + " rule (" +
      CombineRuleEngine(rule) +
      "); sigma propagates both models' predictive distributions assuming "
      "independence; the rule itself is a simulator convention, not a "
      "measurement, and rule_spread is how far the rules' means disagree";
  return HttpResponse::Json(200, body);
}

}  // namespace

void RegisterExportRoutes(HttpServer& http, FrictionLibrary& library) {
  http.Route(
      "GET", "/v1/materials/{id}/export", [&library](const HttpRequest& req) {
        return Export(library, req);
      });
  http.Route("GET",
             "/v1/pairs/{fingertip}/{object}/friction",
             [&library](const HttpRequest& req) {
               return PairFriction(library, req);
             });
}

}  // namespace frictiond
