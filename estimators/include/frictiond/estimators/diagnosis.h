#pragma once
/// @file
/// Model diagnosis (issue 7): replay measured strokes through the friction
/// models, find what the simulation gets wrong, name the cause, extend the
/// model and measure the gain on held-out strokes.
///
/// Models replayed: Coulomb (mu = mu_c, constant), LuGre (paper 001, when a
/// parameter set is given: velocity-driven replay of each stroke) and the
/// stochastic linear model of paper 000, eq. (1):
///
///     mu(t) = b0 + b1 v(t) + b2 Fn(t) + eps                         (eq. 1)
///
/// fitted on slipping samples (section II-C labelling, III-C fitting). The
/// diagnosis then tests candidate causes of the remaining error: every extra
/// numeric column, the derived features of CONTRACT.md (distance_mm, dwell_s,
/// time_s, accel_mm_s2, fn_rate_n_s) and the functional form of the model's
/// inputs (fn_n, v_mm_s). Each candidate is tried as a few term expansions
/// (linear; sin/cos for angles; quadratic, log and hinges for forms; a binned
/// step basis and a scanned single window for localized patches; dwell-weighted
/// slip-onset transients exp(-s/tau) for dwell_s), each a list of regression
/// Terms, so an extended model is an ordinary term list the daemon can store.
///
/// Statistics (samples within a stroke are correlated, strokes differ;
/// issue 18, docs/diagnosis.md):
/// - nested cross-validation with folds assigned by stroke (contiguous
///   blocks in recording order by default): the whole selection runs on
///   each outer fold's training strokes with its own inner folds, and
///   every reported error, gain and p-value comes from the outer folds;
///   the reported model is the selection run on all strokes, and
///   selection_bias_pct is its inner gain minus the outer gain;
/// - significance is a one-sided paired t-test over strokes of
///   d_s = (held-out absolute error of the model without - with the
///   finding) summed over stroke s (normalised by the mean samples per
///   stroke, so mean d_s is the cv_mae gain); one stroke = one observation;
///   the findings the selection proposed are tested as a fixed sequence
///   (in selection order, each at alpha, stopping at the first failure;
///   adjusted p = largest raw p so far), plus a minimum practical gain
///   (min_gain_pct of the baseline cv_mae); inside the selection a
///   candidate needs raw p < selection_alpha;
/// - greedy forward selection over candidates x expansions (linear,
///   splines, quadratic/log/hinge forms, periodic, bins/levels, windows,
///   onset transients, pairwise interactions "x*y"), largest significant
///   gain first;
/// - spread: a log-linear scale model of eps in each input/column against a
///   constant scale, fitted and scored on the within-stroke first
///   differences of the residuals (offsets and slow wander cancel),
///   held-out Gaussian log-likelihood per stroke, Holm over the columns
///   (kind "spread", EpsScaleModel in the extended model);
/// - alternatives: candidates whose gain lies in the finding's 95 %
///   confidence interval (the data cannot tell them apart).
///
/// Noise assumptions: strokes are exchangeable and independent of each other
/// given the covariates (errors within a stroke may be arbitrarily
/// correlated); a covariate constant within a stroke is judged only by how
/// it predicts held-out strokes, so chance alignment with per-stroke offsets
/// does not count.
///
/// Pure computation: no I/O, no clocks; deterministic for a given seed.
///
/// Usage:
/// @code
///   StrokeData a = PrepareDiagnosisData(ParseStrokeCsv(text_a), labelling);
///   a.Append(PrepareDiagnosisData(ParseStrokeCsv(text_b), labelling));
///   DiagnosisOptions options;
///   options.labelling = labelling;
///   const DiagnosisResult r = Diagnose(a, options);
///   if (r.status != DiagnosisStatus::kOk) { /* r.why */ }
///   for (const Finding& f : r.findings) { /* f.cause, f.p_value, f.terms */ }
///   // r.extended.terms is the extended model's term list.
/// @endcode

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "frictiond/estimators/eps_scale.h"
#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/preprocessing.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

