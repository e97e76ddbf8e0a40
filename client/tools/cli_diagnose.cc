// friction diagnose: what the simulation gets wrong, the cause, the
// extended model and its held-out gain (issue 7, CONTRACT.md "Model
// diagnosis"). Offline: reads stroke CSV files, talks to no daemon.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/estimators/regression.h"
#include "frictiond/proto/diagnosis_json.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/proto/sim_export.h"

#include "cli.h"

namespace frictiond::cli {

namespace {

struct DiagnoseArgs {
  std::vector<std::string> files;
  bool json = false;
  std::string report;
  double slip_peak_mm_s = 0.0;
  double slip_floor_mm_s = 0.0;
  int folds = 10;
  int inner_folds = 5;
  bool shuffle_folds = false;
  std::uint64_t seed = 0;
  double alpha = 0.05;
  double min_gain_pct = 1.0;
  int max_findings = 5;
  bool no_strokes = false;
  bool no_tests = false;
  std::vector<double> lugre;  ///< mu_s, mu_c, v0, sigma2, sigma0, sigma1
  std::string lugre_from;     ///< material whose stored LuGre is replayed
};

std::string Fmt(double x, int digits = 3) {
  if (!std::isfinite(x)) return "-";
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, x);
  return buf;
}

void PrintSummary(const DiagnosisResult& r,
                  const DiagnosisOptions& o,
                  const std::string& rule) {
  std::cout << "diagnosis: " << ToString(r.status)
            << (r.why.empty() ? "" : " (" + r.why + ")") << "\n";
  std::cout << "data: " << r.samples << " samples, " << r.fit_samples
            << " slipping, " << r.strokes << " strokes, " << r.folds
            << " outer x " << r.inner_folds << " inner stroke folds ("
            << (o.shuffle_folds ? "shuffled" : "contiguous blocks in time")
            << ")\n";
  std::cout << "slip thresholds: peak " << Fmt(o.labelling.peak_mm_s)
            << " mm/s, floor " << Fmt(o.labelling.floor_mm_s) << " mm/s"
            << (rule.empty() ? "" : " (" + rule + ")") << "\n";
  if (r.status != DiagnosisStatus::kOk) return;
  std::cout << "\nreplay (held-out strokes):\n";
  std::printf("  %-9s %8s %6s %6s %6s %8s %10s %10s\n",
              "model",
              "mu_mae",
              "hits",
              "misses",
              "false",
              "brier",
              "breakaway",
              "bias");
  for (const ModelReplay& m : r.replay) {
    const ReplayErrors& e = m.overall;
    auto count = [&m](int c) {
      return m.predicts_slip ? std::to_string(c) : std::string("-");
    };
    std::printf("  %-9s %8.4f %6s %6s %6s %8.4f %10.4f %10.4f\n",
                m.model.c_str(),
                e.mu_mae,
                count(e.hits).c_str(),
                count(e.misses).c_str(),
                count(e.false_alarms).c_str(),
                e.brier,
                e.breakaway_abs_error,
                e.breakaway_bias);
    if (!m.note.empty()) std::printf("    (%s)\n", m.note.c_str());
  }
  std::fflush(stdout);
  std::cout << "\nbaseline " << r.baseline.model << " [";
  for (std::size_t k = 0; k < r.baseline.terms.size(); ++k)
    std::cout << (k ? ", " : "") << r.baseline.terms[k];
  std::cout << "]: cv_mae " << Fmt(r.baseline.cv_mae, 4) << "\n";
  if (!r.dropped_baseline_terms.empty()) {
    std::cout << "  dropped (no span): ";
    for (const auto& t : r.dropped_baseline_terms) std::cout << t << " ";
    std::cout << "\n";
  }
  if (r.findings.empty()) {
    std::cout << "findings: none significant on the outer folds (alpha "
              << Fmt(o.alpha) << " as a fixed sequence, min gain "
              << Fmt(o.min_gain_pct) << " %)\n";
  } else {
    std::cout << "findings:\n";
    for (std::size_t i = 0; i < r.findings.size(); ++i) {
      const Finding& f = r.findings[i];
      std::cout << "  " << i + 1 << ". " << f.cause << " (" << f.kind << ", "
                << f.expansion << "): gain " << Fmt(f.cv_mae_gain_pct)
                << " %, p " << Fmt(f.p_value, 2) << ", selection bias "
                << Fmt(f.selection_bias_pct) << " %, chosen in "
                << f.folds_selected << "/" << r.folds << " outer folds\n     "
                << f.effect << "\n";
    }
  }
  std::cout << "extended " << r.extended.model << ": cv_mae "
            << Fmt(r.extended.cv_mae, 4) << ", gain " << Fmt(r.gain_pct)
            << " %, log-likelihood gain " << Fmt(r.log_likelihood_gain)
            << " nats/sample (outer folds; the selection saw "
            << Fmt(r.gain_pct + r.selection_bias_pct) << " %)\n";
  std::cout << "  terms:";
  for (const auto& t : r.extended.terms) std::cout << " " << t;
  std::cout << "\n";
}

/// Values of a cause on the fitted rows for a residual plot (the time since
/// slip onset for the onset regime).
std::vector<double> PlotAxis(const StrokeData& data,
                             const std::vector<std::size_t>& rows,
                             const std::string& cause,
                             const std::string& kind,
                             std::string* label) {
  std::vector<double> x;
  x.reserve(rows.size());
  if (kind == "regime") {
    const std::vector<double> s = CalcTimeSinceSlipOnset(data);
    for (std::size_t r : rows) x.push_back(s[r]);
    *label = "time since slip onset [s] (regime of " + cause + ")";
    return x;
  }
  const std::vector<double>* col = data.Column(cause);
  if (!col) return x;
  for (std::size_t r : rows) x.push_back((*col)[r]);
  *label = cause;
  return x;
}

std::string ResidualSvg(const std::vector<double>& x,
                        const std::vector<double>& r,
                        const std::string& label) {
  const double W = 640, H = 300, L = 60, R = 15, T = 15, B = 45;
  std::vector<double> xs, rs;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (std::isfinite(x[i]) && std::isfinite(r[i]))
      xs.push_back(x[i]), rs.push_back(r[i]);
  }
  if (xs.size() < 2) return "<p>(no data)</p>";
  std::vector<double> sx = xs, sr = rs;
  std::sort(sx.begin(), sx.end());
  std::sort(sr.begin(), sr.end());
  const double x0 = sx[sx.size() / 200],
               x1 = sx[sx.size() - 1 - sx.size() / 200];
  const double y0 = sr[sr.size() / 200],
               y1 = sr[sr.size() - 1 - sr.size() / 200];
  const double xr = x1 > x0 ? x1 - x0 : 1.0, yr = y1 > y0 ? y1 - y0 : 1.0;
  auto px = [&](double v) {
    return L + (W - L - R) * (std::clamp(v, x0, x1) - x0) / xr;
  };
  auto py = [&](double v) {
    return T + (H - T - B) * (1.0 - (std::clamp(v, y0, y1) - y0) / yr);
  };
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='"
    << H << "'>";
  s << "<rect x='" << L << "' y='" << T << "' width='" << W - L - R
    << "' height='" << H - T - B << "' fill='none' stroke='#888'/>";
  if (y0 < 0 && y1 > 0) {
    s << "<line x1='" << L << "' x2='" << W - R << "' y1='" << py(0) << "' y2='"
      << py(0) << "' stroke='#bbb'/>";
  }
  const std::size_t stride = std::max<std::size_t>(1, xs.size() / 1500);
  for (std::size_t i = 0; i < xs.size(); i += stride) {
    s << "<circle cx='" << px(xs[i]) << "' cy='" << py(rs[i])
      << "' r='1.5' fill='#4477aa' fill-opacity='0.35'/>";
  }
  // Binned means.
  const int bins = 20;
  std::vector<double> sum(bins, 0.0), cnt(bins, 0.0);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const int b =
        std::clamp(static_cast<int>((xs[i] - x0) / xr * bins), 0, bins - 1);
    sum[b] += rs[i];
    cnt[b] += 1;
  }
  s << "<polyline fill='none' stroke='#cc3311' stroke-width='2' points='";
  for (int b = 0; b < bins; ++b) {
    if (cnt[b] > 0)
      s << px(x0 + (b + 0.5) * xr / bins) << "," << py(sum[b] / cnt[b]) << " ";
  }
  s << "'/>";
  s << "<text x='" << (L + W - R) / 2 << "' y='" << H - 10
    << "' text-anchor='middle' font-size='12'>" << XmlEscape(label) << " ("
    << Fmt(x0) << " .. " << Fmt(x1) << ")</text>";
  s << "<text x='12' y='" << (T + H - B) / 2
    << "' font-size='12' transform='rotate(-90 12 " << (T + H - B) / 2
    << ")' text-anchor='middle'>held-out residual mu (" << Fmt(y0) << " .. "
    << Fmt(y1) << ")</text>";
  s << "</svg>";
  return s.str();
}

