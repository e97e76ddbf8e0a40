// Model diagnosis over HTTP: run `diagnose` on a material's stored strokes
// and, when asked, store the extended model as a new version that is served
// like any other (issue "model diagnosis", item 4).
#include <atomic>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/proto/diagnosis_json.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/server/routes.h"

namespace frictiond {

using nlohmann::json;

namespace {

// Bounds of one diagnosis over HTTP. An outside attack run stored 24
// uploads of 7.9 MB in one material and ran 3 diagnoses at once: 56 s each
// and the daemon at 4 GB. The search's memory and time grow with the
// samples; the CLI (`friction diagnose`) has no such bound.
// Bounded in cells (samples x columns): 360,000 samples of 64 columns took
// the daemon to 1.7 GB.
constexpr std::size_t kMaxDiagnosisCells = 8'000'000;
std::atomic<int> g_diagnoses_running{0};

// At most one diagnosis at a time; others get 503 with a retry hint.
class DiagnosisSlot {
 public:
  DiagnosisSlot() {
    int expected = 0;
    if (!g_diagnoses_running.compare_exchange_strong(expected, 1))
      throw RequestError(StatusCode::kUnavailable,
                         "id",
                         "another diagnosis is running (one at a time); "
                         "retry when it is done");
  }
  ~DiagnosisSlot() { g_diagnoses_running = 0; }
  DiagnosisSlot(const DiagnosisSlot&) = delete;
  DiagnosisSlot& operator=(const DiagnosisSlot&) = delete;
};

}  // namespace

void RegisterDiagnosisRoutes(HttpServer& http, FrictionLibrary& lib) {
  http.Route(
      "POST", "/v1/materials/{id}/diagnose", [&lib](const HttpRequest& req) {
        const std::string& id = req.params[0];
        CheckId(id, "id");
        const std::string fingertip = FingertipParam(req);
        const std::string store = req.QueryOr("store", "0");
        if (store != "0" && store != "1") {
          throw RequestError(
              StatusCode::kInvalidArgument,
              "store",
              "store = '" + store.substr(0, 16) + "' (must be 0 or 1)");
        }
        auto model = lib.RequireModel(id, fingertip, "diagnose");
        DiagnosisOptions options;
        if (model->set.stochastic)
          options.labelling = model->set.stochastic->labelling;
        // Replay the pair's identified LuGre model too (paper 001) when the
        // stored version has one.
        if (model->set.other.contains(kLuGreFamilyKey)) {
          options.lugre =
              LuGreFromJson(model->set.other.at(kLuGreFamilyKey)).theta;
        }
        if (auto seed = req.Query("seed")) {
          const double s = ParseNumberParam("seed", *seed);
          if (!(s >= 0 && s < 1e15))
            throw RequestError(StatusCode::kInvalidArgument,
                               "seed",
                               "seed must be a non-negative integer");
          options.seed = static_cast<std::uint64_t>(s);
        }
        const DiagnosisSlot slot;
        const StrokeData data =
            lib.LoadStrokes(id, fingertip, options.labelling);
        const std::size_t columns = 4 + data.covariates.size();
        if (data.size() * columns > kMaxDiagnosisCells)
          throw RequestError(
              StatusCode::kResourceExhausted,
              "strokes",
              "strokes: " + std::to_string(data.size()) + " samples of " +
                  std::to_string(columns) + " columns stored (at most " +
                  std::to_string(kMaxDiagnosisCells) +
                  " samples x columns for one diagnosis over HTTP; export "
                  "the strokes and run 'friction diagnose' on a part of "
                  "them)");
        const DiagnosisResult result = Diagnose(data, options);
        json out = {
            {"material", id},
            {"fingertip", fingertip},
            {"diagnosed_version", model->set.version},
            {"diagnosis",
             DiagnosisToJson(result,
                             options,
                             "",
                             DiagnosisJsonOptions{true, false, false})}};
        if (result.status != DiagnosisStatus::kOk) {
          throw RequestError(StatusCode::kFailedPrecondition,
                             "strokes",
                             "cannot diagnose: " + result.why,
                             out);
        }
        if (store == "1" && !result.findings.empty()) {
          StochasticFitOptions fit_options;
          fit_options.labelling = options.labelling;
          fit_options.terms = result.extended.terms;
          if (result.extended.eps_scale)
            fit_options.eps_scale_input = result.extended.eps_scale->input;
          const StochasticFit fit = FitStochasticModel(data, fit_options);
          if (fit.status != FitStatus::kOk &&
              fit.status != FitStatus::kPartial) {
            throw RequestError(StatusCode::kFailedPrecondition,
                               "strokes",
                               "extended model could not be fitted: " + fit.why,
                               out);
          }
          json summary = {{"baseline", result.baseline.model},
                          {"baseline_cv_mae", result.baseline.cv_mae},
                          {"extended", result.extended.model},
                          {"extended_cv_mae", result.extended.cv_mae},
                          {"gain_pct", result.gain_pct},
                          {"causes", json::array()}};
          for (const Finding& f : result.findings)
            summary["causes"].push_back(f.cause);
          auto stored = lib.AddModelVersion(id,
                                            fingertip,
                                            fit.model,
                                            "diagnosis",
                                            json{{"diagnosis", summary}});
          out["stored_version"] = stored->set.version;
        }
        return HttpResponse::Json(200, out);
      });
}

}  // namespace frictiond
