// Consumer of the installed package: evaluates a model locally, the way a
// robot's control loop would, after decoding it from the wire format.
#include <cmath>
#include <cstdio>

#include "frictiond/client/client.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/proto/model_json.h"

int main() {
  const char* doc = R"({"material":"felt","version":3,"stochastic":{
    "coefficients":{"intercept":0.9,"v_mm_s":0.004,"fn_n":-0.06},"sigma_eps":0.05,"r2":0.6,"samples":1000,
    "slip_likelihood":{"valid":true,"c1":20.0,"c2":0.8}}})";
  const frictiond::ModelSet m =
      frictiond::ModelSetFromJson(nlohmann::json::parse(doc));
  const frictiond::MuPrediction p =
      frictiond::PredictMu(*m.stochastic, 2.0, 20.0);
  const double L = frictiond::CalcSlipLikelihood(*m.stochastic, 2.0, 1.6);
  frictiond::FrictionClient client(
      {"http://127.0.0.1:9"});  // constructed, not contacted
  std::printf("mu %.4f likelihood %.3f\n", p.mu, L);
  const bool ok = std::fabs(p.mu - (0.9 + 0.08 - 0.12)) < 1e-12 &&
                  std::fabs(L - 0.5) < 1e-12;
  return ok ? 0 : 1;
}