void WriteReport(const std::string& path,
                 const StrokeData& data,
                 const DiagnosisResult& r,
                 const DiagnosisOptions& o,
                 const std::vector<std::string>& files) {
  std::ostringstream h;
  h << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>friction "
       "diagnose</title>"
    << "<style>body{font-family:sans-serif;max-width:900px;margin:2em "
       "auto}table{border-collapse:collapse}"
    << "td,th{border:1px solid #ccc;padding:3px "
       "8px;text-align:right}</style></head><body>";
  h << "<h1>Model diagnosis</h1><p>Files:";
  for (const auto& f : files) h << " <code>" << XmlEscape(f) << "</code>";
  h << "</p><p>Status: " << ToString(r.status) << " " << XmlEscape(r.why)
    << ". " << r.samples << " samples, " << r.fit_samples << " slipping, "
    << r.strokes << " strokes, " << r.folds << " stroke folds; slip thresholds "
    << Fmt(o.labelling.peak_mm_s) << " / " << Fmt(o.labelling.floor_mm_s)
    << " mm/s.</p>";
  h << "<h2>Replay (held-out strokes)</h2><table><tr><th>model</th><th>mu "
       "MAE</th><th>hits</th><th>misses</th>"
    << "<th>false alarms</th><th>Brier</th><th>break-away "
       "|err|</th><th>bias</th></tr>";
  for (const ModelReplay& m : r.replay) {
    const ReplayErrors& e = m.overall;
    auto count = [&m](int c) {
      return m.predicts_slip ? std::to_string(c) : std::string("-");
    };
    h << "<tr><td>" << m.model << "</td><td>" << Fmt(e.mu_mae, 4) << "</td><td>"
      << count(e.hits) << "</td><td>" << count(e.misses) << "</td><td>"
      << count(e.false_alarms) << "</td><td>" << Fmt(e.brier, 4) << "</td><td>"
      << Fmt(e.breakaway_abs_error, 4) << "</td><td>"
      << Fmt(e.breakaway_bias, 4) << "</td></tr>";
  }
  h << "</table><h2>Findings</h2>";
  if (r.findings.empty()) h << "<p>Nothing significant.</p>";
  h << "<ol>";
  for (const Finding& f : r.findings) {
    h << "<li><b>" << XmlEscape(f.cause) << "</b> (" << f.kind << ", "
      << XmlEscape(f.expansion) << "): held-out gain " << Fmt(f.cv_mae_gain_pct)
      << " %, p = " << Fmt(f.p_value, 2) << ". " << XmlEscape(f.effect)
      << "</li>";
  }
  h << "</ol><p>Baseline cv_mae " << Fmt(r.baseline.cv_mae, 4)
    << "; extended <code>" << XmlEscape(r.extended.model) << "</code> cv_mae "
    << Fmt(r.extended.cv_mae, 4) << " (gain " << Fmt(r.gain_pct) << " %).</p>";
  // Top candidates: findings first, then the best step-0 tests.
  std::vector<std::pair<std::string, std::string>> top;
  std::set<std::string> seen;
  for (const Finding& f : r.findings) {
    if (seen.insert(f.cause + "/" + f.kind).second)
      top.push_back({f.cause, f.kind});
  }
  std::vector<CandidateTest> step0;
  for (const CandidateTest& t : r.tests) {
    if (t.step == 0) step0.push_back(t);
  }
  std::sort(step0.begin(), step0.end(), [](const auto& a, const auto& b) {
    return a.gain_pct > b.gain_pct;
  });
  for (const CandidateTest& t : step0) {
    if (top.size() >= 4) break;
    // Only causes with an axis to plot against (a product column x*y is
    // computed inside Diagnose, not in this copy of the data).
    if (t.kind != "regime" && !data.Column(t.cause)) continue;
    if (seen.insert(t.cause + "/" + t.kind).second)
      top.push_back({t.cause, t.kind});
  }
  h << "<h2>Baseline held-out residuals against the top candidates</h2>";
  for (const auto& [cause, kind] : top) {
    std::string label;
    const std::vector<double> x =
        PlotAxis(data, r.fit_rows, cause, kind, &label);
    if (x.empty()) continue;
    h << "<h3>" << XmlEscape(cause) << " (" << kind << ")</h3>"
      << ResidualSvg(x, r.baseline_residuals, label);
  }
  h << "</body></html>\n";
  std::ofstream out(path, std::ios::binary);
  out << h.str();
  if (!out) {
    std::cerr << "friction: " << path << ": cannot write the report\n";
    throw CLI::RuntimeError(2);
  }
}

