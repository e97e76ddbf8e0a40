// Detection and false-alarm RATES of the model diagnosis over many seeds
// (issue 18 item 5), on planted cases from families wider than the
// candidate list (tests/testing planted_effects: GenerateWideCase) and on
// the original planted effects. ctest LABEL "slow" (not rerun under the
// sanitizers).
//
// Each kind runs FRICTIOND_DIAGNOSIS_SEEDS seeds (default 20; the table in
// docs/diagnosis.md uses 50) on 100 strokes (~10,000 samples; the
// generators' default data size; the first three rates rounds used 60).
//
// What is asserted is a rate, tested against its goal with an exact
// binomial test at 5 %: an effect kind fails when P(X <= named first | n,
// goal) < 0.05 (the data show the rate is below the goal; for the issue's
// 90 % and 20 seeds this means fewer than 16/20; kinds where the method
// falls short are held to their measured rate, see Goal()), and the nulls (all
// null kinds pooled) fail when P(X >= false alarms | n, 0.05) < 0.05 (the rate
// is above the nominal 5 %; with 5 x 20 = 100 runs, 10 or more alarms). A fixed
// seed list keeps the test deterministic. The printed markdown table is what
// the docs show.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/estimators/number_text.h"
#include "frictiond/testing/planted_effects.h"

