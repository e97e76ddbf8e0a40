#pragma once
/// @file
/// HTTP front end. Routes are registered as transport-neutral handlers
/// (HttpRequest -> HttpResponse), so feature modules add routes without
/// touching the HTTP library, and handlers are testable without sockets.
/// A handler reports the caller's mistakes by throwing RequestError (a
/// canonical StatusCode, request_error.h); the server maps the code to an
/// HTTP status in one place (HttpStatusFor) and answers {"error", "detail",
/// "field", ...}. HttpError is for what only HTTP has (415 media type).

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frictiond/server/metrics.h"
#include "frictiond/server/request_error.h"

namespace frictiond {

/// An error only the HTTP transport has (e.g. 415: the Content-Type of the
/// body is not one the route reads); `field` names the header.
class HttpError : public std::runtime_error {
 public:
  HttpError(int status, std::string field, const std::string& message)
      : std::runtime_error(message),
        status_(status),
        field_(std::move(field)) {}
  int status() const { return status_; }
  const std::string& field() const { return field_; }

 private:
  int status_;
  std::string field_;
};

/// One HTTP request, as handlers see it.
struct HttpRequest {
  std::string method;
  std::string path;
  std::string body;
  std::string remote_addr;
  std::vector<std::string>
      params;  ///< {captures} of the route pattern, in order
  /// The matched route's pattern, e.g. "/v1/materials/{id}/predict" (set by
  /// Dispatch).
  std::string route;
  std::multimap<std::string, std::string> query;  ///< decoded query parameters
  std::multimap<std::string, std::string> headers;
  /// Set by the authorizer (HttpServer::SetAuthorizer): the caller's token
  /// id and role; both empty for an anonymous (or unchecked) request.
  std::string actor;
  std::string role;
  /// Set by the authorizer when a successful (2xx) answer to this request
  /// is audited: the entry's action, "METHOD /pattern"; empty otherwise.
  /// A handler that stores the audit entry with its own write (in one
  /// transaction) sets HttpResponse::audit_committed.
  std::string audit_action;

  /// First value of a query parameter.
  std::optional<std::string> Query(const std::string& name) const;
  /// Query parameter or a default.
  std::string QueryOr(const std::string& name,
                      const std::string& fallback) const;
  /// Required finite number. @throws RequestError(StatusCode::kInvalidArgument)
  /// naming the parameter.
  double RequireNumber(const std::string& name) const;
  /// Header value ("" when absent; names are case-insensitive).
  std::string Header(const std::string& name) const;
};

/// A response.
struct HttpResponse {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::multimap<std::string, std::string> headers;
  /// The handler committed this write's audit entry with the write itself
  /// (HttpRequest::audit_action); the observer must not append another.
  bool audit_committed = false;

  static HttpResponse Json(int status, const nlohmann::json& body);
  /// Body already serialised as JSON.
  static HttpResponse RawJson(int status, std::string body);
  static HttpResponse Error(int status,
                            const std::string& error,
                            const std::string& detail,
                            const std::string& field = "");
};

using HttpHandler = std::function<HttpResponse(const HttpRequest&)>;

/// Called by Dispatch for a matched route before its handler, with the
/// route's pattern. Returning a response rejects the request (the handler
/// does not run); returning nullopt admits it. May fill request.actor/role.
using HttpAuthorizer = std::function<std::optional<HttpResponse>(
    HttpRequest& request, const std::string& pattern)>;
/// Called by Dispatch after a handler ran (or the authorizer rejected),
/// with the route's pattern and the response (e.g. for an audit log).
using HttpObserver = std::function<void(const HttpRequest& request,
                                        const std::string& pattern,
                                        const HttpResponse& response)>;

/// Called by Dispatch for a request the authorizer admitted, before the
/// body is read and the handler runs, with the route's pattern: throws
/// RequestError to reject the request's query (e.g. an unknown name).
using HttpQueryCheck =
    std::function<void(const HttpRequest& request, const std::string& pattern)>;

/// A registered route.
struct RouteKey {
  std::string method;
  std::string pattern;
};

/// Server options. Every limit holds per connection or request whatever
/// the client sends (docs/security.md "HTTP").
struct HttpOptions {
  /// Larger bodies get 413, checked while reading (Content-Length, chunked
  /// or length-less). Compressed bodies (Content-Encoding) get 415.
  std::size_t max_body_bytes = 16u << 20;
  int threads = 8;                    ///< worker threads
  int keep_alive_max_count = 100000;  ///< requests per kept-alive connection
  int keep_alive_timeout_s = 5;       ///< idle time between requests
  int read_timeout_s = 10;            ///< longest wait for the next bytes
  /// From the first byte of a request to the end of its headers [ms];
  /// later: 408 and the connection is closed.
  int header_timeout_ms = 10000;
  /// From the first byte of a request to the end of its body [ms].
  int request_timeout_ms = 60000;
  /// Request line plus headers [bytes]; more: 431.
  std::size_t max_header_bytes = 32u << 10;
  /// Open connections (idle, reading headers or served); more: 503.
  int max_connections = 512;
  /// Connections with complete headers waiting for a worker; more: 503.
  int max_queue = 128;
};

/// Not copyable or movable.
class HttpServer {
 public:
  explicit HttpServer(HttpOptions options = {});
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// Registers a handler for a path pattern such as
  /// "/v1/materials/{id}/model": literal segments must match, each {name}
  /// captures one segment into HttpRequest::params (in order). The pattern
  /// is also the route's label in metrics.
  void Route(const std::string& method,
             const std::string& pattern,
             HttpHandler handler);

  /// Every registered (method, pattern), in registration order.
  std::vector<RouteKey> Routes() const;

  /// Installs the authorizer and observer (either may be empty). Call
  /// before Serve(). Without an authorizer every route is open.
  void SetAuthorizer(HttpAuthorizer authorizer, HttpObserver observer = {});

  /// Installs the query check (query_parameters.h); call before Serve().
  void SetQueryCheck(HttpQueryCheck check);

  /// Binds to address:port (port 0 picks a free one).
  /// @return the bound port. @throws std::runtime_error when binding fails.
  int Bind(const std::string& address, int port);
  /// Serves until Stop() (blocking). Call after Bind.
  void Serve();
  /// Stops serving; safe from any thread (not from a signal handler).
  void Stop();
  /// True once Serve() is accepting connections.
  bool running() const;

  Metrics& metrics();

  /// Dispatches a request without sockets (used by tests and by the
  /// server itself).
  HttpResponse Dispatch(HttpRequest request) const;

  /// Decides a request from its method, path, query and headers alone,
  /// before its body is read: nullopt when the route exists and admits the
  /// caller, else the answer (404, 405, 400 for invalid text, 401/403 from
  /// the authorizer, 400 from the query check), counted in metrics like
  /// Dispatch's.
  std::optional<HttpResponse> Admit(HttpRequest request) const;

 private:
  // Dispatch (headers_only false: always an answer) and Admit.
  std::optional<HttpResponse> Run(HttpRequest request, bool headers_only) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace frictiond
