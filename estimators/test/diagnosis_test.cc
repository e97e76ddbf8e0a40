#include "frictiond/estimators/diagnosis.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/regression.h"
#include "frictiond/testing/lugre_strokes.h"
#include "frictiond/testing/planted_effects.h"

namespace frictiond {
namespace {

using testing::GeneratePlantedStrokes;
using testing::PlantedCause;
using testing::PlantedEffect;
using testing::PlantedSpec;

DiagnosisResult DiagnosePlanted(PlantedEffect effect,
                                std::uint64_t seed,
                                int noise_columns = 2,
                                bool replay = false) {
  PlantedSpec spec;
  spec.effect = effect;
  spec.noise_columns = noise_columns;
  DiagnosisOptions options;
  options.replay = replay;
  return Diagnose(PrepareDiagnosisData(GeneratePlantedStrokes(spec, seed),
                                       options.labelling),
                  options);
}

std::string Describe(const DiagnosisResult& r) {
  std::string s = std::string(ToString(r.status)) + " " + r.why + "; findings:";
  for (const Finding& f : r.findings) {
    s += " [" + f.cause + " " + f.kind + " " + f.expansion + " gain " +
         std::to_string(f.cv_mae_gain_pct) + "% p " +
         std::to_string(f.p_value) + "]";
  }
  return s;
}

TEST(DiagnosisTermsTest, NewKindsRoundTrip) {
  for (const char* name : {"hinge(fn_n,2.5)",
                           "sind(dir_deg)",
                           "cosd(heading)",
                           "onset(dwell_s,0.15)",
                           "onset(dwell_s,0.15,0)",
                           "in(contact_x_mm,20,26)",
                           "fn_n^2",
                           "fn_n*v_mm_s"}) {
    const Term t = Term::Parse(name);
    EXPECT_EQ(t.Name(), name);
    EXPECT_EQ(Term::Parse(t.Name()), t) << name;
  }
  EXPECT_DOUBLE_EQ(Term::Parse("hinge(x,2)").Eval(3.5), 1.5);
  EXPECT_DOUBLE_EQ(Term::Parse("hinge(x,2)").Eval(1.0), 0.0);
  EXPECT_NEAR(Term::Parse("sind(x)").Eval(30.0), 0.5, 1e-12);
  EXPECT_NEAR(Term::Parse("cosd(x)").Eval(60.0), 0.5, 1e-12);
  const Term onset = Term::Parse("onset(dwell_s,0.2)");
  EXPECT_DOUBLE_EQ(onset.Eval(2.0), 0.0);  // steady sliding
  EXPECT_NEAR(onset.Eval(2.0, 0.2), 2.0 * std::exp(-1.0), 1e-12);
  EXPECT_NEAR(Term::Parse("onset(dwell_s,0.2,0)").Eval(2.0, 0.0), 1.0, 1e-12);
  EXPECT_THROW(Term::Parse("onset(dwell_s,-1)"), std::invalid_argument);
  EXPECT_THROW(Term::Parse("hinge(x)"), std::invalid_argument);
}

TEST(DiagnosisTermsTest, TimeSinceSlipOnset) {
  StrokeData d;
  d.t_s = {0.0, 0.1, 0.2, 0.3, 0.4, 0.5};
  d.slip = {0, 1, 1, 0, 1, 1};
  d.stroke = {0, 0, 0, 1, 1, 1};
  const std::vector<double> s = CalcTimeSinceSlipOnset(d);
  EXPECT_TRUE(std::isinf(s[0]));
  EXPECT_NEAR(s[1], 0.0, 1e-12);
  EXPECT_NEAR(s[2], 0.1, 1e-12);
  EXPECT_TRUE(std::isinf(s[3]));
  EXPECT_NEAR(s[5], 0.1, 1e-12);
}

TEST(DiagnosisOptionsTest, RejectsBadOptionsNamingTheField) {
  DiagnosisOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.folds = 1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("folds = 1"), std::string::npos) << why;
  o = DiagnosisOptions();
  o.alpha = 1.5;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("alpha"), std::string::npos) << why;
  o = DiagnosisOptions();
  o.baseline_terms = {"v_mm_s"};
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("intercept"), std::string::npos) << why;
  EXPECT_THROW(Diagnose(StrokeData(), o), std::invalid_argument);
}

