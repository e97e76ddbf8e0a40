#include "frictiond/proto/slip_likelihood_json.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace frictiond {

using nlohmann::json;

json ConditionalSlipToJson(const ConditionalSlipLikelihood& L) {
  json knots = json::array();
  for (std::size_t k = 0; k < L.knot_fn_n.size(); ++k) {
    knots.push_back(
        {{"fn_n", L.knot_fn_n[k]}, {"c1", L.knot_c1[k]}, {"c2", L.knot_c2[k]}});
  }
  json windows = json::array();
  for (const SlipWindowFit& w : L.windows) {
    json j = {{"fn_n", w.fn_center_n},
              {"samples", w.samples},
              {"slipping", w.slipping},
              {"valid", w.fit.valid}};
    if (w.fit.valid) {
      j["c1"] = w.fit.c1;
      j["c2"] = w.fit.c2;
      j["c1_se"] = std::sqrt(std::max(0.0, w.fit.P_c(0, 0)));
      j["c2_se"] = std::sqrt(std::max(0.0, w.fit.P_c(1, 1)));
    } else {
      j["why"] = w.fit.why;
    }
    windows.push_back(std::move(j));
  }
  return {{"step_n", L.step_n},
          {"window_n", L.window_n},
          {"knots", knots},
          {"windows", windows}};
}

ConditionalSlipLikelihood ConditionalSlipFromJson(const json& j) {
  ConditionalSlipLikelihood L;
  try {
    L.step_n = j.at("step_n").get<double>();
    L.window_n = j.at("window_n").get<double>();
    for (const json& k : j.at("knots")) {
      L.knot_fn_n.push_back(k.at("fn_n").get<double>());
      L.knot_c1.push_back(k.at("c1").get<double>());
      L.knot_c2.push_back(k.at("c2").get<double>());
    }
  } catch (const json::exception& e) {
    throw std::invalid_argument(std::string(kConditionalSlipFamilyKey) + ": " +
                                e.what());
  }
  L.valid = !L.knot_fn_n.empty();
  return L;
}

}  // namespace frictiond
