#include "frictiond/storage/store.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "frictiond/testing/pg_server.h"

namespace frictiond {
namespace {

using testing::PgServer;

/// False when this build has no PostgreSQL back end
/// (FRICTIOND_WITH_POSTGRES=OFF or no libpq): its tests are skipped then.
bool PgBackendBuilt() {
  try {
    OpenStore("postgresql://postgres@127.0.0.1:1/x?connect_timeout=1");
  } catch (const std::invalid_argument&) {
    return false;
  } catch (const std::exception&) {
  }
  return true;
}

/// One throw-away PostgreSQL server for the whole test program; each test
/// gets a fresh database on it.
std::unique_ptr<PgServer>& SharedPgPtr() {
  static std::unique_ptr<PgServer> pg;
  return pg;
}
PgServer& SharedPg() {
  static std::mutex mu;
  std::lock_guard<std::mutex> lock(mu);
  auto& pg = SharedPgPtr();
  if (!pg) {
    auto p = std::make_unique<PgServer>();
    p->Start();
    pg = std::move(p);
  }
  return *pg;
}

std::string FreshPgDatabase() {
  static std::atomic<int> n{0};
  return SharedPg().CreateDatabase("t" + std::to_string(::getpid()) + "_" +
                                   std::to_string(++n));
}

// The suite is parametrised by back end URL factory so a second back end
// (PostgreSQL) runs the same tests unchanged.
class StoreTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("frictiond_store_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    if (GetParam() == "postgresql") {
      if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
      if (!PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
      url_ = FreshPgDatabase();
    } else {
      url_ = GetParam() == "sqlite-file" ? (dir_ / "lib.db").string()
                                         : std::string(":memory:");
    }
    store_ = OpenStore(url_);
  }
  void TearDown() override {
    store_.reset();
    std::filesystem::remove_all(dir_);
  }
  ModelRecord Model(const std::string& material, const std::string& json) {
    ModelRecord m;
    m.material = material;
    m.reason = "test";
    m.json = json;
    return m;
  }
  std::filesystem::path dir_;
  std::string url_;
  std::unique_ptr<Store> store_;
};

TEST_P(StoreTest, MaterialsCrud) {
  Material m{"rubber-1", "Rubber", "soft", {"elastomer", "grey"}, "", ""};
  EXPECT_TRUE(store_->PutMaterial(m));
  m.name = "Rubber v2";
  EXPECT_FALSE(store_->PutMaterial(m));
  auto got = store_->GetMaterial("rubber-1");
  ASSERT_TRUE(got);
  EXPECT_EQ(got->name, "Rubber v2");
  EXPECT_EQ(got->tags, (std::vector<std::string>{"elastomer", "grey"}));
  EXPECT_FALSE(got->created_at.empty());
  EXPECT_EQ(store_->ListMaterials().size(), 1u);
  EXPECT_TRUE(store_->DeleteMaterial("rubber-1"));
  EXPECT_FALSE(store_->DeleteMaterial("rubber-1"));
  EXPECT_FALSE(store_->GetMaterial("rubber-1"));
}

TEST_P(StoreTest, SqlMetacharactersAreData) {
  Material m{"x",
             "Robert'); DROP TABLE materials;--",
             "\"quoted\" ; --",
             {"a'b"},
             "",
             ""};
  store_->PutMaterial(m);
  auto got = store_->GetMaterial("x");
  ASSERT_TRUE(got);
  EXPECT_EQ(got->name, m.name);
  EXPECT_EQ(got->tags[0], "a'b");
  EXPECT_EQ(store_->ListMaterials().size(), 1u);
}

TEST_P(StoreTest, RobotsAreCreatedThenReplaced) {
  EXPECT_FALSE(store_->GetRobot("arm-1").has_value());
  EXPECT_TRUE(
      store_->PutRobot(RobotRecord{"arm-1", R"({"joints":[]})", "", ""}));
  EXPECT_FALSE(store_->PutRobot(RobotRecord{"arm-1", R"({"v":2})", "", ""}));
  const auto r = store_->GetRobot("arm-1");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->json, R"({"v":2})");
  EXPECT_FALSE(r->created_at.empty());
}

