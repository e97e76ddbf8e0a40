#include "frictiond/server/query_parameters.h"

#include <algorithm>
#include <map>
#include <utility>

#include "frictiond/server/request_error.h"
#include "frictiond/server/text.h"

namespace frictiond {
namespace {

using RouteQueries =
    std::map<std::pair<std::string, std::string>, std::vector<QueryParameter>>;

// The one table (units in the names, as in CONTRACT.md): every name a /v1
// route reads. Routes absent here take none. tests/auth_test.cc checks that
// every route accepts each name listed for it and rejects any other.
const RouteQueries& QueryTable() {
  // Shared entries: the model a read route serves (routes_core.cc ModelFor
  // reads fingertip, version and robot) and a joint's family.
  static constexpr QueryParameter fingertip{
      "fingertip", "string", false, "fingertip id (default: default)"};
  static constexpr QueryParameter version{
      "version", "integer", false, "model version (default: latest)"};
  static constexpr QueryParameter robot{
      "robot",
      "string",
      false,
      "requesting robot (else X-Robot-Id), for the stroke "
      "plan of a material without a model"};
  static constexpr QueryParameter joint{
      "joint", "string", false, "joint id (default: default)"};
  static constexpr QueryParameter inputs{
      kModelInputsParameter,
      "object",
      false,
      "further inputs of the stored model by name (e.g. "
      "temp_c=23), numbers; any other name is rejected"};
  static const RouteQueries table = {
      {{"GET", "/v1/materials"},
       {{"q", "string", false, "only ids or names containing this text"}}},
      {{"GET", "/v1/materials/{id}"}, {robot}},
      {{"GET", "/v1/materials/{id}/model"}, {fingertip, version, robot}},
      {{"GET", "/v1/materials/{id}/models"}, {fingertip}},
      {{"GET", "/v1/materials/{id}/strokes"}, {fingertip}},
      {{"POST", "/v1/materials/{id}/strokes"},
       {fingertip,
        {"robot", "string", false, "robot that measured the strokes"},
        {"slip_peak_mm_s", "number", false, "slip threshold [mm/s]"},
        {"slip_floor_mm_s", "number", false, "rest threshold [mm/s]"},
        {"median_window_s", "number", false, "median filter window [s]"},
        {"max_fn_n", "number", false, "largest plausible Fn [N]"},
        {"max_v_mm_s", "number", false, "largest plausible speed [mm/s]"}}},
      {{"GET", "/v1/materials/{id}/predict"},
       {{"fn_n", "number", true, "normal force [N], > 0"},
        {"v_mm_s", "number", true, "sliding speed [mm/s], >= 0"},
        fingertip,
        version,
        robot,
        inputs}},
      {{"GET", "/v1/materials/{id}/slip-likelihood"},
       {{"fn_n", "number", true, "normal force [N], > 0"},
        {"ft_n", "number", true, "tangential force [N], >= 0"},
        {"v_mm_s",
         "number",
         false,
         "sliding speed of the grasp [mm/s]; given (or hold_s given): "
         "P(any slip during the hold) by eq. (1), grip-force's forward "
         "model (default 0 then)"},
        {"hold_s",
         "number",
         false,
         "hold duration [s], as grip-force's (default 0: one instant)"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/materials/{id}/grip-force"},
       {{"load_n", "number", true, "tangential load to hold [N], > 0"},
        {"risk", "number", true, "P(any slip during the hold), in (0, 1)"},
        {"hold_s",
         "number",
         false,
         "hold duration [s] (default 0: one instant)"},
        {"v_mm_s",
         "number",
         false,
         "sliding speed of the grasp [mm/s] (default 0)"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/materials/{id}/target-force"},
       {{"fn_n", "number", true, "normal force [N], > 0 (eq. 3)"},
        {"v_mm_s", "number", true, "sliding speed [mm/s], >= 0"},
        fingertip,
        version,
        robot,
        inputs}},
      {{"GET", "/v1/materials/{id}/sliding-speed"},
       {{"fn_n", "number", true, "normal force [N], > 0 (eq. 4)"},
        {"ft_n", "number", true, "tangential force [N], >= 0"},
        fingertip,
        version,
        robot,
        inputs}},
      {{"GET", "/v1/materials/{id}/conditional-slip-likelihood"},
       {{"fn_n", "number", true, "normal force [N], > 0 (eq. 2)"},
        {"ft_n", "number", false, "tangential force [N] (or ratio)"},
        {"ratio", "number", false, "Ft/Fn (or ft_n; exactly one)"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/materials/{id}/forms"},
       {{"folds", "integer", false, "cross-validation folds, 2..50"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/materials/{id}/mu-spread"},
       {{"fn_n", "number", true, "normal force [N], > 0"},
        {"v_mm_s", "number", true, "sliding speed [mm/s], >= 0"},
        {"fn_widths_n",
         "string",
         false,
         "comma-separated window widths in Fn [N] (default: the fitted "
         "range and its halves)"},
        {"v_widths_mm_s",
         "string",
         false,
         "comma-separated window widths in v [mm/s]"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/materials/{id}/span-variability"},
       {{"subsets", "integer", false, "random stroke subsets (default 200)"},
        {"max_strokes", "integer", false, "strokes per subset at most"},
        {"seed", "integer", false, "subset seed"},
        {"bin_pct", "integer", false, "span bin width [%] (default 10)"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/materials/{id}/breakaway"},
       {{"rho", "number", true, "drag-ratio rate [1/s], > 0"},
        {"fn_n", "number", true, "normal force [N], > 0"},
        {"mass_kg", "number", false, "object mass [kg] (default 0.2)"},
        {"mu_applied",
         "number",
         false,
         "measured Ft/Fn now: predict from the state it implies"},
        {"v_mm_s",
         "number",
         false,
         "measured slip velocity [mm/s] with mu_applied (default 0)"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/materials/{id}/samples"},
       {{"max", "integer", false, "points at most, 1..20000 (default 2000)"},
        fingertip,
        version}},
      {{"GET", "/v1/identifications"},
       {{"open", "boolean", false, "only open jobs"},
        {"limit", "integer", false, "page size (default 100, at most 1000)"},
        {"after", "integer", false, "job id after which the page starts"}}},
      {{"GET", "/v1/materials/{id}/export"},
       {{"format", "string", true, "mjcf, sdf, urdf, usd or isaac"},
        {"name", "string", false, "name in the exported file (default: id)"},
        {"risk", "number", false, "slip risk the exported mu holds at"},
        {"fn_n", "number", false, "normal force [N] the mu is taken at"},
        {"v_mm_s", "number", false, "sliding speed [mm/s]"},
        fingertip,
        version,
        robot}},
      {{"GET", "/v1/pairs/{fingertip}/{object}/friction"},
       {{"rule", "string", false, "how two materials' mu combine"},
        {"reference",
         "string",
         false,
         "the fingertip of the reference models (default: default)"},
        {"risk", "number", false, "slip risk the mu holds at"},
        {"fn_n", "number", false, "normal force [N] the mu is taken at"},
        {"v_mm_s", "number", false, "sliding speed [mm/s]"},
        robot}},
      {{"POST", "/v1/materials/{id}/diagnose"},
       {{"store", "boolean", false, "store the extended model as a version"},
        {"seed", "integer", false, "fold seed"},
        fingertip}},
      {{"POST", "/v1/recognize"},
       {{"material",
         "string",
         false,
         "id for an identification request when the image is unknown"},
        fingertip}},
      {{"GET", "/v1/materials/{id}/joint-friction"},
       {{"v_mm_s", "number", true, "sliding speed [mm/s]"},
        {"load_n", "number", true, "load [N]"},
        {"temp_c", "number", false, "temperature [degC]"},
        {"eta_pa_s", "number", false, "lubricant viscosity [Pa s]"},
        joint,
        version}},
      {{"GET", "/v1/materials/{id}/joint-wear"},
       {{"v_mm_s", "number", true, "sliding speed [mm/s]"},
        {"load_n", "number", true, "load [N]"},
        {"temp_c", "number", false, "temperature [degC]"},
        {"eta_pa_s", "number", false, "lubricant viscosity [Pa s]"},
        {"distance_mm", "number", true, "sliding distance [mm], > 0"},
        {"points", "integer", false, "curve points, 2..1000 (default 11)"},
        joint,
        version}},
      {{"POST", "/v1/materials/{id}/joint-data"},
       {joint,
        {"area_mm2", "number", false, "apparent contact area [mm^2]"},
        {"alt_um", "number", false, "surface: altitude sd [um]"},
        {"salt_um", "number", false, "surface: summit altitude sd [um]"},
        {"radius_log_sd", "number", false, "surface: log radius sd"},
        {"radius_log_mean", "number", false, "surface: log radius mean"},
        {"srad_um", "number", false, "surface: summit radius [um]"},
        {"summits", "number", false, "surface: summits per mm^2"},
        {"modulus_gpa", "number", false, "surface: modulus [GPa]"},
        {"vogel_a_pa_s", "number", false, "lubricant: Vogel a [Pa s]"},
        {"vogel_b_c", "number", false, "lubricant: Vogel b [degC]"},
        {"vogel_c_c", "number", false, "lubricant: Vogel c [degC]"},
        {"k_solid", "number", false, "wear: solid wear coefficient"},
        {"hardness_mpa", "number", false, "wear: hardness [MPa]"},
        {"folds", "integer", false, "cross-validation folds"}}},
      {{"POST", "/v1/materials/{id}/actuator-logs"},
       {joint, {"law", "string", false, "friction law (default auto)"}}},
      {{"GET", "/v1/materials/{id}/actuator-model"}, {joint, version}},
      {{"GET", "/v1/materials/{id}/actuator-mjcf"}, {joint, version}},
      {{"POST", "/v1/materials/{id}/actuator-simulate"}, {joint, version}},
      {{"GET", "/v1/robots/{id}/repeatability"},
       {{"x_mm", "number", true, "target x [mm]"},
        {"y_mm", "number", true, "target y [mm]"},
        {"z_mm", "number", true, "target z [mm]"},
        {"probability",
         "number",
         false,
         "probability of the region, in (0, 1) (default 0.95)"}}},
      {{"GET", "/v1/robots/{id}/repeatability-grid"},
       {{"z_mm", "number", true, "grid height [mm]"},
        {"x0_mm", "number", true, "grid centre x [mm]"},
        {"y0_mm", "number", true, "grid centre y [mm]"},
        {"size_mm", "number", false, "grid side [mm]"},
        {"n", "integer", false, "grid points per side"},
        {"probability", "number", false, "probability, in (0, 1)"}}},
      {{"GET", "/v1/audit"},
       {{"after", "integer", false, "entry id after which the page starts"},
        {"limit", "integer", false, "page size, 1..1000 (default 100)"},
        {"material", "string", false, "only entries about this material"}}},
  };
  return table;
}

bool IsV1(const std::string& pattern) { return pattern.rfind("/v1/", 0) == 0; }

}  // namespace

const std::vector<QueryParameter>& QueryParametersOf(
    const std::string& method, const std::string& pattern) {
  static const std::vector<QueryParameter> kNone;
  const auto it = QueryTable().find({method, pattern});
  return it == QueryTable().end() ? kNone : it->second;
}

std::vector<std::string> DocumentedQueryParameters(const std::string& method,
                                                   const std::string& pattern) {
  std::vector<std::string> out;
  for (const QueryParameter& q : QueryParametersOf(method, pattern))
    out.emplace_back(q.name);
  return out;
}

std::vector<RouteKey> RoutesWithDocumentedQueries() {
  std::vector<RouteKey> out;
  for (const auto& entry : QueryTable())
    out.push_back({entry.first.first, entry.first.second});
  return out;
}

bool TakesQueryParameter(const std::string& method,
                         const std::string& pattern,
                         const std::string& name) {
  const auto& params = QueryParametersOf(method, pattern);
  return std::any_of(params.begin(),
                     params.end(),
                     [&](const QueryParameter& q) { return name == q.name; });
}

bool TakesModelInputs(const std::string& method, const std::string& pattern) {
  return TakesQueryParameter(method, pattern, kModelInputsParameter);
}

RequestError QueryParameterError(const std::string& name,
                                 const std::string& why) {
  const std::string shown = ShownText(name, 64);
  return RequestError(StatusCode::kInvalidArgument,
                      shown,
                      "query parameter '" + shown + "' " + why);
}

void CheckQueryParameters(const HttpRequest& request,
                          const std::string& pattern) {
  if (request.query.empty() || !IsV1(pattern)) return;
  // Every parameter is one value: a repeated name is rejected rather than
  // answered for one of its values (which one the client meant is unknown).
  for (auto it = request.query.begin(); it != request.query.end();
       it = request.query.upper_bound(it->first)) {
    const std::size_t times = request.query.count(it->first);
    if (times > 1) {
      throw QueryParameterError(
          it->first,
          "is given " + std::to_string(times) + " times (give it once)");
    }
  }
  if (TakesModelInputs(request.method, pattern)) return;
  for (const auto& entry : request.query) {
    if (TakesQueryParameter(request.method, pattern, entry.first)) continue;
    std::string allowed;
    for (const std::string& name :
         DocumentedQueryParameters(request.method, pattern))
      allowed += (allowed.empty() ? "" : ", ") + name;
    throw QueryParameterError(entry.first,
                              "is not known here (allowed: " +
                                  (allowed.empty() ? "none" : allowed) + ")");
  }
}

void InstallQueryCheck(HttpServer& http) {
  http.SetQueryCheck(CheckQueryParameters);
}

}  // namespace frictiond