/// Options of Diagnose. Defaults are the documented choices of
/// docs/diagnosis.md.
struct DiagnosisOptions {
  /// Slip labelling and fit bounds (used for data without labels and for
  /// the fit mask).
  SlipLabelOptions labelling;
  /// Outer cross-validation folds, assigned by stroke (at most the stroke
  /// count). Reported errors, gains and p-values come from these folds,
  /// which the selection never sees. 10 (issue 18 rates work): each
  /// outer selection sees 90 % of the strokes and each held-out block is
  /// shorter, which raised every planted kind's detection rate and lowered
  /// the null false alarms against 5 folds (docs/diagnosis.md).
  int folds = 10;
  /// Inner folds: the selection (candidates, forms, windows, bins,
  /// stopping) runs on each outer training part with this many folds.
  int inner_folds = 5;
  /// False (default): folds are contiguous blocks of strokes in recording
  /// order; true: strokes are shuffled (seeded) before the round robin.
  bool shuffle_folds = false;
  /// Seed of the shuffled stroke-to-fold assignment (the only randomness).
  std::uint64_t seed = 0;
  /// Error rate of the outer test: the reported findings' outer p-values
  /// as a fixed sequence, and Holm over all spread candidates.
  double alpha = 0.05;
  /// Inside the selection (inner folds) a candidate may join the model when
  /// its raw one-sided p-value is below this (no correction there: every
  /// finding the selection proposes is then tested on the outer folds,
  /// Holm over the findings, at `alpha`).
  double selection_alpha = 0.05;
  /// Outer test of a finding: an outer fold whose own selection did not
  /// choose the finding's cause but one of its alternatives (a candidate
  /// the selection on all strokes could not tell apart from it) is scored
  /// with that choice instead of contributing no gain (issue 18, third
  /// rates round). False: such folds contribute nothing (before).
  bool outer_alternatives = true;
  /// Smallest held-out MAE gain that counts, in % of the baseline cv_mae.
  double min_gain_pct = 1.0;
  /// At most this many findings (greedy steps).
  int max_findings = 5;
  /// Terms of the baseline model (eq. 1). Must start with "intercept".
  std::vector<std::string> baseline_terms = {"intercept", "v_mm_s", "fn_n"};
  /// A baseline input whose 5-95 % range on fitted samples is below this
  /// fraction of its median magnitude is dropped from the baseline (a
  /// constant-load test cannot identify an Fn slope).
  double min_relative_span = 0.02;
  /// Columns never tested as causes.
  std::vector<std::string> exclude_candidates;
  /// Bins of the step basis for localized effects (>= 2).
  int bins = 8;
  /// Decay times of the slip-onset transient basis [s].
  std::vector<double> onset_decay_s = {0.05, 0.15, 0.5};
  /// Interactions (kind "interaction", cause "x*y", the product column):
  /// the model's inputs with each other and with every numeric candidate,
  /// and the first this-many causes the selection chose with each other
  /// (0: no interactions at all).
  int interaction_candidates = 3;
  /// Test whether the scale of eps depends on an input or column.
  bool spread = true;
  /// Replay Coulomb / linear / extended models (slip events, break-away).
  bool replay = true;
  /// Window after slip onset in which the break-away ratio is measured [s].
  double breakaway_window_s = 0.1;
  /// LuGre parameters to replay (paper 001; e.g. the material's stored
  /// LuGre family). When set (and replay is on), each stroke's measured
  /// v(t) drives SimulateVelocityDriven (direction from a `dir_sign`
  /// column when present, otherwise positive) from the bristle state that
  /// explains the stroke's first Ft/Fn, z0 = min(mu_0, mu_s) / sigma0; the
  /// replay reports |mu_sim| errors on the same slipping samples as the
  /// other models and the peak |mu_sim| in the break-away window. The
  /// parameters are given, not fitted to these strokes (not held-out).
  /// Must satisfy IsValidLuGreTheta.
  std::optional<LuGreTheta> lugre;

  /// True when usable; otherwise *why names the field, value and rule.
  bool IsValid(std::string* why) const;
};

/// Outcome of Diagnose.
enum class DiagnosisStatus {
  kOk,             ///< diagnosed (findings may be empty)
  kTooFewSamples,  ///< fewer than 20 slipping samples within the bounds
  kTooFewStrokes,  ///< fewer than 3 strokes with slipping samples
  kFailed,         ///< numerical failure (see why)
};
/// Short name: "ok", "too_few_samples", "too_few_strokes", "failed".
const char* ToString(DiagnosisStatus status);

