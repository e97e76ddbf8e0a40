#pragma once
/// @file
/// API tokens, roles and the audit log of the HTTP API (docs/auth.md).
///
/// Every route has a required role, kept in one table (RoutePolicies()):
/// public (/healthz, /metrics), reader (lookups), robot (strokes,
/// identification, joint data) or operator (materials, images, fingertips,
/// robots, tokens, audit, deletes). Roles are ordered operator > robot >
/// reader: a token satisfies its own role and every lower one. A route
/// missing from the table gets the secure default: GET -> reader, anything
/// else -> operator.
///
/// Tokens are sent as "Authorization: Bearer <secret>" and stored only as
/// SHA-256 hashes. Reader routes are open to anonymous callers when
/// AuthOptions::open_reads is set (the daemon sets it only when bound to a
/// loopback address and the config allows it).

#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "frictiond/server/http_server.h"
#include "frictiond/storage/store.h"

namespace frictiond {

/// Access levels, ordered.
enum class Role { kPublic = 0, kReader = 1, kRobot = 2, kOperator = 3 };

/// "public", "reader", "robot", "operator".
const char* RoleName(Role role);
/// Parses "reader", "robot" or "operator" (not "public").
std::optional<Role> ParseRole(const std::string& name);

/// One explicit entry of the route policy.
struct RoutePolicy {
  std::string method;
  std::string pattern;
  Role role;
};
/// The explicit route policy table.
const std::vector<RoutePolicy>& RoutePolicies();
/// The role a route needs: its table entry, else GET -> reader and any
/// other method -> operator.
Role RequiredRole(const std::string& method, const std::string& pattern);
/// True when the route has an entry in RoutePolicies().
bool HasExplicitPolicy(const std::string& method, const std::string& pattern);

/// True for 127.0.0.0/8, ::1 and "localhost".
bool IsLoopbackAddress(const std::string& address);

/// Options of the authenticator.
struct AuthOptions {
  /// Reader routes answer anonymous callers (no Authorization header).
  bool open_reads = false;
  /// How long a validated token is trusted before the store is asked again
  /// (bounds how late a revocation made by another daemon takes effect).
  std::chrono::milliseconds cache_ttl{1000};
};

/// A token just created, with its secret (shown only once).
struct CreatedToken {
  TokenRecord record;
  std::string secret;
};

/// Checks tokens against the store, enforces the route policy and writes
/// the audit log. Thread-safe. Not copyable.
class Authenticator {
 public:
  Authenticator(Store& store, Metrics& metrics, AuthOptions options);
  Authenticator(const Authenticator&) = delete;
  Authenticator& operator=(const Authenticator&) = delete;

  /// Installs Authorize/Observe on the server (SetAuthorizer).
  void Install(HttpServer& http);

  /// The HttpAuthorizer: nullopt admits the request (filling request.actor
  /// and request.role), otherwise a 401 or 403 JSON response.
  std::optional<HttpResponse> Authorize(HttpRequest& request,
                                        const std::string& pattern);
  /// The HttpObserver: appends an audit entry for each successful write.
  void Observe(const HttpRequest& request,
               const std::string& pattern,
               const HttpResponse& response);

  /// Creates a token; `secret` empty = 32 random bytes as hex.
  /// @throws std::invalid_argument for a bad name, role or secret.
  CreatedToken CreateToken(const std::string& name,
                           const std::string& role,
                           const std::string& secret = "");
  /// Revokes a token (takes effect at once on this daemon).
  /// @return false when unknown or already revoked.
  bool RevokeToken(const std::string& id);
  /// On a store without tokens, creates the operator token "bootstrap"
  /// (secret `secret`, or a random one when empty) and returns it;
  /// nullopt when tokens exist already.
  std::optional<CreatedToken> BootstrapIfEmpty(const std::string& secret);

  const AuthOptions& options() const { return options_; }

 private:
  std::optional<TokenRecord> Lookup(const std::string& hash);

  Store& store_;
  Metrics& metrics_;
  AuthOptions options_;
  std::mutex mu_;
  struct Cached {
    TokenRecord token;
    std::chrono::steady_clock::time_point at;
  };
  std::map<std::string, Cached> cache_;  // by hash; valid tokens only
};

/// The audit entry of an admitted write (request.audit_action set by
/// Authorize): actor, role, remote address, action, the material of a
/// /v1/materials/{id} route (else detail "target" = the first capture) and
/// detail {"status": status}. The observer adds reply fields; a handler
/// that commits the entry with its write passes it to the library.
AuditEntry HttpAuditEntry(const HttpRequest& request, int status);

/// POST/GET /v1/tokens, DELETE /v1/tokens/{id}, GET /v1/audit.
void RegisterAuthRoutes(HttpServer& http, Authenticator& auth, Store& store);

}  // namespace frictiond
