// Queries of a stored stochastic model beyond the core ones (paper 000,
// docs/paper000.md): controlled sliding (eq. 3), velocity prediction
// (eq. 4), the conditional slip likelihood L(Fn, Ft/Fn) of eq. (2) (stored
// as model family "slip_likelihood_fn"), the forms of mu = f(Fn), the
// spread of mu in windows and the span variability.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "frictiond/estimators/control.h"
#include "frictiond/estimators/friction_forms.h"
#include "frictiond/estimators/mu_windows.h"
#include "frictiond/estimators/number_text.h"
#include "frictiond/estimators/slip_likelihood.h"
#include "frictiond/estimators/span_variability.h"
#include "frictiond/proto/slip_likelihood_json.h"
#include "frictiond/server/routes.h"

namespace frictiond {

using nlohmann::json;

namespace {

// A required query number that must be > 0 (strict) or >= 0.
double ForceParam(const HttpRequest& req,
                  const std::string& name,
                  bool strict) {
  const double x = req.RequireNumber(name);
  if (strict ? !(x > 0) : !(x >= 0)) {
    throw RequestError(StatusCode::kInvalidArgument,
                       name,
                       name + " = " + std::to_string(x) +
                           (strict ? " (must be > 0)" : " (must be >= 0)"));
  }
  return x;
}

HttpResponse HandleTargetForce(FrictionLibrary& lib, const HttpRequest& req) {
  const double fn = ForceParam(req, "fn_n", true);
  const double v = ForceParam(req, "v_mm_s", false);
  auto model = ModelFor(lib, req);
  const StochasticFrictionModel& m = Stochastic(*model);
  const InputValues cov = ModelInputParams(req, m);
  TargetForce f = CalcTargetTangentialForce(m, fn, v, cov);
  InputValues inputs{{"fn_n", fn}, {"v_mm_s", v}};
  inputs.insert(inputs.end(), cov.begin(), cov.end());
  RequireServable(CheckServableMu(m, inputs, f), inputs);
  const bool floored = FloorAtZero(&f);
  return HttpResponse::Json(200,
                            {{"material", model->set.material},
                             {"version", model->set.version},
                             {"fn_n", fn},
                             {"v_mm_s", v},
                             {"ft_n", f.ft_n},
                             {"mu", f.mu},
                             {"interval95_n", {f.ft_lo95_n, f.ft_hi95_n}},
                             {"floored_at_zero", floored},
                             {"extrapolated", f.extrapolated},
                             {"extrapolated_inputs", f.extrapolated_inputs},
                             {"equation", "paper 000 eq. (3)"}});
}

HttpResponse HandleSlidingSpeed(FrictionLibrary& lib, const HttpRequest& req) {
  const double fn = ForceParam(req, "fn_n", true);
  const double ft = ForceParam(req, "ft_n", false);
  auto model = ModelFor(lib, req);
  const StochasticFrictionModel& m = Stochastic(*model);
  const InputValues cov = ModelInputParams(req, m);
  const SlidingSpeed s = PredictSlidingSpeed(m, fn, ft, cov);
  if (s.status != SlidingSpeedStatus::kOk) {
    throw RequestError(StatusCode::kFailedPrecondition,
                       "model",
                       "model version " + std::to_string(model->set.version) +
                           " cannot predict a sliding speed (" +
                           ToString(s.status) + "): " + s.why,
                       json{{"material", model->set.material},
                            {"version", model->set.version},
                            {"status", ToString(s.status)}});
  }
  if (!std::isfinite(s.ratio) || !std::isfinite(s.v_mm_s) ||
      !std::isfinite(s.v_lo95_mm_s) || !std::isfinite(s.v_hi95_mm_s)) {
    throw RequestError(StatusCode::kFailedPrecondition,
                       "ft_n",
                       "ft_n / fn_n = " + NumberText(ft) + " / " +
                           NumberText(fn) + " gives no finite sliding speed");
  }
  return HttpResponse::Json(200,
                            {{"material", model->set.material},
                             {"version", model->set.version},
                             {"fn_n", fn},
                             {"ft_n", ft},
                             {"ratio", s.ratio},
                             {"v_mm_s", s.v_mm_s},
                             {"interval95", {s.v_lo95_mm_s, s.v_hi95_mm_s}},
                             {"b1", s.b1},
                             {"b1_t", s.b1_t},
                             {"below_model_range", s.below_model_range},
                             {"extrapolated", s.extrapolated},
                             {"equation", "paper 000 eq. (4)"}});
}

// --- conditional slip likelihood (eq. 2) ---------------------------------

constexpr const char* kConditionalKey = kConditionalSlipFamilyKey;

// Knots of a stored family; throws std::runtime_error when malformed (a
// server-side fault: the store holds it).
ConditionalSlipLikelihood ConditionalFromJson(const json& j) {
  try {
    return ConditionalSlipFromJson(j);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("stored ") + kConditionalKey +
                             " is malformed: " + e.what());
  }
}

// The family fitter: eq. (2) on every labelled sample (as IdentifyMaterial).
HttpResponse HandleConditional(FrictionLibrary& lib, const HttpRequest& req) {
  const double fn = ForceParam(req, "fn_n", true);
  const bool has_ft = req.Query("ft_n").has_value();
  const bool has_ratio = req.Query("ratio").has_value();
  if (has_ft == has_ratio) {
    throw RequestError(StatusCode::kInvalidArgument,
                       "ft_n",
                       "give exactly one of ft_n [N] and ratio (Ft/Fn)");
  }
  const double ratio = has_ft ? ForceParam(req, "ft_n", false) / fn
                              : ForceParam(req, "ratio", false);
  auto model = ModelFor(lib, req);
  const StochasticFrictionModel& m = Stochastic(*model);
  auto it = model->set.other.find(kConditionalKey);
  if (it == model->set.other.end() || it->is_null()) {
    throw RequestError(
        StatusCode::kFailedPrecondition,
        kConditionalKey,
        "model version " + std::to_string(model->set.version) +
            " has no conditional slip likelihood (slip_likelihood_fn): no Fn "
            "window held both slip and stick samples",
        json{{"material", model->set.material},
             {"version", model->set.version}});
  }
  const ConditionalSlipLikelihood L = ConditionalFromJson(*it);
  if (!L.valid) {
    throw std::runtime_error(std::string("stored ") + kConditionalKey +
                             " has no knots");
  }
  const ConditionalSlipValue v = CalcConditionalSlipLikelihood(L, fn, ratio);
  return HttpResponse::Json(
      200,
      {{"material", model->set.material},
       {"version", model->set.version},
       {"fn_n", fn},
       {"ratio", ratio},
       {"likelihood", v.likelihood},
       {"c1", v.c1},
       {"c2", v.c2},
       {"extrapolated", v.extrapolated},
       {"fn_range_n", {L.knot_fn_n.front(), L.knot_fn_n.back()}},
       {"likelihood_unconditional", CalcSlipLikelihood(m, fn, ratio * fn)},
       {"equation", "paper 000 eq. (2)"}});
}

// Slipping samples of all stored strokes of the pair, within the model's
// exclusion bounds (paper II-C), labelled as the model was.
struct SlipSamples {
  std::vector<double> fn, v, mu;
  std::vector<int> stroke;
};

SlipSamples LoadSlipSamples(FrictionLibrary& lib,
                            const CachedModel& model,
                            const StochasticFrictionModel& m) {
  const StrokeData data =
      lib.LoadStrokes(model.set.material, model.set.fingertip, m.labelling);
  SlipSamples out;
  if (data.slip.size() != data.size()) return out;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (!data.slip[i]) continue;
    if (!(data.fn_n[i] < m.labelling.max_fn_n) ||
        !(data.v_mm_s[i] < m.labelling.max_v_mm_s))
      continue;
    out.fn.push_back(data.fn_n[i]);
    out.v.push_back(data.v_mm_s[i]);
    out.mu.push_back(data.mu(i));
    out.stroke.push_back(data.stroke.size() == data.size() ? data.stroke[i]
                                                           : 0);
  }
  return out;
}

