#pragma once
/// @file
/// JSON wire format of the LuGre model family (paper 001), stored under the
/// key "lugre" of a model set (ModelSet::other) beside the stochastic model
/// and served in GET /v1/materials/{id}/model:
///
/// @code{.json}
/// "lugre": {
///   "theta": {"mu_s": 0.9, "mu_c": 0.6, "v0_mm_s": 5.0, "sigma2_s_mm": 0.004,
///             "sigma0_per_mm": 50.0, "sigma1_s_mm": 0.1},
///   "std_errors": {"mu_s": 0.0004, ...},            // same keys as theta
///   "parameters": ["mu_s", "mu_c", "v0_mm_s", "sigma2_s_mm",
///                  "sigma0_per_mm", "sigma1_s_mm"], // order of covariance
///   "covariance": [[...6 numbers...], ... 6 rows],  // P_theta
///   "status": "converged", "variant": "lm2", "iterations": 17,
///   "residual_rms": 0.0049, "quasi_static_residual_rms": 0.0051,
///   "z0_mm": 0.0, "excited_samples": 120,
///   "strokes_used": {"quasi_static": 1, "dynamic": 1}
/// }
/// @endcode
///
/// Units: theta as in LuGreTheta (v0 mm/s, sigma2 and sigma1 s/mm, sigma0
/// 1/mm; mu dimensionless); the covariance is in the products of those
/// units. Non-finite numbers are written as null and read back as NaN
/// (theta itself must be finite).

#include <string>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/lugre_identification.h"

namespace frictiond {

/// Key of the LuGre family in a model set.
inline constexpr const char* kLuGreFamilyKey = "lugre";

// LuGreFamily (the identified model this file encodes) is declared in
// frictiond/estimators/lugre_identification.h.

/// The JSON key of theta entry i (0..5): "mu_s", "mu_c", "v0_mm_s",
/// "sigma2_s_mm", "sigma0_per_mm", "sigma1_s_mm".
/// @throws std::out_of_range for i outside 0..5.
const char* LuGreParameterName(int i);

/// Encodes theta as {"mu_s": ..., ...}.
nlohmann::json LuGreThetaToJson(const LuGreTheta& theta);
/// Decodes {"mu_s": ..., ...}; every key is required and the result must
/// satisfy IsValidLuGreTheta.
/// @throws std::invalid_argument naming the field, e.g. "lugre.theta.v0_mm_s:
/// missing" or "lugre.theta.v0_mm_s = -1 (must be finite and > 0)".
LuGreTheta LuGreThetaFromJson(const nlohmann::json& j,
                              const std::string& where = "lugre.theta");

/// Encodes a family (the object shown in the file comment).
nlohmann::json LuGreToJson(const LuGreFamily& family);
/// Decodes a family. Required: "theta", "status", "variant". Optional (with
/// the defaults of LuGreFamily): "covariance" (6 x 6), "iterations",
/// "residual_rms", "quasi_static_residual_rms", "z0_mm", "excited_samples",
/// "strokes_used"; "std_errors" and "parameters" are derived and ignored.
/// @throws std::invalid_argument naming the missing or malformed field
/// ("lugre.covariance[2][3]: expected a number or null", ...).
LuGreFamily LuGreFromJson(const nlohmann::json& j);

}  // namespace frictiond