/// One tested expansion of one candidate cause in one greedy step.
struct CandidateTest {
  int step = 0;                    ///< greedy step (0 = against the baseline)
  std::string cause;               ///< column or derived feature name
  std::string kind;                ///< "covariate", "form" or "regime"
  std::string expansion;           ///< "linear", "quadratic", "log", "hinge",
                                   ///< "periodic", "bins", "onset(tau)", ...
  std::vector<std::string> terms;  ///< term names added to the current model
  double cv_mae = 0.0;             ///< held-out MAE of current model + terms
  double gain_pct = 0.0;  ///< (current cv_mae - cv_mae) / baseline cv_mae, in %
  double t_stat = 0.0;    ///< paired t over strokes
  double p_raw = 1.0;     ///< one-sided p-value of the t-test
  double p_holm = 1.0;    ///< Holm-adjusted p-value within the step
  bool significant = false;  ///< p_holm < alpha and gain_pct >= min_gain_pct
};

/// A candidate the data cannot tell apart from a finding's cause: its
/// held-out gain lies within the finding's 95 % confidence interval.
struct Alternative {
  std::string cause;             ///< column or derived feature name
  std::string kind;              ///< as Finding::kind
  std::string expansion;         ///< its best expansion in that step
  double cv_mae_gain_pct = 0.0;  ///< its held-out gain in that step (inner)
  double p_value = 1.0;      ///< two-sided paired test over strokes of "same
                             ///< held-out error as the finding"
  double correlation = 0.0;  ///< Pearson correlation of the two causes'
                             ///< columns on the fitted samples
};

/// A significant cause, in the order it joined the model.
struct Finding {
  std::string cause;               ///< column or derived feature name
  std::string kind;                ///< "covariate", "form", "regime",
                                   ///< "interaction" or "spread"
  std::string expansion;           ///< which expansion won
  std::vector<std::string> terms;  ///< term names it added
  double p_value = 1.0;  ///< outer p-value, fixed-sequence adjusted (the
                         ///< largest raw p of this and earlier findings;
                         ///< spread: Holm over the spread candidates)
  double cv_mae_gain_pct = 0.0;  ///< its step's held-out MAE gain, % of
                                 ///< baseline cv_mae (gains add up)
  double cv_mae = 0.0;           ///< held-out MAE after adding it
  double log_likelihood_gain =
      0.0;  ///< held-out Gaussian log-likelihood gain of the step [nats/sample]
  std::string
      effect;  ///< human-readable effect, e.g. "mu falls 0.011 per degC"
  /// Gain the selection saw for it (inner folds, all strokes) minus its
  /// outer held-out gain cv_mae_gain_pct: the optimism removed [%].
  double selection_bias_pct = 0.0;
  /// Outer folds (of DiagnosisResult::folds) whose inner selection chose
  /// this cause too.
  int folds_selected = 0;
  /// Candidates whose held-out gain is statistically indistinguishable.
  std::vector<Alternative> alternatives;
};

/// A model summarised by its held-out performance.
struct DiagnosedModel {
  std::string model;               ///< "linear", "linear+temp_c", ...
  std::vector<std::string> terms;  ///< term names (Term::Name())
  std::vector<double> beta;  ///< coefficients fitted on all slipping samples
  double cv_mae = 0.0;       ///< held-out MAE of mu
  double cv_log_likelihood =
      0.0;                 ///< held-out Gaussian log-likelihood [nats/sample]
  double sigma_eps = 0.0;  ///< residual std on all slipping samples
  /// eps scale depending on an input (extended model with a spread finding).
  std::optional<EpsScaleModel> eps_scale;
};

/// Replay errors of one model on one stroke (or overall).
struct ReplayErrors {
  int stroke = -1;       ///< stroke id (-1 for the overall row)
  int samples = 0;       ///< all samples
  int slip_samples = 0;  ///< slipping samples within the bounds
  double mu_mae = 0.0;   ///< held-out mean |mu - mu_hat| on slipping samples
  int slip_events = 0;   ///< labelled slip episodes
  int hits = 0;  ///< episodes with predicted slip probability >= 0.5 somewhere
  int misses = 0;  ///< episodes without
  int false_alarms =
      0;  ///< runs of predicted probability >= 0.5 containing no slip sample
  double brier = 0.0;  ///< mean (p - slip)^2 over all samples
  double breakaway_measured =
      0.0;  ///< peak Ft/Fn from 0.25 s before to breakaway_window_s after onset
            ///< (NaN: no episode)
  double breakaway_predicted = 0.0;  ///< model mu at the onset sample
  double breakaway_abs_error = 0.0;  ///< mean |predicted - measured| (overall:
                                     ///< over strokes with an episode)
  double breakaway_bias = 0.0;       ///< mean (predicted - measured)
};

