// ingest: parse + validate + label + fit + store of a 1,000,000-sample stroke
// CSV through FrictionLibrary::IngestStrokes, in-process on a temporary
// SQLite file (the HTTP body limit, 16 MiB by default, is below the size of
// such a CSV, so it is not sent over HTTP). Baseline: parsing the same text
// only (ParseStrokeCsv), the floor any ingest path pays.
//
// Usage: ingest [--samples N] [--repeats R]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/library.h"
#include "frictiond/storage/store.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

#include "bench_json.h"

namespace frictiond::bench {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// `samples` simulated samples (paper 000 eq. (1) truth) as a stroke CSV with
/// the precision a force/speed logger writes (0.1 ms, 6 significant digits).
std::string MakeCsv(std::size_t samples) {
  testing::SimulationSpec spec;
  spec.rate_hz = 1000.0;  // 1 s per stroke: 1000 samples
  spec.strokes = static_cast<int>(samples / 1000 + 1);
  const StrokeData d = testing::SimulateStrokes(spec, /*seed=*/42);
  if (d.size() < samples)
    throw std::runtime_error("simulator gave too few samples");
  std::string csv = "t_s,fn_n,ft_n,v_mm_s\n";
  csv.reserve(samples * 36);
  char row[128];
  for (std::size_t i = 0; i < samples; ++i) {
    const int n = std::snprintf(row,
                                sizeof row,
                                "%.4f,%.6g,%.6g,%.6g\n",
                                d.t_s[i],
                                d.fn_n[i],
                                d.ft_n[i],
                                d.v_mm_s[i]);
    csv.append(row, static_cast<std::size_t>(n));
  }
  return csv;
}

int Main(int argc, char** argv) {
  std::size_t samples = 1'000'000;
  int repeats = 3;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--samples")
      samples = static_cast<std::size_t>(std::atof(argv[i + 1]));
    else if (flag == "--repeats")
      repeats = std::atoi(argv[i + 1]);
    else
      throw std::invalid_argument("unknown flag " + flag);
  }
  if (!(samples >= 1000 && samples <= 5'000'000))
    throw std::invalid_argument("--samples must be in 1000..5e6");
  if (!(repeats >= 1 && repeats <= 9))
    throw std::invalid_argument("--repeats must be in 1..9");

  auto t0 = Clock::now();
  const std::string csv = MakeCsv(samples);
  std::cerr << "ingest: CSV of " << samples << " samples, " << csv.size() / 1e6
            << " MB, generated in " << SecondsSince(t0) << " s\n";

  // Baseline: parse only.
  std::vector<double> parse_s;
  for (int r = 0; r < repeats; ++r) {
    t0 = Clock::now();
    const StrokeData d = ParseStrokeCsv(csv);
    parse_s.push_back(SecondsSince(t0));
    if (d.size() != samples) throw std::runtime_error("parse lost samples");
  }

  // Ingest: one fresh material per repeat, so each refit sees one upload.
  testing::TempDir dir("bench_ingest");
  FrictionLibrary library(OpenStore(dir.path() + "/library.db"));
  std::vector<double> ingest_s;
  {
    // Warm-up (untimed in the result): the first ingest of a process also
    // pays for fresh heap pages and for growing the new database and WAL
    // files; a running daemon has paid that already.
    t0 = Clock::now();
    library.IngestStrokes("bench-ingest-warmup", csv, IngestOptions{});
    std::cerr << "ingest: warm-up (first ingest of the process): "
              << SecondsSince(t0) << " s\n";
  }
  for (int r = 0; r < repeats; ++r) {
    IngestOptions options;
    options.robot = "bench";
    t0 = Clock::now();
    const IngestResult result = library.IngestStrokes(
        "bench-ingest-" + std::to_string(r), csv, options);
    ingest_s.push_back(SecondsSince(t0));
    if (result.samples != samples || result.version != 1)
      throw std::runtime_error("ingest stored an unexpected result");
    std::cerr << "ingest: repeat " << r << ": " << ingest_s.back()
              << " s (parse only " << parse_s[static_cast<std::size_t>(r)]
              << " s), fit " << result.fit_status << "\n";
  }

  // Where the time goes (stderr only): the stages IngestStrokes runs.
  {
    t0 = Clock::now();
    StrokeData d = ParseStrokeCsv(csv);
    const double parse = SecondsSince(t0);
    t0 = Clock::now();
    EnsureLabels(&d, SlipLabelOptions{});
    AddDerivedFeatures(&d, SlipLabelOptions{});
    const double label = SecondsSince(t0);
    t0 = Clock::now();
    const StochasticFit fit = FitStochasticModel(d, StochasticFitOptions{});
    const double fit_s = SecondsSince(t0);
    StrokeRecord stroke;
    stroke.material = "bench-raw";
    stroke.samples = static_cast<std::int64_t>(samples);
    stroke.csv = csv;
    ModelRecord model;
    model.material = "bench-raw";
    model.reason = "bench";
    model.json = "{}";
    t0 = Clock::now();
    library.store().CommitUpload(stroke, model);
    const double store_s = SecondsSince(t0);
    std::cerr << "ingest: stages: parse " << parse << " s, label+features "
              << label << " s, fit " << fit_s << " s (" << ToString(fit.status)
              << "), sqlite commit " << store_s << " s\n";
  }

  BenchResult out;
  out.bench = "ingest";
  out.value = static_cast<double>(samples) / Median(ingest_s);
  out.unit = "samples/s";
  out.baseline = static_cast<double>(samples) / Median(parse_s);
  out.baseline_name = "csv parse only (ParseStrokeCsv, same text)";
  out.goal = ">= 1e6 samples/s";
  out.note =
      "in-process FrictionLibrary::IngestStrokes (parse, validate, label, fit, "
      "SQLite commit, synchronous=FULL) of a " +
      std::to_string(samples) + "-sample CSV (" +
      std::to_string(csv.size() >> 20) +
      " MiB, above the 16 MiB HTTP body limit), median of " +
      std::to_string(repeats) + " after one untimed warm-up ingest";
  PrintBenchLine(out);
  return 0;
}

}  // namespace
}  // namespace frictiond::bench

int main(int argc, char** argv) {
  try {
    return frictiond::bench::Main(argc, argv);
  } catch (const std::exception& e) {
    std::printf("%s\n",
                frictiond::bench::FormatBenchError(
                    "ingest", e.what(), ">= 1e6 samples/s")
                    .c_str());
    return 1;
  }
}
