#include "frictiond/server/http_server.h"

#include <chrono>
#include <iostream>

#include <httplib.h>

#include "frictiond/server/request_error.h"
#include "frictiond/storage/store.h"

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
    throw RequestError(400, name, "query parameter " + name + " is required");
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
  return HttpResponse{status, "application/json", body.dump(), {}};
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

std::vector<std::string> SplitPath(const std::string& path) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (i < path.size()) {
    if (path[i] == '/') {
      ++i;
      continue;
    }
    std::size_t j = path.find('/', i);
    if (j == std::string::npos) j = path.size();
    out.push_back(path.substr(i, j - i));
    i = j;
  }
  return out;
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

}  // namespace

struct HttpServer::Impl {
  HttpOptions options;
  httplib::Server server;
  std::vector<RouteEntry> routes;
  Metrics metrics;
  HttpAuthorizer authorizer;
  HttpObserver observer;
};

HttpServer::HttpServer(HttpOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  auto& svr = impl_->server;
  const int threads = options.threads;
  svr.new_task_queue = [threads] {
    return new httplib::ThreadPool(static_cast<size_t>(threads));
  };
  svr.set_payload_max_length(options.max_body_bytes);
  svr.set_keep_alive_max_count(
      static_cast<size_t>(options.keep_alive_max_count));
  svr.set_keep_alive_timeout(options.keep_alive_timeout_s);
  svr.set_read_timeout(options.read_timeout_s, 0);
  svr.set_tcp_nodelay(true);
  // Every route goes through Dispatch; httplib only parses and writes.
  auto handle = [this](const httplib::Request& req, httplib::Response& res) {
    // httplib 0.11 enforces payload_max_length only on bodies that declare a
    // Content-Length; chunked (or compressed) bodies arrive here unchecked.
    if (req.body.size() > impl_->options.max_body_bytes) {
      res.status = 413;
      res.set_content(json{{"error", "payload too large"},
                           {"detail",
                            "body: " + std::to_string(req.body.size()) +
                                " bytes, larger than the limit of " +
                                std::to_string(impl_->options.max_body_bytes) +
                                " (see --max-body-mb)"}}
                          .dump(),
                      "application/json");
      return;
    }
    HttpRequest r;
    r.method = req.method;
    r.path = req.path;
    r.body = req.body;
    r.remote_addr = req.remote_addr;
    for (const auto& [k, v] : req.params) r.query.emplace(k, v);
    for (const auto& [k, v] : req.headers) r.headers.emplace(k, v);
    HttpResponse out = Dispatch(std::move(r));
    res.status = out.status;
    for (const auto& [k, v] : out.headers) res.set_header(k, v);
    res.set_content(std::move(out.body), out.content_type.c_str());
  };
  svr.Get(".*", handle);
  svr.Post(".*", handle);
  svr.Put(".*", handle);
  svr.Delete(".*", handle);
  svr.Patch(".*", handle);
  svr.Options(".*", handle);
  // Errors httplib produces itself (413, 400 on malformed requests): JSON too.
  svr.set_error_handler(httplib::Server::HandlerWithResponse(
      [](const httplib::Request&, httplib::Response& res) {
        if (!res.body.empty())
          return httplib::Server::HandlerResponse::Unhandled;
        std::string detail = "request rejected by the HTTP layer";
        if (res.status == 413)
          detail = "body larger than the limit (see --max-body-mb)";
        res.set_content(
            json{{"error", ErrorTitle(res.status)}, {"detail", detail}}.dump(),
            "application/json");
        return httplib::Server::HandlerResponse::Handled;
      }));
  svr.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
        res.status = 500;
        res.set_content(json{{"error", "internal error"},
                             {"detail", "unexpected exception"}}
                            .dump(),
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

HttpResponse HttpServer::Dispatch(HttpRequest request) const {
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
    try {
      std::optional<HttpResponse> rejected;
      if (impl_->authorizer) rejected = impl_->authorizer(request, route);
      if (rejected) {
        out = std::move(*rejected);
      } else {
        out = entry->handler(request);
      }
    } catch (const RequestError& e) {
      json j = {{"error", ErrorTitle(e.status())}, {"detail", e.what()}};
      if (!e.field().empty()) j["field"] = e.field();
      if (e.extra().is_object()) {
        for (auto it = e.extra().begin(); it != e.extra().end(); ++it)
          j[it.key()] = *it;
      }
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
    out =
        HttpResponse::Error(405,
                            "method not allowed",
                            request.method + " is not supported on this path");
  } else {
    std::string shown = request.path.substr(0, 100);
    for (char& c : shown) {
      if (static_cast<unsigned char>(c) < 0x20 ||
          static_cast<unsigned char>(c) >= 0x7f)
        c = '?';
    }
    out = HttpResponse::Error(404,
                              "not found",
                              "no route for " + request.method + " " + shown,
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
  return bound;
}

void HttpServer::Serve() { impl_->server.listen_after_bind(); }

void HttpServer::Stop() {
  if (impl_) impl_->server.stop();
}

bool HttpServer::running() const { return impl_->server.is_running(); }

Metrics& HttpServer::metrics() { return impl_->metrics; }

}  // namespace frictiond
