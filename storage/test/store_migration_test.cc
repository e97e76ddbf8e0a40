// Databases made by frictiond before the store logic was shared (commit
// da4cfb6: sqlite_store.cc with five migrations, pg_store.cc with four)
// open with today's store and migrate to one schema: the old migration
// scripts below are copied verbatim from that commit, applied up to each
// old version with rows written as the old code wrote them, then opened
// with OpenStore. Also: SchemaVersion() is the same on every back end, and
// a database newer than this frictiond is refused.
#include <atomic>
#include <filesystem>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "frictiond/storage/store.h"
#include "frictiond/testing/pg_server.h"

#include "connection.h"

namespace frictiond {
namespace {

using internal::Connection;
using internal::Driver;
using internal::LatestSchemaVersion;
using internal::Params;
using internal::Rows;

// sqlite_store.cc at da4cfb6, kMigrations (verbatim).
const char* const kOldSqliteMigrations[] = {
    R"sql(
CREATE TABLE materials(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, description TEXT NOT NULL,
  tags TEXT NOT NULL, created_at TEXT NOT NULL, updated_at TEXT NOT NULL);
CREATE TABLE fingertips(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, description TEXT NOT NULL, created_at TEXT NOT NULL);
CREATE TABLE strokes(
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  fingertip TEXT NOT NULL REFERENCES fingertips(id),
  robot TEXT NOT NULL, received_at TEXT NOT NULL, samples INTEGER NOT NULL, csv BLOB NOT NULL);
CREATE INDEX strokes_pair ON strokes(material, fingertip);
CREATE TABLE models(
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  fingertip TEXT NOT NULL REFERENCES fingertips(id),
  version INTEGER NOT NULL, created_at TEXT NOT NULL, reason TEXT NOT NULL,
  stroke_id INTEGER NOT NULL, json TEXT NOT NULL,
  PRIMARY KEY(material, fingertip, version));
CREATE TABLE jobs(
  id INTEGER PRIMARY KEY AUTOINCREMENT, material TEXT NOT NULL, fingertip TEXT NOT NULL,
  state TEXT NOT NULL, plan_json TEXT NOT NULL, detail TEXT NOT NULL, requested_by TEXT NOT NULL,
  created_at TEXT NOT NULL, updated_at TEXT NOT NULL);
CREATE INDEX jobs_pair ON jobs(material, fingertip, state);
CREATE TABLE images(
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  mime TEXT NOT NULL, features BLOB NOT NULL, created_at TEXT NOT NULL);
)sql",
    R"sql(
CREATE TABLE robots(
  id TEXT PRIMARY KEY, json TEXT NOT NULL, created_at TEXT NOT NULL, updated_at TEXT NOT NULL);
)sql",
    R"sql(
CREATE TABLE tokens(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, role TEXT NOT NULL,
  hash TEXT NOT NULL UNIQUE, created_at TEXT NOT NULL, revoked_at TEXT NOT NULL);
CREATE TABLE audit(
  id INTEGER PRIMARY KEY AUTOINCREMENT, at TEXT NOT NULL, actor TEXT NOT NULL,
  role TEXT NOT NULL, remote TEXT NOT NULL, action TEXT NOT NULL,
  material TEXT NOT NULL, detail TEXT NOT NULL);
CREATE INDEX audit_material ON audit(material, id);
)sql",
    // Identification jobs claimed by one worker (ClaimJob).
    R"sql(
ALTER TABLE jobs ADD COLUMN claimed_by TEXT NOT NULL DEFAULT '';
)sql",
    // Complete strokes of open jobs (PutJobStroke), kept across restarts.
    R"sql(
CREATE TABLE job_strokes(
  job_id INTEGER NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  stroke INTEGER NOT NULL, csv BLOB NOT NULL, PRIMARY KEY(job_id, stroke));
)sql",
};

