#include "frictiond/client/joint_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "frictiond/proto/sim_export.h"

namespace frictiond {

using nlohmann::json;

namespace {

std::string Fmt(const char* f, double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, x);
  return buf;
}

// Blue (low) to yellow (high).
std::string Colour(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const int r = static_cast<int>(40 + 213 * t);
  const int g = static_cast<int>(60 + 171 * t);
  const int b = static_cast<int>(160 - 120 * t);
  char buf[16];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", r, g, b);
  return buf;
}

}  // namespace

std::string RenderFrictionCurveSvg(const JointFamily& f,
                                   double s_min_um,
                                   double s_max_um) {
  if (!(s_min_um > 0 && s_max_um > s_min_um && std::isfinite(s_max_um)))
    throw std::invalid_argument("S range [" + Fmt("%g", s_min_um) + ", " +
                                Fmt("%g", s_max_um) +
                                "] (must be 0 < min < max)");
  const int w = 640, h = 360, left = 60, right = 20, top = 20, bottom = 50;
  const int pw = w - left - right, ph = h - top - bottom;
  const MixedFrictionTheta theta = f.mixed.theta.head<4>();
  // alpha is a load fraction (paper 002 eq. 6): draw the curve at the
  // geometric mean of the uploaded loads (100 N if no span is stored).
  const double load_n = f.load_min_n > 0 && f.load_max_n >= f.load_min_n
                            ? std::sqrt(f.load_min_n * f.load_max_n)
                            : 100.0;
  const double lo = std::log10(s_min_um), hi = std::log10(s_max_um);
  constexpr int kPoints = 200;
  double y_max = 0;
  std::vector<double> xs, mean, sd;
  for (int i = 0; i <= kPoints; ++i) {
    const double ls = lo + (hi - lo) * i / kPoints;
    const double s = std::pow(10.0, ls);
    xs.push_back(ls);
    mean.push_back(CalcMixedFriction(theta, f.config.surface, s, load_n));
    sd.push_back(
        CalcMixedFrictionDispersion(theta, f.config.surface, s, load_n));
    y_max = std::max(y_max, mean.back() + 2 * sd.back());
  }
  y_max = y_max > 0 ? 1.1 * y_max : 1.0;
  auto X = [&](double ls) { return left + pw * (ls - lo) / (hi - lo); };
  auto Y = [&](double y) { return top + ph * (1.0 - y / y_max); };
  std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" +
                    std::to_string(w) + "\" height=\"" + std::to_string(h) +
                    "\" font-family=\"sans-serif\" font-size=\"11\">\n";
  // Data span.
  if (f.s_max_um > f.s_min_um && f.s_min_um > 0) {
    const double a = std::clamp(std::log10(f.s_min_um), lo, hi);
    const double b = std::clamp(std::log10(f.s_max_um), lo, hi);
    svg += "<rect class=\"span\" x=\"" + Fmt("%.1f", X(a)) + "\" y=\"" +
           std::to_string(top) + "\" width=\"" + Fmt("%.1f", X(b) - X(a)) +
           "\" height=\"" + std::to_string(ph) +
           "\" fill=\"#e8f0e8\"><title>data span</title></rect>\n";
  }
  // Dispersion band.
  std::string band;
  for (int i = 0; i <= kPoints; ++i)
    band += Fmt("%.1f,", X(xs[i])) + Fmt("%.1f ", Y(mean[i] + 2 * sd[i]));
  for (int i = kPoints; i >= 0; --i)
    band += Fmt("%.1f,", X(xs[i])) +
            Fmt("%.1f ", Y(std::max(0.0, mean[i] - 2 * sd[i])));
  svg += "<polygon class=\"band\" points=\"" + band +
         "\" fill=\"#9cc3e6\" opacity=\"0.6\"/>\n";
  std::string line;
  for (int i = 0; i <= kPoints; ++i)
    line += Fmt("%.1f,", X(xs[i])) + Fmt("%.1f ", Y(mean[i]));
  svg += "<polyline class=\"curve\" points=\"" + line +
         "\" fill=\"none\" stroke=\"#1f4e8c\" stroke-width=\"2\"/>\n";
  // Axes and decade ticks.
  svg += "<rect x=\"" + std::to_string(left) + "\" y=\"" + std::to_string(top) +
         "\" width=\"" + std::to_string(pw) + "\" height=\"" +
         std::to_string(ph) + "\" fill=\"none\" stroke=\"#333\"/>\n";
  for (int d = static_cast<int>(std::ceil(lo)); d <= std::floor(hi); ++d) {
    svg += "<text x=\"" + Fmt("%.1f", X(d)) + "\" y=\"" +
           std::to_string(top + ph + 15) + "\" text-anchor=\"middle\">1e" +
           std::to_string(d) + "</text>\n";
  }
  for (int k = 0; k <= 4; ++k) {
    const double y = y_max * k / 4;
    svg += "<text x=\"" + std::to_string(left - 5) + "\" y=\"" +
           Fmt("%.1f", Y(y) + 4) + "\" text-anchor=\"end\">" + Fmt("%.3f", y) +
           "</text>\n";
  }
  svg += "<text x=\"" + std::to_string(left + pw / 2) + "\" y=\"" +
         std::to_string(h - 10) +
         "\" text-anchor=\"middle\">Sommerfeld number S = eta V / p "
         "[um]</text>\n<text x=\"14\" y=\"" +
         std::to_string(top + ph / 2) + "\" transform=\"rotate(-90 14 " +
         std::to_string(top + ph / 2) +
         ")\" text-anchor=\"middle\">friction coefficient f</text>\n</svg>\n";
  return svg;
}

