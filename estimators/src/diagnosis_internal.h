#pragma once
// Internal to the model diagnosis (not installed): the pieces shared by
// diagnosis.cc (options, entry), diagnosis_cv.cc (cross-validation, tests),
// diagnosis_candidates.cc (candidate causes, effect texts),
// diagnosis_replay.cc (model replay) and diagnosis_search.cc (nested
// selection, spread, alternatives).

#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/estimators/regression.h"

namespace frictiond::diagnosis_internal {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string Num(double x, int digits = 3);
/// Held-out gain [%]: 100 (before - after) / reference; 0 when the reference
/// error is 0 (a perfect baseline, e.g. constant data, has nothing to gain:
/// the division gave NaN, written as null where CONTRACT.md promises a
/// number; outside attack run).
inline double GainPct(double before, double after, double reference) {
  return reference > 0 ? 100.0 * (before - after) / reference : 0.0;
}
bool EndsWith(const std::string& s, const std::string& suffix);
/// Canonical term: Parse(Name()) so that numbers carry the name's precision
/// and the stored term list reproduces the tested model exactly.
Term Canonical(TermKind kind,
               const std::string& input,
               double a = 0.0,
               double b = 0.0);
/// Rounds to the 6 significant digits term names keep.
double RoundForName(double x);
std::vector<std::string> Names(const std::vector<Term>& terms);

/// A candidate cause tried as one set of extra terms.
struct Expansion {
  std::string cause;
  std::string kind;
  std::string name;
  std::vector<Term> terms;  // fixed terms (empty for a window scan)
  std::vector<Term>
      scan;  // window scan: one of these is chosen on training data
};

/// Rows to fit, grouped by fold, and the stroke bookkeeping of the CV.
struct CvSetup {
  std::vector<std::size_t> rows;     // fit rows, ordered by fold
  std::vector<int> fold_begin;       // K + 1 offsets into rows
  std::vector<int> stroke_of_entry;  // dense stroke index per entry of rows
  std::map<int, int> dense_of_id;    // stroke id -> dense index (all strokes)
  std::vector<int> id_of_dense;
  std::vector<int> fold_of_dense;  // fold per dense stroke
  std::vector<int> fit_count;      // fit rows per dense stroke
  int strokes_with_fit = 0;
  double mean_per_stroke = 1.0;
  Eigen::VectorXd y;
  int folds = 0;
};

/// Cross-validation over the rows where `use` is true: strokes with such
/// rows are split into min(folds, strokes) folds, as contiguous blocks in
/// the order the strokes appear in the data (recording order) unless
/// `shuffle` (then a seeded Fisher-Yates shuffle, round robin).
CvSetup BuildCv(const StrokeData& data,
                const std::vector<bool>& use,
                int folds,
                bool shuffle,
                std::uint64_t seed);

/// Coefficients fitted on each fold's training part (original scale).
struct FoldModels {
  bool ok = false;
  std::vector<Eigen::VectorXd> beta;
  std::vector<double> sigma;
};

/// Fits y ~ X on all folds but one, for each fold, from per-fold Gram
/// matrices of standardised columns (one pass over X). Column 0 must be the
/// intercept. A tiny ridge keeps collinear and empty columns at 0.
FoldModels FitFolds(const Eigen::MatrixXd& X,
                    const Eigen::VectorXd& y,
                    const std::vector<int>& fold_begin);

/// Held-out performance of one model.
struct CvEval {
  bool ok = false;
  Eigen::VectorXd residuals;       // per entry of CvSetup::rows
  std::vector<double> stroke_sae;  // per dense stroke
  double mae = 0.0;
  double log_likelihood = 0.0;  // mean per sample
  FoldModels models;
};

CvEval Evaluate(const CvSetup& cv, const Eigen::MatrixXd& X);

/// A window scan over one column: windows [edges[i], edges[j]) as level
/// ranges, and each CV row's level (-1 outside all edges).
struct WindowScan {
  std::vector<double> edges;
  std::vector<std::pair<int, int>> windows;  // per scan term
  std::vector<int> level;                    // per entry of CvSetup::rows
};
WindowScan MakeWindowScan(const std::vector<Term>& windows,
                          const std::vector<double>& column,
                          const std::vector<std::size_t>& rows);

/// Picks the window whose indicator best explains residuals r (largest
/// (sum r)^2 / count over rows where `use`), among windows covering at least
/// 1 % of those rows. Returns -1 when none qualifies. O(rows + windows).
int PickWindow(const WindowScan& scan,
               const Eigen::VectorXd& r,
               const std::vector<char>& use);

/// Held-out evaluation of current model + one window chosen per fold on that
/// fold's training rows only (the choice is part of the fitted model, so the
/// held-out error is honest). *chosen_all is the window chosen on all rows.
CvEval EvaluateWindowScan(const CvSetup& cv,
                          const Eigen::MatrixXd& X_cur,
                          const CvEval& cur,
                          const Eigen::VectorXd& full_residuals,
                          const WindowScan& scan,
                          int* chosen_all);

/// One-sided paired t-test over per-stroke differences d (strokes with
/// `use`); returns {t, p} for H1: mean d > 0.
std::pair<double, double> OneSidedT(const std::vector<double>& d);

/// One-sided paired t-test over strokes that `cand` has lower held-out
/// absolute error than `cur`. Returns {t, p}.
std::pair<double, double> PairedStrokeTest(const CvSetup& cv,
                                           const CvEval& cur,
                                           const CvEval& cand);

/// Holm's step-down adjustment.
std::vector<double> HolmAdjust(const std::vector<double>& p);

/// Summary of one column on the fit rows.
struct ColumnSummary {
  std::vector<double> sorted;  // values on fit rows, ascending
  int distinct = 0;            // capped at cap + 1
  std::vector<double> levels;  // distinct values when few
};
ColumnSummary SummarizeColumn(const std::vector<double>& col,
                              const std::vector<std::size_t>& rows,
                              int cap);

/// Candidate expansions of every candidate cause, from the values on `rows`
/// only (so that an inner selection never sees its outer test rows).
std::vector<Expansion> BuildExpansions(
    const StrokeData& data,
    const std::vector<std::size_t>& rows,
    const std::vector<std::string>& form_inputs,
    const DiagnosisOptions& options,
    std::vector<std::string>* candidates,
    std::vector<std::string>* skipped);

/// Interaction expansion of columns x and y (kind "interaction", cause
/// "x*y"): the product column (which `data` must hold as covariate "x*y")
/// plus the main effects not in `current`.
Expansion InteractionExpansion(const std::string& x,
                               const std::string& y,
                               const std::vector<Term>& current);

std::string UnitOf(const std::string& name);

std::string DescribeEffect(const Expansion& e,
                           const std::vector<Term>& terms,
                           const Eigen::VectorXd& beta,
                           const StrokeData& data,
                           const std::vector<std::size_t>& rows);

/// Peak measured Ft/Fn around a stroke's first slip onset.
double MeasuredBreakaway(const StrokeData& data,
                         std::size_t i,
                         std::size_t j,
                         double window_s,
                         std::size_t* onset);

ModelReplay Replay(const std::string& model_name,
                   const std::vector<Term>& terms,
                   const StrokeData& data,
                   const CvSetup& cv,
                   const CvEval& mu_eval,
                   const DiagnosisOptions& options);

ModelReplay ReplayLuGre(const LuGreTheta& theta,
                        const StrokeData& data,
                        const CvSetup& cv,
                        const DiagnosisOptions& options);

/// The search and its evaluation (diagnosis_search.cc): `data` prepared
/// (labels, derived features, product columns), `mask` its fit rows,
/// `result` with the counts filled in.
DiagnosisResult RunDiagnosis(const StrokeData& data,
                             const DiagnosisOptions& options,
                             const std::vector<bool>& mask,
                             DiagnosisResult result);

}  // namespace frictiond::diagnosis_internal