// pg_store.cc at da4cfb6, kPgMigrations (verbatim).
const char* const kOldPostgresMigrations[] = {
    R"sql(
CREATE TABLE materials(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, description TEXT NOT NULL,
  tags TEXT NOT NULL, created_at TEXT NOT NULL, updated_at TEXT NOT NULL);
CREATE TABLE fingertips(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, description TEXT NOT NULL,
  created_at TEXT NOT NULL);
CREATE TABLE strokes(
  id BIGSERIAL PRIMARY KEY,
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  fingertip TEXT NOT NULL REFERENCES fingertips(id),
  robot TEXT NOT NULL, received_at TEXT NOT NULL, samples BIGINT NOT NULL,
  csv BYTEA NOT NULL);
CREATE INDEX strokes_pair ON strokes(material, fingertip);
CREATE TABLE models(
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  fingertip TEXT NOT NULL REFERENCES fingertips(id),
  version INTEGER NOT NULL, created_at TEXT NOT NULL, reason TEXT NOT NULL,
  stroke_id BIGINT NOT NULL, json TEXT NOT NULL,
  PRIMARY KEY(material, fingertip, version));
CREATE TABLE jobs(
  id BIGSERIAL PRIMARY KEY, material TEXT NOT NULL, fingertip TEXT NOT NULL,
  state TEXT NOT NULL, plan_json TEXT NOT NULL, detail TEXT NOT NULL,
  requested_by TEXT NOT NULL, created_at TEXT NOT NULL,
  updated_at TEXT NOT NULL, claimed_by TEXT NOT NULL DEFAULT '');
CREATE INDEX jobs_pair ON jobs(material, fingertip, state);
CREATE TABLE images(
  id BIGSERIAL PRIMARY KEY,
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  mime TEXT NOT NULL, features BYTEA NOT NULL, created_at TEXT NOT NULL);
)sql",
    R"sql(
CREATE TABLE robots(
  id TEXT PRIMARY KEY, json TEXT NOT NULL, created_at TEXT NOT NULL,
  updated_at TEXT NOT NULL);
)sql",
    R"sql(
CREATE TABLE tokens(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, role TEXT NOT NULL,
  hash TEXT NOT NULL UNIQUE, created_at TEXT NOT NULL,
  revoked_at TEXT NOT NULL DEFAULT '', seq BIGSERIAL);
CREATE TABLE audit(
  id BIGSERIAL PRIMARY KEY, at TEXT NOT NULL, actor TEXT NOT NULL,
  role TEXT NOT NULL, remote TEXT NOT NULL, action TEXT NOT NULL,
  material TEXT NOT NULL, detail TEXT NOT NULL);
CREATE INDEX audit_material ON audit(material, id);
)sql",
    // Complete strokes of open jobs (PutJobStroke), kept across restarts.
    R"sql(
CREATE TABLE job_strokes(
  job_id BIGINT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  stroke INTEGER NOT NULL, csv BYTEA NOT NULL, PRIMARY KEY(job_id, stroke));
)sql",
};

constexpr const char* kCsv = "t_s,fn_n,ft_n,v_mm_s\n0,1,0.5,0\n";

/// Applies the old migrations 1..version and writes rows as the old code
/// did: the default fingertip, material "felt" with one stroke and model
/// version 1, an open job, and (from version 3) a token and an audit entry.
void MakeOldDatabase(Driver& driver,
                     const char* const* migrations,
                     int version) {
  driver.Write([&](Connection& c) {
    c.ExecuteScript(
        "CREATE TABLE IF NOT EXISTS schema_version(version INTEGER NOT NULL, "
        "applied_at TEXT NOT NULL)");
    for (int v = 1; v <= version; ++v) {
      c.ExecuteScript(migrations[v - 1]);
      c.Execute("INSERT INTO schema_version(version,applied_at) VALUES($1,$2)",
                Params().Int(v).Text("2026-11-01T00:00:00.000Z"));
    }
    c.Execute(
        "INSERT INTO fingertips(id,name,description,created_at) "
        "VALUES('default','default','fingertip used when none is named',"
        "'2026-11-01T00:00:00.000Z')");
    c.Execute(
        "INSERT INTO materials(id,name,description,tags,created_at,"
        "updated_at) VALUES('felt','Felt','old','[\"wool\"]',"
        "'2026-11-01T00:00:01.000Z','2026-11-01T00:00:01.000Z')");
    const std::string csv = kCsv;
    const std::int64_t stroke =
        c.Execute(
             "INSERT INTO strokes(material,fingertip,robot,received_at,"
             "samples,csv) VALUES('felt','default','arm-1',"
             "'2026-11-01T00:00:02.000Z',1,$1) RETURNING id",
             Params().Bytes(csv))
            .Int(0, 0);
    c.Execute(
        "INSERT INTO models(material,fingertip,version,created_at,reason,"
        "stroke_id,json) VALUES('felt','default',1,"
        "'2026-11-01T00:00:02.000Z','upload',$1,'{\"v\":1}')",
        Params().Int(stroke));
    c.Execute(
        "INSERT INTO jobs(material,fingertip,state,plan_json,detail,"
        "requested_by,created_at,updated_at) VALUES('cloth','default',"
        "'requested','{}','','robot-1','2026-11-01T00:00:03.000Z',"
        "'2026-11-01T00:00:03.000Z')");
    if (version >= 3) {
      c.Execute(
          "INSERT INTO tokens(id,name,role,hash,created_at,revoked_at) "
          "VALUES('tok_000000000001','ops','operator',$1,"
          "'2026-11-01T00:00:04.000Z','')",
          Params().Text(std::string(64, 'a')));
      c.Execute(
          "INSERT INTO audit(at,actor,role,remote,action,material,detail) "
          "VALUES('2026-11-01T00:00:04.000Z','system','','','PUT','felt',"
          "'{}')");
    }
  });
}