TEST_P(StoreTest, DefaultFingertipExists) {
  ASSERT_TRUE(store_->GetFingertip("default"));
  EXPECT_TRUE(store_->PutFingertip(
      Fingertip{"silicone-17mm", "Dragon Skin 30", "", ""}));
  EXPECT_EQ(store_->ListFingertips().size(), 2u);
}

TEST_P(StoreTest, UploadsAppendVersionsNeverOverwrite) {
  StrokeRecord s;
  s.material = "felt";
  s.robot = "arm-7";
  s.samples = 3;
  s.csv = "t_s,fn_n,ft_n,v_mm_s\n0,1,1,0\n";
  const UploadCommit c1 = store_->CommitUpload(s, Model("felt", "{\"v\":1}"));
  EXPECT_TRUE(c1.material_created);
  EXPECT_EQ(c1.version, 1);
  const UploadCommit c2 = store_->CommitUpload(s, Model("felt", "{\"v\":2}"));
  EXPECT_FALSE(c2.material_created);
  EXPECT_EQ(c2.version, 2);
  EXPECT_EQ(store_->AddModelVersion(Model("felt", "{\"v\":3}")), 3);
  EXPECT_EQ(store_->GetLatestModel("felt", "default")->json, "{\"v\":3}");
  EXPECT_EQ(store_->GetModel("felt", "default", 1)->json, "{\"v\":1}");
  EXPECT_EQ(store_->GetModel("felt", "default", 2)->stroke_id, c2.stroke_id);
  EXPECT_EQ(store_->ListModels("felt", "default").size(), 3u);
  const auto strokes = store_->ListStrokes("felt", "default");
  ASSERT_EQ(strokes.size(), 2u);
  EXPECT_EQ(strokes[0].robot, "arm-7");
  EXPECT_TRUE(strokes[0].csv.empty());
  EXPECT_EQ(store_->GetStroke(c1.stroke_id)->csv, s.csv);
  // Other fingertips are separate pairs.
  StrokeRecord s2 = s;
  s2.fingertip = "tip-b";
  ModelRecord m2 = Model("felt", "{}");
  m2.fingertip = "tip-b";
  EXPECT_EQ(store_->CommitUpload(s2, m2).version, 1);
  EXPECT_TRUE(store_->GetFingertip("tip-b"));
  // Delete cascades.
  EXPECT_TRUE(store_->DeleteMaterial("felt"));
  EXPECT_FALSE(store_->GetLatestModel("felt", "default"));
  EXPECT_FALSE(store_->GetStroke(c1.stroke_id));
}

TEST_P(StoreTest, UploadCommitsItsAuditEntryWithIt) {
  StrokeRecord s;
  s.material = "felt";
  s.samples = 1;
  s.csv = "t_s,fn_n,ft_n,v_mm_s\n0,1,1,0\n";
  AuditEntry e;
  e.actor = "tok_1";
  e.role = "robot";
  e.remote = "127.0.0.1";
  e.action = "POST /v1/materials/{id}/strokes";
  e.material = "felt";
  e.detail = R"({"status":201,"samples":1})";
  const UploadCommit c = store_->CommitUpload(s, Model("felt", "{}"), &e);
  const auto log = store_->ListAudit(0, 100, "felt");
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(log[0].actor, "tok_1");
  EXPECT_EQ(log[0].action, e.action);
  EXPECT_FALSE(log[0].at.empty());
  const auto d = nlohmann::json::parse(log[0].detail);
  EXPECT_EQ(d["status"], 201);
  EXPECT_EQ(d["samples"], 1);
  EXPECT_EQ(d["stroke_id"], c.stroke_id);
  EXPECT_EQ(d["version"], c.version);
  EXPECT_EQ(d["material_created"], true);
  // A detail that is not a JSON object is refused before anything is
  // written: no stroke, no version, no entry.
  e.detail = "[1]";
  EXPECT_THROW(store_->CommitUpload(s, Model("felt", "{}"), &e),
               std::invalid_argument);
  EXPECT_EQ(store_->ListStrokes("felt", "default").size(), 1u);
  EXPECT_EQ(store_->ListModels("felt", "default").size(), 1u);
  EXPECT_EQ(store_->ListAudit(0, 100, "felt").size(), 1u);
  // Without an entry nothing is logged.
  store_->CommitUpload(s, Model("felt", "{}"));
  EXPECT_EQ(store_->ListAudit(0, 100, "felt").size(), 1u);
}