std::string RenderRepeatabilityGridSvg(const json& grid) {
  if (!grid.is_object() || !grid.contains("n") || !grid["n"].is_number() ||
      !grid.contains("points") || !grid["points"].is_array())
    throw std::invalid_argument("grid: needs n and points");
  const int n = grid["n"].get<int>();
  const json& pts = grid["points"];
  if (n < 1 || pts.size() != static_cast<std::size_t>(n) * n)
    throw std::invalid_argument("grid: points must hold n * n entries");
  double vmin = 1e300, vmax = 0;
  for (const json& p : pts) {
    if (!p.value("reachable", false)) continue;
    const double a = p["semi_axes_um"][2].get<double>();
    vmin = std::min(vmin, a);
    vmax = std::max(vmax, a);
  }
  const int cell = std::max(4, 400 / n), size = cell * n;
  std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" +
                    std::to_string(size + 160) + "\" height=\"" +
                    std::to_string(size + 20) +
                    "\" font-family=\"sans-serif\" font-size=\"11\">\n";
  for (int i = 0; i < n * n; ++i) {
    const json& p = pts[static_cast<std::size_t>(i)];
    const int ix = i % n, iy = i / n;
    std::string fill = "#bbbbbb", title = "unreachable";
    if (p.value("reachable", false)) {
      const double a = p["semi_axes_um"][2].get<double>();
      fill = Colour(vmax > vmin ? (a - vmin) / (vmax - vmin) : 0.5);
      title = Fmt("%.4g um", a);
    }
    svg += "<rect x=\"" + std::to_string(ix * cell) + "\" y=\"" +
           std::to_string((n - 1 - iy) * cell) + "\" width=\"" +
           std::to_string(cell) + "\" height=\"" + std::to_string(cell) +
           "\" fill=\"" + fill + "\"><title>x " +
           Fmt("%.1f", p.value("x_mm", 0.0)) + " mm, y " +
           Fmt("%.1f", p.value("y_mm", 0.0)) + " mm: " + title +
           "</title></rect>\n";
  }
  if (vmax >= vmin) {
    svg += "<rect x=\"" + std::to_string(size + 20) +
           "\" y=\"10\" width=\"14\" height=\"14\" fill=\"" + Colour(1.0) +
           "\"/><text x=\"" + std::to_string(size + 40) + "\" y=\"21\">" +
           Fmt("%.4g um (max)", vmax) + "</text>\n<rect x=\"" +
           std::to_string(size + 20) +
           "\" y=\"30\" width=\"14\" height=\"14\" fill=\"" + Colour(0.0) +
           "\"/><text x=\"" + std::to_string(size + 40) + "\" y=\"41\">" +
           Fmt("%.4g um (min)", vmin) + "</text>\n";
  }
  return svg + "</svg>\n";
}