/// Checks that `store` holds the old rows and takes every kind of write.
void ExpectOldDataAndNewWrites(Store& store, int old_version) {
  EXPECT_EQ(store.SchemaVersion(), LatestSchemaVersion());
  EXPECT_EQ(store.CheckIntegrity(), "");
  const auto felt = store.GetMaterial("felt");
  ASSERT_TRUE(felt.has_value());
  EXPECT_EQ(felt->description, "old");
  EXPECT_EQ(felt->tags, std::vector<std::string>{"wool"});
  const auto strokes = store.ListStrokes("felt", "default");
  ASSERT_EQ(strokes.size(), 1u);
  EXPECT_EQ(store.GetStroke(strokes[0].id)->csv, kCsv);
  EXPECT_EQ(store.GetLatestModel("felt", "default")->json, "{\"v\":1}");

  // Uploads append version 2 and close nothing of another pair.
  StrokeRecord s;
  s.material = "felt";
  s.robot = "arm-2";
  s.samples = 1;
  s.csv = kCsv;
  ModelRecord m;
  m.material = "felt";
  m.reason = "upload";
  m.json = "{\"v\":2}";
  const UploadCommit up = store.CommitUpload(s, m);
  EXPECT_FALSE(up.material_created);
  EXPECT_EQ(up.version, 2);
  EXPECT_GT(up.stroke_id, strokes[0].id);

  // The old open job: still the pair's open job, claimable (claimed_by),
  // keeps strokes (job_strokes), fitted by an upload of its pair.
  IdentificationJob j;
  j.material = "cloth";
  j.plan_json = "{}";
  const IdentificationJob job = store.RequestIdentification(j);
  EXPECT_EQ(job.requested_by, "robot-1");
  EXPECT_TRUE(store.ClaimJob(job.id, "daemon-a").has_value());
  EXPECT_FALSE(store.ClaimJob(job.id, "daemon-b").has_value());
  EXPECT_TRUE(store.PutJobStroke(job.id, 0, kCsv));
  EXPECT_EQ(store.ListJobStrokes(job.id).size(), 1u);
  s.material = m.material = "cloth";
  EXPECT_TRUE(store.CommitUpload(s, m).material_created);
  EXPECT_EQ(store.GetJob(job.id)->state, "fitted");

  // Robots, tokens and audit (tables of old steps 2 and 3).
  EXPECT_TRUE(store.PutRobot(RobotRecord{"arm-1", "{}", "", ""}));
  EXPECT_TRUE(store.AddToken(TokenRecord{
      "tok_000000000002", "arm", "robot", std::string(64, 'b'), "", ""}));
  const auto tokens = store.ListTokens();
  ASSERT_EQ(tokens.size(), old_version >= 3 ? 2u : 1u);
  EXPECT_EQ(tokens.back().id, "tok_000000000002");
  if (old_version >= 3) {
    EXPECT_EQ(tokens.front().id, "tok_000000000001");
    EXPECT_FALSE(store.AddToken(TokenRecord{
        "tok_000000000003", "dup", "robot", std::string(64, 'a'), "", ""}));
  }
  AuditEntry e;
  e.actor = "system";
  e.action = "POST";
  e.material = "felt";
  store.AppendAudit(e);
  EXPECT_EQ(store.ListAudit(0, 100, "felt").size(), old_version >= 3 ? 2u : 1u);
  EXPECT_EQ(store.CheckIntegrity(), "");
}

/// (table, column) of every table of the database.
std::set<std::pair<std::string, std::string>> SqliteColumns(Driver& driver) {
  std::set<std::pair<std::string, std::string>> out;
  driver.Read([&](Connection& c) {
    Rows r = c.Execute(
        "SELECT m.name, p.name FROM sqlite_master m, pragma_table_info(m.name) "
        "p WHERE m.type='table' AND m.name NOT LIKE 'sqlite_%'");
    for (int i = 0; i < r.size(); ++i) out.emplace(r.Take(i, 0), r.Take(i, 1));
  });
  return out;
}

class SqliteFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("frictiond_migration_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Path(const std::string& name) const {
    return (dir_ / name).string();
  }
  std::filesystem::path dir_;
};

// --- SQLite -----------------------------------------------------------------

class OldSqliteDatabase : public SqliteFileTest,
                          public ::testing::WithParamInterface<int> {};