void RunDiagnose(const DiagnoseArgs& a, const Globals& g) {
  std::vector<StrokeData> files;
  bool any_slip_column = false;
  for (const std::string& path : a.files) {
    files.push_back(ReadStrokeCsvFile(path));
    any_slip_column = any_slip_column || !files.back().slip.empty();
  }
  DiagnosisOptions options;
  options.folds = a.folds;
  options.inner_folds = a.inner_folds;
  options.shuffle_folds = a.shuffle_folds;
  options.seed = a.seed;
  options.alpha = a.alpha;
  options.min_gain_pct = a.min_gain_pct;
  options.max_findings = a.max_findings;
  if (!a.lugre.empty()) {
    if (a.lugre.size() != 6) {
      std::cerr << "friction: diagnose: --lugre has " << a.lugre.size()
                << " values (must be 6: mu_s,mu_c,v0,sigma2,sigma0,sigma1)\n";
      throw CLI::RuntimeError(2);
    }
    options.lugre = MakeLuGreTheta(
        a.lugre[0], a.lugre[1], a.lugre[2], a.lugre[3], a.lugre[4], a.lugre[5]);
  }
  if (!a.lugre_from.empty()) {
    if (!a.lugre.empty()) {
      std::cerr << "friction: diagnose: give --lugre or --lugre-from, not "
                   "both\n";
      throw CLI::RuntimeError(2);
    }
    // The LuGre model the daemon identified for that material (paper 001).
    RunCommand([&] {
      const ModelSet set = MakeClient(g).FetchModel(a.lugre_from);
      if (!set.other.contains(kLuGreFamilyKey)) {
        throw std::invalid_argument(
            "--lugre-from " + a.lugre_from + ": model version " +
            std::to_string(set.version) +
            " has no LuGre family (upload a quasi-static and a dynamic "
            "stroke first)");
      }
      options.lugre = LuGreFromJson(set.other.at(kLuGreFamilyKey)).theta;
    });
  }
  std::string rule;
  const bool peak_given = a.slip_peak_mm_s > 0,
             floor_given = a.slip_floor_mm_s > 0;
  if (peak_given || floor_given) {
    options.labelling.peak_mm_s =
        peak_given ? a.slip_peak_mm_s : 2.0 * a.slip_floor_mm_s;
    options.labelling.floor_mm_s =
        floor_given ? a.slip_floor_mm_s : 0.5 * a.slip_peak_mm_s;
    rule = "given on the command line";
  } else if (!any_slip_column) {
    std::vector<double> v;
    for (const StrokeData& d : files)
      v.insert(v.end(), d.v_mm_s.begin(), d.v_mm_s.end());
    options.labelling = CalcAutoSlipLabelOptions(v, options.labelling, &rule);
  } else {
    rule = "paper 000 thresholds (files carry a slip column where given)";
  }
  std::string why;
  if (!options.IsValid(&why)) {
    std::cerr << "friction: diagnose: " << why << "\n";
    throw CLI::RuntimeError(2);
  }
  StrokeData data;
  for (std::size_t i = 0; i < files.size(); ++i) {
    StrokeData prepared =
        PrepareDiagnosisData(std::move(files[i]), options.labelling);
    if (i == 0) {
      data = std::move(prepared);
    } else {
      data.Append(prepared);
    }
  }
  const DiagnosisResult r = Diagnose(data, options);
  if (a.json) {
    DiagnosisJsonOptions jo;
    jo.replay_strokes = !a.no_strokes;
    jo.tests = !a.no_tests;
    std::cout << DiagnosisToJson(r, options, rule, jo).dump(1) << "\n";
  } else {
    PrintSummary(r, options, rule);
  }
  if (!a.report.empty()) WriteReport(a.report, data, r, options, a.files);
  if (r.status != DiagnosisStatus::kOk) {
    std::cerr << "friction: diagnose: " << ToString(r.status) << ": " << r.why
              << "\n";
    throw CLI::RuntimeError(1);
  }
}

}  // namespace

