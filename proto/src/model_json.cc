#include "frictiond/proto/model_json.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace frictiond {

using nlohmann::json;

namespace {

const json& Get(const json& j,
                const std::string& key,
                const std::string& where) {
  if (!j.is_object())
    throw std::invalid_argument(where + ": expected a JSON object");
  auto it = j.find(key);
  if (it == j.end())
    throw std::invalid_argument(where + "." + key + ": missing");
  return *it;
}

double GetNumber(const json& j,
                 const std::string& key,
                 const std::string& where) {
  const json& v = Get(j, key, where);
  if (!v.is_number())
    throw std::invalid_argument(where + "." + key + ": expected a number");
  return v.get<double>();
}

double GetNumberOr(const json& j, const std::string& key, double fallback) {
  auto it = j.find(key);
  return (it != j.end() && it->is_number()) ? it->get<double>() : fallback;
}

json Finite(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

}  // namespace

json RegressionModelToJson(const RegressionModel& m) {
  json j;
  json coef = json::object(), se = json::object();
  json names = json::array();
  for (std::size_t k = 0; k < m.terms.size(); ++k) {
    const std::string n = m.terms[k].Name();
    names.push_back(n);
    coef[n] = m.beta(k);
    se[n] = m.std_err(k);
  }
  j["coefficients"] = coef;
  j["std_errors"] = se;
  if (m.std_err_stroke.size() == static_cast<Eigen::Index>(m.terms.size())) {
    json se_stroke = json::object();
    for (std::size_t k = 0; k < m.terms.size(); ++k)
      se_stroke[m.terms[k].Name()] = m.std_err_stroke(k);
    j["std_errors_stroke"] = se_stroke;
    j["stroke_clusters"] = m.stroke_clusters;
  }
  json cov = json::array();
  for (int a = 0; a < m.P_beta.rows(); ++a) {
    json row = json::array();
    for (int b = 0; b < m.P_beta.cols(); ++b) row.push_back(m.P_beta(a, b));
    cov.push_back(row);
  }
  j["covariance"] = {{"terms", names}, {"matrix", cov}};
  j["unidentified"] = m.unidentified;
  j["sigma_eps"] = m.sigma_eps;
  j["r2"] = m.r2;
  j["f_stat"] = Finite(m.f_stat);
  j["p_value"] = m.p_value;
  j["mae"] = m.mae;
  j["samples"] = m.samples;
  j["eps_quantiles"] = {{"levels", EpsQuantileLevels()},
                        {"values", m.eps_quantiles}};
  return j;
}

RegressionModel RegressionModelFromJson(const json& j,
                                        const std::string& where) {
  RegressionModel m;
  const json& coef = Get(j, "coefficients", where);
  if (!coef.is_object() || coef.empty())
    throw std::invalid_argument(where +
                                ".coefficients: expected a non-empty object");
  // Term order: from covariance.terms when present, else the object's order.
  std::vector<std::string> names;
  if (j.contains("covariance") && j["covariance"].contains("terms")) {
    names = j["covariance"]["terms"].get<std::vector<std::string>>();
  } else {
    if (coef.contains("intercept")) names.push_back("intercept");
    for (auto it = coef.begin(); it != coef.end(); ++it) {
      if (it.key() != "intercept") names.push_back(it.key());
    }
  }
  const int p = static_cast<int>(names.size());
  m.beta = Eigen::VectorXd::Zero(p);
  m.std_err = Eigen::VectorXd::Zero(p);
  m.P_beta = Eigen::MatrixXd::Zero(p, p);
  for (int k = 0; k < p; ++k) {
    m.terms.push_back(Term::Parse(names[k]));
    m.beta(k) = GetNumber(coef, names[k], where + ".coefficients");
    if (j.contains("std_errors"))
      m.std_err(k) = GetNumberOr(j["std_errors"], names[k], 0.0);
  }
  if (j.contains("std_errors_stroke")) {
    const json& se_stroke = j["std_errors_stroke"];
    if (!se_stroke.is_object())
      throw std::invalid_argument(where +
                                  ".std_errors_stroke: expected an object");
    m.std_err_stroke = Eigen::VectorXd::Zero(p);
    for (int k = 0; k < p; ++k)
      m.std_err_stroke(k) = GetNumberOr(se_stroke, names[k], 0.0);
    m.stroke_clusters = static_cast<int>(GetNumberOr(j, "stroke_clusters", 0));
  }
  if (j.contains("covariance") && j["covariance"].contains("matrix")) {
    const json& mat = j["covariance"]["matrix"];
    if (!mat.is_array() || static_cast<int>(mat.size()) != p)
      throw std::invalid_argument(where + ".covariance.matrix: expected " +
                                  std::to_string(p) + " rows");
    for (int a = 0; a < p; ++a) {
      if (!mat[a].is_array() || static_cast<int>(mat[a].size()) != p)
        throw std::invalid_argument(where + ".covariance.matrix[" +
                                    std::to_string(a) + "]: expected " +
                                    std::to_string(p) + " numbers");
      for (int b = 0; b < p; ++b) m.P_beta(a, b) = mat[a][b].get<double>();
    }
  }
  if (j.contains("unidentified"))
    m.unidentified = j["unidentified"].get<std::vector<std::string>>();
  m.sigma_eps = GetNumber(j, "sigma_eps", where);
  if (!(m.sigma_eps >= 0))
    throw std::invalid_argument(where + ".sigma_eps: must be >= 0");
  m.r2 = GetNumberOr(j, "r2", 0.0);
  m.f_stat = GetNumberOr(j, "f_stat", 0.0);
  m.p_value = GetNumberOr(j, "p_value", 1.0);
  m.mae = GetNumberOr(j, "mae", 0.0);
  m.samples = static_cast<int>(GetNumberOr(j, "samples", 0));
  if (j.contains("eps_quantiles") && j["eps_quantiles"].contains("values")) {
    m.eps_quantiles = j["eps_quantiles"]["values"].get<std::vector<double>>();
    if (m.eps_quantiles.size() != EpsQuantileLevels().size()) {
      throw std::invalid_argument(where + ".eps_quantiles.values: expected " +
                                  std::to_string(EpsQuantileLevels().size()) +
                                  " values");
    }
  }
  return m;
}

json StochasticModelToJson(const StochasticFrictionModel& model) {
  json j = RegressionModelToJson(model.mu);
  j["fn_only"] = RegressionModelToJson(model.mu_fn_only);
  const SlipLikelihoodFit& L = model.likelihood;
  j["slip_likelihood"] = {{"valid", L.valid},
                          {"why", L.why},
                          {"c1", L.c1},
                          {"c2", L.c2},
                          {"ratio_never", L.ratio_never},
                          {"ratio_always", L.ratio_always},
                          {"never_level", L.never_level},
                          {"always_level", L.always_level},
                          {"samples", L.samples}};
  json inputs = json::object();
  for (const auto& [name, s] : model.inputs)
    inputs[name] = {{"mean", s.mean}, {"min", s.min}, {"max", s.max}};
  j["inputs"] = inputs;
  j["mu_coulomb"] = model.mu_coulomb;
  j["mae_coulomb"] = model.mae_coulomb;
  j["strokes"] = model.strokes;
  j["samples_total"] = model.samples_total;
  j["samples_slip"] = model.samples_slip;
  const SlipLabelOptions& o = model.labelling;
  j["labelling"] = {{"slip_peak_mm_s", o.peak_mm_s},
                    {"slip_floor_mm_s", o.floor_mm_s},
                    {"median_window_s", o.median_window_s},
                    {"max_fn_n", Finite(o.max_fn_n)},
                    {"max_v_mm_s", Finite(o.max_v_mm_s)},
                    {"gap_factor", o.gap_factor}};
  const EpsTimeModel& t = model.eps_time;
  j["eps_time"] = {{"valid", t.valid},
                   {"why", t.why},
                   {"model", "gaussian_copula_ar1_plus_episode_offset"},
                   {"dt_s", t.dt_s},
                   {"phi", t.phi},
                   {"corr_time_s", t.corr_time_s},
                   {"offset_fraction", t.offset_fraction},
                   {"episodes", t.episodes},
                   {"samples", t.samples},
                   {"effective_samples", t.effective_samples},
                   {"min_instant_risk", t.min_instant_risk},
                   {"tail_xi", t.tail_xi},
                   {"tail_scale", t.tail_scale}};
  if (t.offset.valid) {
    // Offset plus within-episode process (eps_time.h, issue 19); absent:
    // holds use the Gaussian copula (models stored before it).
    const EpsOffsetModel& o = t.offset;
    j["eps_time"]["offset_decomposition"] = {
        {"model", "episode_offset_plus_copula_ar1"},
        {"levels", EpsQuantileLevels()},
        {"offset_quantiles", o.offset_quantiles},
        {"offset_tail_xi", o.offset_tail_xi},
        {"offset_tail_scale", o.offset_tail_scale},
        {"within_quantiles", o.within_quantiles},
        {"within_tail_xi", o.within_tail_xi},
        {"within_tail_scale", o.within_tail_scale},
        {"episodes_used", o.episodes_used}};
    if (!o.innovation_quantiles.empty()) {
      json& d = j["eps_time"]["offset_decomposition"];
      d["innovation_quantiles"] = o.innovation_quantiles;
      d["innovation_tail_xi"] = o.innovation_tail_xi;
      d["innovation_tail_scale"] = o.innovation_tail_scale;
    }
  }
  if (model.eps_scale) {
    // Heteroscedastic eps (eps_scale.h); absent: one scale (paper 000).
    const EpsScaleModel& e = *model.eps_scale;
    j["eps_scale"] = {{"input", e.input},
                      {"model", "log_linear"},
                      {"log_sigma_intercept", e.log_sigma_intercept},
                      {"log_sigma_slope", e.log_sigma_slope},
                      {"x_min", e.x_min},
                      {"x_max", e.x_max},
                      {"sigma_ref", e.sigma_ref}};
  }
  return j;
}

StochasticFrictionModel StochasticModelFromJson(const json& j) {
  StochasticFrictionModel m;
  m.mu = RegressionModelFromJson(j, "stochastic");
  if (j.contains("fn_only"))
    m.mu_fn_only = RegressionModelFromJson(j["fn_only"], "stochastic.fn_only");
  if (j.contains("slip_likelihood")) {
    const json& L = j["slip_likelihood"];
    m.likelihood.valid = L.value("valid", false);
    m.likelihood.why = L.value("why", "");
    m.likelihood.c1 = GetNumberOr(L, "c1", 0.0);
    m.likelihood.c2 = GetNumberOr(L, "c2", 0.0);
    m.likelihood.ratio_never = GetNumberOr(L, "ratio_never", 0.0);
    m.likelihood.ratio_always = GetNumberOr(L, "ratio_always", 0.0);
    m.likelihood.never_level = GetNumberOr(L, "never_level", 0.01);
    m.likelihood.always_level = GetNumberOr(L, "always_level", 0.99);
    m.likelihood.samples = static_cast<int>(GetNumberOr(L, "samples", 0));
  }
  if (j.contains("inputs") && j["inputs"].is_object()) {
    for (auto it = j["inputs"].begin(); it != j["inputs"].end(); ++it) {
      m.inputs[it.key()] = InputStats{GetNumberOr(*it, "mean", 0.0),
                                      GetNumberOr(*it, "min", 0.0),
                                      GetNumberOr(*it, "max", 0.0)};
    }
  }
  m.mu_coulomb = GetNumberOr(j, "mu_coulomb", 0.0);
  m.mae_coulomb = GetNumberOr(j, "mae_coulomb", 0.0);
  m.strokes = static_cast<int>(GetNumberOr(j, "strokes", 0));
  m.samples_total = static_cast<int>(GetNumberOr(j, "samples_total", 0));
  m.samples_slip = static_cast<int>(GetNumberOr(j, "samples_slip", 0));
  if (j.contains("labelling")) {
    const json& o = j["labelling"];
    m.labelling.peak_mm_s =
        GetNumberOr(o, "slip_peak_mm_s", m.labelling.peak_mm_s);
    m.labelling.floor_mm_s =
        GetNumberOr(o, "slip_floor_mm_s", m.labelling.floor_mm_s);
    m.labelling.median_window_s =
        GetNumberOr(o, "median_window_s", m.labelling.median_window_s);
    m.labelling.max_fn_n = GetNumberOr(o, "max_fn_n", m.labelling.max_fn_n);
    m.labelling.max_v_mm_s =
        GetNumberOr(o, "max_v_mm_s", m.labelling.max_v_mm_s);
    m.labelling.gap_factor =
        GetNumberOr(o, "gap_factor", m.labelling.gap_factor);
  }
  if (j.contains("eps_time") && j["eps_time"].is_object()) {
    // Hostile input: anything out of range leaves the time model invalid
    // (hold_s > 0 is then refused) rather than feeding the quadrature.
    const json& t = j["eps_time"];
    EpsTimeModel& e = m.eps_time;
    e.why = t.contains("why") && t["why"].is_string()
                ? t["why"].get<std::string>().substr(0, 512)
                : "";
    e.dt_s = GetNumberOr(t, "dt_s", 0.0);
    e.phi = GetNumberOr(t, "phi", 0.0);
    e.corr_time_s = GetNumberOr(t, "corr_time_s", 0.0);
    e.offset_fraction = GetNumberOr(t, "offset_fraction", 0.0);
    e.episodes =
        static_cast<int>(std::clamp(GetNumberOr(t, "episodes", 0.0), 0.0, 2e9));
    e.samples =
        static_cast<int>(std::clamp(GetNumberOr(t, "samples", 0.0), 0.0, 2e9));
    e.effective_samples = GetNumberOr(t, "effective_samples", 0.0);
    e.min_instant_risk = GetNumberOr(t, "min_instant_risk", 1.0);
    e.tail_xi = GetNumberOr(t, "tail_xi", 0.0);
    e.tail_scale = GetNumberOr(t, "tail_scale", 0.0);
    if (!(e.tail_xi >= -0.5 && e.tail_xi <= 1 && e.tail_scale >= 0 &&
          std::isfinite(e.tail_scale)))
      e.tail_xi = e.tail_scale = 0.0;  // no fitted tail: exponential
    const bool sane = e.dt_s >= 1e-4 && e.dt_s < 3600 && e.phi >= 0 &&
                      e.phi <= 0.98 && e.offset_fraction >= 0 &&
                      e.offset_fraction <= 1 && e.min_instant_risk > 0 &&
                      e.min_instant_risk < 1;
    const bool stored_valid = t.contains("valid") && t["valid"].is_boolean() &&
                              t["valid"].get<bool>();
    bool offset_sane = true;
    if (t.contains("offset_decomposition")) {
      // Hostile input: exactly one finite, non-decreasing quantile per
      // level and tails in range, or the time model is invalid.
      const json& o = t["offset_decomposition"];
      const std::size_t levels = EpsQuantileLevels().size();
      auto quantiles = [&](const char* key, std::vector<double>* out) {
        if (!o.is_object() || !o.contains(key) || !o[key].is_array() ||
            o[key].size() != levels)
          return false;
        for (const json& x : o[key]) {
          if (!x.is_number()) return false;
          const double v = x.get<double>();
          if (!std::isfinite(v) || (!out->empty() && v < out->back()))
            return false;
          out->push_back(v);
        }
        return true;
      };
      auto tail = [&](const char* xi_key,
                      const char* scale_key,
                      double* xi,
                      double* scale) {
        *xi = GetNumberOr(o, xi_key, 0.0);
        *scale = GetNumberOr(o, scale_key, 0.0);
        return *xi >= -0.5 && *xi <= 1 && *scale >= 0 && std::isfinite(*scale);
      };
      EpsOffsetModel& d = e.offset;
      offset_sane =
          quantiles("offset_quantiles", &d.offset_quantiles) &&
          quantiles("within_quantiles", &d.within_quantiles) &&
          tail("offset_tail_xi",
               "offset_tail_scale",
               &d.offset_tail_xi,
               &d.offset_tail_scale) &&
          tail("within_tail_xi",
               "within_tail_scale",
               &d.within_tail_xi,
               &d.within_tail_scale) &&
          (!o.contains("innovation_quantiles") ||
           (quantiles("innovation_quantiles", &d.innovation_quantiles) &&
            tail("innovation_tail_xi",
                 "innovation_tail_scale",
                 &d.innovation_tail_xi,
                 &d.innovation_tail_scale)));
      d.episodes_used = static_cast<int>(
          std::clamp(GetNumberOr(o, "episodes_used", 0.0), 0.0, 2e9));
      d.valid = offset_sane;
      if (!offset_sane) d = EpsOffsetModel{};
    }
    e.valid = stored_valid && sane && offset_sane;
    if (stored_valid && !sane)
      e.why =
          "stored eps_time out of range (dt_s, phi, offset_fraction or "
          "min_instant_risk)";
    else if (stored_valid && !offset_sane)
      e.why =
          "stored eps_time.offset_decomposition malformed (quantiles: one "
          "finite, non-decreasing number per level; tails: xi in [-0.5, 1], "
          "scale >= 0)";
  }
  if (j.contains("eps_scale") && !j["eps_scale"].is_null()) {
    // Hostile input: a malformed scale is refused, naming the field.
    const json& e = j["eps_scale"];
    if (!e.is_object())
      throw std::invalid_argument("stochastic.eps_scale: expected an object");
    EpsScaleModel s;
    if (!e.contains("input") || !e["input"].is_string())
      throw std::invalid_argument(
          "stochastic.eps_scale.input: expected a string");
    s.input = e["input"].get<std::string>().substr(0, 256);
    for (const auto& [name, field] :
         {std::pair<const char*, double*>{"log_sigma_intercept",
                                          &s.log_sigma_intercept},
          {"log_sigma_slope", &s.log_sigma_slope},
          {"x_min", &s.x_min},
          {"x_max", &s.x_max},
          {"sigma_ref", &s.sigma_ref}}) {
      if (!e.contains(name) || !e[name].is_number())
        throw std::invalid_argument(std::string("stochastic.eps_scale.") +
                                    name + ": expected a number");
      *field = e[name].get<double>();
    }
    std::string why;
    if (!s.IsValid(&why))
      throw std::invalid_argument("stochastic." + why.substr(0, 300));
    m.eps_scale = std::move(s);
  }
  return m;
}

json ModelSetToJson(const ModelSet& set) {
  json j = set.other.is_object() ? set.other : json::object();
  j["material"] = set.material;
  j["fingertip"] = set.fingertip;
  j["version"] = set.version;
  j["created_at"] = set.created_at;
  if (set.stochastic) j["stochastic"] = StochasticModelToJson(*set.stochastic);
  return j;
}

ModelSet ModelSetFromJson(const json& j) {
  if (!j.is_object())
    throw std::invalid_argument("model: expected a JSON object");
  ModelSet s;
  s.material = j.value("material", "");
  s.fingertip = j.value("fingertip", "default");
  s.version = j.value("version", 0);
  s.created_at = j.value("created_at", "");
  if (j.contains("stochastic"))
    s.stochastic = StochasticModelFromJson(j["stochastic"]);
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& k = it.key();
    if (k != "material" && k != "fingertip" && k != "version" &&
        k != "created_at" && k != "stochastic") {
      s.other[k] = *it;
    }
  }
  return s;
}

}  // namespace frictiond