// Optional integer query parameter in [lo, hi].
int IntParam(const HttpRequest& req,
             const std::string& name,
             int fallback,
             int lo,
             int hi) {
  auto v = req.Query(name);
  if (!v) return fallback;
  const double x = ParseNumberParam(name, *v);
  if (!(x >= lo && x <= hi && x == std::floor(x))) {
    throw RequestError(StatusCode::kInvalidArgument,
                       name,
                       name + " = '" + v->substr(0, 32) +
                           "' (must be an integer in " + std::to_string(lo) +
                           ".." + std::to_string(hi) + ")");
  }
  return static_cast<int>(x);
}

// --- narrowing of mu with Fn / v priors (III-B, Fig. 6) ----------------------

// Comma-separated positive widths; "inf" allowed.
std::vector<double> WidthsParam(const HttpRequest& req,
                                const std::string& name,
                                std::vector<double> fallback) {
  auto v = req.Query(name);
  if (!v) return fallback;
  std::vector<double> out;
  std::size_t start = 0;
  while (start <= v->size()) {
    const std::size_t end = std::min(v->find(',', start), v->size());
    const std::string item = v->substr(start, end - start);
    double x = 0;
    if (item == "inf") {
      x = std::numeric_limits<double>::infinity();
    } else {
      x = ParseNumberParam(name, item);
    }
    if (!(x > 0)) {
      throw RequestError(StatusCode::kInvalidArgument,
                         name,
                         name + " has width " + item.substr(0, 32) +
                             " (each must be > 0 or inf)");
    }
    out.push_back(x);
    if (out.size() > 100)
      throw RequestError(StatusCode::kInvalidArgument,
                         name,
                         name + " has more than 100 widths");
    start = end + 1;
  }
  return out;
}

