// `friction report DATASET.csv`: an HTML page with SVG plots and a table of
// paper 000's claims beside what the data shows (docs/paper000.md). Offline:
// no daemon, the estimators run in-process.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/estimators/friction_forms.h"
#include "frictiond/estimators/mu_windows.h"
#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/slip_likelihood.h"
#include "frictiond/estimators/span_coverage.h"
#include "frictiond/estimators/span_variability.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/proto/sim_export.h"

#include "cli.h"

namespace frictiond::cli {

namespace {

std::string Fmt(double x, const char* f = "%.4g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, x);
  return buf;
}

// A 480x300 SVG plot with axes, points and optional polylines.
class SvgPlot {
 public:
  SvgPlot(std::string title,
          std::string xlabel,
          std::string ylabel,
          double x0,
          double x1,
          double y0,
          double y1)
      : title_(std::move(title)),
        xlabel_(std::move(xlabel)),
        ylabel_(std::move(ylabel)),
        x0_(x0),
        x1_(x1 > x0 ? x1 : x0 + 1),
        y0_(y0),
        y1_(y1 > y0 ? y1 : y0 + 1) {}
  void Points(const std::vector<double>& x,
              const std::vector<double>& y,
              const std::string& color) {
    const std::size_t step = std::max<std::size_t>(1, x.size() / 3000);
    for (std::size_t i = 0; i < x.size(); i += step) {
      if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
      if (x[i] < x0_ || x[i] > x1_ || y[i] < y0_ || y[i] > y1_) continue;
      body_ += "<circle cx='" + Fmt(X(x[i]), "%.1f") + "' cy='" +
               Fmt(Y(y[i]), "%.1f") + "' r='1.2' fill='" + color +
               "' fill-opacity='0.4'/>";
    }
  }
  void Line(const std::vector<std::pair<double, double>>& p,
            const std::string& color,
            bool closed = false) {
    std::string pts;
    for (const auto& [x, y] : p) {
      if (!std::isfinite(x) || !std::isfinite(y)) continue;
      pts += Fmt(X(std::clamp(x, x0_, x1_)), "%.1f") + "," +
             Fmt(Y(std::clamp(y, y0_, y1_)), "%.1f") + " ";
    }
    body_ += std::string("<") + (closed ? "polygon" : "polyline") +
             " points='" + pts + "' fill='none' stroke='" + color +
             "' stroke-width='2'/>";
  }
  std::string Render() const {
    std::string s =
        "<svg xmlns='http://www.w3.org/2000/svg' width='480' height='300'>"
        "<rect x='60' y='30' width='400' height='220' fill='none' "
        "stroke='#333'/>";
    s += "<text x='260' y='20' text-anchor='middle' font-size='13'>" +
         XmlEscape(title_) + "</text>";
    s += "<text x='260' y='290' text-anchor='middle' font-size='12'>" +
         XmlEscape(xlabel_) + "</text>";
    s += "<text x='14' y='140' font-size='12' transform='rotate(-90 14 140)' "
         "text-anchor='middle'>" +
         XmlEscape(ylabel_) + "</text>";
    for (int k = 0; k <= 4; ++k) {
      const double xv = x0_ + k * (x1_ - x0_) / 4;
      const double yv = y0_ + k * (y1_ - y0_) / 4;
      s += "<text x='" + Fmt(X(xv), "%.1f") +
           "' y='266' font-size='10' text-anchor='middle'>" + Fmt(xv, "%.3g") +
           "</text>";
      s += "<text x='56' y='" + Fmt(Y(yv) + 3, "%.1f") +
           "' font-size='10' text-anchor='end'>" + Fmt(yv, "%.3g") + "</text>";
    }
    return s + body_ + "</svg>\n";
  }

