#include "frictiond/client/client.h"

#include <chrono>
#include <cstdint>
#include <cstdio>

#include <httplib.h>

#include "frictiond/proto/json_parse.h"

#include "exchange_watchdog.h"
#include "model_cache.h"

namespace frictiond {

using nlohmann::json;

std::string UrlEncode(const std::string& s) {
  static const char* kHex = "0123456789ABCDEF";
  std::string out;
  for (unsigned char c : s) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
      out += static_cast<char>(c);
    } else {
      out += '%';
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  return out;
}

/// Bytes a reply's status line and headers may take (ExchangeWatchdog).
constexpr std::uint64_t kMaxReplyHeaderBytes = std::uint64_t{1} << 20;

struct FrictionClient::Impl {
  explicit Impl(const ClientOptions& o)
      : http(o.base_url),
        watchdog([this] { http.stop(); }, kMaxReplyHeaderBytes) {
    const auto sec = static_cast<time_t>(o.timeout_s);
    const auto usec = static_cast<time_t>((o.timeout_s - sec) * 1e6);
    http.set_connection_timeout(sec, usec);
    http.set_read_timeout(sec, usec);
    http.set_write_timeout(sec, usec);
    http.set_keep_alive(true);
    // httplib writes a request's headers and body separately: with Nagle on,
    // the body waited for the daemon's delayed ACK of the headers, 40 ms on
    // every upload after the first on a kept-alive connection (measured with
    // bench/upload: 43 ms per upload, 2.1 ms with TCP_NODELAY).
    http.set_tcp_nodelay(true);
    http.set_socket_options([this](socket_t s) { watchdog.OnSocket(s); });
    max_reply_bytes = o.max_reply_bytes;
    deadline_s = o.deadline_s;
    if (!o.robot.empty()) headers.emplace("X-Robot-Id", o.robot);
    if (!o.token.empty()) headers.emplace("Authorization", "Bearer " + o.token);
  }
  httplib::Client http;
  internal::ExchangeWatchdog watchdog;  // stops `http`: declared after it
  httplib::Headers headers;
  std::size_t max_reply_bytes = 0;
  double deadline_s = 0;

