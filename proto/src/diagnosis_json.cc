#include "frictiond/proto/diagnosis_json.h"

#include <cmath>

namespace frictiond {

namespace {

nlohmann::json Number(double x) {
  return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
}

nlohmann::json ModelJson(const DiagnosedModel& m) {
  nlohmann::json j;
  j["model"] = m.model;
  j["cv_mae"] = Number(m.cv_mae);
  j["terms"] = m.terms;
  nlohmann::json coefficients = nlohmann::json::object();
  for (std::size_t k = 0; k < m.terms.size() && k < m.beta.size(); ++k)
    coefficients[m.terms[k]] = Number(m.beta[k]);
  j["coefficients"] = coefficients;
  j["sigma_eps"] = Number(m.sigma_eps);
  if (m.eps_scale) {
    const EpsScaleModel& e = *m.eps_scale;
    j["eps_scale"] = {{"input", e.input},
                      {"log_sigma_intercept", Number(e.log_sigma_intercept)},
                      {"log_sigma_slope", Number(e.log_sigma_slope)},
                      {"x_min", Number(e.x_min)},
                      {"x_max", Number(e.x_max)},
                      {"sigma_ref", Number(e.sigma_ref)}};
  }
  j["cv_log_likelihood"] = Number(m.cv_log_likelihood);
  return j;
}

/// Replay errors; slip-event fields are null for a model that does not
/// predict slip (predicts_slip false).
nlohmann::json ErrorsJson(const ReplayErrors& e,
                          bool overall,
                          bool predicts_slip) {
  nlohmann::json j;
  if (!overall) j["stroke"] = e.stroke;
  j["samples"] = e.samples;
  j["slip_samples"] = e.slip_samples;
  j["mu_mae"] = Number(e.mu_mae);
  j["slip_events"] = e.slip_events;
  j["hits"] = predicts_slip ? nlohmann::json(e.hits) : nlohmann::json();
  j["misses"] = predicts_slip ? nlohmann::json(e.misses) : nlohmann::json();
  j["false_alarms"] =
      predicts_slip ? nlohmann::json(e.false_alarms) : nlohmann::json();
  j["brier"] = Number(e.brier);
  if (!overall) {
    j["breakaway_measured"] = Number(e.breakaway_measured);
    j["breakaway_predicted"] = Number(e.breakaway_predicted);
  }
  j["breakaway_abs_error"] = Number(e.breakaway_abs_error);
  j["breakaway_bias"] = Number(e.breakaway_bias);
  return j;
}

}  // namespace

nlohmann::json DiagnosisToJson(const DiagnosisResult& r,
                               const DiagnosisOptions& options,
                               const std::string& labelling_rule,
                               const DiagnosisJsonOptions& json_options) {
  nlohmann::json j;
  j["status"] = ToString(r.status);
  if (!r.why.empty()) j["why"] = r.why;
  j["baseline"] = ModelJson(r.baseline);
  nlohmann::json findings = nlohmann::json::array();
  for (const Finding& f : r.findings) {
    nlohmann::json alternatives = nlohmann::json::array();
    for (const Alternative& a : f.alternatives) {
      alternatives.push_back({{"cause", a.cause},
                              {"kind", a.kind},
                              {"expansion", a.expansion},
                              {"cv_mae_gain_pct", Number(a.cv_mae_gain_pct)},
                              {"p_value", Number(a.p_value)},
                              {"correlation", Number(a.correlation)}});
    }
    findings.push_back({{"cause", f.cause},
                        {"kind", f.kind},
                        {"p_value", Number(f.p_value)},
                        {"cv_mae_gain_pct", Number(f.cv_mae_gain_pct)},
                        {"effect", f.effect},
                        {"expansion", f.expansion},
                        {"terms", f.terms},
                        {"cv_mae", Number(f.cv_mae)},
                        {"log_likelihood_gain", Number(f.log_likelihood_gain)},
                        {"selection_bias_pct", Number(f.selection_bias_pct)},
                        {"folds_selected", f.folds_selected},
                        {"alternatives", alternatives}});
  }
  j["findings"] = findings;
  nlohmann::json extended = ModelJson(r.extended);
  extended["gain_pct"] = Number(r.gain_pct);
  extended["log_likelihood_gain"] = Number(r.log_likelihood_gain);
  extended["selection_bias_pct"] = Number(r.selection_bias_pct);
  j["extended"] = extended;
  j["log_likelihood_gain"] = Number(r.log_likelihood_gain);
  j["data"] = {{"samples", r.samples},
               {"fit_samples", r.fit_samples},
               {"strokes", r.strokes},
               {"candidates", r.candidates},
               {"skipped", r.skipped},
               {"dropped_baseline_terms", r.dropped_baseline_terms}};
  j["labelling"] = {{"slip_peak_mm_s", options.labelling.peak_mm_s},
                    {"slip_floor_mm_s", options.labelling.floor_mm_s},
                    {"median_window_s", options.labelling.median_window_s},
                    {"rule", labelling_rule}};
  j["selection_bias_pct"] = Number(r.selection_bias_pct);
  j["statistics"] = {
      {"cross_validation",
       std::string("nested leave-strokes-out K-fold: the selection runs on "
                   "each outer training part with inner folds; reported "
                   "errors, gains and p-values come from the outer folds. "
                   "Folds are ") +
           (options.shuffle_folds
                ? "seeded shuffles of the strokes"
                : "contiguous blocks of strokes in recording order")},
      {"folds", r.folds},
      {"inner_folds", r.inner_folds},
      {"shuffle_folds", options.shuffle_folds},
      {"seed", options.seed},
      {"test",
       "one-sided paired t-test over strokes of outer held-out "
       "absolute-error differences (spread: log-likelihood differences)"},
      {"correction",
       "fixed sequence over the findings the selection proposed, in "
       "selection order (adjusted p = running maximum of the raw p); Holm "
       "over all spread candidates; inside the selection raw p < "
       "selection_alpha"},
      {"alpha", options.alpha},
      {"selection_alpha", options.selection_alpha},
      {"min_gain_pct", options.min_gain_pct},
      {"selection",
       "greedy forward on inner folds, largest significant held-out gain "
       "first; interactions among the model's inputs and chosen causes"}};
  if (json_options.replay) {
    nlohmann::json replay = nlohmann::json::array();
    bool lugre_replayed = false;
    for (const ModelReplay& m : r.replay) {
      lugre_replayed = lugre_replayed || m.model == "lugre";
      nlohmann::json jm = {
          {"model", m.model},
          {"terms", m.terms},
          {"overall", ErrorsJson(m.overall, true, m.predicts_slip)}};
      if (!m.note.empty()) jm["note"] = m.note;
      if (json_options.replay_strokes) {
        nlohmann::json strokes = nlohmann::json::array();
        for (const ReplayErrors& e : m.strokes)
          strokes.push_back(ErrorsJson(e, false, m.predicts_slip));
        jm["strokes"] = strokes;
      }
      replay.push_back(jm);
    }
    j["replay"] = replay;
    j["replay_skipped"] = nlohmann::json::array();
    if (!lugre_replayed && r.status == DiagnosisStatus::kOk) {
      j["replay_skipped"].push_back(
          "lugre: not replayed (no LuGre model: the material has no "
          "identified LuGre family, or friction diagnose got neither "
          "--lugre mu_s,mu_c,v0,sigma2,sigma0,sigma1 nor --lugre-from ID)");
    }
  }
  if (json_options.tests) {
    nlohmann::json tests = nlohmann::json::array();
    for (const CandidateTest& t : r.tests) {
      tests.push_back({{"step", t.step},
                       {"cause", t.cause},
                       {"kind", t.kind},
                       {"expansion", t.expansion},
                       {"terms", t.terms},
                       {"cv_mae", Number(t.cv_mae)},
                       {"gain_pct", Number(t.gain_pct)},
                       {"t", Number(t.t_stat)},
                       {"p_raw", Number(t.p_raw)},
                       {"p_holm", Number(t.p_holm)},
                       {"significant", t.significant}});
    }
    j["tests"] = tests;
  }
  return j;
}

}  // namespace frictiond