TEST_P(StoreTest, StrokesAfterAnIdComeInOneListOldestFirst) {
  StrokeRecord s;
  s.material = "felt";
  s.samples = 1;
  std::vector<std::int64_t> ids;
  for (int i = 0; i < 4; ++i) {
    s.csv = "t_s,fn_n,ft_n,v_mm_s\n" + std::to_string(i) + ",1,1,0\n";
    ids.push_back(store_->CommitUpload(s, Model("felt", "{}")).stroke_id);
  }
  StrokeRecord other = s;  // another pair's stroke is not listed
  other.fingertip = "tip-b";
  ModelRecord m2 = Model("felt", "{}");
  m2.fingertip = "tip-b";
  const UploadCommit c = store_->CommitUpload(other, m2);
  EXPECT_FALSE(c.created_at.empty());
  EXPECT_EQ(store_->GetModel("felt", "tip-b", c.version)->created_at,
            c.created_at);

  const auto all = store_->ListStrokesAfter("felt", "default", 0, true);
  ASSERT_EQ(all.size(), 4u);
  for (std::size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(all[i].id, ids[i]);
    EXPECT_EQ(all[i].csv, store_->GetStroke(ids[i])->csv) << i;
  }
  const auto after = store_->ListStrokesAfter("felt", "default", ids[1], false);
  ASSERT_EQ(after.size(), 2u);
  EXPECT_EQ(after[0].id, ids[2]);
  EXPECT_EQ(after[1].id, ids[3]);
  EXPECT_TRUE(after[0].csv.empty());
  EXPECT_EQ(after[0].samples, 1);
  EXPECT_TRUE(
      store_->ListStrokesAfter("felt", "default", ids[3], true).empty());
  EXPECT_TRUE(store_->ListStrokesAfter("none", "default", 0, true).empty());
}

TEST_P(StoreTest, IdentificationJobsOpenOncePerPair) {
  IdentificationJob j;
  j.material = "unknown-cloth";
  j.plan_json = "{}";
  j.requested_by = "robot-1";
  const auto a = store_->RequestIdentification(j);
  const auto b = store_->RequestIdentification(j);
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.state, "requested");
  EXPECT_EQ(store_->ListJobs(true).size(), 1u);
  StrokeRecord s;
  s.material = "unknown-cloth";
  s.csv = "x";
  ModelRecord m;
  m.material = "unknown-cloth";
  m.json = "{}";
  store_->CommitUpload(s, m);
  EXPECT_EQ(store_->GetJob(a.id)->state, "fitted");
  EXPECT_TRUE(store_->ListJobs(true).empty());
  EXPECT_EQ(store_->ListJobs(false).size(), 1u);
  EXPECT_TRUE(store_->UpdateJob(a.id, "failed", "why"));
  EXPECT_FALSE(store_->UpdateJob(999, "failed", "why"));
}

TEST_P(StoreTest, ReopenKeepsDataAndSchema) {
  if (GetParam() == "sqlite-memory")
    GTEST_SKIP() << "in-memory database does not persist";
  store_->PutMaterial(Material{"a", "A", "", {}, "", ""});
  const int schema = store_->SchemaVersion();
  EXPECT_GE(schema, 1);
  store_.reset();
  store_ = OpenStore(url_);
  EXPECT_EQ(store_->SchemaVersion(), schema);
  EXPECT_TRUE(store_->GetMaterial("a"));
  EXPECT_EQ(store_->CheckIntegrity(), "");
}

