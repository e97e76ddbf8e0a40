#pragma once
/// @file
/// JSON wire format of friction models (the body of
/// GET /v1/materials/{id}/model, CONTRACT.md), shared by the daemon, the
/// client library and the store. Coefficients are keyed by the term they
/// multiply, so an extended model just adds keys.

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {

/// One stored model version of a material-fingertip pair: every model family
/// fitted at that time. Families this build does not know are kept verbatim
/// in `other` and written back unchanged.
struct ModelSet {
  std::string material;               ///< material id
  std::string fingertip = "default";  ///< fingertip id
  int version = 0;                    ///< 1, 2, ... per (material, fingertip)
  std::string created_at;             ///< ISO-8601 UTC
  std::optional<StochasticFrictionModel> stochastic;  ///< paper 000 model
  nlohmann::json other =
      nlohmann::json::object();  ///< other families by key ("lugre", ...)
};

/// Encodes a stochastic model (the "stochastic" object of the contract).
nlohmann::json StochasticModelToJson(const StochasticFrictionModel& model);
/// Decodes a stochastic model.
/// @throws std::invalid_argument naming the missing or malformed field.
StochasticFrictionModel StochasticModelFromJson(const nlohmann::json& j);

/// Encodes a whole model set: {"material", "fingertip", "version",
/// "created_at", "stochastic": {...}, <other families>}.
nlohmann::json ModelSetToJson(const ModelSet& set);
/// Decodes a model set.
/// @throws std::invalid_argument naming the missing or malformed field.
ModelSet ModelSetFromJson(const nlohmann::json& j);

/// Encodes a regression model (coefficients keyed by term name).
nlohmann::json RegressionModelToJson(const RegressionModel& m);
/// @throws std::invalid_argument naming the missing or malformed field.
RegressionModel RegressionModelFromJson(const nlohmann::json& j,
                                        const std::string& where);

}  // namespace frictiond
