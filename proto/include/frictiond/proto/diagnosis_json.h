#pragma once
/// @file
/// JSON encoding of a model diagnosis (CONTRACT.md, "Model diagnosis"): the
/// output of `friction diagnose --json`.
///
///     {"baseline": {"model", "cv_mae", "terms", ...},
///      "findings": [{"cause", "kind", "p_value", "cv_mae_gain_pct", "effect",
///      ...}], "extended": {"model", "cv_mae", "gain_pct", "terms", ...},
///      "status", "log_likelihood_gain", "statistics", "labelling", "replay",
///      "tests", ...}
///
/// The contract's keys are always present; the others are additions.
/// Non-finite numbers are written as null.

#include <string>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/diagnosis.h"

namespace frictiond {

/// What to include beyond the contract's keys.
struct DiagnosisJsonOptions {
  bool replay = true;          ///< "replay": overall errors per model
  bool replay_strokes = true;  ///< per-stroke rows inside "replay"
  bool tests = true;           ///< "tests": every candidate test of every step
};

/// Encodes a diagnosis. `labelling_rule` (may be empty) says how the slip
/// thresholds were chosen.
nlohmann::json DiagnosisToJson(const DiagnosisResult& result,
                               const DiagnosisOptions& options,
                               const std::string& labelling_rule = "",
                               const DiagnosisJsonOptions& json_options = {});

}  // namespace frictiond