TEST_P(StoreTest, TokensFoundByHashAndRevokedOnce) {
  TokenRecord a{
      "tok_000000000001", "ops", "operator", std::string(64, 'a'), "", ""};
  TokenRecord b{
      "tok_000000000002", "arm", "robot", std::string(64, 'b'), "", ""};
  EXPECT_TRUE(store_->AddToken(a));
  EXPECT_TRUE(store_->AddToken(b));
  EXPECT_FALSE(store_->AddToken(a));  // same id
  const auto found = store_->FindTokenByHash(std::string(64, 'b'));
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->id, "tok_000000000002");
  EXPECT_EQ(found->name, "arm");
  EXPECT_EQ(found->role, "robot");
  EXPECT_FALSE(found->created_at.empty());
  EXPECT_TRUE(found->revoked_at.empty());
  EXPECT_FALSE(store_->FindTokenByHash(std::string(64, 'c')).has_value());
  const auto all = store_->ListTokens();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, a.id);
  EXPECT_EQ(all[1].id, b.id);
  EXPECT_TRUE(store_->RevokeToken(b.id));
  EXPECT_FALSE(store_->RevokeToken(b.id));
  EXPECT_FALSE(store_->RevokeToken("tok_unknown"));
  const auto revoked = store_->FindTokenByHash(std::string(64, 'b'));
  ASSERT_TRUE(revoked.has_value());
  EXPECT_FALSE(revoked->revoked_at.empty());
  EXPECT_TRUE(store_->FindTokenByHash(a.hash)->revoked_at.empty());
}

TEST_P(StoreTest, AuditAppendsAndPagesByMaterial) {
  std::vector<std::int64_t> ids;
  for (int i = 0; i < 5; ++i) {
    AuditEntry e;
    e.actor = "tok_" + std::to_string(i);
    e.role = "operator";
    e.remote = "127.0.0.1";
    e.action = "PUT /v1/materials/{id}";
    e.material = i % 2 == 0 ? "even" : "odd";
    e.detail = R"({"i":)" + std::to_string(i) + "}";
    ids.push_back(store_->AppendAudit(e));
  }
  for (std::size_t i = 1; i < ids.size(); ++i) EXPECT_GT(ids[i], ids[i - 1]);
  const auto all = store_->ListAudit(0, 100, "");
  ASSERT_EQ(all.size(), 5u);
  EXPECT_EQ(all[0].actor, "tok_0");
  EXPECT_EQ(all[0].remote, "127.0.0.1");
  EXPECT_EQ(all[0].action, "PUT /v1/materials/{id}");
  EXPECT_EQ(all[4].detail, R"({"i":4})");
  EXPECT_FALSE(all[0].at.empty());
  const auto page = store_->ListAudit(ids[1], 2, "");
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0].id, ids[2]);
  EXPECT_EQ(page[1].id, ids[3]);
  const auto even = store_->ListAudit(0, 100, "even");
  ASSERT_EQ(even.size(), 3u);
  for (const auto& e : even) EXPECT_EQ(e.material, "even");
  EXPECT_TRUE(store_->ListAudit(ids[4], 100, "").empty());
  // Audit outlives the material it names.
  store_->PutMaterial(Material{"even", "E", "", {}, "", ""});
  store_->DeleteMaterial("even");
  EXPECT_EQ(store_->ListAudit(0, 100, "even").size(), 3u);
}

