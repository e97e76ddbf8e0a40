// lugre: LuGre identification and break-away prediction (paper 001), each
// beside a SciPy implementation of the same problem run in the same process
// tree by /usr/bin/python3 (bench/ref/lugre_ref.py).
//
// - lugre_identify [ms]: full six-parameter two-step identification of a
//   two-stroke dataset (Step 1 FitLuGreQuasiStatic on a 0-20-0 mm/s ramp at
//   2 mm/s^2, 20 s at 200 Hz; Step 2 FitLuGreDynamic LM-2 on a 0-10-0 mm/s
//   stroke at 20 mm/s^2, 1 s), simulated from known truth with noise 0.005
//   on mu. Baseline: scipy.optimize.least_squares (trf) on the same data
//   (written to a temporary CSV), the same residuals, starts and bounds.
//   Median wall time of each.
// - breakaway_predict [us]: one PredictBreakawayRatio (force-driven ODE from
//   rest until v > 2 v0, paper 001 eqs. 16-20), mean over drag-ratio rates
//   0.05-2 /s. Baseline: scipy.integrate.solve_ivp (LSODA, analytic
//   Jacobian, same tolerances) of the same ODE with a terminal event.
//
// Also (note of lugre_identify): the time the service's "lugre" family
// fitter takes inside FrictionLibrary::IngestStrokes of the same two strokes
// (stroke recognition, three Step-1 starts, Step 2).
//
// Usage: lugre [--python PATH] (default /usr/bin/python3; the script is
// found through $FRICTIOND_SOURCE_DIR or the source tree of the build).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <unistd.h>

#include "frictiond/estimators/breakaway.h"
#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/lugre_identification.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/routes.h"
#include "frictiond/storage/store.h"

#include "bench_json.h"
#include "python_ref.h"

#ifndef FRICTIOND_SOURCE_DIR
#define FRICTIOND_SOURCE_DIR "."
#endif

namespace frictiond::bench {
namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

LuGreTheta Truth() { return MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1); }

LuGreStroke Simulate(const std::function<double(double)>& v_of_t,
                     double duration_s,
                     unsigned seed) {
  const double fs = 200.0;
  const int n = static_cast<int>(std::round(duration_s * fs)) + 1;
  LuGreStroke s;
  s.t_s.resize(n);
  s.v_mm_s.resize(n);
  for (int k = 0; k < n; ++k) {
    s.t_s[k] = k / fs;
    s.v_mm_s[k] = v_of_t(s.t_s[k]);
  }
  const VelocityDrivenResult r =
      SimulateVelocityDriven(Truth(), s.t_s, s.v_mm_s, 0.0);
  if (r.status != SimulationStatus::kOk)
    throw std::runtime_error("simulation: " + r.why);
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 0.005);
  s.mu = r.mu;
  for (int k = 0; k < n; ++k) s.mu[k] += gauss(rng);
  return s;
}

double SlowRamp(double t) { return t < 10 ? 2.0 * t : 40.0 - 2.0 * t; }
double FastRamp(double t) { return t < 0.5 ? 20.0 * t : 20.0 - 20.0 * t; }

