// Material recognition over HTTP (CONTRACT.md "Recognition"): operators
// register reference images per material; robots send an image and get
// ranked candidates, or "unknown" plus the test stroke to perform.
#include <cstring>
#include <iostream>
#include <memory>
#include <stdexcept>

#include "frictiond/server/identification_json.h"
#include "frictiond/server/routes.h"

#ifdef FRICTIOND_HAVE_RECOGNITION
#include "frictiond/recognition/material_recognizer.h"
#endif

namespace frictiond {

using nlohmann::json;

#ifdef FRICTIOND_HAVE_RECOGNITION

namespace {

// Stored feature blob: "v<version>:" followed by raw little-endian floats.
std::string EncodeFeatures(const std::vector<float>& f) {
  std::string out =
      "v" + std::to_string(MaterialRecognizer::kFeatureVersion) + ":";
  out.append(reinterpret_cast<const char*>(f.data()), f.size() * sizeof(float));
  return out;
}

bool DecodeFeatures(const std::string& blob, std::vector<float>* f) {
  const std::string prefix =
      "v" + std::to_string(MaterialRecognizer::kFeatureVersion) + ":";
  if (blob.compare(0, prefix.size(), prefix) != 0) return false;
  const std::size_t n = (blob.size() - prefix.size()) / sizeof(float);
  if (n != MaterialRecognizer::feature_size()) return false;
  f->resize(n);
  std::memcpy(f->data(), blob.data() + prefix.size(), n * sizeof(float));
  return true;
}

std::string ImageMime(const HttpRequest& req) {
  const std::string ct = req.Header("Content-Type")
                             .substr(0, req.Header("Content-Type").find(';'));
  if (ct == "image/png" || ct == "image/jpeg" ||
      ct == "application/octet-stream" || ct.empty())
    return ct;
  throw HttpError(415,
                  "Content-Type",
                  "Content-Type '" + ct.substr(0, 64) +
                      "' (must be image/png or image/jpeg)");
}

}  // namespace

RecognizeImageFn RegisterRecognitionRoutes(HttpServer& http,
                                           FrictionLibrary& lib,
                                           double operating_point) {
  RecognizerOptions options;
  if (!(operating_point < 0.0)) {
    if (!(operating_point <= 1.0))
      throw std::invalid_argument(
          "recognition_operating_point = " + std::to_string(operating_point) +
          " (must be in [0, 1], or negative for the calibrated default)");
    options.unknown_threshold = operating_point;
  }
  auto recognizer = std::make_shared<MaterialRecognizer>(options);
  int stale = 0;
  for (const ImageRecord& img : lib.store().ListImages()) {
    std::vector<float> f;
    bool used = false;
    if (DecodeFeatures(img.features, &f)) {
      try {
        recognizer->AddReferenceFeatures(img.material, std::move(f));
        used = true;
      } catch (const std::invalid_argument& e) {
        std::cerr << "frictiond: recognition: stored image " << img.id
                  << " of '" << img.material << "' skipped: " << e.what()
                  << "\n";
      }
    }
    if (!used) {
      ++stale;  // another extractor version or invalid: re-register those
                // images
    }
  }
  if (stale > 0) {
    std::cerr << "frictiond: recognition: " << stale
              << " stored reference image(s) have unusable features (another "
                 "feature version (now v"
              << MaterialRecognizer::kFeatureVersion
              << ") or invalid) and are not used; upload them again with POST "
                 "/v1/materials/{id}/images\n";
  }
  http.Route("POST",
             "/v1/materials/{id}/images",
             [&lib, recognizer](const HttpRequest& req) {
               const std::string& id = req.params[0];
               CheckId(id, "id");
               const std::string mime = ImageMime(req);
               // Before decoding the image: an unknown material is a 404
               // whatever the body holds.
               lib.RequireImageMaterial(id);
               std::vector<float> features;
               try {
                 features = recognizer->ExtractFeatures(req.body);
               } catch (const std::invalid_argument& e) {
                 throw RequestError(
                     StatusCode::kInvalidArgument, "body", e.what());
               }
               ImageRecord rec;
               rec.material = id;
               rec.mime = mime.empty() ? "application/octet-stream" : mime;
               rec.features = EncodeFeatures(features);
               const std::int64_t image_id = lib.AddReferenceImage(rec);
               recognizer->AddReferenceFeatures(id, std::move(features));
               return HttpResponse::Json(
                   201,
                   {{"material", id},
                    {"image_id", image_id},
                    {"references", recognizer->reference_count()}});
             });
  http.Route(
      "POST", "/v1/recognize", [&lib, recognizer](const HttpRequest& req) {
        ImageMime(req);
        RecognitionResult r;
        try {
          r = recognizer->Recognize(req.body);
        } catch (const std::invalid_argument& e) {
          throw RequestError(StatusCode::kInvalidArgument, "body", e.what());
        }
        json candidates = json::array();
        for (const RecognitionCandidate& c : r.candidates) {
          if (!lib.store().GetMaterial(c.material))
            continue;  // deleted since registration
          candidates.push_back({{"material", c.material},
                                {"score", c.score},
                                {"similarity", c.similarity}});
        }
        const bool unknown = r.unknown || candidates.empty();
        json out = {{"unknown", unknown},
                    {"candidates", candidates},
                    {"operating_point", r.operating_point},
                    {"reason",
                     candidates.empty() && !r.candidates.empty()
                         ? "every close material has been deleted"
                         : r.reason}};
        if (unknown) {
          // The workflow of paper 000 Fig. 11: an unknown material needs a test
          // stroke.
          if (auto hint = req.Query("material")) {
            CheckId(*hint, "material");
            out["identification"] =
                IdentificationRequestToJson(lib.RequestIdentification(
                    *hint, FingertipParam(req), "recognize"));
          } else {
            out["identification"] = {
                {"requested", false},
                {"stroke",
                 StrokePlanToJson(
                     lib.MakeStrokePlan("<new-id>", FingertipParam(req)))},
                {"detail",
                 "pass ?material=<new id> to record an identification "
                 "request"}};
          }
        }
        return HttpResponse::Json(200, out);
      });
  // The same hook for the LCM endpoint (material_query_v1 with an image).
  return [&lib, recognizer](const std::string& image) {
    const RecognitionResult r = recognizer->Recognize(image);
    ImageRecognition out;
    for (const RecognitionCandidate& c : r.candidates) {
      if (lib.store().GetMaterial(c.material))
        out.candidates.emplace_back(c.material, c.score);
    }
    out.unknown = r.unknown || out.candidates.empty();
    out.reason = r.reason;
    out.operating_point = r.operating_point;
    return out;
  };
}

#else

RecognizeImageFn RegisterRecognitionRoutes(HttpServer& http,
                                           FrictionLibrary& /*lib*/,
                                           double /*operating_point*/) {
  auto unavailable = [](const HttpRequest&) -> HttpResponse {
    return HttpResponse::Error(
        501,
        "not implemented",
        "this frictiond was built without OpenCV recognition");
  };
  http.Route("POST", "/v1/materials/{id}/images", unavailable);
  http.Route("POST", "/v1/recognize", unavailable);
  return {};
}

#endif

}  // namespace frictiond
