// frictiond_robot_sim: plays a robot over LCM against a running frictiond
// (docs/lcm.md): asks for an unknown material, performs the requested test
// strokes from a hidden truth (the stochastic model and LuGre dynamics in
// one friction law, testing::RobotTruth; the LuGre pair when the request
// asks for it), and checks the fitted model against the truth: the
// stochastic coefficients in standard errors, the LuGre family with
// LuGreTolerances. Prints one JSON object; exit 0 when the model matches.
#include <cmath>
#include <iostream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "frictiond/crypto/hmac.h"

#include "robot_simulator.h"

int main(int argc, char** argv) {
  frictiond::testing::RobotSimOptions o;
  CLI::App app{"frictiond_robot_sim: a simulated robot over LCM"};
  o.url = "udpm://239.255.76.67:7667?ttl=0";
  app.add_option("--lcm", o.url, "LCM provider URL");
  app.add_option("--material", o.material, "material id to ask for")
      ->required();
  app.add_option("--fingertip", o.fingertip, "fingertip id");
  app.add_option("--robot", o.robot, "robot name");
  app.add_option("--seed", o.seed, "simulation seed");
  app.add_option("--b0", o.truth.b0, "true intercept");
  app.add_option("--b1", o.truth.b1, "true slope per mm/s");
  app.add_option("--b2", o.truth.b2, "true slope per N");
  app.add_option("--sigma-eps", o.truth.sigma_eps, "true noise std");
  app.add_option(
      "--static-excess", o.truth.static_excess, "true LuGre mu_s - mu_c");
  app.add_option("--v0-mm-s", o.truth.v0_mm_s, "true Stribeck velocity");
  app.add_option("--sigma0", o.truth.sigma0_per_mm, "true sigma0 [1/mm]");
  app.add_option("--sigma1", o.truth.sigma1_s_mm, "true sigma1 [s/mm]");
  bool v1_robot = false;
  app.add_flag("--v1-robot",
               v1_robot,
               "act on identification_request_v1 only (no LuGre pair)");
  app.add_flag("--duplicate", o.duplicate, "send some chunks twice");
  app.add_flag("--reorder", o.reorder, "shuffle chunk order");
  app.add_flag("--hold-back", o.hold_back, "withhold chunk 1 until asked");
  app.add_flag("--narrow-first",
               o.narrow_first_stroke,
               "first stroke covers too little span");
  std::string key_hex;
  app.add_option("--key",
                 key_hex,
                 "the robot's LCM key in hex: sign chunks (stroke_chunk_v2); "
                 "none: unsigned stroke_chunk_v1");
  double tolerance_se = 5.0;
  app.add_option("--tolerance-se",
                 tolerance_se,
                 "allowed |estimate - truth| in standard errors");
  CLI11_PARSE(app, argc, argv);
  o.request_v2 = !v1_robot;
  if (!key_hex.empty()) {
    const auto key = frictiond::FromHex(key_hex);
    if (!key) {
      std::cerr << "frictiond_robot_sim: --key: not a hex string\n";
      return 2;
    }
    o.key = *key;
  }
  const auto r = frictiond::testing::RunRobotSimulation(o);
  nlohmann::json out = {{"ok", r.ok},
                        {"why", r.why},
                        {"job_id", r.job_id},
                        {"version", r.model_version},
                        {"coefficients", r.coefficients},
                        {"std_errors", r.std_errors},
                        {"sigma_eps", r.sigma_eps},
                        {"strokes", r.strokes_sent},
                        {"chunks_sent", r.chunks_sent},
                        {"resend_requests", r.resend_requests},
                        {"follow_ups", r.follow_ups},
                        {"span_pct", r.last_span_pct},
                        {"log", r.log}};
  bool match = r.ok;
  const std::pair<const char*, double> truth[] = {
      {"intercept", o.truth.b0}, {"v_mm_s", o.truth.b1}, {"fn_n", o.truth.b2}};
  for (const auto& [term, value] : truth) {
    if (!r.coefficients.count(term)) {
      match = false;
      continue;
    }
    const double err = r.coefficients.at(term) - value;
    out["error_in_se"][term] = err / r.std_errors.at(term);
    if (!(std::fabs(err) <= tolerance_se * r.std_errors.at(term)))
      match = false;
  }
  // The LuGre family, when the robot performed the pair.
  auto theta_json = [](const frictiond::LuGreTheta& t) {
    nlohmann::json j = nlohmann::json::array();
    for (int i = 0; i < 6; ++i)
      j.push_back(std::isfinite(t[i]) ? nlohmann::json(t[i])
                                      : nlohmann::json());
    return j;
  };
  out["lugre"] = {{"pairs", r.lugre_pairs},
                  {"has_lugre", r.has_lugre},
                  {"theta", theta_json(r.lugre_theta)},
                  {"checked", r.lugre_checked}};
  if (r.lugre_checked) {
    out["lugre"]["fn_n"] = r.lugre_fn_n;
    out["lugre"]["truth"] = theta_json(r.lugre_truth);
    out["lugre"]["mismatch"] = r.lugre_mismatch;
    if (!r.lugre_mismatch.empty()) match = false;
  }
  out["matches_truth"] = match;
  std::cout << out.dump(2) << "\n";
  return match ? 0 : 1;
}
