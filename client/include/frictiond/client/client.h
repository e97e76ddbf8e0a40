#pragma once
/// @file
/// C++ client of frictiond for robots: fetch a material's model once over
/// HTTP, then evaluate it locally in the control loop (PredictMu,
/// CalcSlipLikelihood, CalcGripForce of frictiond/estimators) without
/// further network traffic. The grip force takes the hold and the grasp's
/// state (grip_force.h): CalcGripForce(model, load_n, risk,
/// GripForceOptions{hold_s, v_mm_s}); defaults: one instant, at rest.
///
/// @code
///   frictiond::FrictionClient client({"http://127.0.0.1:8080"});
///   frictiond::ModelSet m = client.FetchModel("felt");          // one request
///   const auto& s = *m.stochastic;
///   double p = frictiond::CalcSlipLikelihood(s, fn_n, ft_n);     // ~ns, no
///   I/O
/// @endcode
///
/// With ClientOptions::cache_dir the client keeps working offline: fetched
/// models are cached on disk and served, marked stale, when no daemon
/// answers (docs/offline.md).

#include <cstddef>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/proto/model_json.h"

namespace frictiond {

/// The daemon answered with an error status, or could not be reached
/// (status 0). body() holds the daemon's JSON error when there was one
/// (for an unknown material: the identification request and stroke plan).
class ClientError : public std::runtime_error {
 public:
  ClientError(int status,
              const std::string& message,
              nlohmann::json body = nullptr)
      : std::runtime_error(message), status_(status), body_(std::move(body)) {}
  int status() const { return status_; }
  const nlohmann::json& body() const { return body_; }

 private:
  int status_;
  nlohmann::json body_;
};

/// Client options.
struct ClientOptions {
  std::string base_url = "http://127.0.0.1:8080";  ///< daemon URL (http only)
  std::string fingertip = "default";  ///< default fingertip of requests
  std::string robot;                  ///< sent as X-Robot-Id (may be empty)
  double timeout_s = 5.0;             ///< connect/read timeout
  /// A reply body larger than this is abandoned (ClientError, status 0):
  /// whatever answers at base_url cannot make the client run out of memory.
  /// A reply's status line and headers may take at most 1 MiB.
  std::size_t max_reply_bytes = std::size_t{256} << 20;
  /// A reply (headers or body) still arriving this long after the request
  /// was sent is abandoned [s] (a server sending one byte per second kept
  /// the CLI waiting for ever; timeout_s bounds each read only).
  double deadline_s = 120.0;
  /// API token secret, sent as "Authorization: Bearer <token>" when not
  /// empty (docs/auth.md).
  std::string token;
  /// Directory of the offline model cache (docs/offline.md): every model
  /// fetched is kept there, and served (stale) when no daemon answers.
  /// "" = no cache. The CLI's --cache-dir / FRICTIOND_CACHE_DIR.
  std::string cache_dir;
};

/// Where a fetched model came from (FetchModelWithInfo).
struct FetchInfo {
  std::string source;        ///< "daemon", or "cache" when no daemon answered
  bool stale = false;        ///< true when served from the cache
  int version = 0;           ///< the model's version
  std::string fetched_at;    ///< when it came from a daemon (UTC, ISO 8601)
  std::string server;        ///< the daemon URL it came from
  std::string daemon_error;  ///< why the daemon was not used (stale only)
  /// A cache problem that did not stop the fetch (e.g. the cache file could
  /// not be written); "" when none.
  std::string cache_error;
};

/// A model and where it came from.
struct FetchResult {
  ModelSet model;
  FetchInfo info;
};

/// One cached (material, fingertip) refreshed by FrictionClient::Resync.
struct ResyncEntry {
  std::string material;
  std::string fingertip;
  int cached_version = 0;  ///< before (0: the cache file was unreadable)
  int version = 0;         ///< after (0: not refreshed, see error)
  std::string error;       ///< why it was not refreshed ("" = refreshed)
};

/// Summary of a material as listed by the daemon.
struct MaterialInfo {
  std::string id;
  std::string name;
  std::string description;
  std::vector<std::string> tags;
  std::optional<int> latest_version;  ///< newest model of the default fingertip
};

/// Result of an upload.
struct UploadReply {
  int version = 0;
  std::int64_t stroke_id = 0;
  nlohmann::json body;  ///< full reply
};

/// HTTP client. Thread-compatible (one instance per thread, or external
/// locking). Move-only.
class FrictionClient {
 public:
  explicit FrictionClient(ClientOptions options = {});
  ~FrictionClient();
  FrictionClient(FrictionClient&&) noexcept;
  FrictionClient& operator=(FrictionClient&&) noexcept;
  FrictionClient(const FrictionClient&) = delete;
  FrictionClient& operator=(const FrictionClient&) = delete;

