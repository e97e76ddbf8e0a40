// Bad input over real HTTP (issue item 7; CONTRACT.md "Stroke data" and
// "HTTP API"; STYLE §7): every malformed request gets a 4xx JSON error
// {"error", "detail"} whose detail names the field or parameter and the rule,
// and a rejected request stores nothing: the SQLite files (.db, .db-wal,
// .db-shm) are byte-for-byte unchanged after a batch of rejected requests.
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::DbFingerprint;
using testing::ExitStatus;
using testing::TempDir;

/// The material that has a model in every test (so evaluation routes get as
/// far as their parameter checks on a real model).
constexpr char kKnown[] = "known-rubber";
/// A valid id nothing is stored under. Requests naming it must fail their
/// parameter checks before any identification request is recorded.
constexpr char kUnknown[] = "valid-but-unknown";

const char kHeader[] = "t_s,fn_n,ft_n,v_mm_s\n";

/// One request that must be rejected.
struct BadRequest {
  std::string what;    ///< test label
  std::string method;  ///< GET, PUT, POST, DELETE, PATCH
  std::string path;    ///< sent as is (httplib only escapes ' ' and >= 0x80)
  std::string body;
  std::string content_type;
  int status;                         ///< expected status
  std::vector<std::string> mentions;  ///< substrings the detail must contain
};

std::string Strokes(const std::string& material, const std::string& q = "") {
  return "/v1/materials/" + material + "/strokes" + q;
}

std::vector<BadRequest> MalformedCsv() {
  const std::string m = kKnown;
  const std::string u = kUnknown;
  const std::string csv = "text/csv";
  return {
      {"missing column",
       "POST",
       Strokes(m),
       "t_s,fn_n,ft_n\n0,1,0.5\n0.1,1,0.5\n",
       csv,
       400,
       {"line 1", "v_mm_s", "missing"}},
      {"text in a number",
       "POST",
       Strokes(m),
       std::string(kHeader) + "0,1,0.5,0\n0.1,abc,0.5,20\n",
       csv,
       400,
       {"line 3", "fn_n", "abc", "not a number"}},
      {"NaN",
       "POST",
       Strokes(m),
       std::string(kHeader) + "0,1,0.5,0\n0.1,1,NaN,20\n",
       csv,
       400,
       {"line 3", "ft_n", "finite"}},
      {"Fn = 0",
       "POST",
       Strokes(m),
       std::string(kHeader) + "0,1,0.5,0\n0.1,0,0.5,20\n",
       csv,
       400,
       {"line 3", "fn_n", "> 0"}},
      {"Fn < 0",
       "POST",
       Strokes(u),
       std::string(kHeader) + "# comment\n0,1,0.5,0\n0.1,-2,0.5,20\n",
       csv,
       400,
       {"line 4", "fn_n", "-2", "> 0"}},
      {"time going backwards",
       "POST",
       Strokes(m),
       std::string(kHeader) + "0,1,0.5,0\n0.2,1,0.5,20\n0.1,1,0.5,20\n",
       csv,
       400,
       {"line 4", "t_s", "backwards"}},
      {"empty body", "POST", Strokes(m), "", csv, 400, {"body", "empty"}},
      {"header only",
       "POST",
       Strokes(m),
       kHeader,
       csv,
       400,
       {"body", "no samples"}},
      {"negative speed",
       "POST",
       Strokes(m),
       std::string(kHeader) + "0,1,0.5,-3\n",
       csv,
       400,
       {"line 2", "v_mm_s", ">= 0"}},
      {"ragged row",
       "POST",
       Strokes(m),
       std::string(kHeader) + "0,1,0.5,0\n0.1,1,0.5\n",
       csv,
       400,
       {"line 3", "cells"}},
      {"bad covariate name",
       "POST",
       Strokes(m),
       "t_s,fn_n,ft_n,v_mm_s,temp c\n0,1,0.5,0,20\n",
       csv,
       400,
       {"line 1", "temp c"}},
      {"wrong Content-Type",
       "POST",
       Strokes(m),
       std::string(kHeader) + "0,1,0.5,0\n",
       "application/json",
       415,
       {"Content-Type", "application/json", "text/csv"}},
      {"image Content-Type",
       "POST",
       Strokes(u),
       std::string(kHeader) + "0,1,0.5,0\n",
       "image/png",
       415,
       {"Content-Type", "text/csv"}},
      {"bad labelling parameter",
       "POST",
       Strokes(m, "?slip_peak_mm_s=abc"),
       std::string(kHeader) + "0,1,0.5,0\n",
       csv,
       400,
       {"slip_peak_mm_s", "not a number"}},
      {"bad fingertip",
       "POST",
       Strokes(m, "?fingertip=a;b"),
       std::string(kHeader) + "0,1,0.5,0\n",
       csv,
       400,
       {"fingertip", "must match"}},
      {"robot too long",
       "POST",
       Strokes(m, "?robot=" + std::string(200, 'r')),
       std::string(kHeader) + "0,1,0.5,0\n",
       csv,
       400,
       {"robot", "128"}},
  };
}

