#pragma once
/// @file
/// A lookup of a pair's model (paper 000, Fig. 11 "library lookup"),
/// independent of the transport: the newest model, or, for a pair without
/// one, the identification request recorded for it (IdentificationJobs).
/// FrictionLibrary::RequireModel (HTTP) and the LCM endpoint's
/// material_query_v1 both answer from it; LookUpModelForQuery adds the
/// recognition of a query image and turns every failure into a result.

#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "frictiond/server/identification_jobs.h"
#include "frictiond/server/library.h"
#include "frictiond/server/recognition_hook.h"

namespace frictiond {

/// What a lookup found.
struct ModelLookup {
  enum class Outcome {
    kKnown,        ///< `model` is the pair's newest model
    kUnknown,      ///< no model: `identification` says what was recorded
    kRejected,     ///< the request is wrong: `field`, `message`
    kUnavailable,  ///< the store or library failed: `message` (retry later)
  };
  Outcome outcome = Outcome::kRejected;
  std::string material;            ///< looked up (recognition may set it)
  double recognition_score = 0.0;  ///< of the recognised material, else 0
  std::shared_ptr<const CachedModel> model;  ///< kKnown
  bool known_material = false;               ///< kUnknown: material exists
  IdentificationRequest identification;      ///< kUnknown
  std::string field;          ///< kRejected (the request's field)
  std::string message;        ///< kUnknown, kRejected, kUnavailable: in words
  bool store_outage = false;  ///< kUnavailable: the store is unreachable
  /// What the recogniser made of the query's image (none without an image;
  /// set from the recognition on, whatever the outcome).
  std::optional<ImageRecognition> recognition;
};

/// The newest model of (material, fingertip), or kUnknown with the
/// identification request recorded for `requested_by` (the caps of
/// LibraryOptions apply) and the message the HTTP 404 shows.
/// @throws RequestError(StatusCode::kInvalidArgument) for an invalid material
/// ("id"), fingertip or requested_by ("robot"); store failures propagate.
ModelLookup LookUpModel(FrictionLibrary& library,
                        const std::string& material,
                        const std::string& fingertip,
                        const std::string& requested_by);

/// A robot's query: by material id, or by image through `recognize` (the
/// recognised material replaces the id; an unrecognised image needs the id
/// the new material should get). Never throws for the request's content:
/// invalid input is kRejected naming the field ("material" for an invalid
/// id, "image", "fingertip", "robot"), a failing store kUnavailable.
ModelLookup LookUpModelForQuery(FrictionLibrary& library,
                                const RecognizeImageFn& recognize,
                                const std::string& material,
                                const std::string& fingertip,
                                const std::string& image,
                                const std::string& requested_by);

/// One stored model family (an entry of the model's other families, such as
/// "actuator" or "joint") of a pair's model.
struct ModelFamily {
  std::shared_ptr<const CachedModel> model;  ///< the version it is from
  const nlohmann::json* family = nullptr;    ///< inside `model`; not null
};

/// The family `family_key` of the pair's newest model, or of model version
/// `version` when given. `kind` names the model in messages ("actuator",
/// "joint"); `hint` (e.g. how to upload the data) is the error's extra.
/// @throws RequestError(StatusCode::kNotFound, "id") when the pair has no
/// model (or not that version); RequestError(StatusCode::kFailedPrecondition,
/// `family_key`) when that version has no such family.
ModelFamily RequireModelFamily(FrictionLibrary& library,
                               const std::string& material,
                               const std::string& fingertip,
                               std::optional<int> version,
                               const std::string& family_key,
                               const std::string& kind,
                               const nlohmann::json& hint);

}  // namespace frictiond