json WindowsToJson(const std::vector<MuWindowStd>& w) {
  auto finite = [](double x) { return std::isfinite(x) ? json(x) : json(); };
  json a = json::array();
  for (const MuWindowStd& x : w) {
    a.push_back({{"fn_width_n", finite(x.fn_width_n)},
                 {"v_width_mm_s", finite(x.v_width_mm_s)},
                 {"samples", x.samples},
                 {"mean_mu", x.mean_mu},
                 {"std_mu", x.std_mu}});
  }
  return a;
}

HttpResponse HandleMuSpread(FrictionLibrary& lib, const HttpRequest& req) {
  const double fn = ForceParam(req, "fn_n", true);
  const double v = ForceParam(req, "v_mm_s", false);
  auto model = ModelFor(lib, req);
  const StochasticFrictionModel& m = Stochastic(*model);
  // Default widths: the fitted range, then halves of it.
  auto defaults = [&m](const char* input) {
    auto it = m.inputs.find(input);
    const double range =
        it != m.inputs.end() ? it->second.max - it->second.min : 0.0;
    std::vector<double> w = {std::numeric_limits<double>::infinity()};
    if (range > 0) {
      for (double f : {1.0, 0.5, 0.25, 0.125}) w.push_back(f * range);
    }
    return w;
  };
  const std::vector<double> fw =
      WidthsParam(req, "fn_widths_n", defaults("fn_n"));
  const std::vector<double> vw =
      WidthsParam(req, "v_widths_mm_s", defaults("v_mm_s"));
  const SlipSamples s = LoadSlipSamples(lib, *model, m);
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<double> fn_inf(vw.size(), inf), v_inf(fw.size(), inf);
  json body = {
      {"material", model->set.material},
      {"version", model->set.version},
      {"fn_n", fn},
      {"v_mm_s", v},
      {"sigma_eps", m.mu.sigma_eps},
      {"samples", s.mu.size()},
      {"fn_windows",
       WindowsToJson(CalcMuStdByWindow(s.fn, s.v, s.mu, fn, v, fw, v_inf))},
      {"v_windows",
       WindowsToJson(CalcMuStdByWindow(s.fn, s.v, s.mu, fn, v, fn_inf, vw))}};
  if (fw.size() == vw.size()) {
    body["both_windows"] =
        WindowsToJson(CalcMuStdByWindow(s.fn, s.v, s.mu, fn, v, fw, vw));
  }
  return HttpResponse::Json(200, body);
}

// --- span variability (III-C-2, Fig. 10) -----------------------------------

