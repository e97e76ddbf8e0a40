// API tokens, roles and audit log (docs/auth.md). The route policy lives in
// kPolicies below and nowhere else.
#include "frictiond/server/auth.h"

#include <algorithm>
#include <cctype>
#include <iostream>

#include "frictiond/crypto/hmac.h"
#include "frictiond/proto/json_parse.h"
#include "frictiond/server/request_error.h"
#include "frictiond/server/text.h"

namespace frictiond {

using nlohmann::json;

namespace {

// The route policy. Routes not listed: GET -> reader, others -> operator.
// GET routes are listed too where they need more than the default, and
// every write is listed so the table reads as the whole write surface.
const std::vector<RoutePolicy> kPolicies = {
    // Open: liveness and Prometheus scraping.
    {"GET", "/healthz", Role::kPublic},
    {"GET", "/metrics", Role::kPublic},
    // The operator console's static files (no data; the page itself asks
    // for a token before it reads or writes anything that needs one).
    {"GET", "/", Role::kPublic},
    {"GET", "/console/{file}", Role::kPublic},
    // Lookups sent as POST (nothing stored).
    {"POST", "/v1/recognize", Role::kReader},
    // Robots: measurements and identification.
    {"POST", "/v1/materials/{id}/strokes", Role::kRobot},
    {"POST", "/v1/materials/{id}/diagnose", Role::kRobot},
    {"POST", "/v1/materials/{id}/joint-data", Role::kRobot},
    {"POST", "/v1/materials/{id}/actuator-logs", Role::kRobot},
    // Simulating a stored actuator model changes nothing: a lookup.
    {"POST", "/v1/materials/{id}/actuator-simulate", Role::kReader},
    // Operators: the library's contents and access to it.
    {"PUT", "/v1/materials/{id}", Role::kOperator},
    {"DELETE", "/v1/materials/{id}", Role::kOperator},
    {"PUT", "/v1/fingertips/{id}", Role::kOperator},
    {"POST", "/v1/materials/{id}/images", Role::kOperator},
    {"PUT", "/v1/robots/{id}", Role::kOperator},
    {"GET", "/v1/tokens", Role::kOperator},
    {"POST", "/v1/tokens", Role::kOperator},
    {"DELETE", "/v1/tokens/{id}", Role::kOperator},
    {"GET", "/v1/audit", Role::kOperator},
};

// Response keys copied into an audit entry's detail (never secrets).
const char* const kAuditKeys[] = {"version",
                                  "stroke_id",
                                  "image_id",
                                  "fingertip",
                                  "samples",
                                  "material_created",
                                  "created",
                                  "stored",
                                  "fit_status",
                                  "robot",
                                  "id",
                                  "name",
                                  "role"};

HttpResponse Unauthorized(const std::string& reason,
                          const std::string& detail) {
  HttpResponse r = HttpResponse::Json(
      401, {{"error", "unauthorized"}, {"detail", detail}, {"reason", reason}});
  r.headers.emplace("WWW-Authenticate", "Bearer realm=\"frictiond\"");
  return r;
}

bool IsValidSecret(const std::string& s) {
  if (s.size() < 16 || s.size() > 256) return false;
  return std::all_of(
      s.begin(), s.end(), [](char c) { return c > 0x20 && c < 0x7f; });
}

json AuditToJson(const AuditEntry& e) {
  json detail = json::parse(e.detail, nullptr, false);
  if (detail.is_discarded()) detail = e.detail;
  return {{"id", e.id},
          {"at", e.at},
          {"actor", e.actor},
          {"role", e.role},
          {"remote", e.remote},
          {"action", e.action},
          {"material", e.material},
          {"detail", detail}};
}

json TokenToJson(const TokenRecord& t) {
  json j = {{"id", t.id},
            {"name", t.name},
            {"role", t.role},
            {"created_at", t.created_at},
            {"revoked", !t.revoked_at.empty()}};
  if (!t.revoked_at.empty()) j["revoked_at"] = t.revoked_at;
  return j;
}

int ParseIntParam(const HttpRequest& req,
                  const std::string& name,
                  int fallback,
                  int lo,
                  int hi) {
  const auto v = req.Query(name);
  if (!v) return fallback;
  const double d = ParseNumberParam(name, *v);
  if (!(d >= lo && d <= hi) || d != static_cast<double>(static_cast<int>(d)))
    throw RequestError(StatusCode::kInvalidArgument,
                       name,
                       name + " = '" + v->substr(0, 32) +
                           "' (must be an integer in " + std::to_string(lo) +
                           ".." + std::to_string(hi) + ")");
  return static_cast<int>(d);
}

}  // namespace

const char* RoleName(Role role) {
  switch (role) {
    case Role::kPublic:
      return "public";
    case Role::kReader:
      return "reader";
    case Role::kRobot:
      return "robot";
    case Role::kOperator:
      return "operator";
  }
  return "operator";
}

std::optional<Role> ParseRole(const std::string& name) {
  if (name == "reader") return Role::kReader;
  if (name == "robot") return Role::kRobot;
  if (name == "operator") return Role::kOperator;
  return std::nullopt;
}

const std::vector<RoutePolicy>& RoutePolicies() { return kPolicies; }

Role RequiredRole(const std::string& method, const std::string& pattern) {
  for (const RoutePolicy& p : kPolicies)
    if (p.method == method && p.pattern == pattern) return p.role;
  return method == "GET" ? Role::kReader : Role::kOperator;
}

bool HasExplicitPolicy(const std::string& method, const std::string& pattern) {
  return std::any_of(kPolicies.begin(), kPolicies.end(), [&](const auto& p) {
    return p.method == method && p.pattern == pattern;
  });
}

bool IsLoopbackAddress(const std::string& address) {
  return address == "localhost" || address == "::1" || address == "[::1]" ||
         address.rfind("127.", 0) == 0;
}

Authenticator::Authenticator(Store& store,
                             Metrics& metrics,
                             AuthOptions options)
    : store_(store), metrics_(metrics), options_(options) {
  // Export the rejection counters from the start (0 until one happens).
  metrics_.Increment("http_unauthorized_total", 0);
  metrics_.Increment("http_forbidden_total", 0);
}

void Authenticator::Install(HttpServer& http) {
  http.SetAuthorizer(
      [this](HttpRequest& r, const std::string& p) { return Authorize(r, p); },
      [this](const HttpRequest& r,
             const std::string& p,
             const HttpResponse& out) { Observe(r, p, out); });
}

std::optional<TokenRecord> Authenticator::Lookup(const std::string& hash) {
  const auto now = std::chrono::steady_clock::now();
  std::optional<TokenRecord> last_known;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = cache_.find(hash);
    if (it != cache_.end()) {
      if (now - it->second.at < options_.cache_ttl) return it->second.token;
      last_known = it->second.token;
    }
  }
  std::optional<TokenRecord> t;
  try {
    t = store_.FindTokenByHash(hash);
  } catch (const StoreUnavailable&) {
    // The database is away (fleet back end): the token's last validation
    // stands, so callers keep getting cached reads (docs/fleet.md); a token
    // never seen before gets the 503.
    if (last_known) return last_known;
    throw;
  }
  std::lock_guard<std::mutex> lock(mu_);
  if (t && t->revoked_at.empty()) {
    cache_[hash] = Cached{*t, now};
  } else {
    cache_.erase(hash);
  }
  return t;
}