/// Replay of one model over all strokes (held-out predictions).
struct ModelReplay {
  std::string model;               ///< "coulomb", "lugre", "linear", "extended"
  std::vector<std::string> terms;  ///< its terms (LuGre: parameter names)
  /// False when the model does not predict slip from forces (LuGre replayed
  /// velocity-driven): hits, misses, false_alarms are 0 and brier is NaN.
  bool predicts_slip = true;
  /// How the replay was made when it differs from the held-out replays.
  std::string note;
  ReplayErrors overall;
  std::vector<ReplayErrors> strokes;
};

/// Everything Diagnose found.
struct DiagnosisResult {
  DiagnosisStatus status = DiagnosisStatus::kFailed;
  std::string why;          ///< reason when status != kOk
  DiagnosedModel baseline;  ///< eq. (1) (inputs without span dropped)
  DiagnosedModel
      extended;  ///< baseline + findings' terms (equals baseline when none)
  double gain_pct =
      0.0;  ///< (baseline - extended cv_mae) / baseline cv_mae, in %
  double log_likelihood_gain =
      0.0;  ///< extended - baseline held-out log-likelihood [nats/sample]
  /// Gain of the selected model seen by the selection itself (inner folds
  /// over all strokes, the pre-nested figure) minus gain_pct [%].
  double selection_bias_pct = 0.0;
  std::vector<Finding> findings;        ///< most important first
  std::vector<CandidateTest> tests;     ///< every test of every step
  std::vector<std::string> candidates;  ///< causes tested
  std::vector<std::string> skipped;  ///< "name: reason" for columns not tested
  std::vector<std::string>
      dropped_baseline_terms;  ///< baseline terms without span
  std::vector<ModelReplay>
      replay;           ///< per model (empty when options.replay is false)
  int samples = 0;      ///< samples offered
  int fit_samples = 0;  ///< slipping samples within the bounds
  int strokes = 0;      ///< strokes with slipping samples
  int folds = 0;        ///< outer folds used
  int inner_folds = 0;  ///< inner folds of the selection
  /// Rows (indices into the data) of the fitted samples and the baseline's
  /// held-out residuals mu - mu_hat there, for residual plots.
  std::vector<std::size_t> fit_rows;
  std::vector<double> baseline_residuals;
};

/// Labels slip and strokes where absent (EnsureLabels) and appends the
/// derived features of CONTRACT.md (AddDerivedFeatures). Call once per input
/// file, before merging files with StrokeData::Append (which keeps stroke
/// ids distinct).
/// @throws std::invalid_argument when the labelling options are invalid.
StrokeData PrepareDiagnosisData(StrokeData data,
                                const SlipLabelOptions& labelling);

/// Slip thresholds adapted to the data's speed scale. With v99 the 99th
/// percentile of v_mm_s: when v99 >= the paper's peak threshold (10 mm/s)
/// the paper's 10 / 5 mm/s are kept; otherwise peak = 0.25 v99 and
/// floor = 0.08 v99 (for the micro-tribometer trace, v99 = 0.26 mm/s gives
/// 0.065 / 0.021 mm/s, the ~0.02 mm/s PROVENANCE suggests). Other fields are
/// taken from `base`. *rule (optional) describes the choice.
SlipLabelOptions CalcAutoSlipLabelOptions(const std::vector<double>& v_mm_s,
                                          const SlipLabelOptions& base,
                                          std::string* rule = nullptr);

/// Diagnoses the linear model on `data` (one or more strokes). Missing
/// labels are derived with options.labelling, missing derived features are
/// added (a copy is made then).
/// @throws std::invalid_argument when options are invalid or a baseline
/// term names a column the data does not have.
DiagnosisResult Diagnose(const StrokeData& data,
                         const DiagnosisOptions& options = {});

}  // namespace frictiond