std::vector<BadRequest> BadJson() {
  const std::string path = std::string("/v1/materials/") + kKnown;
  const std::string upath = std::string("/v1/materials/") + kUnknown;
  const std::string js = "application/json";
  return {
      {"truncated JSON",
       "PUT",
       path,
       R"({"name": )",
       js,
       400,
       {"body", "invalid JSON"}},
      {"not JSON at all",
       "PUT",
       upath,
       "name=steel",
       js,
       400,
       {"body", "invalid JSON"}},
      {"array body", "PUT", path, "[1, 2]", js, 400, {"body", "JSON object"}},
      {"name is a number",
       "PUT",
       path,
       R"({"name": 5})",
       js,
       400,
       {"name", "string"}},
      {"description is null",
       "PUT",
       upath,
       R"({"description": null})",
       js,
       400,
       {"description", "string"}},
      {"tags is a string",
       "PUT",
       path,
       R"({"tags": "metal"})",
       js,
       400,
       {"tags", "array"}},
      {"tags hold a number",
       "PUT",
       path,
       R"({"tags": ["metal", 3]})",
       js,
       400,
       {"tags", "strings"}},
      {"unknown field",
       "PUT",
       path,
       R"({"name": "x", "colour": "red"})",
       js,
       400,
       {"colour", "unknown field"}},
      {"name too long",
       "PUT",
       upath,
       R"({"name": ")" + std::string(201, 'n') + R"("})",
       js,
       400,
       {"name", "at most 200"}},
      {"fingertip unknown field",
       "PUT",
       "/v1/fingertips/glove-1",
       R"({"grip": 1})",
       js,
       400,
       {"grip", "unknown field"}},
  };
}

