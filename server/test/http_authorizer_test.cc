// HttpServer's authorizer and observer hooks, and Routes().
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/server/http_server.h"

namespace frictiond {
namespace {

HttpRequest Req(const std::string& method, const std::string& path) {
  HttpRequest r;
  r.method = method;
  r.path = path;
  return r;
}

TEST(HttpAuthorizer, ServerWithoutAuthorizerIsOpen) {
  HttpServer http;
  int calls = 0;
  http.Route("PUT", "/v1/things/{id}", [&calls](const HttpRequest& r) {
    ++calls;
    return HttpResponse::Json(201, {{"id", r.params.at(0)}});
  });
  EXPECT_EQ(http.Dispatch(Req("PUT", "/v1/things/a")).status, 201);
  EXPECT_EQ(calls, 1);
  const std::vector<RouteKey> routes = http.Routes();
  ASSERT_EQ(routes.size(), 1u);
  EXPECT_EQ(routes[0].method, "PUT");
  EXPECT_EQ(routes[0].pattern, "/v1/things/{id}");
}

TEST(HttpAuthorizer, RejectionSkipsTheHandlerAndObserverSeesAll) {
  HttpServer http;
  int calls = 0;
  http.Route("PUT", "/v1/things/{id}", [&calls](const HttpRequest& r) {
    ++calls;
    return HttpResponse::Json(201, {{"by", r.actor}});
  });
  std::vector<std::string> seen;
  http.SetAuthorizer(
      [](HttpRequest& r,
         const std::string& pattern) -> std::optional<HttpResponse> {
        EXPECT_EQ(pattern, "/v1/things/{id}");
        if (r.Header("Authorization") != "Bearer ok")
          return HttpResponse::Error(401, "unauthorized", "no");
        r.actor = "tok_1";
        r.role = "operator";
        return std::nullopt;
      },
      [&seen](const HttpRequest& r,
              const std::string& pattern,
              const HttpResponse& out) {
        seen.push_back(r.method + " " + pattern + " " +
                       std::to_string(out.status) + " " + r.actor);
      });
  HttpResponse out = http.Dispatch(Req("PUT", "/v1/things/a"));
  EXPECT_EQ(out.status, 401);
  EXPECT_EQ(calls, 0);
  HttpRequest ok = Req("PUT", "/v1/things/b");
  ok.headers.emplace("authorization", "Bearer ok");
  out = http.Dispatch(ok);
  EXPECT_EQ(out.status, 201);
  EXPECT_EQ(calls, 1);
  EXPECT_NE(out.body.find("tok_1"), std::string::npos) << out.body;
  // Unmatched paths never reach the hooks.
  EXPECT_EQ(http.Dispatch(Req("GET", "/nowhere")).status, 404);
  EXPECT_EQ(seen,
            (std::vector<std::string>{"PUT /v1/things/{id} 401 ",
                                      "PUT /v1/things/{id} 201 tok_1"}));
}

TEST(HttpAuthorizer, ThrowingAuthorizerAnswers500) {
  HttpServer http;
  http.Route("GET", "/x", [](const HttpRequest&) {
    return HttpResponse::Json(200, {});
  });
  http.SetAuthorizer(
      [](HttpRequest&, const std::string&) -> std::optional<HttpResponse> {
        throw std::runtime_error("store down");
      });
  const HttpResponse out = http.Dispatch(Req("GET", "/x"));
  EXPECT_EQ(out.status, 500);
  EXPECT_NE(out.body.find("store down"), std::string::npos);
}

}  // namespace
}  // namespace frictiond