std::optional<HttpResponse> Authenticator::Authorize(
    HttpRequest& request, const std::string& pattern) {
  request.actor.clear();
  request.role.clear();
  const Role need = RequiredRole(request.method, pattern);
  if (need == Role::kPublic) return std::nullopt;
  const std::string header = request.Header("Authorization");
  const std::string what = request.method + " " + pattern;
  if (header.empty()) {
    if (need == Role::kReader && options_.open_reads) return std::nullopt;
    metrics_.Increment("http_unauthorized_total");
    return Unauthorized("missing",
                        what +
                            " needs a token (Authorization: Bearer "
                            "<secret>) with role " +
                            RoleName(need) + " or higher");
  }
  std::string scheme =
      header.substr(0, std::min<std::size_t>(7, header.size()));
  std::transform(scheme.begin(), scheme.end(), scheme.begin(), [](char c) {
    return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  });
  std::string secret = header.size() > 7 ? header.substr(7) : std::string();
  while (!secret.empty() && secret.back() == ' ') secret.pop_back();
  while (!secret.empty() && secret.front() == ' ') secret.erase(0, 1);
  if (scheme != "bearer " || secret.empty()) {
    metrics_.Increment("http_unauthorized_total");
    return Unauthorized("malformed",
                        "Authorization header must be 'Bearer <secret>'");
  }
  const std::optional<TokenRecord> token = Lookup(Sha256Hex(secret));
  if (!token) {
    metrics_.Increment("http_unauthorized_total");
    return Unauthorized("invalid", "unknown token");
  }
  if (!token->revoked_at.empty()) {
    metrics_.Increment("http_unauthorized_total");
    return Unauthorized(
        "revoked",
        "token " + token->id + " was revoked at " + token->revoked_at);
  }
  const std::optional<Role> has = ParseRole(token->role);
  if (!has || static_cast<int>(*has) < static_cast<int>(need)) {
    metrics_.Increment("http_forbidden_total");
    std::cerr << "frictiond: 403 " << what << " for token " << token->id
              << " (role " << token->role << ") from " << request.remote_addr
              << "\n";
    return HttpResponse::Json(
        403,
        {{"error", "forbidden"},
         {"detail",
          what + " needs role " + RoleName(need) + "; token " + token->id +
              " has role " + token->role},
         {"required_role", RoleName(need)},
         {"role", token->role}});
  }
  request.actor = token->id;
  request.role = token->role;
  if (request.method != "GET" &&
      static_cast<int>(need) >= static_cast<int>(Role::kRobot))
    request.audit_action = what;
  return std::nullopt;
}

