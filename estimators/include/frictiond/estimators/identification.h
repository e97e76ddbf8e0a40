#pragma once

/// @file
/// Identification of one material from its strokes (paper 000): slip
/// labels and strokes (II-B/C), eq. (1) with the Fn-only model and the
/// sigmoid slip likelihood (III-A/C), the conditional likelihood of eq. (2),
/// and the span coverage of the slipping samples (III-C-2), in one call.
///
/// @code
///   MaterialIdentificationOptions o;
///   o.reference = {0.5, 4.5, 15.0, 80.0};  // the stroke plan's span
///   const MaterialIdentification id = IdentifyMaterial(strokes, o);
///   if (id.coverage.span_pct < 50.0) { /* ask for id.coverage.missing */ }
/// @endcode

#include "frictiond/estimators/slip_likelihood.h"
#include "frictiond/estimators/span_coverage.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

struct MaterialIdentificationOptions {
  StochasticFitOptions fit;                  ///< labelling, terms, levels
  ConditionalSlipOptions conditional;        ///< eq. (2) windows
  SpanRect reference{0.5, 4.5, 15.0, 80.0};  ///< span the coverage is of
  /// 1: every step on the calling thread. 2: the conditional likelihood and
  /// the coverage run on a second thread while the regressions run (the
  /// results are the same; only the wall time differs).
  int threads = 2;
};

struct MaterialIdentification {
  StochasticFit fit;
  ConditionalSlipLikelihood conditional;
  SpanCoverage coverage;  ///< against options.reference (the plan)
  /// Paper 000 III-C-2: the hull of all slipping samples and each stroke's
  /// coverage of it (CalcMaterialHullCoverage; the 50 % rule applies here).
  MaterialHullCoverage hull;
};

/// Labels `data` where it has no slip/stroke labels (EnsureLabels with
/// options.fit.labelling), then fits eq. (1), the Fn-only model and the
/// sigmoid likelihood (FitStochasticModel), the conditional likelihood on
/// every finite sample (FitConditionalSlipLikelihood) and the coverage of
/// the slipping samples (CalcSpanCoverage against options.reference, and
/// CalcMaterialHullCoverage per stroke). Throws std::invalid_argument
/// for invalid options (threads < 1 included).
MaterialIdentification IdentifyMaterial(
    StrokeData data, const MaterialIdentificationOptions& options = {});

}  // namespace frictiond