TEST(DiagnosisTest, AutoSlipThresholdsFollowTheSpeedScale) {
  std::vector<double> slow(1000);
  for (int i = 0; i < 1000; ++i) slow[i] = 0.26 * i / 999.0;
  std::string rule;
  const SlipLabelOptions o =
      CalcAutoSlipLabelOptions(slow, SlipLabelOptions(), &rule);
  EXPECT_NEAR(o.peak_mm_s, 0.25 * 0.2574, 2e-3) << rule;
  EXPECT_NEAR(o.floor_mm_s, 0.08 * 0.2574, 1e-3) << rule;
  std::vector<double> fast(1000);
  for (int i = 0; i < 1000; ++i) fast[i] = 80.0 * i / 999.0;
  const SlipLabelOptions p =
      CalcAutoSlipLabelOptions(fast, SlipLabelOptions(), &rule);
  EXPECT_EQ(p.peak_mm_s, 10.0);
  EXPECT_EQ(p.floor_mm_s, 5.0);
}

TEST(DiagnosisTest, TooFewStrokesIsAStatus) {
  PlantedSpec spec;
  spec.strokes = 2;
  const DiagnosisResult r = Diagnose(GeneratePlantedStrokes(spec, 3));
  EXPECT_EQ(r.status, DiagnosisStatus::kTooFewStrokes) << r.why;
  EXPECT_FALSE(r.why.empty());
}

// Constant mu (the baseline's held-out error is 0): every gain is 0, never
// NaN (written as null where CONTRACT.md promises a number; outside attack
// run).
TEST(DiagnosisTest, ConstantDataGivesFiniteZeroGains) {
  PlantedSpec spec;
  spec.strokes = 12;
  StrokeData d = GeneratePlantedStrokes(spec, 5);
  for (std::size_t i = 0; i < d.size(); ++i) d.ft_n[i] = 0.5 * d.fn_n[i];
  const DiagnosisResult r = Diagnose(d);
  ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
  EXPECT_TRUE(std::isfinite(r.gain_pct));
  EXPECT_EQ(r.gain_pct, 0.0);
  EXPECT_TRUE(std::isfinite(r.selection_bias_pct));
  EXPECT_TRUE(r.findings.empty()) << Describe(r);
  for (const CandidateTest& t : r.tests) EXPECT_TRUE(std::isfinite(t.gain_pct));
}

// Rates of naming planted effects first, and false alarms on null data,
// over many seeds: diagnosis_rates_test.cc (ctest LABEL slow).

TEST(DiagnosisTest, PlantedEffectKindsAndTerms) {
  const DiagnosisResult fn = DiagnosePlanted(PlantedEffect::kNonlinearFn, 1);
  ASSERT_FALSE(fn.findings.empty()) << Describe(fn);
  EXPECT_EQ(fn.findings[0].kind, "form");
  const DiagnosisResult onset =
      DiagnosePlanted(PlantedEffect::kOnsetTransient, 1);
  ASSERT_FALSE(onset.findings.empty()) << Describe(onset);
  EXPECT_EQ(onset.findings[0].kind, "regime");
  const DiagnosisResult temp = DiagnosePlanted(PlantedEffect::kTemperature, 1);
  ASSERT_FALSE(temp.findings.empty()) << Describe(temp);
  EXPECT_EQ(temp.findings[0].kind, "covariate");
  // The extended model is the baseline's terms followed by the findings'.
  std::vector<std::string> expected = temp.baseline.terms;
  for (const Finding& f : temp.findings)
    expected.insert(expected.end(), f.terms.begin(), f.terms.end());
  EXPECT_EQ(temp.extended.terms, expected);
  for (const std::string& name : temp.extended.terms)
    EXPECT_EQ(Term::Parse(name).Name(), name);
  double sum = 0.0;
  for (const Finding& f : temp.findings) sum += f.cv_mae_gain_pct;
  EXPECT_NEAR(sum, temp.gain_pct, 1e-9);
  EXPECT_GT(temp.log_likelihood_gain, 0.0);
  // Outer figures: the selection's own (inner) gain minus the outer gain is
  // reported, and the finding was chosen inside the outer folds too.
  EXPECT_TRUE(std::isfinite(temp.selection_bias_pct));
  EXPECT_NEAR(temp.selection_bias_pct,
              temp.findings[0].selection_bias_pct,
              1e-9 + std::fabs(temp.selection_bias_pct));
  EXPECT_GE(temp.findings[0].folds_selected, 1);
  EXPECT_LE(temp.findings[0].folds_selected, temp.folds);
  EXPECT_EQ(temp.folds, 10);
  EXPECT_EQ(temp.inner_folds, 5);
}