TEST_P(StoreTest, TokensAndAudit) {
  TokenRecord t{
      "tok_000000000001", "ci", "robot", std::string(64, 'a'), "", ""};
  EXPECT_TRUE(store_->AddToken(t));
  EXPECT_FALSE(store_->AddToken(t));
  TokenRecord t2 = t;
  t2.id = "tok_000000000002";
  t2.hash = std::string(64, 'b');
  t2.role = "operator";
  EXPECT_TRUE(store_->AddToken(t2));
  const auto found = store_->FindTokenByHash(std::string(64, 'b'));
  ASSERT_TRUE(found);
  EXPECT_EQ(found->id, t2.id);
  EXPECT_EQ(found->role, "operator");
  EXPECT_FALSE(found->created_at.empty());
  EXPECT_TRUE(found->revoked_at.empty());
  EXPECT_FALSE(store_->FindTokenByHash("c"));
  const auto all = store_->ListTokens();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, t.id);
  EXPECT_TRUE(store_->RevokeToken(t.id));
  EXPECT_FALSE(store_->RevokeToken(t.id));
  EXPECT_FALSE(store_->RevokeToken("tok_nope"));
  EXPECT_FALSE(store_->FindTokenByHash(t.hash)->revoked_at.empty());

  AuditEntry e;
  e.actor = t.id;
  e.role = "robot";
  e.action = "POST /v1/materials/{id}/strokes";
  e.material = "felt";
  e.detail = R"({"version":1})";
  const std::int64_t a1 = store_->AppendAudit(e);
  e.material = "cork";
  const std::int64_t a2 = store_->AppendAudit(e);
  e.material = "felt";
  const std::int64_t a3 = store_->AppendAudit(e);
  EXPECT_LT(a1, a2);
  EXPECT_LT(a2, a3);
  EXPECT_EQ(store_->ListAudit(0, 100, "").size(), 3u);
  const auto felt = store_->ListAudit(0, 100, "felt");
  ASSERT_EQ(felt.size(), 2u);
  EXPECT_EQ(felt[1].id, a3);
  EXPECT_EQ(felt[0].detail, e.detail);
  EXPECT_FALSE(felt[0].at.empty());
  EXPECT_EQ(store_->ListAudit(a1, 1, "").size(), 1u);
  EXPECT_EQ(store_->ListAudit(a1, 1, "")[0].id, a2);
}

TEST_P(StoreTest, JobIsClaimedByOneWorker) {
  IdentificationJob j;
  j.material = "m";
  j.plan_json = "{}";
  const auto job = store_->RequestIdentification(j);
  EXPECT_FALSE(store_->ClaimJob(job.id + 1000, "a"));
  const auto a = store_->ClaimJob(job.id, "daemon-a");
  ASSERT_TRUE(a);
  EXPECT_EQ(a->id, job.id);
  EXPECT_FALSE(store_->ClaimJob(job.id, "daemon-b"));
  EXPECT_TRUE(store_->ClaimJob(job.id, "daemon-a"));  // idempotent
  store_->UpdateJob(job.id, "failed", "x");
  EXPECT_FALSE(store_->ClaimJob(job.id, "daemon-a"));  // closed
}

// A daemon that claimed a job and died (stopped renewing) loses it to
// another daemon once the lease has run out, and not before.
TEST_P(StoreTest, DeadWorkersClaimIsTakenOverAfterTheLease) {
  IdentificationJob j;
  j.material = "m";
  j.plan_json = "{}";
  const auto job = store_->RequestIdentification(j);
  ASSERT_TRUE(store_->ClaimJobWithLease(job.id, "daemon-a", 1));
  EXPECT_FALSE(store_->ClaimJobWithLease(job.id, "daemon-b", 1));  // alive
  std::this_thread::sleep_for(std::chrono::milliseconds(1300));
  EXPECT_TRUE(store_->ClaimJobWithLease(job.id, "daemon-b", 1));   // taken over
  EXPECT_FALSE(store_->ClaimJobWithLease(job.id, "daemon-a", 1));  // lost
  EXPECT_FALSE(store_->ClaimJob(job.id, "daemon-a"));  // 60 s lease: also
  EXPECT_TRUE(store_->ClaimJob(job.id, "daemon-b"));   // renewed by its owner
  EXPECT_THROW(store_->ClaimJobWithLease(job.id, "daemon-c", 0),
               std::invalid_argument);
}

// Strokes of an open job are kept (replaced per stroke index), listed in
// stroke order, dropped on request; an unknown job keeps nothing.
TEST_P(StoreTest, JobStrokesAreKeptUntilDropped) {
  IdentificationJob j;
  j.material = "m";
  j.plan_json = "{}";
  const auto job = store_->RequestIdentification(j);
  const std::string binary("t_s,fn_n\n0,1\n\0\xff", 15);
  EXPECT_TRUE(store_->PutJobStroke(job.id, 1, "second"));
  EXPECT_TRUE(store_->PutJobStroke(job.id, 0, "first"));
  EXPECT_TRUE(store_->PutJobStroke(job.id, 1, binary));  // replaces
  EXPECT_FALSE(store_->PutJobStroke(job.id + 1000, 0, "x"));
  EXPECT_TRUE(store_->ListJobStrokes(job.id + 1000).empty());
  const auto kept = store_->ListJobStrokes(job.id);
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(kept[0], std::make_pair(0, std::string("first")));
  EXPECT_EQ(kept[1], std::make_pair(1, binary));
  store_->DeleteJobStrokes(job.id);
  EXPECT_TRUE(store_->ListJobStrokes(job.id).empty());
}

