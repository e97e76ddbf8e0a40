// Tokens, roles and audit log (docs/auth.md). Part 1 runs a daemon in this
// process and dispatches every registered route (enumerated from the server)
// with each role: none, reader, robot, operator and a revoked token. Part 2
// runs the real `frictiond` and `friction` binaries over loopback HTTP.
#include "frictiond/server/auth.h"

#include <cctype>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>

#include "frictiond/crypto/hmac.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/daemon.h"
#include "frictiond/server/openapi.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

// After Eigen: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks
// Eigen's headers.
#include <httplib.h>

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::DbFingerprint;
using testing::TempDir;

const char* const kBoot = "boot-secret-0123456789abcdef0123456789";

// The role each route needs, written down independently of the server's
// table: a route the server registers but this list lacks fails the test,
// so a new route cannot ship without a decided policy.
const std::map<std::pair<std::string, std::string>, Role> kExpected = {
    {{"GET", "/healthz"}, Role::kPublic},
    {{"GET", "/metrics"}, Role::kPublic},
    {{"GET", "/"}, Role::kPublic},
    {{"GET", "/console/{file}"}, Role::kPublic},
    {{"GET", "/v1/materials/{id}/samples"}, Role::kReader},
    {{"GET", "/v1/materials"}, Role::kReader},
    {{"GET", "/v1/materials/{id}"}, Role::kReader},
    {{"PUT", "/v1/materials/{id}"}, Role::kOperator},
    {{"DELETE", "/v1/materials/{id}"}, Role::kOperator},
    {{"GET", "/v1/fingertips"}, Role::kReader},
    {{"PUT", "/v1/fingertips/{id}"}, Role::kOperator},
    {{"GET", "/v1/materials/{id}/model"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/models"}, Role::kReader},
    {{"POST", "/v1/materials/{id}/strokes"}, Role::kRobot},
    {{"GET", "/v1/materials/{id}/strokes"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/predict"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/slip-likelihood"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/grip-force"}, Role::kReader},
    {{"GET", "/v1/identifications"}, Role::kReader},
    {{"GET", "/v1/openapi.json"}, Role::kReader},
    {{"POST", "/v1/materials/{id}/diagnose"}, Role::kRobot},
    {{"GET", "/v1/materials/{id}/export"}, Role::kReader},
    {{"GET", "/v1/pairs/{fingertip}/{object}/friction"}, Role::kReader},
    {{"POST", "/v1/materials/{id}/joint-data"}, Role::kRobot},
    {{"POST", "/v1/materials/{id}/actuator-logs"}, Role::kRobot},
    {{"GET", "/v1/materials/{id}/actuator-model"}, Role::kReader},
    {{"POST", "/v1/materials/{id}/actuator-simulate"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/actuator-mjcf"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/joint-friction"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/joint-wear"}, Role::kReader},
    {{"PUT", "/v1/robots/{id}"}, Role::kOperator},
    {{"GET", "/v1/robots/{id}"}, Role::kReader},
    {{"GET", "/v1/robots/{id}/repeatability"}, Role::kReader},
    {{"GET", "/v1/robots/{id}/repeatability-grid"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/breakaway"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/conditional-slip-likelihood"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/target-force"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/sliding-speed"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/forms"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/mu-spread"}, Role::kReader},
    {{"GET", "/v1/materials/{id}/span-variability"}, Role::kReader},
    {{"POST", "/v1/materials/{id}/images"}, Role::kOperator},
    {{"POST", "/v1/recognize"}, Role::kReader},
    {{"GET", "/v1/tokens"}, Role::kOperator},
    {{"POST", "/v1/tokens"}, Role::kOperator},
    {{"DELETE", "/v1/tokens/{id}"}, Role::kOperator},
    {{"GET", "/v1/audit"}, Role::kOperator},
};

std::string SimulatedCsv(std::uint64_t seed) {
  testing::SimulationSpec spec;
  spec.strokes = 8;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

std::string ReplaceAll(std::string s,
                       const std::string& from,
                       const std::string& to) {
  for (std::size_t p = s.find(from); p != std::string::npos;
       p = s.find(from, p + to.size()))
    s.replace(p, from.size(), to);
  return s;
}

// One in-process daemon on a file database, reached through Dispatch.
class AuthDispatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    DaemonConfig c;
    c.db = dir_.path() + "/lib.db";
    c.port = 0;
    c.data_dir = "none";
    c.threads = 2;
    c.bootstrap_token = kBoot;
    c.open_reads = open_reads_;
    c.bind = bind_;
    daemon_ = std::make_unique<Daemon>(c);
    daemon_->Start();
    auto& auth = daemon_->auth();
    secrets_["reader"] = auth.CreateToken("r", "reader").secret;
    secrets_["robot"] = auth.CreateToken("b", "robot").secret;
    secrets_["operator"] = kBoot;
    const CreatedToken gone = auth.CreateToken("old", "operator");
    secrets_["revoked"] = gone.secret;
    ASSERT_TRUE(auth.RevokeToken(gone.record.id));
    for (const TokenRecord& t : Store().ListTokens()) {
      if (t.name == "bootstrap") operator_id_ = t.id;
    }
    ASSERT_FALSE(operator_id_.empty());
  }
  frictiond::Store& Store() { return daemon_->library().store(); }

  HttpResponse Send(const std::string& who,
                    const std::string& method,
                    const std::string& path,
                    const std::string& body = "",
                    const std::string& content_type = "application/json",
                    std::multimap<std::string, std::string> query = {}) {
    HttpRequest r;
    r.method = method;
    r.path = path;
    r.body = body;
    r.remote_addr = "127.0.0.1";
    r.query = std::move(query);
    if (!content_type.empty()) r.headers.emplace("Content-Type", content_type);
    if (who != "none")
      r.headers.emplace("Authorization", "Bearer " + secrets_.at(who));
    return daemon_->http().Dispatch(r);
  }

  // Counts of everything a request could store.
  std::vector<std::size_t> Counts() {
    std::vector<std::size_t> out;
    out.push_back(Store().ListMaterials().size());
    out.push_back(Store().ListFingertips().size());
    out.push_back(Store().ListStrokes("m1", "default").size());
    out.push_back(Store().ListModels("m1", "default").size());
    out.push_back(Store().ListJobs(false).size());
    out.push_back(Store().ListImages().size());
    out.push_back(Store().ListTokens().size());
    std::size_t revoked = 0;
    for (const auto& t : Store().ListTokens()) revoked += !t.revoked_at.empty();
    out.push_back(revoked);
    out.push_back(Store().ListAudit(0, 100000, "").size());
    out.push_back(Store().GetRobot("r1").has_value());
    return out;
  }

  bool open_reads_ = true;
  std::string bind_ = "127.0.0.1";
  TempDir dir_{"auth_test"};
  std::unique_ptr<Daemon> daemon_;
  std::map<std::string, std::string> secrets_;
  std::string operator_id_;
};

// Request that would change the library if it got through.
struct Probe {
  std::string path;
  std::string body;
  std::string content_type = "application/json";
  std::multimap<std::string, std::string> query;
};

Probe DamagingProbe(const RouteKey& r, const std::string& operator_id) {
  Probe p;
  p.path = ReplaceAll(r.pattern, "{fingertip}", "default");
  p.path = ReplaceAll(p.path, "{object}", "m1");
  const bool tokens = r.pattern.rfind("/v1/tokens", 0) == 0;
  const bool robots = r.pattern.rfind("/v1/robots", 0) == 0;
  p.path = ReplaceAll(p.path,
                      "{id}",
                      tokens   ? operator_id
                      : robots ? "r1"
                               : "m1");
  if (r.method == "PUT" && r.pattern == "/v1/materials/{id}") {
    p.body = R"({"name":"Hijacked"})";
  } else if (r.pattern == "/v1/materials/{id}/strokes") {
    p.body = SimulatedCsv(7);
    p.content_type = "text/csv";
  } else if (r.pattern == "/v1/materials/{id}/diagnose") {
    p.query = {{"store", "1"}};
  } else if (r.pattern == "/v1/fingertips/{id}") {
    p.path = "/v1/fingertips/newtip";
    p.body = R"({"name":"tip"})";
  } else if (r.pattern == "/v1/robots/{id}") {
    p.body = R"({"joints":[{"type":"revolute","a_mm":100,"stiffness":1000,
                 "sigma_tau":1}],"q_home":[0]})";
  } else if (r.pattern == "/v1/tokens") {
    p.body = R"({"name":"sneaky","role":"operator"})";
  }
  return p;
}

// GET /v1/openapi.json (CONTRACT.md) describes every registered /v1 route
// with its path parameters and role, and its query-parameter table names
// only registered routes.
TEST_F(AuthDispatchTest, OpenApiDescribesEveryRegisteredRoute) {
  const HttpResponse res = Send("none", "GET", "/v1/openapi.json");
  ASSERT_EQ(res.status, 200) << res.body;
  const nlohmann::json doc = nlohmann::json::parse(res.body);
  EXPECT_EQ(doc.value("openapi", ""), "3.0.3");
  const std::vector<RouteKey> routes = daemon_->http().Routes();
  std::set<std::pair<std::string, std::string>> registered;
  for (const RouteKey& r : routes) {
    registered.insert({r.method, r.pattern});
    if (r.pattern.rfind("/v1/", 0) != 0) continue;
    std::string method = r.method;
    for (char& c : method) c = static_cast<char>(std::tolower(c));
    ASSERT_TRUE(doc["paths"].contains(r.pattern)) << r.pattern;
    ASSERT_TRUE(doc["paths"][r.pattern].contains(method))
        << r.method << " " << r.pattern;
    const nlohmann::json& op = doc["paths"][r.pattern][method];
    EXPECT_EQ(op.value("x-frictiond-role", ""),
              std::string(RoleName(RequiredRole(r.method, r.pattern))));
    std::size_t braces = 0;
    for (char c : r.pattern) braces += c == '{';
    std::size_t path_params = 0, query_params = 0;
    for (const auto& p : op.value("parameters", nlohmann::json::array())) {
      path_params += p.value("in", "") == "path";
      query_params += p.value("in", "") == "query";
    }
    EXPECT_EQ(path_params, braces) << r.pattern;
    EXPECT_EQ(query_params,
              DocumentedQueryParameters(r.method, r.pattern).size())
        << r.pattern;
  }
  for (const RouteKey& r : RoutesWithDocumentedQueries())
    EXPECT_TRUE(registered.count({r.method, r.pattern}))
        << "query table names an unregistered route: " << r.method << " "
        << r.pattern;
  const auto& grip = doc["paths"]["/v1/materials/{id}/grip-force"]["get"];
  std::set<std::string> names;
  for (const auto& p : grip["parameters"]) names.insert(p.value("name", ""));
  for (const char* n : {"load_n", "risk", "hold_s", "v_mm_s"})
    EXPECT_TRUE(names.count(n)) << n;
}

// The one table behind openapi.json is what the server enforces: every /v1
// route rejects a name the table does not list for it, naming it and listing
// exactly the documented names, and accepts each documented name. A route
// that takes the model's further inputs rejects a name that is neither
// documented nor an input of the model.
TEST_F(AuthDispatchTest, OpenApiQueryParametersAreThoseTheRoutesAccept) {
  // m1 has a model, so that model routes get past their lookup.
  ASSERT_EQ(Send("operator",
                 "POST",
                 "/v1/materials/m1/strokes",
                 SimulatedCsv(11),
                 "text/csv")
                .status,
            201);
  auto path_of = [](const std::string& pattern) {
    std::string path;
    for (std::size_t i = 0; i < pattern.size();) {
      if (pattern[i] == '{') {
        path += "m1";
        i = pattern.find('}', i) + 1;
      } else {
        path += pattern[i++];
      }
    }
    return path;
  };
  const nlohmann::json doc =
      nlohmann::json::parse(Send("none", "GET", "/v1/openapi.json").body);
  int checked_routes = 0;
  for (const RouteKey& r : daemon_->http().Routes()) {
    if (r.pattern.rfind("/v1/", 0) != 0) continue;
    SCOPED_TRACE(r.method + " " + r.pattern);
    const std::vector<std::string> documented =
        DocumentedQueryParameters(r.method, r.pattern);
    std::set<std::string> names(documented.begin(), documented.end());
    names.erase(kModelInputsParameter);
    // The required parameters, set, so that a route gets to its checks.
    std::multimap<std::string, std::string> base;
    std::string method = r.method;
    for (char& c : method) c = static_cast<char>(std::tolower(c));
    for (const auto& p : doc["paths"][r.pattern][method].value(
             "parameters", nlohmann::json::array())) {
      if (p.value("in", "") == "query" && p.value("required", false))
        base.emplace(p.value("name", ""), "1");
    }
    auto rejected_as_unknown = [](const HttpResponse& res,
                                  const std::string& name) {
      if (res.status != 400) return false;
      const auto j = nlohmann::json::parse(res.body, nullptr, false);
      return j.is_object() && j.value("field", "") == name &&
             j.value("detail", "").find("not known here") != std::string::npos;
    };
    auto q = base;
    q.emplace("zz_unknown", "1");
    const HttpResponse res =
        Send("operator", r.method, path_of(r.pattern), "", "", q);
    ASSERT_TRUE(rejected_as_unknown(res, "zz_unknown")) << res.body;
    ++checked_routes;
    const std::string detail =
        nlohmann::json::parse(res.body).value("detail", "");
    if (TakesModelInputs(r.method, r.pattern)) {
      EXPECT_NE(detail.find("not an input of this model"), std::string::npos)
          << detail;
    } else {
      const std::size_t at = detail.find("(allowed: ");
      ASSERT_NE(at, std::string::npos) << detail;
      const std::string list =
          detail.substr(at + 10, detail.find(')', at) - at - 10);
      std::set<std::string> allowed;
      for (std::size_t i = 0; list != "none" && i < list.size();) {
        std::size_t end = list.find(", ", i);
        if (end == std::string::npos) end = list.size();
        allowed.insert(list.substr(i, end - i));
        i = end + 2;
      }
      EXPECT_EQ(allowed, names) << detail;
    }
    if (r.method == "DELETE") continue;  // its documented names: none
    for (const std::string& n : names) {
      auto one = base;
      if (!one.count(n)) one.emplace(n, "1");
      EXPECT_FALSE(rejected_as_unknown(
          Send("operator", r.method, path_of(r.pattern), "", "", one), n))
          << "documented but rejected: " << n;
    }
  }
  EXPECT_GE(checked_routes, 40);
}

// The query check runs before the body is read: a typo is a 400 even when the
// body would be too large, and the handler never runs (nothing is stored).
TEST_F(AuthDispatchTest, UnknownQueryNameIsRejectedBeforeTheHandler) {
  HttpRequest r;
  r.method = "POST";
  r.path = "/v1/materials/typo/strokes";
  r.remote_addr = "127.0.0.1";
  r.query.emplace("fingertips", "a");  // one letter too many
  r.headers.emplace("Authorization", "Bearer " + secrets_.at("operator"));
  r.headers.emplace("Content-Type", "text/csv");
  const std::optional<HttpResponse> admitted = daemon_->http().Admit(r);
  ASSERT_TRUE(admitted.has_value());
  EXPECT_EQ(admitted->status, 400);
  r.body = SimulatedCsv(12);
  const HttpResponse res = daemon_->http().Dispatch(r);
  EXPECT_EQ(res.status, 400);
  const auto j = nlohmann::json::parse(res.body);
  EXPECT_EQ(j.value("field", ""), "fingertips");
  EXPECT_NE(j.value("detail", "").find("allowed: fingertip, robot"),
            std::string::npos)
      << res.body;
  EXPECT_FALSE(Store().GetMaterial("typo").has_value());
}

// Each query parameter is one value: a repeated name is a 400 naming it, on
// a route that takes model inputs as on any other, instead of an answer for
// whichever value the server happened to read.
TEST_F(AuthDispatchTest, RepeatedQueryNameIsRejected) {
  for (const char* path :
       {"/v1/materials/m1/predict", "/v1/materials/m1/grip-force"}) {
    SCOPED_TRACE(path);
    const HttpResponse res =
        Send("operator",
             "GET",
             path,
             "",
             "",
             {{"fn_n", "1"}, {"fn_n", "2"}, {"v_mm_s", "1"}});
    EXPECT_EQ(res.status, 400);
    const auto j = nlohmann::json::parse(res.body);
    EXPECT_EQ(j.value("field", ""), "fn_n");
    EXPECT_NE(j.value("detail", "").find("given 2 times"), std::string::npos)
        << res.body;
  }
}

TEST_F(AuthDispatchTest, EveryRouteHasTheExpectedPolicy) {
  const std::vector<RouteKey> routes = daemon_->http().Routes();
  ASSERT_GT(routes.size(), 30u);
  std::set<std::pair<std::string, std::string>> seen;
  for (const RouteKey& r : routes) {
    const auto key = std::make_pair(r.method, r.pattern);
    if (!seen.insert(key).second) continue;
    const auto it = kExpected.find(key);
    ASSERT_NE(it, kExpected.end())
        << r.method << " " << r.pattern
        << " is registered but has no decided role in this test (add it to "
           "kExpected and, for a write, to server/src/auth.cc)";
    EXPECT_EQ(RoleName(RequiredRole(r.method, r.pattern)),
              std::string(RoleName(it->second)))
        << r.method << " " << r.pattern;
    if (r.method != "GET") {
      EXPECT_TRUE(HasExplicitPolicy(r.method, r.pattern))
          << "write route without an explicit policy: " << r.method << " "
          << r.pattern;
    }
  }
  for (const RoutePolicy& p : RoutePolicies()) {
    EXPECT_TRUE(seen.count({p.method, p.pattern}))
        << "policy for a route that does not exist: " << p.method << " "
        << p.pattern;
  }
  // Unlisted routes get the secure default.
  EXPECT_EQ(RequiredRole("GET", "/v1/new-thing"), Role::kReader);
  EXPECT_EQ(RequiredRole("POST", "/v1/new-thing"), Role::kOperator);
  EXPECT_EQ(RequiredRole("PATCH", "/v1/materials/{id}"), Role::kOperator);
}

TEST_F(AuthDispatchTest, EveryRouteTimesEveryRole) {
  // A material with a model, so that allowed lookups have data.
  ASSERT_EQ(Send("robot",
                 "POST",
                 "/v1/materials/m1/strokes",
                 SimulatedCsv(1),
                 "text/csv")
                .status,
            201);
  const std::string db = dir_.path() + "/lib.db";
  const std::vector<RouteKey> routes = daemon_->http().Routes();
  const std::vector<std::string> whos = {
      "none", "reader", "robot", "operator", "revoked"};
  int rejected = 0, allowed = 0;
  // Rejections first, with requests that would store something if admitted.
  const std::vector<std::size_t> counts_before = Counts();
  const auto fp_before = DbFingerprint(db);
  // Roles from this test's own table, not the server's.
  auto need_of = [](const RouteKey& r) {
    const auto it = kExpected.find({r.method, r.pattern});
    return it == kExpected.end() ? Role::kOperator : it->second;
  };
  for (const RouteKey& r : routes) {
    const Role need = need_of(r);
    for (const std::string& who : whos) {
      int want = 0;  // 0: admitted
      if (need == Role::kPublic) {
        want = 0;
      } else if (who == "revoked") {
        want = 401;
      } else if (who == "none") {
        want = need == Role::kReader ? 0 : 401;
      } else if (static_cast<int>(*ParseRole(who)) < static_cast<int>(need)) {
        want = 403;
      }
      if (want == 0) continue;
      const Probe p = DamagingProbe(r, operator_id_);
      const HttpResponse out =
          Send(who, r.method, p.path, p.body, p.content_type, p.query);
      ++rejected;
      EXPECT_EQ(out.status, want)
          << who << " " << r.method << " " << r.pattern << ": " << out.body;
      const json body = json::parse(out.body, nullptr, false);
      ASSERT_TRUE(body.is_object()) << out.body;
      EXPECT_EQ(body.value("error", ""),
                want == 401 ? "unauthorized" : "forbidden");
      EXPECT_FALSE(body.value("detail", "").empty());
      if (want == 401) {
        EXPECT_EQ(body.value("reason", ""),
                  who == "revoked" ? "revoked" : "missing");
      }
    }
  }
  EXPECT_EQ(Counts(), counts_before) << "a rejected request stored something";
  EXPECT_EQ(DbFingerprint(db), fp_before)
      << "a rejected request changed the database";
  EXPECT_GT(rejected, 60);
  // Admitted: any status but 401/403 (a harmless id so nothing is deleted).
  for (const RouteKey& r : routes) {
    const Role need = need_of(r);
    for (const std::string& who : whos) {
      const bool admit =
          need == Role::kPublic || (who == "none" && need == Role::kReader) ||
          (who != "none" && who != "revoked" &&
           static_cast<int>(*ParseRole(who)) >= static_cast<int>(need));
      if (!admit) continue;
      std::string path = ReplaceAll(r.pattern, "{id}", "ghost");
      path = ReplaceAll(path, "{fingertip}", "default");
      path = ReplaceAll(path, "{object}", "m1");
      const HttpResponse out = Send(who, r.method, path);
      ++allowed;
      EXPECT_NE(out.status, 401) << who << " " << r.method << " " << path;
      EXPECT_NE(out.status, 403) << who << " " << r.method << " " << path;
    }
  }
  EXPECT_GT(allowed, 100);
  const std::string metrics = daemon_->http().metrics().Render();
  EXPECT_NE(metrics.find("frictiond_http_unauthorized_total "),
            std::string::npos);
  EXPECT_NE(metrics.find("frictiond_http_forbidden_total "), std::string::npos);
}

TEST_F(AuthDispatchTest, UnlistedRoutesGetTheSecureDefault) {
  int calls = 0;
  auto handler = [&calls](const HttpRequest&) {
    ++calls;
    return HttpResponse::Json(200, {{"ok", true}});
  };
  daemon_->http().Route("POST", "/v1/unlisted/{id}", handler);
  daemon_->http().Route("GET", "/v1/unlisted/{id}", handler);
  EXPECT_EQ(Send("none", "POST", "/v1/unlisted/a").status, 401);
  EXPECT_EQ(Send("reader", "POST", "/v1/unlisted/a").status, 403);
  EXPECT_EQ(Send("robot", "POST", "/v1/unlisted/a").status, 403);
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(Send("operator", "POST", "/v1/unlisted/a").status, 200);
  EXPECT_EQ(Send("revoked", "GET", "/v1/unlisted/a").status, 401);
  EXPECT_EQ(Send("none", "GET", "/v1/unlisted/a").status, 200);  // open read
  EXPECT_EQ(calls, 2);
}

TEST_F(AuthDispatchTest, BadHeadersAreRejectedWithTheReason) {
  HttpRequest r;
  r.method = "PUT";
  r.path = "/v1/materials/x";
  r.body = R"({"name":"X"})";
  for (const auto& [header, reason] :
       std::vector<std::pair<std::string, std::string>>{
           {"Basic abc", "malformed"},
           {"Bearer", "malformed"},
           {"Bearer not-a-known-secret-at-all", "invalid"},
           {std::string("Bearer ") + kBoot + "x", "invalid"}}) {
    r.headers = {{"Authorization", header}};
    const HttpResponse out = daemon_->http().Dispatch(r);
    EXPECT_EQ(out.status, 401) << header;
    EXPECT_EQ(json::parse(out.body).value("reason", ""), reason) << header;
  }
  EXPECT_FALSE(Store().GetMaterial("x"));
  r.headers = {{"authorization", std::string("bearer  ") + kBoot}};
  EXPECT_EQ(daemon_->http().Dispatch(r).status, 201);
}

TEST_F(AuthDispatchTest, TokensAreHashedListedAndRevoked) {
  HttpResponse out = Send(
      "operator", "POST", "/v1/tokens", R"({"name":"arm-7","role":"robot"})");
  ASSERT_EQ(out.status, 201) << out.body;
  const json created = json::parse(out.body);
  const std::string secret = created["secret"];
  const std::string id = created["id"];
  EXPECT_EQ(secret.size(), 64u);
  EXPECT_EQ(id.rfind("tok_", 0), 0u);
  EXPECT_EQ(created["role"], "robot");
  // Stored as the SHA-256 of the secret, never the secret.
  const auto rec = Store().FindTokenByHash(Sha256Hex(secret));
  ASSERT_TRUE(rec.has_value());
  EXPECT_EQ(rec->id, id);
  for (const TokenRecord& t : Store().ListTokens()) EXPECT_NE(t.hash, secret);
  // The list shows no secrets or hashes.
  out = Send("operator", "GET", "/v1/tokens");
  ASSERT_EQ(out.status, 200);
  EXPECT_EQ(out.body.find(secret), std::string::npos);
  EXPECT_EQ(out.body.find(rec->hash), std::string::npos);
  EXPECT_NE(out.body.find(id), std::string::npos);
  // The new token works, then stops working once revoked.
  secrets_["new"] = secret;
  EXPECT_EQ(Send("new",
                 "POST",
                 "/v1/materials/m2/strokes",
                 SimulatedCsv(3),
                 "text/csv")
                .status,
            201);
  EXPECT_EQ(Send("operator", "DELETE", "/v1/tokens/" + id).status, 200);
  EXPECT_EQ(Send("operator", "DELETE", "/v1/tokens/" + id).status, 409);
  EXPECT_EQ(Send("operator", "DELETE", "/v1/tokens/tok_nope").status, 404);
  out = Send("new", "GET", "/v1/materials");
  EXPECT_EQ(out.status, 401);
  EXPECT_EQ(json::parse(out.body).value("reason", ""), "revoked");
  // Validation names the field.
  for (const auto& [body, field] :
       std::vector<std::pair<std::string, std::string>>{
           {R"({"name":"x","role":"admin"})", "role"},
           {R"({"role":"robot"})", "name"},
           {R"({"name":"","role":"robot"})", "name"},
           {R"({"name":"x","role":"robot","secret":"s"})", "secret"},
           {"[1]", "body"}}) {
    out = Send("operator", "POST", "/v1/tokens", body);
    EXPECT_EQ(out.status, 400) << body;
    EXPECT_EQ(json::parse(out.body).value("field", ""), field) << body;
  }
}

TEST_F(AuthDispatchTest, AuditRecordsWhoChangedWhat) {
  const std::size_t before = Store().ListAudit(0, 1000, "").size();
  ASSERT_EQ(Send("operator", "PUT", "/v1/materials/felt", R"({"name":"Felt"})")
                .status,
            201);
  ASSERT_EQ(Send("robot",
                 "POST",
                 "/v1/materials/felt/strokes",
                 SimulatedCsv(5),
                 "text/csv")
                .status,
            201);
  // Failed and read-only requests leave no entry.
  EXPECT_EQ(Send("robot",
                 "POST",
                 "/v1/materials/felt/strokes",
                 "x,y\n1,2\n",
                 "text/csv")
                .status,
            400);
  EXPECT_EQ(Send("reader", "GET", "/v1/materials/felt").status, 200);
  EXPECT_EQ(Send("robot", "PUT", "/v1/materials/felt", "{}").status, 403);
  HttpResponse out =
      Send("operator", "GET", "/v1/audit", "", "", {{"material", "felt"}});
  ASSERT_EQ(out.status, 200) << out.body;
  const json entries = json::parse(out.body)["entries"];
  ASSERT_EQ(entries.size(), 2u) << out.body;
  std::string robot_id;
  for (const TokenRecord& t : Store().ListTokens()) {
    if (t.role == "robot") robot_id = t.id;
  }
  EXPECT_EQ(entries[0]["actor"], operator_id_);
  EXPECT_EQ(entries[0]["role"], "operator");
  EXPECT_EQ(entries[0]["action"], "PUT /v1/materials/{id}");
  EXPECT_EQ(entries[0]["material"], "felt");
  EXPECT_EQ(entries[0]["remote"], "127.0.0.1");
  EXPECT_EQ(entries[0]["detail"]["status"], 201);
  EXPECT_EQ(entries[1]["actor"], robot_id);
  EXPECT_EQ(entries[1]["role"], "robot");
  EXPECT_EQ(entries[1]["action"], "POST /v1/materials/{id}/strokes");
  EXPECT_EQ(entries[1]["detail"]["version"], 1);
  EXPECT_GT(entries[1]["detail"]["stroke_id"].get<int>(), 0);
  EXPECT_EQ(Store().ListAudit(0, 1000, "").size(), before + 2);
  // Paging and validation.
  const std::int64_t first = entries[0]["id"];
  out = Send("operator",
             "GET",
             "/v1/audit",
             "",
             "",
             {{"after", std::to_string(first)}, {"limit", "1"}});
  ASSERT_EQ(out.status, 200);
  EXPECT_EQ(json::parse(out.body)["entries"].size(), 1u);
  EXPECT_EQ(
      Send("operator", "GET", "/v1/audit", "", "", {{"limit", "0"}}).status,
      400);
  EXPECT_EQ(
      Send("operator", "GET", "/v1/audit", "", "", {{"after", "-1"}}).status,
      400);
  EXPECT_EQ(Send("reader", "GET", "/v1/audit").status, 403);
  // Token creation is audited without its secret.
  out = Send(
      "operator", "POST", "/v1/tokens", R"({"name":"cam","role":"reader"})");
  ASSERT_EQ(out.status, 201);
  const std::string secret = json::parse(out.body)["secret"];
  const auto all = Store().ListAudit(0, 1000, "");
  ASSERT_FALSE(all.empty());
  EXPECT_EQ(all.back().action, "POST /v1/tokens");
  EXPECT_EQ(all.back().detail.find(secret), std::string::npos);
}

class ClosedReadsTest : public AuthDispatchTest {
 protected:
  void SetUp() override {
    open_reads_ = false;
    AuthDispatchTest::SetUp();
  }
};

TEST_F(ClosedReadsTest, ReadsNeedAReaderWhenOpenReadsIsOff) {
  EXPECT_FALSE(daemon_->auth().options().open_reads);
  const auto before = Counts();
  HttpResponse out = Send("none", "GET", "/v1/materials/m9/model");
  EXPECT_EQ(out.status, 401);
  // The 404 lookup would have recorded an identification job.
  EXPECT_EQ(Counts(), before);
  EXPECT_EQ(Send("reader", "GET", "/v1/materials").status, 200);
  EXPECT_EQ(Send("none", "GET", "/healthz").status, 200);
  EXPECT_EQ(Send("none", "GET", "/metrics").status, 200);
}

class NonLoopbackTest : public AuthDispatchTest {
 protected:
  void SetUp() override {
    bind_ = "0.0.0.0";  // open_reads stays true but is not honoured
    AuthDispatchTest::SetUp();
  }
};

TEST_F(NonLoopbackTest, ReadsNeedAReaderWhenNotOnLoopback) {
  EXPECT_FALSE(daemon_->auth().options().open_reads);
  EXPECT_EQ(Send("none", "GET", "/v1/materials").status, 401);
  EXPECT_EQ(Send("reader", "GET", "/v1/materials").status, 200);
}

TEST(Loopback, Addresses) {
  EXPECT_TRUE(IsLoopbackAddress("127.0.0.1"));
  EXPECT_TRUE(IsLoopbackAddress("127.1.2.3"));
  EXPECT_TRUE(IsLoopbackAddress("::1"));
  EXPECT_TRUE(IsLoopbackAddress("localhost"));
  EXPECT_FALSE(IsLoopbackAddress("0.0.0.0"));
  EXPECT_FALSE(IsLoopbackAddress("::"));
  EXPECT_FALSE(IsLoopbackAddress("192.168.1.10"));
  EXPECT_FALSE(IsLoopbackAddress("1270.0.0.1"));
}

// --- real binaries over loopback ---------------------------------------

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct CliRun {
  int exit_code = -1;
  std::string out, err;
};

TEST(AuthDaemon, GeneratedTokenAndCliTokenCommands) {
  TempDir dir("auth_daemon");
  DaemonOptions o;
  o.db = dir.path() + "/lib.db";
  o.data = "none";
  o.operator_token = "";  // let the daemon generate and print one
  DaemonProcess d(o);
  d.Start();
  const std::string log = d.ReadLog();
  const auto at = log.find("operator token: ");
  ASSERT_NE(at, std::string::npos) << log;
  const std::string secret = log.substr(at + 16, 64);
  EXPECT_EQ(secret.find_first_not_of("0123456789abcdef"), std::string::npos)
      << secret;
  // Over HTTP: no token -> 401 JSON, nothing stored; the printed one works.
  auto anon = d.MakeClientWithToken("");
  auto res =
      anon->Put("/v1/materials/felt", R"({"name":"Felt"})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 401);
  EXPECT_EQ(res->get_header_value("WWW-Authenticate").rfind("Bearer", 0), 0u);
  EXPECT_EQ(json::parse(res->body).value("reason", ""), "missing");
  EXPECT_EQ(anon->Get("/v1/materials/felt")->status, 404);
  EXPECT_EQ(anon->Get("/v1/materials")->status, 200);  // open read, loopback
  auto op = d.MakeClientWithToken(secret);
  EXPECT_EQ(
      op->Put("/v1/materials/felt", R"({"name":"Felt"})", "application/json")
          ->status,
      201);
  const std::string metrics = anon->Get("/metrics")->body;
  EXPECT_NE(metrics.find("frictiond_http_unauthorized_total 1"),
            std::string::npos)
      << metrics;

  auto cli = [&](const std::string& args, const std::string& env_token) {
    CliRun r;
    const std::string out = dir.path() + "/cli.out";
    const std::string err = dir.path() + "/cli.err";
    const std::string cmd =
        "FRICTIOND_TOKEN=" + env_token + " " + testing::BinaryPath("friction") +
        " --server " + d.base_url() + " " + args + " >" + out + " 2>" + err;
    const int status = std::system(cmd.c_str());
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = ReadAll(out);
    r.err = ReadAll(err);
    return r;
  };
  CliRun r = cli("token create --name arm-1 --role robot", secret);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string robot_secret = r.out.substr(0, 64);
  EXPECT_EQ(r.out, robot_secret + "\n");
  r = cli("token list --json", secret);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json list = json::parse(r.out)["tokens"];
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[1]["name"], "arm-1");
  EXPECT_EQ(list[1]["role"], "robot");
  EXPECT_EQ(r.out.find(robot_secret), std::string::npos);
  const std::string robot_id = list[1]["id"];
  // The robot token can upload strokes but not create tokens.
  r = cli("token create --name x --role operator", robot_secret);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("HTTP 403"), std::string::npos) << r.err;
  r = cli("token revoke " + robot_id, secret);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = cli("token list", secret);
  EXPECT_NE(r.out.find(robot_id + "\trobot\trevoked"), std::string::npos)
      << r.out;
  r = cli("--token " + robot_secret + " token list", "");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("HTTP 401"), std::string::npos) << r.err;
  r = cli("audit --material felt", secret);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(json::parse(r.out)["entries"].size(), 1u) << r.out;
  // Restart on the same database: no new token, nothing printed.
  d.Stop(SIGTERM);
  const std::size_t log_size = d.ReadLog().size();
  d.Start();
  EXPECT_EQ(d.ReadLog().substr(log_size).find("operator token: "),
            std::string::npos);
  EXPECT_EQ(d.MakeClientWithToken(secret)->Get("/v1/tokens")->status, 200);
}

TEST(AuthDaemon, BootstrapTokenFromEnvironmentAndBadValue) {
  TempDir dir("auth_boot");
  const std::string port = std::to_string(testing::FindFreePort());
  const std::string cmd =
      "FRICTIOND_BOOTSTRAP_TOKEN=short timeout -s KILL 20 " +
      testing::BinaryPath("frictiond") + " --db " + dir.path() +
      "/x.db --data none --port " + port + " >/dev/null 2>" + dir.path() +
      "/err";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
  EXPECT_NE(ReadAll(dir.path() + "/err").find("--bootstrap-token"),
            std::string::npos);
}

}  // namespace
}  // namespace frictiond