  /// Sends one request; the reply is abandoned beyond max_reply_bytes (its
  /// body), kMaxReplyHeaderBytes (what comes before the body) or deadline_s
  /// (all of it); then *limit says which and the result is an error.
  httplib::Result Send(const std::string& method,
                       const std::string& path,
                       const std::string* body,
                       const std::string& content_type,
                       std::string* limit) {
    httplib::Request req;
    req.method = method;
    req.path = path;
    req.headers = headers;
    if (body) {
      req.body = *body;
      req.set_header("Content-Type", content_type);
    }
    const auto deadline =
        std::chrono::steady_clock::now() +
        std::chrono::milliseconds(static_cast<long>(deadline_s * 1000));
    const std::size_t max = max_reply_bytes;
    // The body is received here, not by httplib (its progress callback is
    // not called for chunked replies): every piece is checked first.
    std::string received;
    req.content_receiver = [&](const char* data,
                               std::size_t n,
                               std::uint64_t /*offset*/,
                               std::uint64_t total) {
      if (received.empty()) watchdog.OnBody();
      if (total > max || received.size() + n > max) {
        *limit = "reply larger than max_reply_bytes = " + std::to_string(max);
        return false;
      }
      received.append(data, n);
      return true;
    };
    // The deadline holds for the whole exchange, body included: the
    // watchdog is the one place that enforces it.
    watchdog.Begin(
        deadline, http.is_socket_open() ? static_cast<int>(http.socket()) : -1);
    httplib::Result res = http.send(req);
    const std::string fired = watchdog.End();
    if (!res && limit->empty()) {
      if (fired == "deadline")
        *limit = "reply not complete within deadline_s = " +
                 std::to_string(deadline_s) + " s";
      else if (fired == "headers")
        *limit = "reply headers larger than " +
                 std::to_string(kMaxReplyHeaderBytes) + " bytes";
    }
    if (res) res->body = std::move(received);
    return res;
  }
};

FrictionClient::FrictionClient(ClientOptions options)
    : options_(std::move(options)), impl_(std::make_unique<Impl>(options_)) {}
FrictionClient::~FrictionClient() = default;
FrictionClient::FrictionClient(FrictionClient&&) noexcept = default;
FrictionClient& FrictionClient::operator=(FrictionClient&&) noexcept = default;

namespace {

json Check(const httplib::Result& res,
           const std::string& what,
           const std::string& base_url,
           const std::string& limit = "") {
  if (!res) {
    if (!limit.empty())
      throw ClientError(0, what + ": " + base_url + ": " + limit);
    throw ClientError(0,
                      what + ": cannot reach frictiond at " + base_url + " (" +
                          httplib::to_string(res.error()) + ")");
  }
  json body = ParseJsonOrDiscarded(res->body);
  if (res->status >= 400) {
    std::string msg = what + ": HTTP " + std::to_string(res->status);
    if (body.is_object() && body.contains("detail") &&
        body["detail"].is_string())
      msg += ": " + body["detail"].get<std::string>();
    throw ClientError(
        res->status, msg, body.is_discarded() ? json(nullptr) : body);
  }
  if (body.is_discarded())
    throw ClientError(res->status, what + ": reply is not JSON");
  return body;
}

std::string WithQuery(
    std::string path,
    const std::vector<std::pair<std::string, std::string>>& params) {
  char sep = path.find('?') == std::string::npos ? '?' : '&';
  for (const auto& [k, v] : params) {
    path += sep + UrlEncode(k) + "=" + UrlEncode(v);
    sep = '&';
  }
  return path;
}

// "/v1/materials/{material}/{route}" with the query `first`, then the
// fingertip, then `extra` (the caller's optional parameters).
std::string MaterialPath(
    const std::string& material,
    const std::string& route,
    std::vector<std::pair<std::string, std::string>> first,
    const std::string& fingertip,
    const std::vector<std::pair<std::string, std::string>>& extra = {}) {
  first.emplace_back("fingertip", fingertip);
  first.insert(first.end(), extra.begin(), extra.end());
  return WithQuery("/v1/materials/" + UrlEncode(material) + "/" + route, first);
}

}  // namespace

std::string FrictionClient::GetText(const std::string& path,
                                    std::string* content_type) {
  std::string limit;
  const httplib::Result res = impl_->Send("GET", path, nullptr, "", &limit);
  const std::string what = "GET " + path;
  if (!res || res->status >= 400) {
    Check(res, what, options_.base_url, limit);  // throws with the detail
    throw ClientError(res->status,
                      what + ": HTTP " + std::to_string(res->status));
  }
  if (content_type) *content_type = res->get_header_value("Content-Type");
  return res->body;
}

std::string FrictionClient::ExportMaterial(
    const std::string& material,
    const std::string& format,
    const std::vector<std::pair<std::string, std::string>>& params) {
  return GetText(MaterialPath(
      material, "export", {{"format", format}}, options_.fingertip, params));
}

json FrictionClient::FetchPairFriction(
    const std::string& fingertip_material,
    const std::string& object_material,
    const std::vector<std::pair<std::string, std::string>>& params) {
  return GetJson(WithQuery("/v1/pairs/" + UrlEncode(fingertip_material) + "/" +
                               UrlEncode(object_material) + "/friction",
                           params));
}

namespace {

std::string NumText(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

}  // namespace

json FrictionClient::FetchTargetForce(
    const std::string& material,
    double fn_n,
    double v_mm_s,
    const std::vector<std::pair<std::string, std::string>>& params) {
  return GetJson(
      MaterialPath(material,
                   "target-force",
                   {{"fn_n", NumText(fn_n)}, {"v_mm_s", NumText(v_mm_s)}},
                   options_.fingertip,
                   params));
}

json FrictionClient::FetchSlidingSpeed(
    const std::string& material,
    double fn_n,
    double ft_n,
    const std::vector<std::pair<std::string, std::string>>& params) {
  return GetJson(
      MaterialPath(material,
                   "sliding-speed",
                   {{"fn_n", NumText(fn_n)}, {"ft_n", NumText(ft_n)}},
                   options_.fingertip,
                   params));
}

json FrictionClient::FetchConditionalSlipLikelihood(const std::string& material,
                                                    double fn_n,
                                                    double ratio) {
  return GetJson(
      MaterialPath(material,
                   "conditional-slip-likelihood",
                   {{"fn_n", NumText(fn_n)}, {"ratio", NumText(ratio)}},
                   options_.fingertip));
}

json FrictionClient::FetchForms(const std::string& material, int folds) {
  return GetJson(MaterialPath(material,
                              "forms",
                              {{"folds", std::to_string(folds)}},
                              options_.fingertip));
}

json FrictionClient::FetchMuSpread(
    const std::string& material,
    double fn_n,
    double v_mm_s,
    const std::vector<std::pair<std::string, std::string>>& params) {
  return GetJson(
      MaterialPath(material,
                   "mu-spread",
                   {{"fn_n", NumText(fn_n)}, {"v_mm_s", NumText(v_mm_s)}},
                   options_.fingertip,
                   params));
}

json FrictionClient::FetchSpanVariability(
    const std::string& material,
    const std::vector<std::pair<std::string, std::string>>& params) {
  return GetJson(MaterialPath(
      material, "span-variability", {}, options_.fingertip, params));
}

json FrictionClient::GetJson(const std::string& path) {
  std::string limit;
  const httplib::Result res = impl_->Send("GET", path, nullptr, "", &limit);
  return Check(res, "GET " + path, options_.base_url, limit);
}

json FrictionClient::SendJson(const std::string& method,
                              const std::string& path,
                              const std::string& body,
                              const std::string& content_type) {
  if (method != "POST" && method != "PUT" && method != "DELETE")
    throw std::invalid_argument("method: " + method +
                                " (must be POST, PUT or DELETE)");
  std::string limit;
  const httplib::Result res =
      impl_->Send(method, path, &body, content_type, &limit);
  return Check(res, method + " " + path, options_.base_url, limit);
}

std::vector<MaterialInfo> FrictionClient::ListMaterials() {
  const json j = GetJson("/v1/materials");
  std::vector<MaterialInfo> out;
  for (const json& m : j.at("materials")) {
    MaterialInfo info;
    info.id = m.value("id", "");
    info.name = m.value("name", "");
    info.description = m.value("description", "");
    info.tags = m.value("tags", std::vector<std::string>{});
    if (m.contains("latest_version") && m["latest_version"].is_number())
      info.latest_version = m["latest_version"].get<int>();
    out.push_back(info);
  }
  return out;
}

ModelSet FrictionClient::FetchModel(const std::string& material,
                                    int version,
                                    const std::string& fingertip,
                                    FetchInfo* info) {
  FetchResult r = FetchModelWithInfo(material, version, fingertip);
  if (info) *info = std::move(r.info);
  return std::move(r.model);
}

FetchResult FrictionClient::FetchModelWithInfo(const std::string& material,
                                               int version,
                                               const std::string& fingertip) {
  const std::string tip = fingertip.empty() ? options_.fingertip : fingertip;
  std::string path = "/v1/materials/" + UrlEncode(material) +
                     "/model?fingertip=" + UrlEncode(tip);
  if (version > 0) path += "&version=" + std::to_string(version);
  FetchResult out;
  json j;
  try {
    j = GetJson(path);
  } catch (const ClientError& e) {
    // No daemon answered: the offline cache, if there is one.
    if (e.status() != 0 || options_.cache_dir.empty()) throw;
    const internal::ModelCache cache(options_.cache_dir);
    std::optional<internal::CachedEntry> entry;
    try {
      entry = cache.Get(material, tip, version);
      if (!entry && version > 0) {
        // The newest cached model may be the version asked for.
        entry = cache.Get(material, tip, 0);
        if (entry && entry->version != version) entry.reset();
      }
    } catch (const std::runtime_error& bad) {
      throw ClientError(
          0, std::string(e.what()) + "; " + bad.what() + " and was not used");
    }
    if (!entry)
      throw ClientError(
          0,
          std::string(e.what()) + "; no cached model of " + material +
              " (fingertip " + tip +
              (version > 0 ? ", version " + std::to_string(version)
                           : std::string()) +
              ") in " + options_.cache_dir);
    out.model = ModelSetFromJson(entry->model);  // verified by Get
    out.info.source = "cache";
    out.info.stale = true;
    out.info.version = entry->version;
    out.info.fetched_at = entry->fetched_at;
    out.info.server = entry->server;
    out.info.daemon_error = e.what();
    return out;
  }
  try {
    out.model = ModelSetFromJson(j);
  } catch (const std::exception& e) {
    throw ClientError(200, "GET " + path + ": malformed model: " + e.what(), j);
  }
  out.info.source = "daemon";
  out.info.stale = false;
  out.info.version = out.model.version;
  out.info.fetched_at = internal::UtcNowIso8601();
  out.info.server = options_.base_url;
  if (!options_.cache_dir.empty()) {
    // The fetch succeeded; a cache that cannot be written is reported, not
    // fatal.
    try {
      internal::ModelCache(options_.cache_dir)
          .Put(material,
               tip,
               j,
               out.model.version,
               /*latest=*/version == 0,
               out.info.fetched_at,
               out.info.server);
    } catch (const std::exception& e) {
      out.info.cache_error = e.what();
    }
  }
  return out;
}

std::vector<ResyncEntry> FrictionClient::Resync() {
  std::vector<ResyncEntry> out;
  if (options_.cache_dir.empty()) return out;
  const internal::ModelCache cache(options_.cache_dir);
  for (const auto& [material, fingertip] : cache.ListLatest()) {
    ResyncEntry r;
    r.material = material;
    r.fingertip = fingertip;
    try {
      if (auto e = cache.Get(material, fingertip, 0))
        r.cached_version = e->version;
    } catch (const std::runtime_error&) {
      r.cached_version = 0;  // corrupted: replaced below
    }
    try {
      FetchResult f = FetchModelWithInfo(material, 0, fingertip);
      if (f.info.stale) {
        // Served from the cache: no daemon answered.
        throw ClientError(0, "resync: " + f.info.daemon_error);
      }
      r.version = f.info.version;
      r.error = f.info.cache_error;
    } catch (const ClientError& e) {
      if (e.status() == 0)
        throw ClientError(0,
                          std::string(e.what()).rfind("resync: ", 0) == 0
                              ? e.what()
                              : std::string("resync: ") + e.what());
      r.error = e.what();
    }
    out.push_back(r);
  }
  return out;
}

UploadReply FrictionClient::UploadStrokes(
    const std::string& material,
    const std::string& csv,
    const std::vector<std::pair<std::string, std::string>>& params) {
  std::string path = "/v1/materials/" + UrlEncode(material) +
                     "/strokes?fingertip=" + UrlEncode(options_.fingertip);
  if (!options_.robot.empty()) path += "&robot=" + UrlEncode(options_.robot);
  for (const auto& [k, v] : params)
    path += "&" + UrlEncode(k) + "=" + UrlEncode(v);
  UploadReply r;
  r.body = SendJson("POST", path, csv, "text/csv");
  r.version = r.body.value("version", 0);
  r.stroke_id = r.body.value("stroke_id", std::int64_t{0});
  return r;
}

}  // namespace frictiond