// Pages of ListJobs: newest first, below `after`, at most `limit`, open
// ones only when asked; the pages together are ListJobs.
TEST_P(StoreTest, JobsArePagedNewestFirst) {
  std::vector<std::int64_t> ids;
  for (int i = 0; i < 5; ++i) {
    IdentificationJob j;
    j.material = "m" + std::to_string(i);
    j.plan_json = "{}";
    ids.push_back(store_->RequestIdentification(j).id);
  }
  store_->UpdateJob(ids[3], "failed", "x");
  const auto first = store_->ListJobsPage(false, 0, 2);
  ASSERT_EQ(first.size(), 2u);
  EXPECT_EQ(first[0].id, ids[4]);
  EXPECT_EQ(first[1].id, ids[3]);
  const auto second = store_->ListJobsPage(false, first[1].id, 2);
  ASSERT_EQ(second.size(), 2u);
  EXPECT_EQ(second[0].id, ids[2]);
  EXPECT_EQ(second[1].id, ids[1]);
  const auto last = store_->ListJobsPage(false, second[1].id, 2);
  ASSERT_EQ(last.size(), 1u);
  EXPECT_EQ(last[0].id, ids[0]);
  EXPECT_TRUE(store_->ListJobsPage(false, ids[0], 2).empty());
  const auto open = store_->ListJobsPage(true, 0, 10);
  ASSERT_EQ(open.size(), 4u);
  for (const auto& j : open) EXPECT_NE(j.id, ids[3]);
  EXPECT_EQ(store_->ListJobsPage(true, 0, 0).size(), 1u);  // limit >= 1
  EXPECT_EQ(store_->ListJobsPage(false, 0, 100).size(),
            store_->ListJobs(false).size());
}

TEST(OpenStore, RejectsUnsupportedUrl) {
  // Unbuilt back end (invalid_argument) or unreachable server
  // (StoreUnavailable); either way no store.
  try {
    OpenStore("postgresql://postgres@127.0.0.1:1/x?connect_timeout=2");
    ADD_FAILURE() << "opened a store on a closed port";
  } catch (const StoreUnavailable&) {
  } catch (const std::invalid_argument&) {
  }
  EXPECT_THROW(OpenStore(""), std::invalid_argument);
  EXPECT_THROW(OpenStore("/nonexistent-dir/x/y.db"), std::runtime_error);
}

INSTANTIATE_TEST_SUITE_P(Backends,
                         StoreTest,
                         ::testing::Values("sqlite-file",
                                           "sqlite-memory",
                                           "postgresql"));

// --- PostgreSQL only: several stores (daemons) on one database -------------

class PgFleetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
    if (!PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
    url_ = FreshPgDatabase();
  }
  std::string url_;
};

TEST_F(PgFleetTest, ConcurrentUploadsGetDistinctConsecutiveVersions) {
  auto a = OpenStore(url_);
  auto b = OpenStore(url_);
  ASSERT_EQ(a->BackendName(), "postgresql");
  constexpr int kPerStore = 10;
  std::mutex mu;
  std::vector<int> versions;
  auto run = [&](Store* s, const std::string& robot) {
    for (int i = 0; i < kPerStore; ++i) {
      StrokeRecord st;
      st.material = "shared";
      st.robot = robot;
      st.samples = 1;
      st.csv = "x";
      ModelRecord m;
      m.material = "shared";
      m.reason = "upload";
      m.json = "{\"robot\":\"" + robot + "\"}";
      const int v = s->CommitUpload(st, m).version;
      std::lock_guard<std::mutex> lock(mu);
      versions.push_back(v);
    }
  };
  std::thread ta(run, a.get(), "a");
  std::thread tb(run, b.get(), "b");
  ta.join();
  tb.join();
  const std::set<int> distinct(versions.begin(), versions.end());
  EXPECT_EQ(distinct.size(), versions.size());
  EXPECT_EQ(*distinct.begin(), 1);
  EXPECT_EQ(*distinct.rbegin(), 2 * kPerStore);
  EXPECT_EQ(a->ListModels("shared", "default").size(), 2u * kPerStore);
  EXPECT_EQ(b->ListStrokes("shared", "default").size(), 2u * kPerStore);
  EXPECT_EQ(a->CheckIntegrity(), "");
}