 private:
  double X(double x) const { return 60 + 400 * (x - x0_) / (x1_ - x0_); }
  double Y(double y) const { return 250 - 220 * (y - y0_) / (y1_ - y0_); }
  std::string title_, xlabel_, ylabel_, body_;
  double x0_, x1_, y0_, y1_;
};

std::pair<double, double> Range(const std::vector<double>& v) {
  if (v.empty()) return {0, 1};
  std::vector<double> s = v;
  std::sort(s.begin(), s.end());
  const double lo = s[static_cast<std::size_t>(0.005 * (s.size() - 1))];
  const double hi = s[static_cast<std::size_t>(0.995 * (s.size() - 1))];
  const double pad = 0.05 * (hi - lo > 0 ? hi - lo : std::fabs(hi) + 1e-9);
  return {lo - pad, hi + pad};
}

struct Claim {
  std::string claim, shows, verdict;
};

std::string BuildReport(const std::string& name,
                        StrokeData data,
                        const SlipLabelOptions& labelling) {
  EnsureLabels(&data, labelling);
  StochasticFitOptions options;
  options.labelling = labelling;
  const StochasticFit fit = FitStochasticModel(data, options);
  if (fit.status != FitStatus::kOk && fit.status != FitStatus::kPartial)
    throw std::invalid_argument("no model can be identified: " + fit.why);
  const StochasticFrictionModel& m = fit.model;
  std::vector<double> fn, v, mu, ratio;
  std::vector<int> stroke, slip;
  for (std::size_t i = 0; i < data.size(); ++i) {
    ratio.push_back(data.mu(i));
    slip.push_back(data.slip[i]);
    if (!data.slip[i] || !(data.fn_n[i] < labelling.max_fn_n) ||
        !(data.v_mm_s[i] < labelling.max_v_mm_s))
      continue;
    fn.push_back(data.fn_n[i]);
    v.push_back(data.v_mm_s[i]);
    mu.push_back(data.mu(i));
    stroke.push_back(data.stroke[i]);
  }
  const bool fn_identified =
      std::find(m.mu.unidentified.begin(), m.mu.unidentified.end(), "fn_n") ==
      m.mu.unidentified.end();
  std::vector<Claim> claims;
  // Table I.
  claims.push_back(
      {"eq. (1) fits with strong significance (Table I: R² 0.55-0.64, p < "
       "1e-4)",
       "R² = " + Fmt(m.mu.r2, "%.3f") + ", F = " + Fmt(m.mu.f_stat, "%.0f") +
           ", p = " + Fmt(m.mu.p_value, "%.2g") + ", " +
           std::to_string(m.mu.samples) + " slipping samples",
       m.mu.p_value < 1e-4 ? "holds (significant)" : "does not hold"});
  // Fig. 7.
  const double mae_ratio =
      m.mae_coulomb > 0 ? m.mu.mae / m.mae_coulomb : std::nan("");
  claims.push_back({"regression MAE roughly half of Coulomb's (Fig. 7)",
                    "MAE " + Fmt(m.mu.mae, "%.3f") + " vs Coulomb " +
                        Fmt(m.mae_coulomb, "%.3f") + " (mu_Coulomb " +
                        Fmt(m.mu_coulomb, "%.3f") + "): ratio " +
                        Fmt(mae_ratio, "%.2f") + " (in-sample)",
                    mae_ratio <= 0.6
                        ? "holds"
                        : (mae_ratio < 1 ? "partly (better, not halved)"
                                         : "does not hold")});
  // Fn slope and Table II forms.
  const FormComparison forms = CompareFrictionForms(fn, mu, stroke);
  std::string forms_text;
  for (const FormFit& f : forms.forms) {
    forms_text += std::string(ToString(f.form)) + ": " +
                  (f.valid && forms.valid ? Fmt(f.cv_mae, "%.4f") : "n/a") +
                  "; ";
  }
  claims.push_back(
      {"mu depends on Fn; Table II forms comparable to linear",
       fn_identified
           ? "b2 = " + Fmt(m.mu.beta(2), "%.4g") + " per N; held-out MAE " +
                 forms_text + "best: " + ToString(forms.best)
           : "Fn has no span: b2 not identified; held-out MAE " + forms_text,
       fn_identified ? "tested (see MAE per form)" : "cannot be tested"});
  // Fig. 3.
  const SlipLikelihoodFit& L = m.likelihood;
  claims.push_back(
      {"slip likelihood is a sigmoid in Ft/Fn rising from 'never' to "
       "'always' (Fig. 3)",
       L.valid ? "c1 = " + Fmt(L.c1) + ", c2 = " + Fmt(L.c2) +
                     "; never slips below " + Fmt(L.ratio_never, "%.3f") +
                     ", always above " + Fmt(L.ratio_always, "%.3f")
               : L.why,
       L.valid ? "holds" : "does not hold"});
  // Fig. 5/6.
  const auto fn_range = Range(fn);
  const double fn_mid = 0.5 * (fn_range.first + fn_range.second);
  const double inf = std::numeric_limits<double>::infinity();
  const auto w = CalcMuStdByWindow(
      fn,
      v,
      mu,
      fn_mid,
      0,
      {inf, std::max(1e-12, 0.1 * (fn_range.second - fn_range.first))},
      {inf, inf});
  claims.push_back({"a prior on Fn narrows the mu distribution (Fig. 5/6)",
                    "std of mu " + Fmt(w[0].std_mu, "%.3f") + " overall, " +
                        Fmt(w[1].std_mu, "%.3f") +
                        " in an Fn window of 10 % of the range (" +
                        std::to_string(w[1].samples) + " samples)",
                    !fn_identified ? "cannot be tested"
                                   : (w[1].std_mu < 0.95 * w[0].std_mu
                                          ? "holds (std down by >= 5 %)"
                                          : "does not hold (std within 5 %)")});
  // Fig. 10.
  SpanVariabilityOptions so;
  so.subsets = 200;
  const SpanVariability sv = CalcSpanVariability(fn, v, mu, stroke, so);
  std::string sv_text = "std of b1, b2 per span bin:";
  for (const SpanBin& b : sv.bins) {
    if (b.subsets > 1)
      sv_text += " " + Fmt(b.span_lo_pct, "%.0f") + "-" +
                 Fmt(b.span_hi_pct, "%.0f") +
                 "%: " + Fmt(b.beta_std[1], "%.3g") + ", " +
                 Fmt(b.beta_std[2], "%.3g");
  }
  // Steady state above 50 %: the pooled spread over 50-100 % within 2x of
  // that over 80-100 %, for b1 and b2.
  auto pooled = [&sv](double lo, int j) {
    double ss = 0;
    int n = 0;
    for (const SpanBin& b : sv.bins) {
      if (b.span_lo_pct < lo || b.subsets < 2) continue;
      ss += b.beta_std[j] * b.beta_std[j] * (b.subsets - 1);
      n += b.subsets - 1;
    }
    return n > 0 ? std::sqrt(ss / n) : std::nan("");
  };
  bool steady = sv.valid;
  for (int j = 1; j <= 2; ++j) {
    const double r = pooled(50, j) / pooled(80, j);
    sv_text += std::string("; b") + std::to_string(j) +
               " spread 50-100 % / 80-100 %: " + Fmt(r, "%.2f");
    steady = steady && r <= 2.0;
  }
  int single_half = 0;
  std::vector<int> ids = stroke;
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  for (int id : ids) {
    std::vector<std::pair<double, double>> pts;
    for (std::size_t i = 0; i < fn.size(); ++i)
      if (stroke[i] == id) pts.emplace_back(fn[i], v[i]);
    if (sv.full_hull_area > 0 &&
        CalcConvexHullArea(pts) >= 0.5 * sv.full_hull_area)
      ++single_half;
  }
  sv_text +=
      "; single strokes with >= 50 % span: " + std::to_string(single_half) +
      " of " + std::to_string(ids.size());
  claims.push_back(
      {"parameter spread reaches steady state above ~50 % span; one stroke "
       "with >= 50 % span suffices (Fig. 10)",
       sv.valid ? sv_text : sv.why,
       !(fn_identified && sv.valid)
           ? "cannot be tested (no Fn span)"
           : (steady ? "holds (spread above 50 % within 2x of 80-100 %)"
                     : "does not hold (spread still falling above 50 %)")});

  // Plots.
  std::string plots;
  {
    const auto fr = Range(fn), mr = Range(mu);
    SvgPlot p("mu vs Fn (slipping) with eq. (1) at mean v",
              "Fn [N]",
              "mu",
              fr.first,
              fr.second,
              mr.first,
              mr.second);
    p.Points(fn, mu, "#1f77b4");
    const double vm = m.inputs.count("v_mm_s") ? m.inputs.at("v_mm_s").mean : 0;
    std::vector<std::pair<double, double>> line;
    for (int k = 0; k <= 40; ++k) {
      const double x = fr.first + k * (fr.second - fr.first) / 40;
      line.emplace_back(x, PredictMu(m, x, vm).mu);
    }
    p.Line(line, "#d62728");
    plots += p.Render();
  }
  {
    const auto vr = Range(v), mr = Range(mu);
    SvgPlot p("mu vs v (slipping) with eq. (1) at mean Fn",
              "v [mm/s]",
              "mu",
              vr.first,
              vr.second,
              mr.first,
              mr.second);
    p.Points(v, mu, "#2ca02c");
    const double fm = m.inputs.count("fn_n") ? m.inputs.at("fn_n").mean : 1;
    std::vector<std::pair<double, double>> line;
    for (int k = 0; k <= 40; ++k) {
      const double x = vr.first + k * (vr.second - vr.first) / 40;
      line.emplace_back(x, PredictMu(m, fm, x).mu);
    }
    p.Line(line, "#d62728");
    plots += p.Render();
  }
  {
    const auto mr = Range(mu);
    const int n_bins = 40;
    std::vector<int> h(n_bins, 0);
    for (double x : mu) {
      const int b =
          static_cast<int>((x - mr.first) / (mr.second - mr.first) * n_bins);
      if (b >= 0 && b < n_bins) ++h[b];
    }
    const int hmax = std::max(1, *std::max_element(h.begin(), h.end()));
    SvgPlot p("distribution of mu (slipping)",
              "mu",
              "share of the fullest bin",
              mr.first,
              mr.second,
              0,
              1);
    std::vector<std::pair<double, double>> steps;
    for (int b = 0; b < n_bins; ++b) {
      const double x0 = mr.first + b * (mr.second - mr.first) / n_bins;
      const double x1 = mr.first + (b + 1) * (mr.second - mr.first) / n_bins;
      steps.emplace_back(x0, static_cast<double>(h[b]) / hmax);
      steps.emplace_back(x1, static_cast<double>(h[b]) / hmax);
    }
    p.Line(steps, "#9467bd");
    plots += p.Render();
  }
  {
    const auto rr = Range(ratio);
    const double width = (rr.second - rr.first) / 40;
    const std::vector<SlipRatioBin> bins =
        CalcBinnedSlipRatio(ratio, slip, width > 0 ? width : 0.05);
    SvgPlot p("slip ratio vs Ft/Fn: bins, ML sigmoid (red), Coulomb (black)",
              "Ft/Fn",
              "P(slip)",
              rr.first,
              rr.second,
              0,
              1);
    std::vector<double> bx, by;
    for (const SlipRatioBin& b : bins) {
      if (b.samples < 5) continue;
      bx.push_back(0.5 * (b.ratio_lo + b.ratio_hi));
      by.push_back(b.slip_ratio);
    }
    p.Points(bx, by, "#000000");
    std::vector<std::pair<double, double>> sig, step;
    for (int k = 0; k <= 80; ++k) {
      const double x = rr.first + k * (rr.second - rr.first) / 80;
      if (L.valid) sig.emplace_back(x, 1 / (1 + std::exp(-L.c1 * (x - L.c2))));
    }
    if (L.valid) p.Line(sig, "#d62728");
    step = {
        {rr.first, 0}, {m.mu_coulomb, 0}, {m.mu_coulomb, 1}, {rr.second, 1}};
    p.Line(step, "#333333");
    plots += p.Render();
  }
  {
    const auto fr = Range(fn), vr = Range(v);
    SvgPlot p("coverage: convex hull of slipping (Fn, v)",
              "Fn [N]",
              "v [mm/s]",
              fr.first,
              fr.second,
              vr.first,
              vr.second);
    p.Points(fn, v, "#ff7f0e");
    std::vector<std::pair<double, double>> pts;
    for (std::size_t i = 0; i < fn.size(); ++i) pts.emplace_back(fn[i], v[i]);
    // Monotone chain hull for drawing.
    std::sort(pts.begin(), pts.end());
    pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
    std::vector<std::pair<double, double>> hull;
    auto cross = [](const std::pair<double, double>& o,
                    const std::pair<double, double>& a,
                    const std::pair<double, double>& b) {
      return (a.first - o.first) * (b.second - o.second) -
             (a.second - o.second) * (b.first - o.first);
    };
    for (int pass = 0; pass < 2; ++pass) {
      const std::size_t start = hull.size();
      for (std::size_t k = 0; k < pts.size(); ++k) {
        const auto& q = pass == 0 ? pts[k] : pts[pts.size() - 1 - k];
        while (hull.size() >= start + 2 &&
               cross(hull[hull.size() - 2], hull.back(), q) <= 0)
          hull.pop_back();
        hull.push_back(q);
      }
      if (!hull.empty()) hull.pop_back();
    }
    p.Line(hull, "#d62728", /*closed=*/true);
    plots += p.Render();
  }

  std::string html =
      "<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>friction "
      "report: " +
      XmlEscape(name) +
      "</title><style>body{font-family:sans-serif;max-width:1000px;margin:"
      "auto}table{border-collapse:collapse}td,th{border:1px solid "
      "#999;padding:4px;vertical-align:top}</style></head><body>\n";
  html += "<h1>Paper 000 claims on " + XmlEscape(name) + "</h1>\n";
  html += "<p>" + std::to_string(data.size()) + " samples, " +
          std::to_string(m.strokes) + " strokes with slip, " +
          std::to_string(mu.size()) +
          " slipping samples. mu = " + Fmt(m.mu.beta(0)) + " + " +
          Fmt(m.mu.beta(1)) + " v + " + Fmt(m.mu.beta(2)) +
          " Fn + eps, sigma_eps = " + Fmt(m.mu.sigma_eps, "%.3f") + ".</p>\n";
  html +=
      "<table><tr><th>paper 000 claim</th><th>this data</th><th>"
      "verdict</th></tr>\n";
  for (const Claim& c : claims) {
    html += "<tr><td>" + XmlEscape(c.claim) + "</td><td>" + XmlEscape(c.shows) +
            "</td><td>" + XmlEscape(c.verdict) + "</td></tr>\n";
  }
  html += "</table>\n" + plots + "</body></html>\n";
  return html;
}

}  // namespace

void RegisterReportCommand(CLI::App& app, Globals& /*g*/) {
  auto* cmd = app.add_subcommand(
      "report",
      "HTML page with SVG plots and paper 000's claims vs the data (offline)");
  static std::string file, out = "report.html";
  static SlipLabelOptions labelling;
  cmd->add_option("DATASET", file, "stroke CSV")->required();
  cmd->add_option("-o,--output", out, "HTML file to write")
      ->capture_default_str();
  cmd->add_option("--slip-peak-mm-s", labelling.peak_mm_s, "slip episode peak")
      ->capture_default_str();
  cmd->add_option(
         "--slip-floor-mm-s", labelling.floor_mm_s, "slip neighbour floor")
      ->capture_default_str();
  cmd->add_option("--median-window-s",
                  labelling.median_window_s,
                  "velocity median filter")
      ->capture_default_str();
  cmd->callback([] {
    std::string why;
    StochasticFitOptions check;
    check.labelling = labelling;
    if (!check.IsValid(&why)) {
      std::cerr << "friction: " << why << "\n";
      throw CLI::RuntimeError(2);
    }
    const StrokeData data = ReadStrokeCsvFile(file);
    std::string html;
    try {
      html = BuildReport(file, data, labelling);
    } catch (const std::invalid_argument& e) {
      std::cerr << "friction: " << file << ": " << e.what() << "\n";
      throw CLI::RuntimeError(1);
    }
    std::ofstream o(out);
    o << html;
    if (!o) {
      std::cerr << "friction: cannot write " << out << "\n";
      throw CLI::RuntimeError(2);
    }
    std::cout << out << "\n";
  });
}

}  // namespace frictiond::cli