std::vector<BadRequest> BadRoutesAndIds() {
  const std::string long_id(65, 'a');
  return {
      {"unknown route", "GET", "/v1/nothing", "", "", 404, {"/v1/nothing"}},
      {"unknown route under a material",
       "GET",
       std::string("/v1/materials/") + kKnown + "/colour",
       "",
       "",
       404,
       {"no route"}},
      {"no version prefix", "GET", "/materials", "", "", 404, {"no route"}},
      {"method not allowed",
       "PATCH",
       std::string("/v1/materials/") + kKnown,
       "{}",
       "application/json",
       405,
       {"PATCH"}},
      {"dot-dot id", "GET", "/v1/materials/..", "", "", 400, {"id", "'..'"}},
      {"dot-dot id, model",
       "GET",
       "/v1/materials/../model",
       "",
       "",
       400,
       {"id", "'..'"}},
      {"encoded dot-dot id",
       "GET",
       "/v1/materials/%2e%2e/model",
       "",
       "",
       400,
       {"id", "'..'"}},
      {"encoded dot-dot PUT",
       "PUT",
       "/v1/materials/%2e%2e",
       "{}",
       "application/json",
       400,
       {"id", "'..'"}},
      {"encoded slash in id",
       "GET",
       "/v1/materials/a%2Fb",
       "",
       "",
       404,
       {"no route"}},
      {"encoded slash upload",
       "POST",
       "/v1/materials/a%2Fb/strokes",
       std::string(kHeader) + "0,1,0.5,0\n",
       "text/csv",
       404,
       {"no route"}},
      {"65-character id",
       "GET",
       "/v1/materials/" + long_id,
       "",
       "",
       400,
       {"id", "{1,64}"}},
      {"65-character id PUT",
       "PUT",
       "/v1/materials/" + long_id,
       "{}",
       "application/json",
       400,
       {"id", "{1,64}"}},
      {"semicolon in id",
       "GET",
       "/v1/materials/id;drop/model",
       "",
       "",
       400,
       {"id", "id;drop"}},
      {"semicolon in id DELETE",
       "DELETE",
       "/v1/materials/id;drop",
       "",
       "",
       400,
       {"id", "id;drop"}},
      {"quote in id",
       "PUT",
       "/v1/materials/x'%20OR%20'1'='1",
       "{}",
       "application/json",
       400,
       {"id", "must match"}},
      {"unicode id",
       "GET",
       "/v1/materials/caf\xc3\xa9",
       "",
       "",
       400,
       {"id", "must match"}},
      {"encoded unicode id upload",
       "POST",
       "/v1/materials/caf%C3%A9/strokes",
       std::string(kHeader) + "0,1,0.5,0\n",
       "text/csv",
       400,
       {"id", "must match"}},
      {"NUL in id",
       "GET",
       "/v1/materials/a%00b/model",
       "",
       "",
       400,
       {"id", "must match"}},
  };
}

std::vector<BadRequest> BadQueryNumbers() {
  const std::string k = std::string("/v1/materials/") + kKnown;
  const std::string u = std::string("/v1/materials/") + kUnknown;
  return {
      {"predict fn_n=abc",
       "GET",
       k + "/predict?fn_n=abc&v_mm_s=10",
       "",
       "",
       400,
       {"fn_n", "abc", "not a number"}},
      {"predict fn_n=-1",
       "GET",
       k + "/predict?fn_n=-1&v_mm_s=10",
       "",
       "",
       400,
       {"fn_n", "> 0"}},
      {"predict fn_n=0 on an unknown material",
       "GET",
       u + "/predict?fn_n=0&v_mm_s=10",
       "",
       "",
       400,
       {"fn_n", "> 0"}},
      {"predict missing v_mm_s",
       "GET",
       k + "/predict?fn_n=1",
       "",
       "",
       400,
       {"v_mm_s", "required"}},
      {"predict missing v_mm_s, unknown material",
       "GET",
       u + "/predict?fn_n=1",
       "",
       "",
       400,
       {"v_mm_s", "required"}},
      {"predict v_mm_s=-5",
       "GET",
       k + "/predict?fn_n=1&v_mm_s=-5",
       "",
       "",
       400,
       {"v_mm_s", ">= 0"}},
      {"predict fn_n=inf",
       "GET",
       k + "/predict?fn_n=inf&v_mm_s=1",
       "",
       "",
       400,
       {"fn_n"}},
      {"predict fn_n=nan",
       "GET",
       k + "/predict?fn_n=nan&v_mm_s=1",
       "",
       "",
       400,
       {"fn_n"}},
      {"predict fn_n=1e999",
       "GET",
       k + "/predict?fn_n=1e999&v_mm_s=1",
       "",
       "",
       400,
       {"fn_n"}},
      {"predict fn_n empty",
       "GET",
       k + "/predict?fn_n=&v_mm_s=1",
       "",
       "",
       400,
       {"fn_n"}},
      {"predict fn_n=1,5",
       "GET",
       k + "/predict?fn_n=1,5&v_mm_s=1",
       "",
       "",
       400,
       {"fn_n", "not a number"}},
      {"predict unknown input",
       "GET",
       k + "/predict?fn_n=1&v_mm_s=1&temp_c=20",
       "",
       "",
       400,
       {"temp_c", "not an input"}},
      {"predict bad fingertip",
       "GET",
       k + "/predict?fn_n=1&v_mm_s=1&fingertip=..",
       "",
       "",
       400,
       {"fingertip"}},
      {"slip-likelihood ft_n=x",
       "GET",
       k + "/slip-likelihood?fn_n=1&ft_n=x",
       "",
       "",
       400,
       {"ft_n", "not a number"}},
      {"slip-likelihood ft_n=-1",
       "GET",
       u + "/slip-likelihood?fn_n=1&ft_n=-1",
       "",
       "",
       400,
       {"ft_n", ">= 0"}},
      {"slip-likelihood missing fn_n",
       "GET",
       k + "/slip-likelihood?ft_n=1",
       "",
       "",
       400,
       {"fn_n", "required"}},
      {"grip-force risk=2",
       "GET",
       k + "/grip-force?load_n=1&risk=2",
       "",
       "",
       400,
       {"risk", "(0, 1)"}},
      {"grip-force risk=0",
       "GET",
       u + "/grip-force?load_n=1&risk=0",
       "",
       "",
       400,
       {"risk", "(0, 1)"}},
      {"grip-force load_n=-1",
       "GET",
       k + "/grip-force?load_n=-1&risk=0.1",
       "",
       "",
       400,
       {"load_n", "> 0"}},
      {"grip-force missing risk",
       "GET",
       k + "/grip-force?load_n=1",
       "",
       "",
       400,
       {"risk", "required"}},
      {"model version=abc",
       "GET",
       k + "/model?version=abc",
       "",
       "",
       400,
       {"version", "not a number"}},
      {"model version=0",
       "GET",
       k + "/model?version=0",
       "",
       "",
       400,
       {"version", "positive integer"}},
      {"model version=1.5",
       "GET",
       u + "/model?version=1.5",
       "",
       "",
       400,
       {"version", "positive integer"}},
  };
}