void RegisterDiagnoseCommand(CLI::App& app, Globals& g) {
  auto args = std::make_shared<DiagnoseArgs>();
  CLI::App* cmd =
      app.add_subcommand("diagnose",
                         "Replay strokes through Coulomb and the linear model "
                         "(and LuGre with --lugre or --lugre-from), "
                         "find significant causes of the remaining error "
                         "(columns, derived features, functional form), extend "
                         "the model and report held-out gains");
  cmd->add_option(
         "files",
         args->files,
         "stroke CSV files (each parsed separately; stroke ids kept distinct)")
      ->required();
  cmd->add_flag("--json",
                args->json,
                "print one JSON object (CONTRACT.md, Model diagnosis)");
  cmd->add_option("--report",
                  args->report,
                  "write an HTML report with residual plots to this file");
  cmd->add_option("--slip-peak-mm-s",
                  args->slip_peak_mm_s,
                  "episode peak speed for slip [mm/s] (default: 10, or 0.25 x "
                  "the 99th percentile speed when "
                  "that is below 10 and no file has a slip column)");
  cmd->add_option("--slip-floor-mm-s",
                  args->slip_floor_mm_s,
                  "speed above which samples around the peak are slip [mm/s] "
                  "(default: 5, or 0.08 x the 99th "
                  "percentile speed, as above)");
  cmd->add_option("--folds",
                  args->folds,
                  "outer cross-validation folds (reported figures), "
                  "assigned by stroke")
      ->capture_default_str();
  cmd->add_option("--inner-folds",
                  args->inner_folds,
                  "inner folds of the selection on each outer training part")
      ->capture_default_str();
  cmd->add_flag("--shuffle-folds",
                args->shuffle_folds,
                "shuffle strokes into folds (default: contiguous blocks of "
                "strokes in recording order)");
  cmd->add_option(
         "--seed", args->seed, "seed of the shuffled stroke-to-fold assignment")
      ->capture_default_str();
  cmd->add_option("--alpha",
                  args->alpha,
                  "error rate of the outer tests (the findings as a fixed "
                  "sequence; Holm over the spread candidates)")
      ->capture_default_str();
  cmd->add_option("--min-gain-pct",
                  args->min_gain_pct,
                  "smallest held-out MAE gain that counts [% of baseline]")
      ->capture_default_str();
  cmd->add_option(
         "--max-findings", args->max_findings, "at most this many findings")
      ->capture_default_str();
  cmd->add_flag("--no-stroke-rows",
                args->no_strokes,
                "JSON: leave out per-stroke replay rows");
  cmd->add_flag("--no-tests",
                args->no_tests,
                "JSON: leave out the list of all candidate tests");
  cmd->add_option("--lugre",
                  args->lugre,
                  "also replay LuGre (paper 001) with these parameters: "
                  "mu_s,mu_c,v0[mm/s],sigma2[s/mm],sigma0[1/mm],sigma1[s/mm] "
                  "(e.g. from friction show ID --json)")
      ->delimiter(',');
  cmd->add_option("--lugre-from",
                  args->lugre_from,
                  "also replay the LuGre model the daemon identified for this "
                  "material (fetched from --server)");
  cmd->callback([args, &g]() { RunDiagnose(*args, g); });
}

}  // namespace frictiond::cli
