#include "frictiond/server/identification_json.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace frictiond {

using nlohmann::json;

json StrokePlanToJson(const StrokePlan& p) {
  json plan = json{{"material", p.material},
                   {"fingertip", p.fingertip},
                   {"fn_n", {p.fn_min_n, p.fn_max_n}},
                   {"v_mm_s", {p.v_min_mm_s, p.v_max_mm_s}},
                   {"max_duration_s", p.max_duration_s},
                   {"min_span_pct", p.min_span_pct},
                   {"instructions", p.instructions}};
  if (p.lugre) {
    const LuGrePairPlan& l = *p.lugre;
    plan["lugre"] = json{{"fn_n", l.fn_n},
                         {"slow",
                          {{"accel_mm_s2", l.slow_accel_mm_s2},
                           {"peak_mm_s", l.slow_peak_mm_s}}},
                         {"fast",
                          {{"strokes", l.fast_strokes},
                           {"accel_mm_s2", l.fast_accel_mm_s2},
                           {"peak_mm_s", l.fast_peak_mm_s}}},
                         {"rest_s", l.rest_s},
                         {"instructions", l.instructions}};
  }
  return plan;
}

namespace {

// A [min, max] pair of numbers.
void ReadRange(const json& plan, const char* key, double* lo, double* hi) {
  const auto it = plan.find(key);
  if (it == plan.end() || !it->is_array() || it->size() != 2 ||
      !(*it)[0].is_number() || !(*it)[1].is_number())
    throw std::invalid_argument(std::string(key) +
                                ": the stroke plan needs [min, max] numbers");
  *lo = (*it)[0].get<double>();
  *hi = (*it)[1].get<double>();
}

double Number(const json& o, const char* key, double fallback) {
  const auto it = o.find(key);
  return it != o.end() && it->is_number() ? it->get<double>() : fallback;
}

std::string Text(const json& o, const char* key) {
  const auto it = o.find(key);
  return it != o.end() && it->is_string() ? it->get<std::string>()
                                          : std::string();
}

}  // namespace

StrokePlan StrokePlanFromJson(const json& plan) {
  if (!plan.is_object())
    throw std::invalid_argument("plan: the stroke plan is not an object");
  StrokePlan p;
  p.material = Text(plan, "material");
  p.fingertip = Text(plan, "fingertip");
  ReadRange(plan, "fn_n", &p.fn_min_n, &p.fn_max_n);
  ReadRange(plan, "v_mm_s", &p.v_min_mm_s, &p.v_max_mm_s);
  p.max_duration_s = Number(plan, "max_duration_s", 120.0);
  p.min_span_pct = Number(plan, "min_span_pct", 50.0);
  p.instructions = Text(plan, "instructions");
  if (const auto it = plan.find("lugre"); it != plan.end() && it->is_object()) {
    const json& l = *it;
    const double nan = std::nan("");
    const json none = json::object();
    const auto group = [&](const char* key) -> const json& {
      const auto g = l.find(key);
      return g != l.end() && g->is_object() ? *g : none;
    };
    LuGrePairPlan pair;
    pair.fn_n = Number(l, "fn_n", nan);
    pair.slow_accel_mm_s2 = Number(group("slow"), "accel_mm_s2", nan);
    pair.slow_peak_mm_s = Number(group("slow"), "peak_mm_s", nan);
    const json& fast = group("fast");
    const auto strokes = fast.find("strokes");
    pair.fast_strokes = strokes != fast.end() && strokes->is_number_integer()
                            ? strokes->get<int>()
                            : 0;
    pair.fast_accel_mm_s2 = Number(fast, "accel_mm_s2", nan);
    pair.fast_peak_mm_s = Number(fast, "peak_mm_s", nan);
    pair.rest_s = Number(l, "rest_s", nan);
    pair.instructions = Text(l, "instructions");
    p.lugre = pair;
  }
  return p;
}

json IdentificationRequestToJson(const IdentificationRequest& r) {
  if (!r.requested)
    return json{{"requested", false},
                {"reason", r.reason},
                {"stroke", StrokePlanToJson(r.plan)}};
  return json{{"requested", true},
              {"job_id", r.job_id},
              {"state", JobStateName(r.state)},
              {"created_at", r.created_at},
              {"stroke", StrokePlanToJson(r.plan)}};
}

}  // namespace frictiond
