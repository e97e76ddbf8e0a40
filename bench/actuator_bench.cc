// Actuator benchmarks (issue 20 item 7) beside a NumPy reference of the same
// closed-loop rollout run by /usr/bin/python3 (bench/ref/actuator_ref.py):
//
//   actuator_simulate  us per closed-loop rollout of one 6 s log (1200 steps,
//                      kp 400 sin_sin) with BAM's published M1 parameters;
//                      baseline: the same rollout in NumPy (step loop).
//   actuator_fit       s for the full identification (`--law auto`) of the
//                      12 bundled logs; baseline: the NumPy rollout time times
//                      the rollouts this fit used (a projection: a NumPy
//                      identification doing the same rollouts).
//
// Usage: actuator [--python PATH] (default /usr/bin/python3).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/actuator_sim.h"
#include "frictiond/proto/actuator_json.h"
#include "frictiond/proto/actuator_report.h"

#include "bench_json.h"
#include "python_ref.h"

namespace frictiond {
namespace {

using Clock = std::chrono::steady_clock;

std::string Read(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read " + path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

double Median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  return x[x.size() / 2];
}

int Main(int argc, char** argv) {
  const auto ref = bench::ParsePythonReference(
      argc, argv, "actuator", "actuator_ref.py", FRICTIOND_SOURCE_DIR);
  if (!ref) return 2;
  const char* env_root = std::getenv("FRICTIOND_SOURCE_DIR");
  const std::string root =
      (env_root ? std::string(env_root) : std::string(FRICTIOND_SOURCE_DIR)) +
      "/data/bam_xl330";
  const std::string log_path = root + "/logs/xl330_kp400_sin_sin.json";
  const std::string m1_path = root + "/published_params/m1.json";
  const ActuatorLog log = ParseActuatorLog(Read(log_path), "kp400_sin_sin");
  const ActuatorModel m1 = ParseBamParams(Read(m1_path));

  // ------------------------------------------------------ actuator_simulate
  double mae = 0;
  std::vector<double> us;
  for (int rep = 0; rep < 15; ++rep) {
    const auto t0 = Clock::now();
    constexpr int kInner = 50;
    for (int i = 0; i < kInner; ++i) mae = SimulateActuatorLog(m1, log);
    us.push_back(
        std::chrono::duration<double, std::micro>(Clock::now() - t0).count() /
        kInner);
  }
  const nlohmann::json py = nlohmann::json::parse(
      bench::RunCommand(ref->python + " " + ref->script + " rollout --log " +
                        log_path + " --params " + m1_path + " --reps 5"));
  const double py_us = py.at("ms").get<double>() * 1e3;
  bench::BenchResult sim;
  sim.bench = "actuator_simulate";
  sim.value = Median(us);
  sim.unit = "us";
  sim.baseline = py_us;
  sim.baseline_name = "NumPy, same closed-loop rollout (step loop)";
  sim.lower_is_better = true;
  sim.goal = ">= 50x faster than NumPy";
  char note[240];
  std::snprintf(note,
                sizeof note,
                "1200 steps, BAM M1 parameters; mae %.9g rad, reference %.9g",
                mae,
                py.at("mae_rad").get<double>());
  sim.note = note;
  if (!(std::abs(mae - py.at("mae_rad").get<double>()) <= 1e-9))
    sim.note += " MISMATCH";
  bench::PrintBenchLine(sim);

  // ----------------------------------------------------------- actuator_fit
  std::vector<ActuatorLog> logs;
  for (const char* kp : {"100", "200", "400", "800"})
    for (const char* shape : {"lift_and_drop", "sin_sin", "sin_time_square"})
      logs.push_back(ParseActuatorLog(
          Read(root + "/logs/xl330_kp" + kp + "_" + shape + ".json"),
          std::string("kp") + kp + "_" + shape));
  const auto t0 = Clock::now();
  const ActuatorFitResult fit = FitActuatorLaw(logs, kAutoActuatorLaw);
  const double fit_s = std::chrono::duration<double>(Clock::now() - t0).count();
  // Rollouts of one log: set evaluations x 12 (plus the staged CV fit,
  // not counted: the projection is a lower bound for NumPy).
  const double rollouts = static_cast<double>(fit.evaluations) * logs.size();
  bench::BenchResult fr;
  fr.bench = "actuator_fit";
  fr.value = fit_s;
  fr.unit = "s";
  fr.baseline = rollouts * py_us * 1e-6;
  fr.baseline_name =
      "NumPy rollout time x the rollouts this fit used (projection)";
  fr.lower_is_better = true;
  fr.goal = "report (rollout goal >= 50x faster than NumPy)";
  std::snprintf(note,
                sizeof note,
                "12 logs, law %s, %.0f log rollouts, in-sample mae %.5g rad",
                ActuatorFrictionLawName(fit.model.law).c_str(),
                rollouts,
                fit.mae_rad);
  fr.note = note;
  bench::PrintBenchLine(fr);
  return 0;
}

}  // namespace
}  // namespace frictiond

int main(int argc, char** argv) {
  try {
    return frictiond::Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "actuator: " << e.what() << "\n";
    return 1;
  }
}
