#pragma once
/// @file
/// JSON wire format of the conditional slip likelihood L(Fn, Ft/Fn) of
/// paper 000 eq. (2), stored under the key "slip_likelihood_fn" of a model
/// set (ModelSet::other) and served in GET /v1/materials/{id}/model:
///
/// @code{.json}
/// "slip_likelihood_fn": {
///   "step_n": 0.5, "window_n": 1.0,
///   "knots": [{"fn_n": 1.0, "c1": 30.2, "c2": 0.61}, ...],
///   "windows": [{"fn_n": 1.0, "samples": 812, "slipping": 301,
///                "valid": true, "c1": 30.2, "c2": 0.61,
///                "c1_se": 1.1, "c2_se": 0.004}, ...]   // or "why"
/// }
/// @endcode

#include <nlohmann/json.hpp>

#include "frictiond/estimators/slip_likelihood.h"

namespace frictiond {

/// Key of the eq. (2) family in a model set.
inline constexpr const char* kConditionalSlipFamilyKey = "slip_likelihood_fn";

/// Encodes a fitted conditional likelihood (the object above).
nlohmann::json ConditionalSlipToJson(const ConditionalSlipLikelihood& L);

/// Decodes the knots of a stored family ("windows" is informative and not
/// read back); valid is true when there is at least one knot.
/// @throws std::invalid_argument naming the malformed field.
ConditionalSlipLikelihood ConditionalSlipFromJson(const nlohmann::json& j);

}  // namespace frictiond
