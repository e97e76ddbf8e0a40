#pragma once
/// @file
/// LuGre part of the robot client (paper 001): ask the daemon for a
/// break-away friction ratio, or take the identified LuGre parameters out of
/// a fetched model and predict locally with PredictBreakawayRatio /
/// BreakawayMonitor in the control loop (no network traffic per tick).
///
/// @code
///   frictiond::FrictionClient client({"http://127.0.0.1:8080"});
///   // Remote: one request per prediction.
///   frictiond::BreakawayReply r =
///       frictiond::FetchBreakaway(client, "steel", /*rho_per_s=*/0.5, 5.0);
///   // Local: fetch once, predict as often as needed (~20 us each).
///   const frictiond::ModelSet m = client.FetchModel("steel");
///   if (auto theta = frictiond::LuGreFromModel(m)) {
///     const auto p = frictiond::PredictBreakawayRatio(*theta, 0.5, 5.0);
///   }
/// @endcode

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "frictiond/client/client.h"
#include "frictiond/estimators/breakaway.h"
#include "frictiond/estimators/lugre.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/proto/model_json.h"

namespace frictiond {

/// Answer of GET /v1/materials/{id}/breakaway.
struct BreakawayReply {
  std::string material;
  int version = 0;           ///< model version used
  double bf_ratio = 0.0;     ///< break-away friction ratio [-]; NaN unless ok
  double t_breakaway_s = 0;  ///< time of the velocity jump from rest [s]
  double rho_per_s = 0.0;    ///< drag-ratio rate asked for [1/s]
  double fn_n = 0.0;         ///< normal force asked for [N]
  double mass_kg = 0.0;      ///< mass used by the simulation [kg]
  /// "ok", or the simulation status ("no_breakaway", ...; SimulationStatus).
  std::string status;
  nlohmann::json body;  ///< full reply
};

/// Asks the daemon for the break-away friction ratio of `material` at
/// drag-ratio rate rho_per_s [1/s] and normal force fn_n [N] (paper 001,
/// eqs. 16-20), with the daemon's default mass (0.2 kg) unless mass_kg is
/// given. `fingertip` empty: the client's default.
/// @throws std::invalid_argument when rho_per_s, fn_n or mass_kg is not
/// finite and > 0 (nothing is sent).
/// @throws ClientError: 404 unknown material (body() holds the
/// identification request), 422 the model has no LuGre family, 400 bad
/// parameters, 0 daemon unreachable.
BreakawayReply FetchBreakaway(FrictionClient& client,
                              const std::string& material,
                              double rho_per_s,
                              double fn_n,
                              std::optional<double> mass_kg = std::nullopt,
                              const std::string& fingertip = "");

/// The stored LuGre family of a model set, or nullopt when the set has none
/// (the daemon could not identify it yet).
/// @throws std::invalid_argument when the family is present but malformed
/// (naming the field, see LuGreFromJson).
std::optional<LuGreFamily> LuGreFamilyFromModel(const ModelSet& set);

/// The identified LuGre parameters of a model set, or nullopt when the set
/// has no LuGre family. Use with PredictBreakawayRatio or BreakawayMonitor.
/// @throws std::invalid_argument when the family is malformed.
std::optional<LuGreTheta> LuGreFromModel(const ModelSet& set);

}  // namespace frictiond