std::string RenderJointReportHtml(const std::string& material,
                                  const std::string& joint,
                                  const JointFamily& f,
                                  const json& grid) {
  std::string html =
      "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>Joint "
      "friction: " +
      XmlEscape(material) + " / " + XmlEscape(joint) +
      "</title></head><body>\n<h1>Joint friction: " + XmlEscape(material) +
      " / " + XmlEscape(joint) +
      "</h1>\n<h2>Friction against Sommerfeld number "
      "(paper 002, eq. 1)</h2>\n";
  if (f.mixed.theta.size() == 4 && f.mixed.theta.allFinite() &&
      f.mixed.status != JointFitStatus::kFailed &&
      f.mixed.status != JointFitStatus::kNotObservable) {
    const double a = f.s_min_um > 0 ? f.s_min_um / 30 : 1e-5;
    const double b = f.s_max_um > a ? f.s_max_um * 30 : 1.0;
    html += RenderFrictionCurveSvg(f, a, b);
    html +=
        "<p>Line: mixed model; band: +-2 sd contact dispersion; shaded: "
        "Sommerfeld span of the data.</p>\n";
  } else {
    html += "<p>The mixed model is not identified (" +
            XmlEscape(ToString(f.mixed.status)) + ": " +
            XmlEscape(f.mixed.why) + ").</p>\n";
  }
  html +=
      "<h2>Models</h2>\n<table border=\"1\" cellpadding=\"4\"><tr><th>model</"
      "th><th>status</th><th>parameters</th><th>held-out RMSE</th></tr>\n";
  const JointFitResult* fits[3] = {&f.mixed, &f.stribeck, &f.lugre};
  for (int k = 0; k < 3; ++k) {
    const JointFitResult& r = *fits[k];
    const auto names = ParameterNames(r.kind);
    std::string params;
    for (std::size_t i = 0; i < names.size(); ++i) {
      const auto ii = static_cast<Eigen::Index>(i);
      if (ii >= r.theta.size()) break;
      params += names[i] + " = " + Fmt("%.4g", r.theta[ii]);
      if (ii < r.P_theta.rows() && r.P_theta(ii, ii) > 0)
        params += " &plusmn; " + Fmt("%.2g", std::sqrt(r.P_theta(ii, ii)));
      params += "<br>";
    }
    double rmse = std::nan("");
    for (const JointModelScore& s : f.scores)
      if (s.kind == r.kind) rmse = s.heldout_rmse;
    html += "<tr><td>" + ToString(r.kind) + "</td><td>" +
            XmlEscape(ToString(r.status)) + "</td><td>" + params + "</td><td>" +
            (std::isfinite(rmse) ? Fmt("%.4g", rmse) : "-") + "</td></tr>\n";
  }
  html += "</table>\n";
  if (grid.is_object()) {
    html += "<h2>Repeatability field (largest ellipsoid semi-axis, " +
            Fmt("%.0f", 100 * grid.value("probability", 0.95)) +
            " %) at z = " + Fmt("%.1f", grid.value("z_mm", 0.0)) +
            " mm</h2>\n" + RenderRepeatabilityGridSvg(grid);
  }
  return html + "</body></html>\n";
}

}  // namespace frictiond