std::string Num(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

std::string Short(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", x);
  return buf;
}

// The two strokes as one stroke CSV (Ft = |mu| Fn, v as magnitude, 10 s
// apart) for the service measurement.
std::string ServiceCsv(const LuGreStroke& slow, const LuGreStroke& fast) {
  StrokeData d;
  auto add = [&d](const LuGreStroke& s, double t0) {
    for (Eigen::Index k = 0; k < s.size(); ++k) {
      d.t_s.push_back(t0 + s.t_s[k]);
      d.fn_n.push_back(5.0);
      d.ft_n.push_back(5.0 * std::abs(s.mu[k]));
      d.v_mm_s.push_back(std::abs(s.v_mm_s[k]));
    }
  };
  add(slow, 0.0);
  add(fast, 30.0);
  return FormatStrokeCsv(d);
}

// Median ms the "lugre" family fitter takes inside IngestStrokes of `csv`:
// fitters run in registration order, so two no-op fitters registered before
// and after RegisterLuGreFeature bracket it.
double FamilyFitterMs(const std::string& csv, int repeats) {
  FrictionLibrary lib(OpenStore(":memory:"));
  HttpServer http;
  Clock::time_point t0;
  std::vector<double> ms;
  lib.AddFamilyFitter("bench_t0",
                      [&t0](const StrokeData&,
                            const StrokeData&,
                            const CachedModel*,
                            std::string*) -> json {
                        t0 = Clock::now();
                        return nullptr;
                      });
  RegisterLuGreFeature(http, lib);
  lib.AddFamilyFitter("bench_t1",
                      [&t0, &ms](const StrokeData&,
                                 const StrokeData&,
                                 const CachedModel*,
                                 std::string*) -> json {
                        ms.push_back(MsSince(t0));
                        return nullptr;
                      });
  for (int r = 0; r < repeats; ++r) {
    const IngestResult res =
        lib.IngestStrokes("m" + std::to_string(r), csv, IngestOptions{});
    if (!res.model->set.other.contains("lugre"))
      throw std::runtime_error("service did not identify lugre: " +
                               res.fit_note);
  }
  return Median(ms);
}

int Main(int argc, char** argv) {
  const auto ref = ParsePythonReference(
      argc, argv, "lugre", "lugre_ref.py", FRICTIOND_SOURCE_DIR);
  if (!ref) return 2;
  const std::string& python = ref->python;
  const std::string& script = ref->script;

  // ---------------------------------------------------------- identification
  const LuGreStroke slow = Simulate(SlowRamp, 20.0, 7);
  const LuGreStroke fast = Simulate(FastRamp, 1.0, 107);
  const Eigen::Vector4d start(0.3, 0.2, 1.0, 0.0);
  auto identify = [&]() {
    const LuGreFitResult qs = FitLuGreQuasiStatic(slow, start);
    LuGreTheta guess = qs.theta;
    guess[LuGreIndex::kStiffness] = 10.0;
    guess[LuGreIndex::kDamping] = 0.01;
    return FitLuGreDynamic(fast, guess, 0.0);
  };
  LuGreFitResult fit = identify();  // warm-up
  std::vector<double> ms;
  for (int r = 0; r < 31; ++r) {
    const auto t0 = Clock::now();
    fit = identify();
    ms.push_back(MsSince(t0));
  }
  const double cpp_ms = Median(ms);
  if (fit.status != LuGreFitStatus::kConverged)
    std::cerr << "lugre: dynamic fit " << ToString(fit.status) << ": "
              << fit.why << "\n";

  // Same data for SciPy.
  char path[] = "/tmp/frictiond_lugre_bench_XXXXXX";
  const int fd = mkstemp(path);
  if (fd < 0) throw std::runtime_error("mkstemp failed");
  close(fd);
  {
    std::ofstream out(path);
    out << "stroke,t_s,v_mm_s,mu\n";
    const LuGreStroke* strokes[2] = {&slow, &fast};
    for (int s = 0; s < 2; ++s) {
      for (Eigen::Index k = 0; k < strokes[s]->size(); ++k) {
        out << s << "," << Num(strokes[s]->t_s[k]) << ","
            << Num(strokes[s]->v_mm_s[k]) << "," << Num(strokes[s]->mu[k])
            << "\n";
      }
    }
  }
  double py_ms = std::nan("");
  std::string id_note;
  try {
    const json py = json::parse(RunCommand(
        python + " " + script + " identify " + path + " --repeats 3"));
    py_ms = py.at("ms").get<double>();
    const std::vector<double> th = py.at("theta").get<std::vector<double>>();
    double max_rel = 0;
    for (int i = 0; i < 6; ++i)
      max_rel =
          std::max(max_rel, std::abs(th[i] - fit.theta[i]) / std::abs(th[i]));
    id_note = "scipy theta within " + Short(100 * max_rel) +
              " % of ours (sigma0 " + Short(th[4]) + " vs " +
              Short(fit.theta[4]) + ")";
  } catch (const std::exception& e) {
    id_note = std::string("scipy baseline failed: ") + e.what();
  }
  std::remove(path);
  // The service path: the extra time of the lugre family fitter per upload.
  const std::string csv = ServiceCsv(slow, fast);
  const double service_ms = FamilyFitterMs(ServiceCsv(slow, fast), 11);
  id_note += "; " + std::to_string(slow.size()) + " + " +
             std::to_string(fast.size()) +
             " samples; the service's lugre family fitter (stroke "
             "recognition, 3 Step-1 starts, Step 2) takes " +
             Short(service_ms) + " ms per upload of the same data";

  BenchResult id;
  id.bench = "lugre_identify";
  id.value = cpp_ms;
  id.unit = "ms";
  id.baseline = py_ms;
  id.baseline_name =
      "scipy.optimize.least_squares (trf), same residuals, data and starts";
  id.lower_is_better = true;
  id.goal = "<= 50 ms";
  id.note = id_note;
  PrintBenchLine(id);

  // --------------------------------------------------------------- break-away
  const LuGreTheta truth = Truth();
  std::vector<double> rates(200);
  for (int i = 0; i < 200; ++i)
    rates[i] = 0.05 * std::pow(2.0 / 0.05, i / 199.0);
  double best_us = 1e300;
  std::vector<double> bf(rates.size());
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = Clock::now();
    for (std::size_t i = 0; i < rates.size(); ++i)
      bf[i] = PredictBreakawayRatio(truth, rates[i], 5.0).bf_ratio;
    best_us = std::min(best_us, 1e3 * MsSince(t0) / rates.size());
  }
  // SciPy on every 10th rate (it is slower).
  std::string rate_list, theta_list;
  std::vector<double> sub;
  for (std::size_t i = 0; i < rates.size(); i += 10) {
    rate_list += (rate_list.empty() ? "" : ",") + Num(rates[i]);
    sub.push_back(bf[i]);
  }
  for (int i = 0; i < 6; ++i) theta_list += (i ? "," : "") + Num(truth[i]);
  double py_us = std::nan("");
  std::string bf_note;
  try {
    const json py = json::parse(
        RunCommand(python + " " + script + " breakaway --theta " + theta_list +
                   " --fn-n 5 --mass-kg 0.2 --rates " + rate_list));
    py_us = py.at("us").get<double>();
    const std::vector<double> pbf = py.at("bf").get<std::vector<double>>();
    double max_diff = 0;
    for (std::size_t i = 0; i < sub.size() && i < pbf.size(); ++i)
      max_diff = std::max(max_diff, std::abs(pbf[i] - sub[i]));
    bf_note = "BF-ratio agrees with scipy to " + Short(max_diff) + " over " +
              std::to_string(sub.size()) + " rates";
  } catch (const std::exception& e) {
    bf_note = std::string("scipy baseline failed: ") + e.what();
  }
  BenchResult br;
  br.bench = "breakaway_predict";
  br.value = best_us;
  br.unit = "us";
  br.baseline = py_us;
  br.baseline_name =
      "scipy.integrate.solve_ivp (LSODA), same ODE and tolerances";
  br.lower_is_better = true;
  br.goal = "<= 50 us";
  br.note = bf_note + "; mean over 200 rates 0.05-2 /s, Fn 5 N, m 0.2 kg";
  PrintBenchLine(br);
  return 0;
}

}  // namespace
}  // namespace frictiond::bench

int main(int argc, char** argv) {
  try {
    return frictiond::bench::Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "lugre: " << e.what() << "\n";
    return 1;
  }
}