HttpResponse HandleSpanVariability(FrictionLibrary& lib,
                                   const HttpRequest& req) {
  SpanVariabilityOptions o;
  o.subsets = IntParam(req, "subsets", 200, 1, 2000);
  o.max_strokes = IntParam(req, "max_strokes", 40, 1, 100000);
  o.seed = static_cast<std::uint64_t>(IntParam(req, "seed", 1, 0, 1 << 30));
  o.bin_pct = static_cast<double>(IntParam(req, "bin_pct", 10, 1, 100));
  auto model = ModelFor(lib, req);
  const StochasticFrictionModel& m = Stochastic(*model);
  const SlipSamples s = LoadSlipSamples(lib, *model, m);
  const SpanVariability r = CalcSpanVariability(s.fn, s.v, s.mu, s.stroke, o);
  json bins = json::array();
  for (const SpanBin& b : r.bins) {
    bins.push_back({{"span_pct", {b.span_lo_pct, b.span_hi_pct}},
                    {"subsets", b.subsets},
                    {"beta_mean", b.beta_mean},
                    {"beta_std", b.beta_std}});
  }
  json body = {{"material", model->set.material},
               {"version", model->set.version},
               {"valid", r.valid},
               {"strokes", r.strokes},
               {"subsets", o.subsets},
               {"seed", o.seed},
               {"full_hull_area", r.full_hull_area},
               {"coefficients", {"intercept", "v_mm_s", "fn_n"}},
               {"bins", bins}};
  if (!r.valid) body["why"] = r.why;
  return HttpResponse::Json(200, body);
}

// --- alternative forms of mu = f(Fn) (Table II) ---------------------------

HttpResponse HandleForms(FrictionLibrary& lib, const HttpRequest& req) {
  int folds = 5;
  if (auto f = req.Query("folds")) {
    const double x = ParseNumberParam("folds", *f);
    if (!(x >= 2 && x <= 50 && x == std::floor(x))) {
      throw RequestError(StatusCode::kInvalidArgument,
                         "folds",
                         "folds = '" + *f + "' (must be an integer in 2..50)");
    }
    folds = static_cast<int>(x);
  }
  auto model = ModelFor(lib, req);
  const StochasticFrictionModel& m = Stochastic(*model);
  const SlipSamples slip = LoadSlipSamples(lib, *model, m);
  const std::vector<double>& fn = slip.fn;
  const FormComparison c =
      CompareFrictionForms(slip.fn, slip.mu, slip.stroke, folds);
  json forms = json::array();
  for (const FormFit& f : c.forms) {
    json j = {{"form", ToString(f.form)},
              {"formula", FormulaOf(f.form)},
              {"valid", f.valid}};
    if (f.valid) {
      j["a"] = f.a;
      j["b"] = f.b;
      j["params"] = f.params;
      j["r2"] = f.r2;
      j["mae"] = f.mae;
      if (c.valid) j["cv_mae"] = f.cv_mae;
    } else {
      j["why"] = f.why;
    }
    forms.push_back(std::move(j));
  }
  json body = {{"material", model->set.material},
               {"version", model->set.version},
               {"samples", fn.size()},
               {"strokes", c.strokes},
               {"folds", c.folds},
               {"compared", c.valid},
               {"forms", forms}};
  if (c.valid) {
    body["best"] = ToString(c.best);
  } else {
    body["best"] = nullptr;
    body["why"] = c.why;
  }
  return HttpResponse::Json(200, body);
}

}  // namespace

void RegisterModelQueryRoutes(HttpServer& http, FrictionLibrary& lib) {
  // The eq. (2) family is identified on upload by IdentifyMaterial
  // (FrictionLibrary::FitModelSet); these routes only read it.
  http.Route(
      "GET",
      "/v1/materials/{id}/conditional-slip-likelihood",
      [&lib](const HttpRequest& req) { return HandleConditional(lib, req); });
  http.Route(
      "GET", "/v1/materials/{id}/target-force", [&lib](const HttpRequest& req) {
        return HandleTargetForce(lib, req);
      });
  http.Route(
      "GET",
      "/v1/materials/{id}/sliding-speed",
      [&lib](const HttpRequest& req) { return HandleSlidingSpeed(lib, req); });
  http.Route("GET", "/v1/materials/{id}/forms", [&lib](const HttpRequest& req) {
    return HandleForms(lib, req);
  });
  http.Route(
      "GET", "/v1/materials/{id}/mu-spread", [&lib](const HttpRequest& req) {
        return HandleMuSpread(lib, req);
      });
  http.Route("GET",
             "/v1/materials/{id}/span-variability",
             [&lib](const HttpRequest& req) {
               return HandleSpanVariability(lib, req);
             });
}

}  // namespace frictiond