/// Daemon shared by the suite (no bundled data; one uploaded material).
class BadInputTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("bad_input_test");
    DaemonOptions options;
    options.db = dir_->path() + "/library.db";
    options.data = "none";
    daemon_ = new DaemonProcess(options);
    daemon_->Start();
    auto client = daemon_->MakeClient();
    testing::SimulationSpec spec;
    spec.strokes = 8;
    auto res = client->Post(Strokes(kKnown).c_str(),
                            FormatStrokeCsv(testing::SimulateStrokes(spec, 5)),
                            "text/csv");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
  }
  static void TearDownTestSuite() {
    const ExitStatus s = daemon_->Stop(SIGTERM);
    EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
    delete daemon_;
    delete dir_;
  }
  void SetUp() override { client_ = daemon_->MakeClient(60.0); }

  httplib::Result Send(const BadRequest& r) {
    httplib::Headers headers;
    if (r.method == "GET") return client_->Get(r.path.c_str());
    if (r.method == "DELETE") return client_->Delete(r.path.c_str());
    const char* ct = r.content_type.c_str();
    if (r.method == "PUT") return client_->Put(r.path.c_str(), r.body, ct);
    if (r.method == "PATCH") return client_->Patch(r.path.c_str(), r.body, ct);
    return client_->Post(r.path.c_str(), r.body, ct);
  }

  /// Sends the request and checks status, JSON error shape and detail.
  void ExpectRejected(const BadRequest& r) {
    SCOPED_TRACE(r.what + ": " + r.method + " " + r.path.substr(0, 120));
    auto res = Send(r);
    ASSERT_TRUE(res) << httplib::to_string(res.error());
    EXPECT_EQ(res->status, r.status) << res->body.substr(0, 500);
    EXPECT_GE(res->status, 400);
    EXPECT_LT(res->status, 500);
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json");
    const json j = json::parse(res->body, nullptr, false);
    ASSERT_TRUE(j.is_object()) << res->body.substr(0, 500);
    ASSERT_TRUE(j.contains("error") && j["error"].is_string()) << res->body;
    ASSERT_TRUE(j.contains("detail") && j["detail"].is_string()) << res->body;
    const std::string detail = j["detail"].get<std::string>();
    for (const std::string& s : r.mentions)
      EXPECT_NE(detail.find(s), std::string::npos)
          << "detail should mention '" << s << "': " << detail;
  }

  /// Materials and identification jobs as the daemon lists them.
  std::string Snapshot() {
    std::string out;
    for (const char* path :
         {"/v1/materials", "/v1/identifications", "/v1/fingertips"}) {
      auto res = client_->Get(path);
      out += res ? res->body : "(no response)";
    }
    auto res = client_->Get(Strokes(kKnown).c_str());
    out += res ? res->body : "(no response)";
    return out;
  }

  /// Runs a batch of rejected requests and checks that the database files
  /// are unchanged and that the listed state is the same.
  void ExpectBatchStoresNothing(const std::vector<BadRequest>& batch) {
    const std::string db = daemon_->options().db;
    const std::string before = Snapshot();  // also settles the WAL index
    const std::vector<std::uint64_t> hash_before = DbFingerprint(db);
    for (const BadRequest& r : batch) ExpectRejected(r);
    const std::vector<std::uint64_t> hash_after = DbFingerprint(db);
    EXPECT_EQ(hash_before, hash_after)
        << "database files (.db, .db-wal, .db-shm) changed after rejected "
           "requests";
    EXPECT_EQ(Snapshot(), before);
  }

  static TempDir* dir_;
  static DaemonProcess* daemon_;
  std::unique_ptr<httplib::Client> client_;
};

