// mujoco_step_overhead (issue 21): time per step of a 10-contact grasp scene
// stepped by the friction adapter (sim/mujoco) over plain mj_step of the
// same scene, measured in the same run (alternating rounds, medians).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>
#include <unistd.h>

#include "frictiond/mujoco/friction_adapter.h"

#include "bench_json.h"

namespace frictiond {
namespace {

// A free box pinched by ten soft fingertips (five per side, each a sphere
// on an x slide pressed by a motor): ten sphere-box contacts.
std::string Scene() {
  std::string xml = R"(<mujoco model="grasp10">
  <option timestep="0.002" integrator="Euler" cone="elliptic" impratio="10"
          noslip_iterations="30"/>
  <worldbody>
    <body name="box"><freejoint/>
      <geom type="box" size="0.02 0.04 0.04" mass="0.2"/></body>
)";
  std::string act;
  const double yz[5][2] = {{0, 0},
                           {0.025, 0.025},
                           {-0.025, 0.025},
                           {0.025, -0.025},
                           {-0.025, -0.025}};
  for (int side = 0; side < 2; ++side) {
    for (int k = 0; k < 5; ++k) {
      const std::string n = "f" + std::to_string(side * 5 + k);
      const double x = side == 0 ? -0.03 : 0.03;
      xml += "    <body name=\"" + n + "\" pos=\"" + std::to_string(x) + " " +
             std::to_string(yz[k][0]) + " " + std::to_string(yz[k][1]) +
             "\"><joint name=\"" + n + "\" type=\"slide\" axis=\"1 0 0\" " +
             "damping=\"2\"/><geom name=\"" + n +
             "\" type=\"sphere\" size=\"0.01\" mass=\"0.02\" " +
             "solref=\"0.01 1\"/></body>\n";
      act += "    <motor joint=\"" + n + "\" gear=\"" +
             (side == 0 ? "1" : "-1") + "\"/>\n";
    }
  }
  return xml + "  </worldbody>\n  <actuator>\n" + act +
         "  </actuator>\n</mujoco>\n";
}

StochasticFrictionModel Model() {
  StochasticFrictionModel t;
  t.mu.terms = {
      Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")};
  t.mu.beta = Eigen::Vector3d(0.8, -0.002, -0.01);
  t.mu.sigma_eps = 0.1;
  for (double p : EpsQuantileLevels())
    t.mu.eps_quantiles.push_back(CalcEpsQuantile(t.mu, p));
  // eps with an identified time structure sampled every step (the adapter's
  // costliest eps path: an AR(1) advance and a quantile per contact-step).
  t.eps_time.valid = true;
  t.eps_time.dt_s = 0.002;
  t.eps_time.phi = 0.9;
  t.eps_time.offset_fraction = 0.5;
  return t;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

int Main() {
  const std::string path =
      "/tmp/frictiond_grasp10_" + std::to_string(::getpid()) + ".xml";
  std::ofstream(path) << Scene();
  char err[1000] = "";
  mjModel* m = mj_loadXML(path.c_str(), nullptr, err, sizeof err);
  std::remove(path.c_str());
  if (!m) throw std::runtime_error(std::string("MJCF: ") + err);
  mjData* d_plain = mj_makeData(m);
  mjData* d_live = mj_makeData(m);
  mujoco::FrictionAdapter adapter{mujoco::AdapterOptions{}};
  for (int k = 0; k < 10; ++k)
    adapter.TagGeom(m, "f" + std::to_string(k), Model());
  for (mjData* d : {d_plain, d_live})
    for (int k = 0; k < m->nu; ++k) d->ctrl[k] = 3.0;
  // Settle both (contacts established), then time alternating rounds.
  for (int i = 0; i < 200; ++i) {
    mj_step(m, d_plain);
    adapter.Step(m, d_live);
  }
  const int steps = 2000;
  std::vector<double> plain, live;
  int contacts = 0;
  for (int round = 0; round < 15; ++round) {
    auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < steps; ++i) mj_step(m, d_plain);
    auto t1 = std::chrono::steady_clock::now();
    for (int i = 0; i < steps; ++i) adapter.Step(m, d_live);
    auto t2 = std::chrono::steady_clock::now();
    plain.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count() /
                    steps);
    live.push_back(std::chrono::duration<double, std::micro>(t2 - t1).count() /
                   steps);
    contacts = d_live->ncon;
  }
  bench::BenchResult r;
  r.bench = "mujoco_step_overhead";
  r.value = Median(live);
  r.unit = "us/step";
  r.baseline = Median(plain);
  r.baseline_name = "plain mj_step, same scene";
  r.lower_is_better = true;
  r.goal = "<= 1.15x plain mj_step (ratio >= 0.87)";
  r.note = "10-fingertip grasp, elliptic cone, noslip 30, " +
           std::to_string(contacts) + " contacts (plain " +
           std::to_string(d_plain->ncon) + "), medians of 15 rounds of " +
           std::to_string(steps) + " steps";
  bench::PrintBenchLine(r);
  mj_deleteData(d_plain);
  mj_deleteData(d_live);
  mj_deleteModel(m);
  return 0;
}

}  // namespace
}  // namespace frictiond

int main() {
  try {
    return frictiond::Main();
  } catch (const std::exception& e) {
    std::cerr << "mujoco_step_overhead: " << e.what() << "\n";
    return 1;
  }
}