namespace frictiond {
namespace {

using testing::GeneratePlantedStrokes;
using testing::GenerateWideCase;
using testing::PlantedEffect;
using testing::PlantedSpec;
using testing::WideKind;

/// Strokes per case: 100 (the generators' default), or
/// FRICTIOND_DIAGNOSIS_STROKES (by hand; the first three rates rounds of
/// docs/diagnosis.md used 60).
int Strokes() {
  const char* env = std::getenv("FRICTIOND_DIAGNOSIS_STROKES");
  return env ? std::max(10, std::atoi(env)) : 100;
}

int Seeds() {
  const char* env = std::getenv("FRICTIOND_DIAGNOSIS_SEEDS");
  return env ? std::max(1, std::atoi(env)) : 20;
}

/// FRICTIOND_DIAGNOSIS_FIRST_SEED=101 runs seeds 101.. instead of 1.. (the
/// tuning seeds of docs/diagnosis.md; unset = 1, as in CI and the table).
int FirstSeed() {
  const char* env = std::getenv("FRICTIOND_DIAGNOSIS_FIRST_SEED");
  return env ? std::max(1, std::atoi(env)) : 1;
}

/// FRICTIOND_DIAGNOSIS_KINDS=a,b runs only those kinds (while iterating;
/// unset = every kind, as in CI).
bool Wanted(const std::string& kind) {
  const char* env = std::getenv("FRICTIOND_DIAGNOSIS_KINDS");
  if (!env || !*env) return true;
  const std::string list = std::string(",") + env + ",";
  return list.find("," + kind + ",") != std::string::npos;
}

/// P(X <= k) for X ~ Binomial(n, p).
double BinomialCdf(int k, int n, double p) {
  double sum = 0.0;
  for (int i = 0; i <= k; ++i) {
    sum += std::exp(std::lgamma(n + 1.0) - std::lgamma(i + 1.0) -
                    std::lgamma(n - i + 1.0) + i * std::log(p) +
                    (n - i) * std::log1p(-p));
  }
  return std::min(1.0, sum);
}

/// The findings; with FRICTIOND_DIAGNOSIS_DEBUG set also the 4 best
/// candidate tests of each step of the selection on all strokes (inner
/// figures), to see what a miss would have needed.
std::string Describe(const DiagnosisResult& r) {
  std::string s;
  if (std::getenv("FRICTIOND_DIAGNOSIS_DEBUG")) {
    std::vector<CandidateTest> t = r.tests;
    std::sort(t.begin(), t.end(), [](const auto& a, const auto& b) {
      return a.step != b.step ? a.step < b.step : a.gain_pct > b.gain_pct;
    });
    int shown = 0, step = -1;
    for (const auto& c : t) {
      if (c.step != step) step = c.step, shown = 0;
      if (shown++ < 4)
        s += "\n    step " + std::to_string(c.step) + " " + c.cause + " " +
             c.expansion + " gain " + std::to_string(c.gain_pct) + " p " +
             std::to_string(c.p_raw) + (c.significant ? " *" : "");
    }
    s += "\n   ";
  }
  for (const Finding& f : r.findings) {
    s += " [" + f.cause + " " + f.kind + " " + f.expansion;
    for (const Alternative& a : f.alternatives) s += " | or " + a.cause;
    s += "]";
  }
  return s.empty() ? " (none)" : s;
}

struct Row {
  std::string kind;
  int runs = 0, first = 0, any = 0;
  std::vector<std::string> failures;
};

/// True when the expected cause is named first among findings of its kind
/// class: mean findings ("covariate", "form", "regime", "interaction")
/// first for mean effects, the spread finding for spread effects.
bool NamedFirst(const DiagnosisResult& r,
                const std::string& cause,
                bool spread) {
  for (const Finding& f : r.findings) {
    if ((f.kind == "spread") != spread) continue;
    return f.cause == cause;
  }
  return false;
}

void PrintTable(const std::vector<Row>& rows, const std::string& title) {
  std::printf("\n| %s | seeds | named first | rate | any finding |\n",
              title.c_str());
  std::printf("|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    std::printf("| %s | %d | %d | %.0f %% | %d |\n",
                r.kind.c_str(),
                r.runs,
                r.first,
                100.0 * r.first / std::max(1, r.runs),
                r.any);
  }
  for (const Row& r : rows) {
    for (const std::string& f : r.failures)
      std::printf("[ miss ] %s %s\n", r.kind.c_str(), f.c_str());
  }
}

/// The rate each kind is tested against: the goal, 90 %, except
/// where the method measurably falls short of it at this data size
/// (docs/diagnosis.md, "Where it fails"); those kinds are held to the rate
/// measured over 50 seeds, so that a regression still fails.
double Goal(const std::string& kind) {
  // Gaussian level shifts, which can be arbitrarily small (50 seeds: 86 %
  // at 100 strokes, 80 % at 60); categorical_bounded (shifts' sd
  // 0.04-0.06) is held to the goal.
  if (kind == "categorical") return 0.8;
  return 0.9;
}

/// The categorical draws whose realised shift size (WideCase::effect_sd)
/// is at least the other kinds' planted sizes (smooth curve 0.05,
/// interaction about 0.035-0.06, categorical_bounded 0.04-0.06) are held
/// to the goal: the Gaussian kind's shortfall is its draws below it.
constexpr double kComparableSd = 0.035;

void ExpectRate(const Row& row) {
  const double goal = Goal(row.kind);
  const double p = BinomialCdf(row.first, row.runs, goal);
  EXPECT_GE(p, 0.05) << row.kind << ": named first in " << row.first << "/"
                     << row.runs << " seeds; P(X <= " << row.first << " | rate "
                     << goal << ") = " << p << " (the rate is below "
                     << 100 * goal << " %)";
  if (goal < 0.9) {
    std::printf(
        "[ below goal ] %s: tested against %.0f %%, not the 90 %% "
        "goal (%d/%d)\n",
        row.kind.c_str(),
        100 * goal,
        row.first,
        row.runs);
  }
}

DiagnosisOptions Options() {
  DiagnosisOptions o;
  o.replay = false;
  return o;
}

TEST(DiagnosisRatesTest, WiderFamiliesNamedFirst) {
  const int seeds = Seeds();
  std::vector<Row> rows;
  for (WideKind kind : {WideKind::kSmoothCurve,
                        WideKind::kInteraction,
                        WideKind::kSpread,
                        WideKind::kCategorical,
                        WideKind::kCategoricalBounded}) {
    Row row;
    row.kind = testing::ToString(kind);
    if (!Wanted(row.kind)) continue;
    // The Gaussian draws of comparable size (kComparableSd), tallied apart.
    Row sized;
    sized.kind = row.kind + " (drawn sd >= " + NumberText(kComparableSd) + ")";
    for (int seed = FirstSeed(); seed < FirstSeed() + seeds; ++seed) {
      const testing::WideCase c = GenerateWideCase(kind, seed, Strokes());
      const DiagnosisOptions o = Options();
      const DiagnosisResult r =
          Diagnose(PrepareDiagnosisData(c.data, o.labelling), o);
      ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
      const bool first = NamedFirst(r, c.cause, c.kind == "spread");
      ++row.runs;
      row.any += !r.findings.empty();
      std::string size;
      if (c.effect_sd > 0) size = ", sd " + NumberText(c.effect_sd);
      if (first) {
        ++row.first;
      } else {
        row.failures.push_back("seed " + std::to_string(seed) + " (" + c.truth +
                               size + "):" + Describe(r));
      }
      if (kind == WideKind::kCategorical && c.effect_sd >= kComparableSd) {
        ++sized.runs;
        sized.any += !r.findings.empty();
        sized.first += first;
      }
    }
    rows.push_back(row);
    if (sized.runs > 0) rows.push_back(sized);
  }
  PrintTable(rows, "planted (wider families)");
  for (const Row& row : rows) ExpectRate(row);
}

// Detection against the size of a categorical effect: the level pattern of
// categorical_bounded (same seeds), its shifts scaled to an exact sd over
// the strokes. A report for docs/diagnosis.md ("Power against size"), run
// by hand: FRICTIOND_DIAGNOSIS_POWER=1 (with FRICTIOND_DIAGNOSIS_SEEDS=50);
// nothing is asserted.
TEST(DiagnosisRatesTest, CategoricalPowerAgainstSize) {
  if (!std::getenv("FRICTIOND_DIAGNOSIS_POWER"))
    GTEST_SKIP() << "set FRICTIOND_DIAGNOSIS_POWER=1 to run";
  std::vector<Row> rows;
  for (const double sd : {0.01, 0.015, 0.02, 0.025, 0.03, 0.035, 0.04}) {
    Row row;
    row.kind = "categorical, sd " + NumberText(sd);
    for (int seed = FirstSeed(); seed < FirstSeed() + Seeds(); ++seed) {
      const testing::WideCase c =
          GenerateWideCase(WideKind::kCategoricalBounded, seed, Strokes(), sd);
      const DiagnosisOptions o = Options();
      const DiagnosisResult r =
          Diagnose(PrepareDiagnosisData(c.data, o.labelling), o);
      ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
      ++row.runs;
      row.any += !r.findings.empty();
      row.first += NamedFirst(r, c.cause, false);
    }
    rows.push_back(row);
  }
  PrintTable(rows, "categorical power against size");
}

TEST(DiagnosisRatesTest, OriginalEffectsNamedFirst) {
  const int seeds = Seeds();
  std::vector<Row> rows;
  for (PlantedEffect effect : {PlantedEffect::kTemperature,
                               PlantedEffect::kDirection,
                               PlantedEffect::kWear,
                               PlantedEffect::kOnsetTransient,
                               PlantedEffect::kNonlinearFn,
                               PlantedEffect::kPositionPatch}) {
    Row row;
    row.kind = testing::ToString(effect);
    if (!Wanted(row.kind)) continue;
    const std::string cause = testing::PlantedCause(effect);
    for (int seed = FirstSeed(); seed < FirstSeed() + seeds; ++seed) {
      PlantedSpec spec;
      spec.effect = effect;
      spec.strokes = Strokes();
      const DiagnosisOptions o = Options();
      const DiagnosisResult r = Diagnose(
          PrepareDiagnosisData(GeneratePlantedStrokes(spec, seed), o.labelling),
          o);
      ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
      ++row.runs;
      row.any += !r.findings.empty();
      if (NamedFirst(r, cause, false)) {
        ++row.first;
      } else {
        row.failures.push_back("seed " + std::to_string(seed) + ":" +
                               Describe(r));
      }
    }
    rows.push_back(row);
  }
  PrintTable(rows, "planted (original effects)");
  for (const Row& row : rows) ExpectRate(row);
}

TEST(DiagnosisRatesTest, NullFalseAlarms) {
  const int seeds = Seeds();
  std::vector<Row> rows;
  int runs = 0, alarms = 0;
  auto tally = [&](Row& row, const DiagnosisResult& r, int seed) {
    ++row.runs;
    ++runs;
    if (!r.findings.empty()) {
      ++row.any;
      ++alarms;
      row.failures.push_back("seed " + std::to_string(seed) + ":" +
                             Describe(r));
    } else {
      ++row.first;  // "named first" column: correctly silent
    }
  };
  for (WideKind kind : {WideKind::kNullHeavyTail,
                        WideKind::kNullOffsets,
                        WideKind::kNullArNoise,
                        WideKind::kNullManyColumns}) {
    Row row;
    row.kind = testing::ToString(kind);
    if (!Wanted(row.kind)) continue;
    for (int seed = FirstSeed(); seed < FirstSeed() + seeds; ++seed) {
      const testing::WideCase c = GenerateWideCase(kind, seed, Strokes());
      const DiagnosisOptions o = Options();
      const DiagnosisResult r =
          Diagnose(PrepareDiagnosisData(c.data, o.labelling), o);
      ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
      tally(row, r, seed);
    }
    rows.push_back(row);
  }
  if (Wanted("null_eq1_6_columns")) {
    Row row;
    row.kind = "null_eq1_6_columns";
    for (int seed = FirstSeed(); seed < FirstSeed() + seeds; ++seed) {
      PlantedSpec spec;
      spec.strokes = Strokes();
      spec.noise_columns = 6;
      const DiagnosisOptions o = Options();
      const DiagnosisResult r =
          Diagnose(PrepareDiagnosisData(
                       GeneratePlantedStrokes(spec, 100 + seed), o.labelling),
                   o);
      ASSERT_EQ(r.status, DiagnosisStatus::kOk) << r.why;
      tally(row, r, 100 + seed);
    }
    rows.push_back(row);
  }
  PrintTable(rows, "null (silent = no finding)");
  if (runs == 0) return;
  const double p = 1.0 - BinomialCdf(alarms - 1, runs, 0.05);
  std::printf("[ null ] false alarms %d/%d runs (%.1f %%)\n",
              alarms,
              runs,
              100.0 * alarms / runs);
  EXPECT_GE(p, 0.05) << alarms << "/" << runs
                     << " false alarms; P(X >= alarms | rate 0.05) = " << p;
}

}  // namespace
}  // namespace frictiond