  /// @throws ClientError on HTTP errors or when unreachable.
  std::vector<MaterialInfo> ListMaterials();
  /// Newest model (version 0) or a given version of a material.
  /// @throws ClientError: 404 carries the identification request the daemon
  /// recorded (body()["identification"]).
  /// With options().cache_dir set, the model is also written to the cache
  /// (atomically), and when no daemon answers (status 0) the cached model is
  /// returned instead; `info` (when not null) says which, and whether it is
  /// stale.
  /// @throws ClientError(0) when no daemon answers and the cache has no
  /// usable model (none, or a corrupted file: the message says which).
  ModelSet FetchModel(const std::string& material,
                      int version = 0,
                      const std::string& fingertip = "",
                      FetchInfo* info = nullptr);
  /// FetchModel with where the model came from.
  FetchResult FetchModelWithInfo(const std::string& material,
                                 int version = 0,
                                 const std::string& fingertip = "");
  /// Fetches the newest model of every (material, fingertip) in the cache
  /// from the daemon and overwrites the cache (a corrupted file is replaced
  /// too). No-op without cache_dir.
  /// @throws ClientError(0) when no daemon answers (nothing is changed).
  std::vector<ResyncEntry> Resync();
  /// Uploads a stroke CSV (text/csv). Extra query parameters (e.g.
  /// slip_peak_mm_s) may be given as name/value pairs.
  UploadReply UploadStrokes(
      const std::string& material,
      const std::string& csv,
      const std::vector<std::pair<std::string, std::string>>& params = {});
  /// A material's friction in a simulator's format (GET
  /// /v1/materials/{id}/export): format is mjcf, sdf, urdf, usd or isaac;
  /// params are further query parameters (risk, fn_n, v_mm_s, name,
  /// version). The fingertip is options().fingertip. Returns the text.
  /// @throws ClientError: 400 names the bad parameter, 404 unknown material.
  std::string ExportMaterial(
      const std::string& material,
      const std::string& format,
      const std::vector<std::pair<std::string, std::string>>& params = {});
  /// The friction distribution of a fingertip-object pair (GET
  /// /v1/pairs/{fingertip}/{object}/friction): measured when that pair was
  /// identified, otherwise combined by a rule ("measured": false). params:
  /// fn_n, v_mm_s, rule, risk, reference.
  nlohmann::json FetchPairFriction(
      const std::string& fingertip_material,
      const std::string& object_material,
      const std::vector<std::pair<std::string, std::string>>& params = {});
  /// Target tangential force for sliding at v_mm_s under fn_n (paper 000,
  /// eq. 3; GET /v1/materials/{id}/target-force): {"ft_n", "mu",
  /// "interval95_n", "extrapolated", ...}. params: model covariates,
  /// version. The fingertip is options().fingertip.
  /// @throws ClientError: 400 names the bad parameter, 404 unknown material.
  nlohmann::json FetchTargetForce(
      const std::string& material,
      double fn_n,
      double v_mm_s,
      const std::vector<std::pair<std::string, std::string>>& params = {});
  /// Sliding speed predicted from measured forces of a slipping contact
  /// (paper 000, eq. 4; GET /v1/materials/{id}/sliding-speed): {"v_mm_s",
  /// "interval95", "b1_t", "below_model_range", "extrapolated", ...}.
  /// @throws ClientError: 400 bad parameter, 404 unknown material, 422 the
  /// model has no identified speed slope.
  nlohmann::json FetchSlidingSpeed(
      const std::string& material,
      double fn_n,
      double ft_n,
      const std::vector<std::pair<std::string, std::string>>& params = {});
  /// Conditional slip likelihood L(Fn, Ft/Fn) of paper 000 eq. (2) (GET
  /// /v1/materials/{id}/conditional-slip-likelihood?fn_n=&ratio=):
  /// {"likelihood", "c1", "c2", "extrapolated", "fn_range_n", ...};
  /// "extrapolated" is true when fn_n lies outside the fitted Fn windows.
  /// @throws ClientError: 400 bad parameter, 404 unknown material, 422 the
  /// model has no conditional likelihood.
  nlohmann::json FetchConditionalSlipLikelihood(const std::string& material,
                                                double fn_n,
                                                double ratio);
  /// The alternative forms of mu = f(Fn) (Table II, section I) compared by
  /// leave-strokes-out error (GET /v1/materials/{id}/forms): {"best",
  /// "forms": [{"form", "formula", "a", "b", "r2", "cv_mae"}, ...], ...}.
  nlohmann::json FetchForms(const std::string& material, int folds = 5);
  /// Spread of mu inside Fn and v windows around (fn_n, v_mm_s) (paper 000
  /// III-B, Fig. 6; GET /v1/materials/{id}/mu-spread): {"fn_windows",
  /// "v_windows", "both_windows": [{"fn_width_n", "v_width_mm_s",
  /// "samples", "std_mu"}, ...], "sigma_eps"}. params: fn_widths_n,
  /// v_widths_mm_s (comma-separated, "inf" = no window).
  nlohmann::json FetchMuSpread(
      const std::string& material,
      double fn_n,
      double v_mm_s,
      const std::vector<std::pair<std::string, std::string>>& params = {});
  /// Fig. 10 experiment on the stored strokes (GET
  /// /v1/materials/{id}/span-variability): spread of b0, b1, b2 per span
  /// bin. params: subsets, max_strokes, seed, bin_pct.
  nlohmann::json FetchSpanVariability(
      const std::string& material,
      const std::vector<std::pair<std::string, std::string>>& params = {});
  /// Generic text GET (any Content-Type); *content_type receives the reply's
  /// Content-Type when not null. @throws ClientError like GetJson.
  std::string GetText(const std::string& path_and_query,
                      std::string* content_type = nullptr);
  /// Generic JSON GET of a daemon path (e.g. "/v1/materials/x/predict?...").
  nlohmann::json GetJson(const std::string& path_and_query);
  /// Generic JSON request with a body.
  nlohmann::json SendJson(const std::string& method,
                          const std::string& path,
                          const std::string& body,
                          const std::string& content_type = "application/json");

  const ClientOptions& options() const { return options_; }

 private:
  struct Impl;
  ClientOptions options_;
  std::unique_ptr<Impl> impl_;
};

/// Percent-encodes a query parameter value.
std::string UrlEncode(const std::string& s);

}  // namespace frictiond