TEST_P(OldSqliteDatabase, OpensMigratesAndTakesWrites) {
  const int old_version = GetParam();
  const std::string path = Path("old.db");
  MakeOldDatabase(
      *internal::OpenSqliteDriver(path), kOldSqliteMigrations, old_version);
  {
    auto store = OpenStore(path);
    ExpectOldDataAndNewWrites(*store, old_version);
  }
  // Reopening migrates nothing more and keeps the data.
  auto store = OpenStore(path);
  EXPECT_EQ(store->SchemaVersion(), LatestSchemaVersion());
  EXPECT_EQ(store->ListModels("felt", "default").size(), 2u);
  // Same tables and columns as a database made by today's store.
  OpenStore(Path("new.db"));
  EXPECT_EQ(SqliteColumns(*internal::OpenSqliteDriver(path)),
            SqliteColumns(*internal::OpenSqliteDriver(Path("new.db"))));
}

INSTANTIATE_TEST_SUITE_P(OldVersions,
                         OldSqliteDatabase,
                         ::testing::Values(1, 3, 4, 5));

TEST_F(SqliteFileTest, NewerSchemaIsRefused) {
  const std::string path = Path("future.db");
  OpenStore(path);
  internal::OpenSqliteDriver(path)->Write([](Connection& c) {
    c.Execute("INSERT INTO schema_version(version,applied_at) VALUES(99,'x')");
  });
  try {
    OpenStore(path);
    ADD_FAILURE() << "opened a database of schema version 99";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(),
                 ("sqlite: database schema version 99 is newer than this "
                  "frictiond (" +
                  std::to_string(LatestSchemaVersion()) + ")")
                     .c_str());
  }
}

// --- PostgreSQL
// ---------------------------------------------------------------

bool PgBackendBuilt() {
#ifdef FRICTIOND_HAVE_POSTGRES
  return true;
#else
  return false;
#endif
}

testing::PgServer& SharedPg() {
  static std::mutex mu;
  static std::unique_ptr<testing::PgServer> pg;
  std::lock_guard<std::mutex> lock(mu);
  if (!pg) {
    auto p = std::make_unique<testing::PgServer>();
    p->Start();
    pg = std::move(p);
  }
  return *pg;
}

std::string FreshPgDatabase() {
  static std::atomic<int> n{0};
  return SharedPg().CreateDatabase("m" + std::to_string(::getpid()) + "_" +
                                   std::to_string(++n));
}

#ifdef FRICTIOND_HAVE_POSTGRES
std::set<std::pair<std::string, std::string>> PostgresColumns(Driver& driver) {
  std::set<std::pair<std::string, std::string>> out;
  driver.Read([&](Connection& c) {
    Rows r = c.Execute(
        "SELECT table_name::text, column_name::text FROM "
        "information_schema.columns WHERE table_schema='public'");
    for (int i = 0; i < r.size(); ++i) out.emplace(r.Take(i, 0), r.Take(i, 1));
  });
  return out;
}

class OldPostgresDatabase : public ::testing::TestWithParam<int> {};

TEST_P(OldPostgresDatabase, OpensMigratesAndTakesWrites) {
  if (!testing::PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
  const int old_version = GetParam();
  const std::string url = FreshPgDatabase();
  MakeOldDatabase(
      *internal::OpenPostgresDriver(url), kOldPostgresMigrations, old_version);
  {
    auto store = OpenStore(url);
    ExpectOldDataAndNewWrites(*store, old_version);
  }
  auto store = OpenStore(url);
  EXPECT_EQ(store->SchemaVersion(), LatestSchemaVersion());
  EXPECT_EQ(store->ListModels("felt", "default").size(), 2u);
  const std::string fresh = FreshPgDatabase();
  OpenStore(fresh);
  EXPECT_EQ(PostgresColumns(*internal::OpenPostgresDriver(url)),
            PostgresColumns(*internal::OpenPostgresDriver(fresh)));
}

INSTANTIATE_TEST_SUITE_P(OldVersions,
                         OldPostgresDatabase,
                         ::testing::Values(1, 2, 3, 4));
#endif

// --- every back end
// -----------------------------------------------------------

TEST(SchemaVersion, IsTheSameOnEveryBackend) {
  EXPECT_EQ(LatestSchemaVersion(), 5);  // the five steps of migrations.cc
  EXPECT_EQ(OpenStore(":memory:")->SchemaVersion(), LatestSchemaVersion());
  if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
  if (!testing::PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
  EXPECT_EQ(OpenStore(FreshPgDatabase())->SchemaVersion(),
            LatestSchemaVersion());
}

}  // namespace
}  // namespace frictiond