TEST_F(PgFleetTest, OtherStoresWritesAreNotified) {
  auto a = OpenStore(url_);
  auto b = OpenStore(url_);
  std::mutex mu;
  std::vector<std::string> seen_b, seen_a;
  b->SetChangeListener([&](const std::string& m, const std::string& f) {
    std::lock_guard<std::mutex> lock(mu);
    seen_b.push_back(m + "/" + f);
  });
  a->SetChangeListener([&](const std::string& m, const std::string& f) {
    std::lock_guard<std::mutex> lock(mu);
    seen_a.push_back(m + "/" + f);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // LISTEN
  StrokeRecord st;
  st.material = "felt";
  st.csv = "x";
  ModelRecord m;
  m.material = "felt";
  m.json = "{}";
  const auto t0 = std::chrono::steady_clock::now();
  a->CommitUpload(st, m);
  bool got = false;
  while (!got &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(2)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    std::lock_guard<std::mutex> lock(mu);
    got = !seen_b.empty();
  }
  const double ms = std::chrono::duration<double, std::milli>(
                        std::chrono::steady_clock::now() - t0)
                        .count();
  ASSERT_TRUE(got) << "no notification within 2 s";
  EXPECT_LT(ms, 1000.0);
  std::lock_guard<std::mutex> lock(mu);
  EXPECT_EQ(seen_b[0], "felt/default");
  EXPECT_TRUE(seen_a.empty()) << "a store is not told about its own writes";
}

TEST_F(PgFleetTest, ClaimSkipsLockedAndClaimedJobs) {
  auto a = OpenStore(url_);
  auto b = OpenStore(url_);
  IdentificationJob j;
  j.material = "cloth";
  j.plan_json = "{}";
  const auto job = a->RequestIdentification(j);
  EXPECT_EQ(b->RequestIdentification(j).id, job.id);  // one open job
  std::atomic<int> wins{0};
  std::thread ta([&] { wins += a->ClaimJob(job.id, "a") ? 1 : 0; });
  std::thread tb([&] { wins += b->ClaimJob(job.id, "b") ? 1 : 0; });
  ta.join();
  tb.join();
  EXPECT_EQ(wins.load(), 1);
}

TEST(PgFaults, UnavailableWhileStoppedThenReconnects) {
  if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
  if (!PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
  // The shared server: stopped and crashed here, running again at the end.
  PgServer& pg = SharedPg();
  const std::string url = FreshPgDatabase();
  auto store = OpenStore(url);
  StrokeRecord st;
  st.material = "felt";
  st.csv = "x";
  ModelRecord m;
  m.material = "felt";
  m.json = "{}";
  EXPECT_EQ(store->CommitUpload(st, m).version, 1);
  pg.Stop();
  EXPECT_THROW(store->CommitUpload(st, m), StoreUnavailable);
  EXPECT_THROW(store->GetMaterial("felt"), StoreUnavailable);
  EXPECT_THROW(OpenStore(url), StoreUnavailable);
  pg.Start();  // same data directory and port
  EXPECT_EQ(store->CommitUpload(st, m).version, 2);
  EXPECT_EQ(store->ListModels("felt", "default").size(), 2u);
  pg.Crash();  // immediate shutdown: acknowledged writes survive recovery
  pg.Start();
  EXPECT_EQ(store->GetLatestModel("felt", "default")->version, 2);
}

}  // namespace
}  // namespace frictiond
