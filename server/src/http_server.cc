#include "frictiond/server/http_server.h"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdint>
#include <iostream>
#include <set>
#include <string>

#include <httplib.h>

#include "frictiond/server/request_error.h"
#include "frictiond/server/text.h"
#include "frictiond/storage/store.h"

#include "http_connections.h"

namespace frictiond {

using nlohmann::json;

std::optional<std::string> HttpRequest::Query(const std::string& name) const {
  auto it = query.find(name);
  if (it == query.end()) return std::nullopt;
  return it->second;
}

std::string HttpRequest::QueryOr(const std::string& name,
                                 const std::string& fallback) const {
  auto v = Query(name);
  return v ? *v : fallback;
}

double HttpRequest::RequireNumber(const std::string& name) const {
  auto v = Query(name);
  if (!v)
    throw RequestError(StatusCode::kInvalidArgument,
                       name,
                       "query parameter " + name + " is required");
  return ParseNumberParam(name, *v);
}

std::string HttpRequest::Header(const std::string& name) const {
  for (const auto& [k, v] : headers) {
    if (k.size() == name.size() &&
        std::equal(k.begin(), k.end(), name.begin(), [](char a, char b) {
          return std::tolower(a) == std::tolower(b);
        }))
      return v;
  }
  return "";
}

HttpResponse HttpResponse::Json(int status, const json& body) {
  // Strings reaching a response are checked where they enter (text.h); the
  // replacing dump is the last guard, so no stored byte can turn into a 500.
  return HttpResponse{status,
                      "application/json",
                      body.dump(-1, ' ', false, json::error_handler_t::replace),
                      {}};
}

HttpResponse HttpResponse::RawJson(int status, std::string body) {
  return HttpResponse{status, "application/json", std::move(body), {}};
}

HttpResponse HttpResponse::Error(int status,
                                 const std::string& error,
                                 const std::string& detail,
                                 const std::string& field) {
  json j = {{"error", error}, {"detail", detail}};
  if (!field.empty()) j["field"] = field;
  return Json(status, j);
}

namespace {

struct RouteEntry {
  std::string method;
  std::vector<std::string> segments;  // "{x}" captures one segment
  std::string route;
  HttpHandler handler;
};

// Segments between slashes. One leading and one trailing slash are
// ignored; an empty segment inside the path ("a//b", or a %2F that httplib
// decoded before routing) is kept, so it matches no route instead of
// vanishing: "/v1/materials/%2F/model" was served as material "model" and
// recorded an identification request for it (outside attack run).
std::vector<std::string> SplitPath(const std::string& path) {
  std::vector<std::string> out;
  std::size_t begin = !path.empty() && path[0] == '/' ? 1 : 0;
  std::size_t end = path.size();
  if (end > begin && path[end - 1] == '/') --end;
  if (begin >= end) return out;
  for (std::size_t i = begin;;) {
    const std::size_t j = path.find('/', i);
    if (j == std::string::npos || j >= end) {
      out.push_back(path.substr(i, end - i));
      return out;
    }
    out.push_back(path.substr(i, j - i));
    i = j + 1;
  }
}

// Matches path segments against a route; fills captures.
bool MatchRoute(const RouteEntry& e,
                const std::vector<std::string>& segs,
                const std::string& path,
                std::vector<std::string>* captures) {
  if (segs.size() != e.segments.size()) return false;
  if (path.size() > 1 && path.back() == '/') return false;
  captures->clear();
  for (std::size_t i = 0; i < segs.size(); ++i) {
    const std::string& p = e.segments[i];
    if (!p.empty() && p.front() == '{') {
      captures->push_back(segs[i]);
    } else if (p != segs[i]) {
      return false;
    }
  }
  return true;
}

std::string ErrorTitle(int status) {
  switch (status) {
    case 400:
      return "bad request";
    case 401:
      return "unauthorized";
    case 403:
      return "forbidden";
    case 404:
      return "not found";
    case 405:
      return "method not allowed";
    case 409:
      return "conflict";
    case 413:
      return "payload too large";
    case 415:
      return "unsupported media type";
    case 422:
      return "unprocessable";
    case 503:
      return "unavailable";
    default:
      return status >= 500 ? "internal error" : "error";
  }
}

// Checks the text of a request every handler may read: path segments,
// query names and values, header values (text.h). Throws
// RequestError(StatusCode::kInvalidArgument). Path captures are only checked
// for UTF-8 and length here, under the capture's name; the route's own id rule
// (CheckId) names what else fails.
void CheckRequestText(const HttpRequest& r, const RouteEntry& e) {
  std::size_t k = 0;
  for (const std::string& p : e.segments) {
    if (p.empty() || p.front() != '{') continue;
    if (k >= r.params.size()) break;
    const std::string name = p.substr(1, p.size() - 2);
    const std::string& value = r.params[k++];
    if (value.size() > kMaxPathSegmentBytes || !IsValidUtf8(value))
      CheckText(value, name, kMaxPathSegmentBytes);
  }
  for (const auto& [k, v] : r.query) {
    CheckText(k, "query", kMaxPathSegmentBytes);
    CheckText(v, k, kMaxQueryValueBytes);
  }
  for (const auto& [k, v] : r.headers) {
    CheckText(k, "header", kMaxPathSegmentBytes);
    CheckText(v, "header " + k, kMaxHeaderValueBytes);
  }
}

std::string ErrorJson(int status,
                      const std::string& detail,
                      const std::string& field = "") {
  json j = {{"error", ErrorTitle(status)}, {"detail", detail}};
  if (!field.empty()) j["field"] = field;
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

// Answers from the HTTP layer and closes the connection afterwards (a
// body may be left unread).
void RejectAndClose(httplib::Response& res,
                    int status,
                    const std::string& detail,
                    const std::string& field = "") {
  res.status = status;
  res.set_header("Connection", "close");
  res.set_content(ErrorJson(status, detail, field), "application/json");
  if (auto* strm = internal::ConnectionStream::Current())
    strm->CloseAfterResponse();
}

// Whether httplib's parse of the request line succeeded (then a 400 of its
// own came from a header): a method it knows and HTTP/1.0 or 1.1.
bool RequestLineIsValid(const httplib::Request& req) {
  static const std::set<std::string> kMethods = {"GET",
                                                 "HEAD",
                                                 "POST",
                                                 "PUT",
                                                 "DELETE",
                                                 "CONNECT",
                                                 "OPTIONS",
                                                 "TRACE",
                                                 "PATCH",
                                                 "PRI"};
  return kMethods.count(req.method) > 0 &&
         (req.version == "HTTP/1.1" || req.version == "HTTP/1.0");
}

HttpRequest ToHttpRequest(const httplib::Request& req) {
  HttpRequest r;
  r.method = req.method;
  r.path = req.path;
  r.remote_addr = req.remote_addr;
  for (const auto& [k, v] : req.params) r.query.emplace(k, v);
  for (const auto& [k, v] : req.headers) {
    // httplib adds these itself; they are not the client's.
    if (k == "REMOTE_ADDR" || k == "REMOTE_PORT" || k == "LOCAL_ADDR" ||
        k == "LOCAL_PORT")
      continue;
    r.headers.emplace(k, v);
  }
  return r;
}

}  // namespace

struct HttpServer::Impl {
  explicit Impl(const HttpOptions& o)
      : options(o), server([&o] {
          internal::ConnectionLimits l;
          l.threads = o.threads;
          l.max_connections = o.max_connections;
          l.max_queue = o.max_queue;
          l.max_header_bytes = o.max_header_bytes;
          l.header_timeout_ms = o.header_timeout_ms;
          l.request_timeout_ms = o.request_timeout_ms;
          l.read_timeout_ms = o.read_timeout_s * 1000;
          l.write_timeout_ms = o.read_timeout_s * 1000;
          l.keep_alive_timeout_ms = o.keep_alive_timeout_s * 1000;
          l.keep_alive_max_count = o.keep_alive_max_count;
          return l;
        }()) {}
  HttpOptions options;
  internal::GuardedServer server;
  std::vector<RouteEntry> routes;
  Metrics metrics;
  HttpAuthorizer authorizer;
  HttpObserver observer;
  HttpQueryCheck query_check;
};

HttpServer::HttpServer(HttpOptions options)
    : impl_(std::make_unique<Impl>(options)) {
  auto& svr = impl_->server;
  svr.set_payload_max_length(options.max_body_bytes);
  svr.set_keep_alive_max_count(
      static_cast<size_t>(options.keep_alive_max_count));
  svr.set_keep_alive_timeout(options.keep_alive_timeout_s);
  svr.set_read_timeout(options.read_timeout_s, 0);
  svr.set_tcp_nodelay(true);
  // Everything decidable from the request line and headers is decided
  // before a body byte is read: encodings, declared size, route and
  // authentication (httplib 0.11 would otherwise buffer a chunked or
  // length-less body whole, and inflate gzip without a limit).
  svr.set_pre_routing_handler([this](const httplib::Request& req,
                                     httplib::Response& res) {
    // Range requests are not served: httplib would cut a JSON answer to
    // the range (200 with 11 bytes of it, or 416 with no body; outside
    // attack run). The Request is httplib's own non-const object.
    const_cast<httplib::Request&>(req).ranges.clear();
    const std::string encoding = req.get_header_value("Content-Encoding");
    if (!encoding.empty() && encoding != "identity") {
      RejectAndClose(res,
                     415,
                     "Content-Encoding " + ShownText(encoding) +
                         ": compressed request bodies are not accepted "
                         "(send identity)",
                     "Content-Encoding");
      return httplib::Server::HandlerResponse::Handled;
    }
    const bool has_te = req.has_header("Transfer-Encoding");
    const bool chunked = has_te && req.get_header_value("Transfer-Encoding") ==
                                       std::string("chunked");
    if (has_te && !chunked) {
      RejectAndClose(res,
                     415,
                     "Transfer-Encoding " +
                         ShownText(req.get_header_value("Transfer-Encoding")) +
                         ": only chunked is accepted",
                     "Transfer-Encoding");
      return httplib::Server::HandlerResponse::Handled;
    }
    const bool has_length = req.has_header("Content-Length");
    if (has_length &&
        (chunked || req.get_header_value_count("Content-Length") != 1)) {
      RejectAndClose(res,
                     400,
                     "Content-Length with Transfer-Encoding, or twice",
                     "Content-Length");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (has_length) {
      const std::string text = req.get_header_value("Content-Length");
      std::uint64_t length = 0;
      const auto [p, ec] =
          std::from_chars(text.data(), text.data() + text.size(), length);
      if (text.empty() || ec != std::errc() || p != text.data() + text.size()) {
        RejectAndClose(res,
                       400,
                       "Content-Length " + ShownText(text) +
                           ": not a non-negative integer",
                       "Content-Length");
        return httplib::Server::HandlerResponse::Handled;
      }
      if (length > impl_->options.max_body_bytes) {
        RejectAndClose(res,
                       413,
                       "body: " + text + " bytes, larger than the limit of " +
                           std::to_string(impl_->options.max_body_bytes) +
                           " (see --max-body-mb)",
                       "body");
        return httplib::Server::HandlerResponse::Handled;
      }
    }
    const bool has_body =
        chunked ||
        (has_length &&
         req.get_header_value("Content-Length") != std::string("0")) ||
        (!has_length && (req.method == "POST" || req.method == "PUT" ||
                         req.method == "PATCH"));
    if (has_body) {
      if (auto rejected = Admit(ToHttpRequest(req))) {
        res.status = rejected->status;
        res.set_header("Connection", "close");
        for (const auto& [k, v] : rejected->headers) res.set_header(k, v);
        res.set_content(rejected->body, rejected->content_type.c_str());
        if (auto* strm = internal::ConnectionStream::Current())
          strm->CloseAfterResponse();
        return httplib::Server::HandlerResponse::Handled;
      }
      // A GET or HEAD body is never read: close after answering.
      if (req.method != "POST" && req.method != "PUT" &&
          req.method != "PATCH" && req.method != "DELETE") {
        if (auto* strm = internal::ConnectionStream::Current())
          strm->CloseAfterResponse();
      }
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  // Every route goes through Dispatch; httplib only parses and writes.
  auto answer = [this](HttpRequest r, httplib::Response& res) {
    HttpResponse out = Dispatch(std::move(r));
    res.status = out.status;
    for (const auto& [k, v] : out.headers) res.set_header(k, v);
    res.set_content(std::move(out.body), out.content_type.c_str());
  };
  auto handle = [answer](const httplib::Request& req, httplib::Response& res) {
    answer(ToHttpRequest(req), res);
  };
  // Bodies are read here, counted while they arrive: Content-Length and
  // chunked alike stop at max_body_bytes + 1 and answer 413. A request with
  // neither has no body (RFC 7230 3.3.3); httplib would read one to the end
  // of the stream, so `curl -X POST` without data waited 10 s for a 408
  // (outside attack run). What follows its headers is the next request.
  auto handle_with_body = [this, answer](
                              const httplib::Request& req,
                              httplib::Response& res,
                              const httplib::ContentReader& content_reader) {
    const std::size_t limit = impl_->options.max_body_bytes;
    HttpRequest r = ToHttpRequest(req);
    if (!req.has_header("Content-Length") &&
        !req.has_header("Transfer-Encoding")) {
      answer(std::move(r), res);
      return;
    }
    if (req.has_header("Content-Length")) {
      // Checked against the limit before routing (pre-routing handler).
      const std::string text = req.get_header_value("Content-Length");
      std::size_t length = 0;
      std::from_chars(text.data(), text.data() + text.size(), length);
      r.body.reserve(std::min(length, limit));
    }
    bool too_large = false;
    const bool ok = content_reader([&](const char* data, std::size_t n) {
      if (r.body.size() + n > limit) {
        too_large = true;
        return false;
      }
      r.body.append(data, n);
      return true;
    });
    if (!ok || too_large) {
      auto* strm = internal::ConnectionStream::Current();
      if (too_large) {
        RejectAndClose(res,
                       413,
                       "body: more than the limit of " + std::to_string(limit) +
                           " bytes (see --max-body-mb)",
                       "body");
      } else if (strm && strm->timed_out()) {
        RejectAndClose(res,
                       408,
                       "body not complete in time (the client stopped "
                       "sending, or the request deadline passed)",
                       "body");
      } else {
        RejectAndClose(res, 400, "body: malformed or cut short", "body");
      }
      impl_->metrics.Record("unmatched", req.method, res.status, 0.0);
      return;
    }
    answer(std::move(r), res);
  };
  svr.Get(".*", handle);
  svr.Post(".*", handle_with_body);
  svr.Put(".*", handle_with_body);
  svr.Delete(".*", handle_with_body);
  svr.Patch(".*", handle_with_body);
  svr.Options(".*", handle);
  // Errors httplib produces itself (400 on malformed requests, 414): JSON.
  svr.set_error_handler(httplib::Server::HandlerWithResponse(
      [](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty())
          return httplib::Server::HandlerResponse::Unhandled;
        if (res.status == 400) {
          // httplib's own 400: a request line or header it could not parse
          // (unknown or lower-case method, no version). httplib would keep
          // the connection and read each following header line as a new
          // request, answering 400 once per line (an outside attack saw 3-4
          // answers to one request). The rest of the request cannot be
          // framed: close after this answer.
          RejectAndClose(res,
                         400,
                         "malformed request line or header (must be METHOD "
                         "TARGET HTTP/1.x with an upper-case method, then "
                         "Name: value lines)",
                         RequestLineIsValid(req) ? "header" : "request line");
          return httplib::Server::HandlerResponse::Handled;
        }
        // Every other answer of the HTTP layer itself comes before the
        // body was read: close after it, or the unread body would be read
        // as the next request (an outside attack smuggled a PUT with its
        // own token in the body of a request answered 414).
        std::string detail = "request rejected by the HTTP layer";
        std::string field = "target";
        if (res.status == 413) {
          detail = "body larger than the limit (see --max-body-mb)";
          field = "body";
        } else if (res.status == 414) {
          detail = "request target longer than the limit";
        } else if (res.status == 404) {
          detail = "request target not routable (it decodes to no path)";
        } else if (res.status == 416) {
          // httplib answers an unparsable Range header before routing;
          // a parsable one is ignored (pre-routing handler).
          detail =
              "Range header not understood (ranges are not served: omit it)";
          field = "Range";
        }
        RejectAndClose(res, res.status, detail, field);
        return httplib::Server::HandlerResponse::Handled;
      }));
  svr.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
        res.status = 500;
        res.set_content(ErrorJson(500, "unexpected exception"),
                        "application/json");
      });
}

HttpServer::~HttpServer() { Stop(); }

void HttpServer::Route(const std::string& method,
                       const std::string& pattern,
                       HttpHandler handler) {
  impl_->routes.push_back(
      RouteEntry{method, SplitPath(pattern), pattern, std::move(handler)});
}

std::vector<RouteKey> HttpServer::Routes() const {
  std::vector<RouteKey> out;
  for (const RouteEntry& e : impl_->routes)
    out.push_back(RouteKey{e.method, e.route});
  return out;
}

void HttpServer::SetAuthorizer(HttpAuthorizer authorizer,
                               HttpObserver observer) {
  impl_->authorizer = std::move(authorizer);
  impl_->observer = std::move(observer);
}

void HttpServer::SetQueryCheck(HttpQueryCheck check) {
  impl_->query_check = std::move(check);
}

HttpResponse HttpServer::Dispatch(HttpRequest request) const {
  return *Run(std::move(request), /*headers_only=*/false);
}

std::optional<HttpResponse> HttpServer::Admit(HttpRequest request) const {
  return Run(std::move(request), /*headers_only=*/true);
}

std::optional<HttpResponse> HttpServer::Run(HttpRequest request,
                                            bool headers_only) const {
  const auto start = std::chrono::steady_clock::now();
  std::string route = "unmatched";
  HttpResponse out;
  bool path_matched = false;
  const RouteEntry* entry = nullptr;
  const std::vector<std::string> segs = SplitPath(request.path);
  std::vector<std::string> captures;
  for (const RouteEntry& e : impl_->routes) {
    if (MatchRoute(e, segs, request.path, &captures)) {
      path_matched = true;
      if (e.method == request.method) {
        entry = &e;
        break;
      }
    }
  }
  if (entry) {
    route = entry->route;
    MatchRoute(*entry, segs, request.path, &captures);
    request.params = std::move(captures);
    request.route = route;
    try {
      CheckRequestText(request, *entry);
      std::optional<HttpResponse> rejected;
      if (impl_->authorizer) rejected = impl_->authorizer(request, route);
      if (!rejected && impl_->query_check) impl_->query_check(request, route);
      if (rejected) {
        out = std::move(*rejected);
      } else if (headers_only) {
        return std::nullopt;  // admitted; Dispatch runs the handler later
      } else {
        out = entry->handler(request);
      }
    } catch (const RequestError& e) {
      const int status = HttpStatusFor(e.code());
      json j = {{"error", ErrorTitle(status)}, {"detail", e.what()}};
      if (!e.field().empty()) j["field"] = e.field();
      if (e.extra().is_object()) {
        for (auto it = e.extra().begin(); it != e.extra().end(); ++it)
          j[it.key()] = *it;
      }
      out = HttpResponse::Json(status, j);
    } catch (const HttpError& e) {
      json j = {{"error", ErrorTitle(e.status())}, {"detail", e.what()}};
      if (!e.field().empty()) j["field"] = e.field();
      out = HttpResponse::Json(e.status(), j);
    } catch (const std::invalid_argument& e) {
      out = HttpResponse::Error(400, "bad request", e.what());
    } catch (const StoreUnavailable& e) {
      // The database server is unreachable: nothing was stored; retry later.
      out = HttpResponse::Error(503, "unavailable", e.what());
    } catch (const std::exception& e) {
      out = HttpResponse::Error(500, "internal error", e.what());
    }
    if (impl_->observer) {
      try {
        impl_->observer(request, route, out);
      } catch (const std::exception& e) {
        // The request itself succeeded or failed already; report and go on.
        std::cerr << "frictiond: observer of " << route << ": " << e.what()
                  << "\n";
      }
    }
  } else if (path_matched) {
    out = HttpResponse::Error(
        405,
        "method not allowed",
        ShownText(request.method, 16) + " is not supported on this path");
  } else {
    out = HttpResponse::Error(404,
                              "not found",
                              "no route for " + ShownText(request.method, 16) +
                                  " " + ShownText(request.path, 100),
                              "path");
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  impl_->metrics.Record(route, request.method, out.status, seconds);
  return out;
}

int HttpServer::Bind(const std::string& address, int port) {
  auto& svr = impl_->server;
  int bound = port;
  if (port == 0) {
    bound = svr.bind_to_any_port(address);
  } else if (!svr.bind_to_port(address, port)) {
    bound = -1;
  }
  if (bound <= 0)
    throw std::runtime_error("cannot bind HTTP to " + address + ":" +
                             std::to_string(port));
  svr.StartWorkers();
  return bound;
}

void HttpServer::Serve() { impl_->server.listen_after_bind(); }

void HttpServer::Stop() {
  if (!impl_) return;
  impl_->server.stop();
  impl_->server.StopWorkers();
}

bool HttpServer::running() const { return impl_->server.is_running(); }

Metrics& HttpServer::metrics() { return impl_->metrics; }

}  // namespace frictiond