// Blocked folds (default) and shuffled folds give the same finding on a
// strong effect; the options are validated.
TEST(DiagnosisTest, BlockedAndShuffledFolds) {
  PlantedSpec spec;
  spec.effect = PlantedEffect::kTemperature;
  spec.strokes = 60;
  DiagnosisOptions o;
  o.replay = false;
  const StrokeData data =
      PrepareDiagnosisData(GeneratePlantedStrokes(spec, 2), o.labelling);
  const DiagnosisResult blocked = Diagnose(data, o);
  o.shuffle_folds = true;
  o.seed = 9;
  const DiagnosisResult shuffled = Diagnose(data, o);
  ASSERT_FALSE(blocked.findings.empty()) << Describe(blocked);
  ASSERT_FALSE(shuffled.findings.empty()) << Describe(shuffled);
  EXPECT_EQ(blocked.findings[0].cause, "temp_c");
  EXPECT_EQ(shuffled.findings[0].cause, "temp_c");
  EXPECT_NE(blocked.baseline.cv_mae, shuffled.baseline.cv_mae);
  std::string why;
  o.inner_folds = 1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("inner_folds = 1"), std::string::npos) << why;
}

// Issue 18 item 2: the Fn slope depends on a per-stroke column with a
// meaningless name (no main effect): found as an interaction x*y whose
// term round-trips.
TEST(DiagnosisTest, InteractionFound) {
  const testing::WideCase c =
      testing::GenerateWideCase(testing::WideKind::kInteraction, 3, 100);
  DiagnosisOptions o;
  o.replay = false;
  const DiagnosisResult r =
      Diagnose(PrepareDiagnosisData(c.data, o.labelling), o);
  ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
  ASSERT_FALSE(r.findings.empty()) << c.truth << Describe(r);
  EXPECT_EQ(r.findings[0].cause, c.cause) << c.truth << Describe(r);
  EXPECT_EQ(r.findings[0].kind, "interaction");
  EXPECT_NE(r.findings[0].effect.find("slope"), std::string::npos);
  for (const std::string& t : r.findings[0].terms)
    EXPECT_EQ(Term::Parse(t).Name(), t);
}

// Issue 18 item 3: noise growing with a column is a spread finding; the
// extended model carries the eps scale, which grows with that column.
TEST(DiagnosisTest, SpreadFoundAndServed) {
  const testing::WideCase c =
      testing::GenerateWideCase(testing::WideKind::kSpread, 2, 100);
  DiagnosisOptions o;
  o.replay = false;
  const DiagnosisResult r =
      Diagnose(PrepareDiagnosisData(c.data, o.labelling), o);
  ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
  const Finding* spread = nullptr;
  for (const Finding& f : r.findings) {
    if (f.kind == "spread") spread = &f;
  }
  ASSERT_NE(spread, nullptr) << c.truth << Describe(r) << " " << r.why;
  EXPECT_EQ(spread->cause, c.cause);
  EXPECT_LT(spread->p_value, 0.05);
  EXPECT_GT(spread->log_likelihood_gain, 0.0);
  ASSERT_TRUE(r.extended.eps_scale.has_value());
  const EpsScaleModel& s = *r.extended.eps_scale;
  EXPECT_EQ(s.input, c.cause);
  EXPECT_GT(s.log_sigma_slope, 0.0);
  EXPECT_GT(s.ScaleFactor(s.x_max), 2.0 * s.ScaleFactor(s.x_min));
  EXPECT_DOUBLE_EQ(s.Sigma(s.x_max + 100.0), s.Sigma(s.x_max));  // clamped
  EXPECT_NE(r.extended.model.find("scale(" + c.cause + ")"), std::string::npos);
}

// Issue 18 item 4, designed: two columns drifting together over the
// recording (correlation ~0.95), only `load_h` acts on mu. On the
// confounded data the diagnosis names one and lists the other as an
// alternative it cannot tell apart (the effect text says so). In new data
// where the confound is broken (the columns independent) the causal column
// predicts and the other does not: the model with load_h (fitted on the
// confounded data) beats the baseline on the new data, the model with
// oven_c does not, and the diagnosis of the new data names load_h alone.
StrokeData AddConfounded(StrokeData d,
                         std::uint64_t seed,
                         bool confounded,
                         double effect) {
  d = PrepareDiagnosisData(std::move(d), SlipLabelOptions());
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<double> load(d.size()), oven(d.size());
  double a = 0.0, b = 0.0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (i == 0 || d.stroke[i] != d.stroke[i - 1]) {
      a = 0.9 * a + 0.45 * normal(rng);
      b = confounded ? a + 0.15 * normal(rng) : 0.9 * b + 0.45 * normal(rng);
    }
    load[i] = 10.0 + 3.0 * a;
    oven[i] = 40.0 + 5.0 * b;
    if (d.slip[i] == 1) d.ft_n[i] += effect * a * d.fn_n[i];
  }
  d.covariate_names.push_back("load_h");
  d.covariates.push_back(load);
  d.covariate_names.push_back("oven_c");
  d.covariates.push_back(oven);
  return d;
}

