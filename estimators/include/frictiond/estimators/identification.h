#pragma once

/// @file
/// Identification of one material from its strokes, every model family in
/// one call (the daemon's upload calls exactly this):
/// - paper 000: slip labels and strokes (II-B/C), eq. (1) with eps, the
///   Fn-only model and the sigmoid slip likelihood (III-A/C;
///   FitStochasticModel), the conditional likelihood of eq. (2)
///   (FitConditionalSlipLikelihood), and the span coverage of the slipping
///   samples (III-C-2; CalcSpanCoverage);
/// - paper 001: the LuGre model from the recognised low- and high-
///   acceleration strokes (IdentifyLuGreFromStrokes), when the strokes
///   hold that pair (otherwise `lugre.why` says what is missing).
///
/// @code
///   MaterialIdentificationOptions o;
///   o.reference = {0.5, 4.5, 15.0, 80.0};  // the stroke plan's span
///   const MaterialIdentification id = IdentifyMaterial(strokes, o);
///   if (id.coverage.span_pct < 50.0) { /* ask for id.coverage.missing */ }
///   if (id.lugre.identified) { /* id.lugre.family */ }
/// @endcode

#include <functional>

#include "frictiond/estimators/identification_memo.h"
#include "frictiond/estimators/lugre_identification.h"
#include "frictiond/estimators/slip_likelihood.h"
#include "frictiond/estimators/span_coverage.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

struct MaterialIdentificationOptions {
  StochasticFitOptions fit;                  ///< labelling, terms, levels
  ConditionalSlipOptions conditional;        ///< eq. (2) windows
  SpanRect reference{0.5, 4.5, 15.0, 80.0};  ///< span the coverage is of
  /// Identify the LuGre family (paper 001) from the recognised strokes.
  /// false: `lugre` stays unidentified with why = "not requested".
  bool lugre = true;
  /// 1: every step on the calling thread. 2: the conditional likelihood,
  /// the span coverage and the LuGre identification run on a second thread
  /// while the regressions and the hull run (the results are the same;
  /// only the wall time differs).
  int threads = 2;
  /// With threads = 2: where the second share runs. Unset: a new thread per
  /// call (std::async). A long-running caller passes a function that hands
  /// the task to a persistent worker (the daemon's FitWorkers), so a call
  /// neither starts a thread nor begins with an empty allocator cache. The
  /// task is claimed once: when the calling thread finishes its own share
  /// before a worker has started the posted task, it runs the task itself,
  /// so a busy worker never delays a call. `post` must not run the task
  /// synchronously while holding a lock the task could need, and must not
  /// throw after taking the task (a task it drops is run by the caller).
  std::function<void(std::function<void()>)> post;
  /// Optional, kept by the caller between calls for the same material
  /// (identification_memo.h): the per-stroke steps (the hull of a stroke's
  /// slipping samples, the LuGre recognition of a run) of strokes an
  /// earlier call saw are looked up. The results are the same with or
  /// without it; the call sweeps it at its end (it keeps what this call
  /// used). One call at a time per memo.
  IdentificationMemo* memo = nullptr;
  /// Optional: an earlier eq. (2) fit of this material (the daemon passes
  /// the pair's previous refit's). Each Fn window's Newton steps start from
  /// the start's window at the same centre (FitConditionalSlipLikelihood),
  /// which converges in fewer passes to the same optimum.
  const ConditionalSlipLikelihood* conditional_start = nullptr;
};

/// Every family identified from one material's strokes. A family that
/// cannot be identified is a status inside its member (fit.status,
/// conditional.valid, lugre.identified), never an exception.
struct MaterialIdentification {
  StochasticFit fit;  ///< eq. (1) with eps, Fn-only, sigmoid
  ConditionalSlipLikelihood conditional;  ///< eq. (2)
  SpanCoverage coverage;                  ///< of the slipping samples
  LuGreIdentification lugre;              ///< paper 001 (options.lugre)
  /// Paper 000 III-C-2: the hull of all slipping samples and each stroke's
  /// coverage of it (CalcMaterialHullCoverage; the 50 % rule applies here).
  MaterialHullCoverage hull;
};

/// Labels `data` where it has no slip/stroke labels (EnsureLabels with
/// options.fit.labelling), then fits eq. (1), the Fn-only model and the
/// sigmoid likelihood (FitStochasticModel), the conditional likelihood on
/// every finite sample (FitConditionalSlipLikelihood), the coverage of
/// the slipping samples (CalcSpanCoverage against options.reference, and
/// CalcMaterialHullCoverage per stroke) and, with options.lugre, the
/// LuGre family (IdentifyLuGreFromStrokes on the same samples). Pass the
/// data by std::move when the caller no longer needs it. Throws
/// std::invalid_argument for invalid options (threads < 1 included).
MaterialIdentification IdentifyMaterial(
    StrokeData data, const MaterialIdentificationOptions& options = {});

}  // namespace frictiond
