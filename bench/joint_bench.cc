// Joint friction benchmarks (issue 9 item 7) beside a NumPy/SciPy reference
// of the same computation run in the same process tree by /usr/bin/python3
// (bench/ref/joint_ref.py):
//
//   mixed_friction_eval  ns per evaluation of the mixed-lubrication friction
//                        at a joint state (Vogel eta(T), S = eta V / p, film
//                        d(S), alpha the Hertz load fraction of paper 002
//                        eqs. 6-7, eq. 1), one state at a time; baseline:
//                        NumPy vectorised over 1e5 states.
//   ellipsoid_grid       ms for repeatability ellipsoids over a 50 x 50 grid
//                        of a 400 x 400 mm plane (IK + Jacobian + eigen per
//                        point) for a 3R arm; baseline: the same algorithm in
//                        NumPy.
//
// Usage: joint [--python PATH] (default /usr/bin/python3).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/joint_friction.h"
#include "frictiond/estimators/repeatability.h"

#include "bench_json.h"
#include "python_ref.h"

namespace frictiond {
namespace {

using bench::RunCommand;

using Clock = std::chrono::steady_clock;
constexpr double kPi = 3.14159265358979323846;

double Median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  return x[x.size() / 2];
}

double Fraction(double x) { return x - std::floor(x); }

int Main(int argc, char** argv) {
  const auto ref = bench::ParsePythonReference(
      argc, argv, "joint", "joint_ref.py", FRICTIOND_SOURCE_DIR);
  if (!ref) return 2;
  const std::string& python = ref->python;
  const std::string& script = ref->script;

  // ------------------------------------------------------ mixed_friction_eval
  const MixedFrictionTheta theta = MakeMixedFrictionTheta(0.1, 0.004, 0.5, 0.6);
  AsperitySurface surface;  // Alt 0.5, SAlt 0.15 (as joint_ref.py)
  const Lubricant oil;
  JointContact contact;
  contact.area_mm2 = 50.0;
  // 1e5 states: the direct path (quadrature, Newton for heavy loads) and
  // the NumPy reference cost microseconds per state (issue 19).
  constexpr int kStates = 100000;
  std::vector<double> v(kStates), load(kStates), temp(kStates);
  for (int i = 0; i < kStates; ++i) {
    v[i] = 5.0 * std::pow(400.0, Fraction(i * 0.6180339887));
    load[i] = 20.0 + 180.0 * Fraction(i * 0.7548776662);
    temp[i] = 20.0 + 60.0 * Fraction(i * 0.5698402910);
  }
  // Tabulated f(ln S, W) (the hot path), then the direct path for the note.
  const MixedFrictionTable table(theta, surface, oil, contact);
  double checksum = 0;
  std::vector<double> ns;
  for (int rep = 0; rep < 7; ++rep) {
    double sum = 0;
    const auto t0 = Clock::now();
    for (int i = 0; i < kStates; ++i) sum += table.Eval(v[i], load[i], temp[i]);
    const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
    ns.push_back(dt / kStates * 1e9);
    checksum = sum;
  }
  double checksum_closed = 0;
  std::vector<double> ns_closed;
  for (int rep = 0; rep < 3; ++rep) {
    double sum = 0;
    const auto t0 = Clock::now();
    for (int i = 0; i < kStates; ++i) {
      const double eta = CalcViscosity(oil, temp[i]);
      const double s = CalcSommerfeldUm(eta, v[i], load[i], contact);
      sum += CalcMixedFriction(theta, surface, s, load[i]);
    }
    const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
    ns_closed.push_back(dt / kStates * 1e9);
    checksum_closed = sum;
  }
  const nlohmann::json ref_mixed = nlohmann::json::parse(RunCommand(
      python + " " + script + " mixed --n " + std::to_string(kStates)));
  const double ref_checksum = ref_mixed.at("checksum").get<double>();
  bench::BenchResult mixed;
  mixed.bench = "mixed_friction_eval";
  mixed.value = Median(ns);
  mixed.unit = "ns";
  mixed.baseline = ref_mixed.at("ns").get<double>();
  mixed.baseline_name = "NumPy vectorised over 1e5 states";
  mixed.lower_is_better = true;
  mixed.goal = "<= 200 ns";
  char note[240];
  std::snprintf(note,
                sizeof note,
                "scalar, one state per call, tabulated f(ln S, W) (Vogel in "
                "log form, cubic Hermite; alpha the Hertz load fraction); "
                "direct (quadrature) %.4g ns; sum f over 1e5 states %.9g, "
                "direct %.9g, reference %.9g",
                Median(ns_closed),
                checksum,
                checksum_closed,
                ref_checksum);
  mixed.note = note;
  if (!(std::abs(checksum - ref_checksum) <= 1e-6) ||
      !(std::abs(checksum_closed - ref_checksum) <=
        1e-9 * std::abs(ref_checksum)))
    mixed.note += " MISMATCH";
  bench::PrintBenchLine(mixed);

  // ------------------------------------------------------------ ellipsoid_grid
  SerialArm arm;
  arm.joints.resize(3);
  arm.joints[0].alpha_rad = kPi / 2;
  arm.joints[0].d_mm = 300;
  arm.joints[1].a_mm = 400;
  arm.joints[2].a_mm = 350;
  for (DhJoint& j : arm.joints) {
    j.stiffness = 2e4;
    j.sigma_tau = 5.0;
  }
  const Eigen::Vector3d q_start(0.0, 0.3, -1.0);
  std::vector<double> ms;
  int reachable = 0;
  double biggest = 0;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = Clock::now();
    const auto grid =
        CalcEllipsoidGrid(arm, 200, -200, 400, 400, 0.0, 50, 50, q_start, 0.95);
    ms.push_back(
        std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    reachable = 0;
    biggest = 0;
    for (const GridEllipsoid& g : grid) {
      if (!g.reachable) continue;
      ++reachable;
      biggest = std::max(biggest, g.semi_axes_mm[2] * 1e3);
    }
  }
  const nlohmann::json ref_grid =
      nlohmann::json::parse(RunCommand(python + " " + script + " grid --n 50"));
  bench::BenchResult grid;
  grid.bench = "ellipsoid_grid";
  grid.value = Median(ms);
  grid.unit = "ms";
  grid.baseline = ref_grid.at("ms").get<double>();
  grid.baseline_name = "NumPy/SciPy, same IK and ellipsoid per point";
  grid.lower_is_better = true;
  grid.goal = "<= 100 ms";
  std::snprintf(note,
                sizeof note,
                "50 x 50 over 400 x 400 mm, 3R arm: %d reachable, largest "
                "semi-axis %.4g um (reference %d, %.4g um)",
                reachable,
                biggest,
                ref_grid.at("reachable").get<int>(),
                ref_grid.at("max_axis_um").get<double>());
  grid.note = note;
  bench::PrintBenchLine(grid);
  return 0;
}

}  // namespace
}  // namespace frictiond

int main(int argc, char** argv) {
  try {
    return frictiond::Main(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "joint: " << e.what() << "\n";
    return 1;
  }
}