double HeldMae(const StrokeData& d,
               const std::vector<std::string>& names,
               const std::vector<double>& beta) {
  std::vector<Term> terms;
  for (const std::string& n : names) terms.push_back(Term::Parse(n));
  const std::vector<bool> mask = CalcFitMask(d, SlipLabelOptions());
  std::vector<std::size_t> rows;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (mask[i]) rows.push_back(i);
  }
  const Eigen::MatrixXd X = BuildDesign(d, terms, rows);
  double sae = 0.0;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    double m = 0.0;
    for (std::size_t j = 0; j < beta.size(); ++j) m += X(k, j) * beta[j];
    sae += std::fabs(d.mu(rows[k]) - m);
  }
  return sae / rows.size();
}

TEST(DiagnosisTest, ConfoundersNamedAndBrokenConfoundPredicts) {
  PlantedSpec spec;
  spec.strokes = 100;
  spec.write_labels = true;
  const StrokeData train =
      AddConfounded(GeneratePlantedStrokes(spec, 21), 5, true, 0.04);
  const StrokeData fresh =
      AddConfounded(GeneratePlantedStrokes(spec, 22), 6, false, 0.04);
  DiagnosisOptions o;
  o.replay = false;
  const DiagnosisResult r = Diagnose(train, o);
  ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
  ASSERT_FALSE(r.findings.empty()) << Describe(r);
  const Finding& f = r.findings[0];
  ASSERT_TRUE(f.cause == "load_h" || f.cause == "oven_c") << Describe(r);
  const std::string other = f.cause == "load_h" ? "oven_c" : "load_h";
  bool listed = false;
  for (const Alternative& a : f.alternatives) {
    if (a.cause == other) {
      listed = true;
      EXPECT_GT(a.correlation, 0.8);
    }
  }
  EXPECT_TRUE(listed) << other << " not listed as an alternative: " << f.effect;
  EXPECT_NE(f.effect.find("cannot tell"), std::string::npos) << f.effect;
  // Each of the two models, fitted on the confounded data, predicting the
  // new data.
  auto fit_with = [&](const std::string& column) {
    DiagnosisOptions m = o;
    m.baseline_terms = {"intercept", "v_mm_s", "fn_n", column};
    m.max_findings = 0;
    m.spread = false;
    const DiagnosisResult rm = Diagnose(train, m);
    EXPECT_EQ(rm.status, DiagnosisStatus::kOk) << rm.why;
    return HeldMae(fresh, rm.baseline.terms, rm.baseline.beta);
  };
  const double mae_load = fit_with("load_h");
  const double mae_oven = fit_with("oven_c");
  const double mae_base = HeldMae(fresh, r.baseline.terms, r.baseline.beta);
  std::printf(
      "[ confound broken ] new-data MAE: load_h model %.4f, oven_c model "
      "%.4f, baseline %.4f (chosen on confounded data: %s)\n",
      mae_load,
      mae_oven,
      mae_base,
      f.cause.c_str());
  EXPECT_LT(mae_load, 0.95 * mae_base);
  EXPECT_GT(mae_oven, mae_base);
  const DiagnosisResult rf = Diagnose(fresh, o);
  ASSERT_FALSE(rf.findings.empty()) << Describe(rf);
  EXPECT_EQ(rf.findings[0].cause, "load_h") << Describe(rf);
  for (const Alternative& a : rf.findings[0].alternatives)
    EXPECT_NE(a.cause, "oven_c") << rf.findings[0].effect;
}

// Issue 7: 25,000 samples with 10 candidate columns (timing: bench).
TEST(DiagnosisTest, Speed25kSamplesTenCandidates) {
  PlantedSpec spec;
  spec.effect = PlantedEffect::kTemperature;
  spec.strokes = 240;
  spec.noise_columns = 2;  // temp_c, dir_deg, contact_x_mm, noise_0, noise_1 +
                           // 5 derived = 10 columns
  DiagnosisOptions options;
  const StrokeData data =
      PrepareDiagnosisData(GeneratePlantedStrokes(spec, 5), options.labelling);
  const auto t0 = std::chrono::steady_clock::now();
  const DiagnosisResult r = Diagnose(data, options);
  const double s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
          .count();
  ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
  std::printf(
      "[ speed ] %zu samples, %zu covariate columns, %zu candidates, %zu "
      "tests: %.3f s\n",
      data.size(),
      data.covariate_names.size(),
      r.candidates.size(),
      r.tests.size(),
      s);
  EXPECT_GE(data.size(), 25000u);
  EXPECT_EQ(data.covariate_names.size(), 10u);
  // The 5 s budget is the diagnose_25k benchmark's goal (bench/), not a
  // timed unit test (this also runs under the sanitizers).
}

}  // namespace
}  // namespace frictiond