void Authenticator::Observe(const HttpRequest& request,
                            const std::string& /*pattern*/,
                            const HttpResponse& response) {
  if (request.audit_action.empty() || response.audit_committed ||
      response.status < 200 || response.status >= 300)
    return;
  AuditEntry e = HttpAuditEntry(request, response.status);
  json detail = json::parse(e.detail);
  const json body = json::parse(response.body, nullptr, false);
  if (body.is_object()) {
    for (const char* k : kAuditKeys) {
      auto it = body.find(k);
      if (it != body.end() && it->is_primitive()) detail[k] = *it;
    }
  }
  e.detail = detail.dump();
  store_.AppendAudit(e);
}

AuditEntry HttpAuditEntry(const HttpRequest& request, int status) {
  AuditEntry e;
  e.actor = request.actor;
  e.role = request.role;
  e.remote = request.remote_addr;
  e.action = request.audit_action;
  const std::string pattern = e.action.substr(e.action.find(' ') + 1);
  const bool material_route = pattern.rfind("/v1/materials/{id}", 0) == 0;
  json detail = {{"status", status}};
  if (!request.params.empty()) {
    if (material_route)
      e.material = request.params[0];
    else
      detail["target"] = request.params[0];
  }
  e.detail = detail.dump();
  return e;
}

CreatedToken Authenticator::CreateToken(const std::string& name,
                                        const std::string& role,
                                        const std::string& secret) {
  if (name.empty() || name.size() > 64 ||
      !std::all_of(name.begin(), name.end(), [](char c) {
        return c >= 0x20 && c < 0x7f;
      }))
    throw RequestError(StatusCode::kInvalidArgument,
                       "name",
                       "name must be 1..64 printable ASCII characters");
  if (!ParseRole(role))
    throw RequestError(StatusCode::kInvalidArgument,
                       "role",
                       "role '" + ShownText(role, 32) +
                           "' (must be reader, robot or operator)");
  if (!secret.empty() && !IsValidSecret(secret))
    throw RequestError(StatusCode::kInvalidArgument,
                       "secret",
                       "token secret must be 16..256 printable characters "
                       "without spaces");
  CreatedToken out;
  out.secret = secret.empty() ? RandomHex(32) : secret;
  out.record.name = name;
  out.record.role = role;
  out.record.hash = Sha256Hex(out.secret);
  for (int attempt = 0; attempt < 4; ++attempt) {
    out.record.id = "tok_" + RandomHex(6);
    if (store_.AddToken(out.record)) {
      if (auto stored = store_.FindTokenByHash(out.record.hash))
        out.record = *stored;
      return out;
    }
    if (store_.FindTokenByHash(out.record.hash))
      throw RequestError(StatusCode::kAlreadyExists,
                         "secret",
                         "a token with this secret exists");
  }
  throw std::runtime_error("could not allocate a token id");
}