TempDir* BadInputTest::dir_ = nullptr;
DaemonProcess* BadInputTest::daemon_ = nullptr;

TEST_F(BadInputTest, MalformedCsvIsRejectedWithLineAndReason) {
  ExpectBatchStoresNothing(MalformedCsv());
}

TEST_F(BadInputTest, MalformedCsvErrorCarriesLineNumber) {
  auto res = client_->Post(
      Strokes(kKnown).c_str(),
      std::string(kHeader) + "0,1,0.5,0\n0.1,1,0.5,0\n0.2,1,0.5,oops\n",
      "text/csv");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400);
  const json j = json::parse(res->body, nullptr, false);
  EXPECT_EQ(j.value("line", 0), 4) << res->body;
  EXPECT_EQ(j.value("field", ""), "v_mm_s") << res->body;
}

TEST_F(BadInputTest, BadJsonAndWrongTypesAreRejected) {
  ExpectBatchStoresNothing(BadJson());
}

TEST_F(BadInputTest, UnknownRoutesAndPathTricksAreRejected) {
  ExpectBatchStoresNothing(BadRoutesAndIds());
}

TEST_F(BadInputTest, BadQueryNumbersAreRejected) {
  ExpectBatchStoresNothing(BadQueryNumbers());
}

/// A 50 MB body is over the 16 MiB default limit: 413 (JSON), nothing stored.
TEST_F(BadInputTest, HugeBodyIsRejected) {
  std::string big = kHeader;
  big.reserve(50u << 20);
  for (int i = 0; big.size() < (50u << 20); ++i)
    big += std::to_string(i) + ",1.0,0.5,20.0\n";
  ExpectBatchStoresNothing({{"50 MB body",
                             "POST",
                             Strokes(kKnown),
                             big,
                             "text/csv",
                             413,
                             {"body", "limit"}}});
}

