// The operator console (docs/console.md): its static files, compiled into
// the daemon (cmake/EmbedFiles.cmake), at GET / and GET /console/{file},
// and the read route its plots need, GET /v1/materials/{id}/samples.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/estimators/span_coverage.h"
#include "frictiond/server/routes.h"

#include "embedded_files.h"

namespace frictiond {

using nlohmann::json;

namespace {

// Everything the console loads comes from the daemon: no other origin, no
// inline script, no plugins, no framing.
constexpr const char* kConsoleCsp =
    "default-src 'none'; script-src 'self'; style-src 'self'; "
    "img-src 'self' data: blob:; connect-src 'self'; font-src 'self'; "
    "base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

std::string ContentTypeOf(const std::string& name) {
  auto ends_with = [&name](const char* ext) {
    const std::size_t n = std::strlen(ext);
    return name.size() >= n && name.compare(name.size() - n, n, ext) == 0;
  };
  if (ends_with(".html")) return "text/html; charset=utf-8";
  if (ends_with(".js")) return "text/javascript; charset=utf-8";
  if (ends_with(".css")) return "text/css; charset=utf-8";
  return "application/octet-stream";
}

HttpResponse ServeConsoleFile(const std::string& name) {
  for (std::size_t i = 0; i < kConsoleFilesCount; ++i) {
    const EmbeddedFile& f = kConsoleFiles[i];
    if (name != f.name) continue;
    HttpResponse out{200,
                     ContentTypeOf(name),
                     std::string(reinterpret_cast<const char*>(f.data), f.size),
                     {}};
    out.headers.emplace("Content-Security-Policy", kConsoleCsp);
    out.headers.emplace("X-Content-Type-Options", "nosniff");
    out.headers.emplace("Referrer-Policy", "no-referrer");
    out.headers.emplace("Cache-Control", "no-cache");
    return out;
  }
  std::string shown = name.substr(0, 64);
  for (char& c : shown) {
    if (static_cast<unsigned char>(c) < 0x20 ||
        static_cast<unsigned char>(c) >= 0x7f)
      c = '?';
  }
  throw RequestError(
      StatusCode::kNotFound, "file", "no console file '" + shown + "'");
}

// The model version named by ?version= (or the newest). Unlike the model
// routes, an unknown pair does not request an identification: looking at a
// material in the console is not a robot asking for it.
std::shared_ptr<const CachedModel> FindModelFor(FrictionLibrary& lib,
                                                const HttpRequest& req,
                                                const std::string& id,
                                                const std::string& fingertip) {
  if (auto v = req.Query("version")) {
    const int version = ParseVersionParam(*v);
    auto m = lib.FindModelVersion(id, fingertip, version);
    if (!m)
      throw RequestError(StatusCode::kNotFound,
                         "version",
                         "material '" + id + "' has no model version " +
                             std::to_string(version) + " for fingertip '" +
                             fingertip + "'");
    return m;
  }
  auto m = lib.FindModel(id, fingertip);
  if (!m) {
    throw RequestError(StatusCode::kNotFound,
                       "id",
                       "material '" + id + "' has no model for fingertip '" +
                           fingertip + "' (upload a stroke first)");
  }
  return m;
}

HttpResponse HandleSamples(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  CheckId(id, "id");
  std::size_t max_points = 2000;
  if (auto m = req.Query("max")) {
    const double x = ParseNumberParam("max", *m);
    if (!(x >= 1 && x <= 20000 && x == std::floor(x))) {
      throw RequestError(
          StatusCode::kInvalidArgument,
          "max",
          "max = '" + m->substr(0, 32) + "' (must be an integer in 1..20000)");
    }
    max_points = static_cast<std::size_t>(x);
  }
  const std::string fingertip = FingertipParam(req);
  auto model = FindModelFor(lib, req, id, fingertip);
  std::optional<SlipLabelOptions> labelling;
  double max_fn = std::numeric_limits<double>::infinity();
  double max_v = std::numeric_limits<double>::infinity();
  if (model->set.stochastic) {
    labelling = model->set.stochastic->labelling;
    max_fn = labelling->max_fn_n;
    max_v = labelling->max_v_mm_s;
  }
  // Slipping samples as the model saw them (same labelling and limits).
  const StrokeData data = lib.LoadStrokes(id, fingertip, labelling);
  std::vector<std::size_t> slip;
  if (data.slip.size() == data.size()) {
    for (std::size_t i = 0; i < data.size(); ++i) {
      if (data.slip[i] && data.fn_n[i] < max_fn && data.v_mm_s[i] < max_v &&
          std::isfinite(data.mu(i)))
        slip.push_back(i);
    }
  }
  std::vector<std::pair<double, double>> points;
  points.reserve(slip.size());
  for (std::size_t i : slip) points.emplace_back(data.fn_n[i], data.v_mm_s[i]);
  const auto hull = CalcConvexHull(points);
  // Decimation: every stride-th slipping sample, so strokes keep their share.
  const std::size_t stride =
      std::max<std::size_t>(1, (slip.size() + max_points - 1) / max_points);
  json fn = json::array(), v = json::array(), mu = json::array(),
       stroke = json::array();
  const bool has_stroke = data.stroke.size() == data.size();
  for (std::size_t k = 0; k < slip.size(); k += stride) {
    const std::size_t i = slip[k];
    fn.push_back(data.fn_n[i]);
    v.push_back(data.v_mm_s[i]);
    mu.push_back(data.mu(i));
    stroke.push_back(has_stroke ? data.stroke[i] : 0);
  }
  json hull_fn = json::array(), hull_v = json::array();
  for (const auto& [f, s] : hull) {
    hull_fn.push_back(f);
    hull_v.push_back(s);
  }
  const StrokePlanOptions& plan = lib.options().plan;
  const SpanRect plan_rect{
      plan.fn_min_n, plan.fn_max_n, plan.v_min_mm_s, plan.v_max_mm_s};
  std::vector<double> all_fn, all_v;
  for (const auto& [f, s] : points) {
    all_fn.push_back(f);
    all_v.push_back(s);
  }
  const SpanCoverage cov = CalcSpanCoverage(all_fn, all_v, plan_rect);
  // Paper 000 III-C-2: each stroke's hull against the hull of all of the
  // material's slipping samples (the 50 % rule applies to this; the plan's
  // rectangle above stays what the robot is asked to sweep). Newest 1000
  // strokes at most.
  json per_stroke = json::array();
  if (has_stroke) {
    std::map<int, std::pair<std::vector<double>, std::vector<double>>> by;
    for (std::size_t i : slip) {
      auto& [sf, sv] = by[data.stroke[i]];
      sf.push_back(data.fn_n[i]);
      sv.push_back(data.v_mm_s[i]);
    }
    std::size_t skip = by.size() > 1000 ? by.size() - 1000 : 0;
    for (const auto& [sid, xy] : by) {
      if (skip > 0) {
        --skip;
        continue;
      }
      const HullSpanCoverage h =
          CalcHullSpanCoverage(xy.first, xy.second, all_fn, all_v);
      per_stroke.push_back({{"stroke", sid},
                            {"span_pct", h.span_pct},
                            {"reliable", h.reliable},
                            {"samples", h.samples}});
    }
  }
  json body = {{"material", id},
               {"fingertip", fingertip},
               {"version", model->set.version},
               {"slip_samples", slip.size()},
               {"returned", fn.size()},
               {"stride", stride},
               {"fn_n", fn},
               {"v_mm_s", v},
               {"mu", mu},
               {"stroke", stroke},
               {"hull",
                {{"fn_n", hull_fn},
                 {"v_mm_s", hull_v},
                 {"area", CalcConvexHullArea(points)}}},
               {"coverage",
                {{"plan",
                  {{"fn_n", {plan.fn_min_n, plan.fn_max_n}},
                   {"v_mm_s", {plan.v_min_mm_s, plan.v_max_mm_s}}}},
                 {"span_pct", cov.span_pct},
                 {"min_span_pct", plan.min_span_pct},
                 {"material_hull_area", CalcConvexHullArea(points)},
                 {"per_stroke", per_stroke}}}};
  return HttpResponse::Json(200, body);
}

}  // namespace

void RegisterConsoleRoutes(HttpServer& http, FrictionLibrary& lib) {
  http.Route("GET", "/", [](const HttpRequest&) {
    return ServeConsoleFile("index.html");
  });
  http.Route("GET", "/console/{file}", [](const HttpRequest& req) {
    return ServeConsoleFile(req.params.at(0));
  });
  http.Route(
      "GET", "/v1/materials/{id}/samples", [&lib](const HttpRequest& req) {
        return HandleSamples(lib, req);
      });
}

}  // namespace frictiond
