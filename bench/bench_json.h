#pragma once
/// @file
/// One benchmark result as the JSON line CONTRACT.md ("Benchmarks") asks for:
/// {"bench", "value", "unit", "baseline", "baseline_name", "ratio", "goal"}
/// (plus an optional "note"). Every program in bench/ prints its results
/// with PrintBenchLine; bench/run selects lines by their "bench" name.

#include <cmath>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

namespace frictiond::bench {

/// A measured figure and the baseline measured in the same run.
struct BenchResult {
  std::string bench;          ///< name, as listed in bench/run
  double value = 0.0;         ///< this project's figure, in `unit`
  std::string unit;           ///< "req/s", "ms", "samples/s", ...
  double baseline = 0.0;      ///< reference figure, in `unit`
  std::string baseline_name;  ///< what the baseline is (a floor or a peer)
  /// True for times (ratio = baseline / value), false for rates
  /// (ratio = value / baseline); > 1 always means better than the baseline.
  bool lower_is_better = false;
  std::string goal;  ///< e.g. ">= 15000 req/s"
  std::string note;  ///< how it was measured (omitted when empty)
};

/// Rounds to `digits` significant digits (keeps the lines readable).
inline double RoundSignificant(double x, int digits = 4) {
  if (!std::isfinite(x) || x == 0.0) return x;
  const double scale = std::pow(
      10.0,
      digits - 1 - static_cast<int>(std::floor(std::log10(std::fabs(x)))));
  return std::round(x * scale) / scale;
}

/// value/baseline for rates, baseline/value for times; NaN when undefined.
inline double CalcRatio(const BenchResult& r) {
  const double num = r.lower_is_better ? r.baseline : r.value;
  const double den = r.lower_is_better ? r.value : r.baseline;
  return den > 0 ? num / den : std::nan("");
}

/// The result as one JSON line, keys in the contract's order, formatted
/// like CONTRACT.md's example ({"bench": "http_lookup", "value": ...}).
inline std::string FormatBenchLine(const BenchResult& r) {
  auto num = [](double x, int digits) {
    return std::isfinite(x) ? nlohmann::json(RoundSignificant(x, digits)).dump()
                            : std::string("null");
  };
  auto str = [](const std::string& s) { return nlohmann::json(s).dump(); };
  std::string line =
      "{\"bench\": " + str(r.bench) + ", \"value\": " + num(r.value, 4) +
      ", \"unit\": " + str(r.unit) + ", \"baseline\": " + num(r.baseline, 4) +
      ", \"baseline_name\": " + str(r.baseline_name) +
      ", \"ratio\": " + num(CalcRatio(r), 3) + ", \"goal\": " + str(r.goal);
  if (!r.note.empty()) line += ", \"note\": " + str(r.note);
  return line + "}";
}

/// Prints the line to stdout and flushes (diagnostics go to stderr).
inline void PrintBenchLine(const BenchResult& r) {
  std::printf("%s\n", FormatBenchLine(r).c_str());
  std::fflush(stdout);
}

/// A line for a benchmark that could not run: the contract's keys with null
/// figures, and "error" saying why.
inline std::string FormatBenchError(const std::string& bench,
                                    const std::string& error,
                                    const std::string& goal = "") {
  return "{\"bench\": " + nlohmann::json(bench).dump() +
         ", \"value\": null, \"unit\": null, \"baseline\": null, "
         "\"baseline_name\": null, \"ratio\": null, \"goal\": " +
         nlohmann::json(goal).dump() +
         ", \"error\": " + nlohmann::json(error).dump() + "}";
}

}  // namespace frictiond::bench