/// The same 50 MB body sent with chunked transfer encoding (no
/// Content-Length) must hit the same limit.
TEST_F(BadInputTest, HugeChunkedBodyIsRejected) {
  const std::string db = daemon_->options().db;
  const std::string before = Snapshot();
  const std::vector<std::uint64_t> hash_before = DbFingerprint(db);
  std::string row;
  std::size_t sent = 0;
  int i = 0;
  auto res = client_->Post(
      Strokes(kKnown, "?robot=chunked").c_str(),
      [&](std::size_t, httplib::DataSink& sink) {
        if (sent == 0) {
          sink.write(kHeader, sizeof(kHeader) - 1);
          sent += sizeof(kHeader) - 1;
        }
        std::string chunk;
        while (chunk.size() < (1u << 20))
          chunk += std::to_string(i++) + ",1.0,0.5,20.0\n";
        if (!sink.write(chunk.data(), chunk.size())) return false;
        sent += chunk.size();
        if (sent >= (50u << 20)) sink.done();
        return true;
      },
      "text/csv");
  if (res) {
    EXPECT_GE(res->status, 400) << res->body.substr(0, 300);
    EXPECT_LT(res->status, 500) << res->body.substr(0, 300);
    const json j = json::parse(res->body, nullptr, false);
    EXPECT_TRUE(j.is_object() && j.contains("error") && j.contains("detail"))
        << res->body.substr(0, 300);
  }  // else: the server closed the connection on an oversized body; fine.
  EXPECT_EQ(DbFingerprint(db), hash_before)
      << "a 50 MB chunked upload was stored";
  EXPECT_EQ(Snapshot(), before);
}

/// SQL metacharacters in names, descriptions, tags and the robot name are
/// stored literally and read back unchanged.
TEST_F(BadInputTest, SqlMetacharactersAreStoredLiterally) {
  const std::string name = "Robert'); DROP TABLE materials;--";
  const std::string description =
      "\" OR 1=1 -- ; /* */ % _ \\ ' '' ` $1 ?1 :x @y \xe2\x9c\x93";
  const std::vector<std::string> tags = {"'", "%", "_", "*", "--", "\\"};
  const json body = {
      {"name", name}, {"description", description}, {"tags", tags}};
  auto res =
      client_->Put("/v1/materials/sql-meta_1", body.dump(), "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  res = client_->Get("/v1/materials/sql-meta_1");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  json j = json::parse(res->body);
  EXPECT_EQ(j.value("name", ""), name);
  EXPECT_EQ(j.value("description", ""), description);
  EXPECT_EQ(j["tags"], json(tags));
  // Other materials were not touched.
  res = client_->Get((std::string("/v1/materials/") + kKnown).c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  // A search with SQL wildcards matches literally (none of the names has
  // a '%').
  res = client_->Get("/v1/materials?q=%25");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  EXPECT_EQ(json::parse(res->body)["materials"].size(), 0u) << res->body;
  res = client_->Get("/v1/materials?q=DROP%20TABLE");
  ASSERT_TRUE(res);
  j = json::parse(res->body);
  ASSERT_EQ(j["materials"].size(), 1u) << res->body;
  EXPECT_EQ(j["materials"][0].value("id", ""), "sql-meta_1");

  // The robot name of an upload.
  const std::string robot = "r'); DELETE FROM strokes;--";
  testing::SimulationSpec spec;
  spec.strokes = 4;
  res = client_->Post(
      "/v1/materials/sql-meta_1/strokes?robot=r%27%29%3B%20DELETE%20FROM%"
      "20strokes%3B--",
      FormatStrokeCsv(testing::SimulateStrokes(spec, 9)),
      "text/csv");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  res = client_->Get("/v1/materials/sql-meta_1/strokes");
  ASSERT_TRUE(res);
  j = json::parse(res->body);
  ASSERT_EQ(j["strokes"].size(), 1u) << res->body;
  EXPECT_EQ(j["strokes"][0].value("robot", ""), robot);
  res = client_->Get(Strokes(kKnown).c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(json::parse(res->body)["strokes"].size(), 1u) << res->body;
}

/// A NUL inside a JSON string is either kept or refused, never truncated
/// silently.
TEST_F(BadInputTest, NulInNameIsNotTruncated) {
  auto res = client_->Put("/v1/materials/nul-name",
                          R"({"name": "before\u0000after"})",
                          "application/json");
  ASSERT_TRUE(res);
  if (res->status >= 400) {
    EXPECT_LT(res->status, 500) << res->body;
    return;
  }
  res = client_->Get("/v1/materials/nul-name");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(json::parse(res->body).value("name", ""),
            std::string("before\0after", 12));
}

}  // namespace
}  // namespace frictiond
