// frictiond_robot_sim: plays a robot over LCM against a running frictiond
// (docs/lcm.md): asks for an unknown material, performs the requested test
// strokes from a hidden true model, and checks the fitted model against
// the truth. Prints one JSON object; exit 0 when the model matches.
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
  out["matches_truth"] = match;
  std::cout << out.dump(2) << "\n";
  return match ? 0 : 1;
}
