#include "frictiond/server/model_lookup.h"

#include <exception>
#include <stdexcept>

#include "frictiond/server/request_error.h"

namespace frictiond {

ModelLookup LookUpModel(FrictionLibrary& library,
                        const std::string& material,
                        const std::string& fingertip,
                        const std::string& requested_by) {
  CheckId(material, "id");
  CheckId(fingertip, "fingertip");
  ModelLookup out;
  out.material = material;
  if ((out.model = library.FindModel(material, fingertip))) {
    out.outcome = ModelLookup::Outcome::kKnown;
    return out;
  }
  out.outcome = ModelLookup::Outcome::kUnknown;
  out.known_material = library.store().GetMaterial(material).has_value();
  out.identification =
      library.RequestIdentification(material, fingertip, requested_by);
  const std::string outcome = out.identification.requested
                                  ? "an identification was requested"
                                  : "no identification was recorded (" +
                                        out.identification.reason + ")";
  out.message = out.known_material
                    ? "material '" + material +
                          "' has no friction model for fingertip '" +
                          fingertip + "' yet: " + outcome
                    : "unknown material '" + material + "': " + outcome;
  return out;
}

ModelLookup LookUpModelForQuery(FrictionLibrary& library,
                                const RecognizeImageFn& recognize,
                                const std::string& material,
                                const std::string& fingertip,
                                const std::string& image,
                                const std::string& requested_by) {
  ModelLookup out;
  out.material = material;
  auto reject = [&](std::string field, std::string message) {
    out.outcome = ModelLookup::Outcome::kRejected;
    out.field = std::move(field);
    out.message = std::move(message);
    return out;
  };
  if (!image.empty()) {
    // The recognition hook (paper 000 Fig. 11: material recognition);
    // below its confidence threshold the material is unknown and the
    // query's material id names the new material.
    if (!recognize)
      return reject("image",
                    "image: this frictiond has no recognition (built "
                    "without OpenCV); query by material id");
    ImageRecognition r;
    try {
      r = recognize(image);
    } catch (const std::invalid_argument& e) {
      return reject("image", std::string("image: ") + e.what());
    }
    out.recognition = r;
    if (!r.unknown && !r.candidates.empty()) {
      out.material = r.candidates.front().first;
      out.recognition_score = r.candidates.front().second;
    } else if (material.empty()) {
      return reject("material",
                    "material: empty, and the image was not recognised "
                    "(unknown material); give the id the new material "
                    "should get to start its identification");
    }
  }
  try {
    ModelLookup found =
        LookUpModel(library, out.material, fingertip, requested_by);
    found.recognition_score = out.recognition_score;
    found.recognition = std::move(out.recognition);
    return found;
  } catch (const RequestError& e) {
    return reject(e.field() == "id" ? "material" : e.field(), e.what());
  } catch (const std::exception& e) {
    // The store or library failed (e.g. PostgreSQL away): the caller
    // answers with an error and keeps serving.
    out.outcome = ModelLookup::Outcome::kUnavailable;
    out.store_outage = dynamic_cast<const StoreUnavailable*>(&e) != nullptr;
    out.field = "(daemon)";
    out.message = std::string(
                      "the library is unavailable (nothing stored; ask again "
                      "later): ") +
                  e.what();
    return out;
  }
}

ModelFamily RequireModelFamily(FrictionLibrary& library,
                               const std::string& material,
                               const std::string& fingertip,
                               std::optional<int> version,
                               const std::string& family_key,
                               const std::string& kind,
                               const nlohmann::json& hint) {
  ModelFamily out;
  out.model = version ? library.FindModelVersion(material, fingertip, *version)
                      : library.FindModel(material, fingertip);
  if (!out.model)
    throw RequestError(StatusCode::kNotFound,
                       "id",
                       "no " + kind + " model for material '" + material +
                           "', joint '" + fingertip + "'",
                       hint);
  auto it = out.model->set.other.find(family_key);
  if (it == out.model->set.other.end() || it->is_null())
    throw RequestError(StatusCode::kFailedPrecondition,
                       family_key,
                       "model version " +
                           std::to_string(out.model->set.version) + " of '" +
                           material + "' (joint '" + fingertip + "') has no " +
                           kind + " family",
                       hint);
  out.family = &*it;
  return out;
}

}  // namespace frictiond