bool Authenticator::RevokeToken(const std::string& id) {
  const bool ok = store_.RevokeToken(id);
  std::lock_guard<std::mutex> lock(mu_);
  for (auto it = cache_.begin(); it != cache_.end();) {
    if (it->second.token.id == id) {
      it = cache_.erase(it);
    } else {
      ++it;
    }
  }
  return ok;
}

std::optional<CreatedToken> Authenticator::BootstrapIfEmpty(
    const std::string& secret) {
  if (!store_.ListTokens().empty()) return std::nullopt;
  if (!secret.empty() && !IsValidSecret(secret))
    throw std::invalid_argument(
        "--bootstrap-token: must be 16..256 printable characters without "
        "spaces");
  CreatedToken t = CreateToken("bootstrap", "operator", secret);
  AuditEntry e;
  e.actor = "system";
  e.action = "bootstrap token";
  e.detail = json{{"id", t.record.id}, {"role", "operator"}}.dump();
  store_.AppendAudit(e);
  return t;
}

void RegisterAuthRoutes(HttpServer& http, Authenticator& auth, Store& store) {
  http.Route("POST", "/v1/tokens", [&auth](const HttpRequest& req) {
    const json body = ParseJsonOrDiscarded(req.body);
    if (!body.is_object())
      throw RequestError(StatusCode::kInvalidArgument,
                         "body",
                         "expected a JSON object {name, role}");
    for (const char* key : {"name", "role"}) {
      if (!body.contains(key) || !body[key].is_string())
        throw RequestError(StatusCode::kInvalidArgument,
                           key,
                           std::string(key) + ": required, must be a string");
    }
    for (auto it = body.begin(); it != body.end(); ++it) {
      if (it.key() != "name" && it.key() != "role")
        throw RequestError(StatusCode::kInvalidArgument,
                           ShownText(it.key(), 64),
                           "unknown key '" + ShownText(it.key(), 64) + "'");
    }
    const CreatedToken t = auth.CreateToken(body["name"].get<std::string>(),
                                            body["role"].get<std::string>());
    json out = TokenToJson(t.record);
    out["secret"] = t.secret;
    out["created_by"] = req.actor;
    return HttpResponse::Json(201, out);
  });
  http.Route("GET", "/v1/tokens", [&store](const HttpRequest&) {
    json list = json::array();
    for (const TokenRecord& t : store.ListTokens())
      list.push_back(TokenToJson(t));
    return HttpResponse::Json(200, {{"tokens", list}});
  });
  http.Route(
      "DELETE", "/v1/tokens/{id}", [&auth, &store](const HttpRequest& req) {
        const std::string& id = req.params[0];
        CheckId(id, "id");
        if (!auth.RevokeToken(id)) {
          for (const TokenRecord& t : store.ListTokens()) {
            if (t.id == id)
              throw RequestError(StatusCode::kAlreadyExists,
                                 "id",
                                 "token " + id + " is already revoked");
          }
          throw RequestError(
              StatusCode::kNotFound, "id", "unknown token '" + id + "'");
        }
        return HttpResponse::Json(200, {{"id", id}, {"revoked", true}});
      });
  http.Route("GET", "/v1/audit", [&store](const HttpRequest& req) {
    const int after = ParseIntParam(req, "after", 0, 0, 2000000000);
    const int limit = ParseIntParam(req, "limit", 100, 1, 1000);
    const std::string material = req.QueryOr("material", "");
    if (!material.empty()) CheckId(material, "material");
    json list = json::array();
    std::int64_t last = after;
    for (const AuditEntry& e : store.ListAudit(after, limit, material)) {
      list.push_back(AuditToJson(e));
      last = e.id;
    }
    return HttpResponse::Json(200, {{"entries", list}, {"next_after", last}});
  });
}

}  // namespace frictiond
