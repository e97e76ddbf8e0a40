// SQLite back end of Store: WAL journal, synchronous=FULL (acknowledged
// writes survive kill -9 and power loss), schema migrations recorded in
// schema_version, prepared statements only (values are always bound).
#include <algorithm>
#include <chrono>
#include <ctime>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>

#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include "frictiond/storage/store.h"

namespace frictiond {

namespace {
// A locked, read-only, full or failing database file is an outage of the
// store (StoreUnavailable: HTTP 503, nothing stored), not a bug (500).
[[noreturn]] void ThrowSqliteError(int rc, const std::string& why) {
  switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
    case SQLITE_READONLY:
    case SQLITE_IOERR:
    case SQLITE_FULL:
    case SQLITE_CANTOPEN:
      throw StoreUnavailable("sqlite: " + why);
    default:
      throw std::runtime_error("sqlite: " + why);
  }
}
}  // namespace

std::string NowIso8601() {
  using namespace std::chrono;
  const auto now = system_clock::now();
  const std::time_t t = system_clock::to_time_t(now);
  const int ms = static_cast<int>(
      duration_cast<milliseconds>(now.time_since_epoch()).count() % 1000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::snprintf(buf,
                sizeof buf,
                "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ",
                tm.tm_year + 1900,
                tm.tm_mon + 1,
                tm.tm_mday,
                tm.tm_hour,
                tm.tm_min,
                tm.tm_sec,
                ms);
  return buf;
}

namespace internal {
#ifdef FRICTIOND_HAVE_POSTGRES
/// The PostgreSQL back end (pg_store.cc).
std::unique_ptr<Store> OpenPgStore(const std::string& url);
#endif
namespace {

// Schema migrations; index i brings the schema from version i to i + 1.
const char* const kMigrations[] = {
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

constexpr const char* kOpenStates =
    "('requested','stroking','enough_coverage')";

class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK) {
      throw std::runtime_error(std::string("sqlite: prepare: ") +
                               sqlite3_errmsg(db) + " in: " + sql);
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    next_ = 1;
    return *this;
  }
  Statement& Bind(const std::string& s) {
    sqlite3_bind_text(
        stmt_, next_++, s.data(), static_cast<int>(s.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Statement& BindBlob(const std::string& s) {
    sqlite3_bind_blob(
        stmt_, next_++, s.data(), static_cast<int>(s.size()), SQLITE_STATIC);
    return *this;
  }
  Statement& Bind(std::int64_t v) {
    sqlite3_bind_int64(stmt_, next_++, v);
    return *this;
  }
  /// Steps once: true when a row is available.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    const std::string why = sqlite3_errmsg(db_);
    // A failed statement left un-reset stays "in progress" and makes every
    // later COMMIT on this connection fail, long after the cause (e.g. a
    // lock held by another process) is gone.
    sqlite3_reset(stmt_);
    ThrowSqliteError(rc, why);
  }
  void Run() {
    while (Step()) {
    }
  }
  std::string Text(int col) const {
    const auto* p = sqlite3_column_blob(stmt_, col);
    const int n = sqlite3_column_bytes(stmt_, col);
    return p ? std::string(static_cast<const char*>(p), n) : std::string();
  }
  std::int64_t Int(int col) const { return sqlite3_column_int64(stmt_, col); }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  int next_ = 1;
};

std::string TagsToJson(const std::vector<std::string>& tags) {
  return nlohmann::json(tags).dump();
}
std::vector<std::string> TagsFromJson(const std::string& s) {
  try {
    return nlohmann::json::parse(s).get<std::vector<std::string>>();
  } catch (const std::exception&) {
    return {};
  }
}

}  // namespace

class SqliteStore final : public Store {
 public:
  explicit SqliteStore(const std::string& path) {
    if (sqlite3_open_v2(
            path.c_str(),
            &db_,
            SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
            nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      throw std::runtime_error("sqlite: cannot open '" + path + "': " + why);
    }
    sqlite3_busy_timeout(db_, 5000);
    Exec("PRAGMA foreign_keys=ON");
    if (path != ":memory:") Exec("PRAGMA journal_mode=WAL");
    Exec("PRAGMA synchronous=FULL");
    Migrate();
  }
  ~SqliteStore() override {
    stmts_.clear();
    sqlite3_close(db_);
  }

  bool PutMaterial(const Material& m) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    const std::string now = NowIso8601();
    auto& exists =
        Stmt("SELECT 1 FROM materials WHERE id=?").Reset().Bind(m.id);
    const bool existed = exists.Step();
    exists.Reset();
    if (existed) {
      Stmt(
          "UPDATE materials SET name=?, description=?, tags=?, updated_at=? "
          "WHERE id=?")
          .Reset()
          .Bind(m.name)
          .Bind(m.description)
          .Bind(TagsToJson(m.tags))
          .Bind(now)
          .Bind(m.id)
          .Run();
    } else {
      Stmt(
          "INSERT INTO "
          "materials(id,name,description,tags,created_at,updated_at) "
          "VALUES(?,?,?,?,?,?)")
          .Reset()
          .Bind(m.id)
          .Bind(m.name)
          .Bind(m.description)
          .Bind(TagsToJson(m.tags))
          .Bind(now)
          .Bind(now)
          .Run();
    }
    tx.Commit();
    return !existed;
  }

  std::optional<Material> GetMaterial(const std::string& id) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,name,description,tags,created_at,updated_at FROM "
                  "materials WHERE id=?")
                  .Reset()
                  .Bind(id);
    std::optional<Material> out;
    if (s.Step()) out = ReadMaterial(s);
    s.Reset();
    return out;
  }

  std::vector<Material> ListMaterials() override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,name,description,tags,created_at,updated_at FROM "
                  "materials ORDER BY id")
                  .Reset();
    std::vector<Material> out;
    while (s.Step()) out.push_back(ReadMaterial(s));
    return out;
  }

  bool DeleteMaterial(const std::string& id) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    Stmt("DELETE FROM jobs WHERE material=?").Reset().Bind(id).Run();
    auto& s = Stmt("DELETE FROM materials WHERE id=?").Reset().Bind(id);
    s.Run();
    const bool deleted = sqlite3_changes(db_) > 0;
    tx.Commit();
    return deleted;
  }

  bool PutRobot(const RobotRecord& r) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    const std::string now = NowIso8601();
    auto& exists = Stmt("SELECT 1 FROM robots WHERE id=?").Reset().Bind(r.id);
    const bool existed = exists.Step();
    exists.Reset();
    if (existed) {
      Stmt("UPDATE robots SET json=?, updated_at=? WHERE id=?")
          .Reset()
          .Bind(r.json)
          .Bind(now)
          .Bind(r.id)
          .Run();
    } else {
      Stmt("INSERT INTO robots(id,json,created_at,updated_at) VALUES(?,?,?,?)")
          .Reset()
          .Bind(r.id)
          .Bind(r.json)
          .Bind(now)
          .Bind(now)
          .Run();
    }
    tx.Commit();
    return !existed;
  }

  std::optional<RobotRecord> GetRobot(const std::string& id) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s =
        Stmt("SELECT id,json,created_at,updated_at FROM robots WHERE id=?")
            .Reset()
            .Bind(id);
    std::optional<RobotRecord> out;
    if (s.Step()) out = RobotRecord{s.Text(0), s.Text(1), s.Text(2), s.Text(3)};
    s.Reset();
    return out;
  }

  bool PutFingertip(const Fingertip& f) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    auto& exists =
        Stmt("SELECT 1 FROM fingertips WHERE id=?").Reset().Bind(f.id);
    const bool existed = exists.Step();
    exists.Reset();
    if (existed) {
      Stmt("UPDATE fingertips SET name=?, description=? WHERE id=?")
          .Reset()
          .Bind(f.name)
          .Bind(f.description)
          .Bind(f.id)
          .Run();
    } else {
      Stmt(
          "INSERT INTO fingertips(id,name,description,created_at) "
          "VALUES(?,?,?,?)")
          .Reset()
          .Bind(f.id)
          .Bind(f.name)
          .Bind(f.description)
          .Bind(NowIso8601())
          .Run();
    }
    tx.Commit();
    return !existed;
  }

  std::optional<Fingertip> GetFingertip(const std::string& id) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s =
        Stmt("SELECT id,name,description,created_at FROM fingertips WHERE id=?")
            .Reset()
            .Bind(id);
    std::optional<Fingertip> out;
    if (s.Step()) out = Fingertip{s.Text(0), s.Text(1), s.Text(2), s.Text(3)};
    s.Reset();
    return out;
  }

  std::vector<Fingertip> ListFingertips() override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s =
        Stmt(
            "SELECT id,name,description,created_at FROM fingertips ORDER BY id")
            .Reset();
    std::vector<Fingertip> out;
    while (s.Step())
      out.push_back(Fingertip{s.Text(0), s.Text(1), s.Text(2), s.Text(3)});
    return out;
  }

  UploadCommit CommitUpload(const StrokeRecord& stroke,
                            const ModelRecord& model) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    UploadCommit out;
    const std::string now = NowIso8601();
    auto& exists = Stmt("SELECT 1 FROM materials WHERE id=?")
                       .Reset()
                       .Bind(stroke.material);
    const bool existed = exists.Step();
    exists.Reset();
    if (!existed) {
      Stmt(
          "INSERT INTO "
          "materials(id,name,description,tags,created_at,updated_at) "
          "VALUES(?,?,?,?,?,?)")
          .Reset()
          .Bind(stroke.material)
          .Bind(stroke.material)
          .Bind(std::string())
          .Bind(std::string("[]"))
          .Bind(now)
          .Bind(now)
          .Run();
      out.material_created = true;
    }
    EnsureFingertip(stroke.fingertip, now);
    Stmt(
        "INSERT INTO strokes(material,fingertip,robot,received_at,samples,csv) "
        "VALUES(?,?,?,?,?,?)")
        .Reset()
        .Bind(stroke.material)
        .Bind(stroke.fingertip)
        .Bind(stroke.robot)
        .Bind(now)
        .Bind(stroke.samples)
        .BindBlob(stroke.csv)
        .Run();
    out.stroke_id = sqlite3_last_insert_rowid(db_);
    ModelRecord m = model;
    m.stroke_id = out.stroke_id;
    out.version = InsertModel(m, now);
    Stmt(std::string("UPDATE jobs SET state='fitted', detail=?, updated_at=? "
                     "WHERE material=? AND fingertip=? AND "
                     "state IN ") +
         kOpenStates)
        .Reset()
        .Bind("model version " + std::to_string(out.version) + " from stroke " +
              std::to_string(out.stroke_id))
        .Bind(now)
        .Bind(stroke.material)
        .Bind(stroke.fingertip)
        .Run();
    tx.Commit();
    return out;
  }

  int AddModelVersion(const ModelRecord& model) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    const std::string now = NowIso8601();
    EnsureFingertip(model.fingertip, now);
    const int v = InsertModel(model, now);
    tx.Commit();
    return v;
  }

  std::vector<StrokeRecord> ListStrokes(const std::string& material,
                                        const std::string& fingertip) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,material,fingertip,robot,received_at,samples FROM "
                  "strokes WHERE material=? AND "
                  "fingertip=? ORDER BY id")
                  .Reset()
                  .Bind(material)
                  .Bind(fingertip);
    std::vector<StrokeRecord> out;
    while (s.Step()) {
      out.push_back(StrokeRecord{
          s.Int(0), s.Text(1), s.Text(2), s.Text(3), s.Text(4), s.Int(5), {}});
    }
    return out;
  }

  std::optional<StrokeRecord> GetStroke(std::int64_t id) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,material,fingertip,robot,received_at,samples,csv "
                  "FROM strokes WHERE id=?")
                  .Reset()
                  .Bind(id);
    std::optional<StrokeRecord> out;
    if (s.Step())
      out = StrokeRecord{s.Int(0),
                         s.Text(1),
                         s.Text(2),
                         s.Text(3),
                         s.Text(4),
                         s.Int(5),
                         s.Text(6)};
    s.Reset();
    return out;
  }

  std::optional<ModelRecord> GetLatestModel(
      const std::string& material, const std::string& fingertip) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT "
                  "material,fingertip,version,created_at,reason,stroke_id,json "
                  "FROM models WHERE material=? "
                  "AND fingertip=? ORDER BY version DESC LIMIT 1")
                  .Reset()
                  .Bind(material)
                  .Bind(fingertip);
    std::optional<ModelRecord> out;
    if (s.Step()) out = ReadModel(s, true);
    s.Reset();
    return out;
  }

  std::optional<ModelRecord> GetModel(const std::string& material,
                                      const std::string& fingertip,
                                      int version) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT "
                  "material,fingertip,version,created_at,reason,stroke_id,json "
                  "FROM models WHERE material=? "
                  "AND fingertip=? AND version=?")
                  .Reset()
                  .Bind(material)
                  .Bind(fingertip)
                  .Bind(static_cast<std::int64_t>(version));
    std::optional<ModelRecord> out;
    if (s.Step()) out = ReadModel(s, true);
    s.Reset();
    return out;
  }

  std::vector<ModelRecord> ListModels(const std::string& material,
                                      const std::string& fingertip) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s =
        Stmt(
            "SELECT material,fingertip,version,created_at,reason,stroke_id,'' "
            "FROM models WHERE material=? AND "
            "fingertip=? ORDER BY version")
            .Reset()
            .Bind(material)
            .Bind(fingertip);
    std::vector<ModelRecord> out;
    while (s.Step()) out.push_back(ReadModel(s, false));
    return out;
  }

  IdentificationJob RequestIdentification(
      const IdentificationJob& job) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    auto& open = Stmt(std::string("SELECT id FROM jobs WHERE material=? AND "
                                  "fingertip=? AND state IN ") +
                      kOpenStates + " ORDER BY id DESC LIMIT 1")
                     .Reset()
                     .Bind(job.material)
                     .Bind(job.fingertip);
    std::int64_t id = 0;
    if (open.Step()) id = open.Int(0);
    open.Reset();
    if (id == 0) {
      const std::string now = NowIso8601();
      Stmt(
          "INSERT INTO "
          "jobs(material,fingertip,state,plan_json,detail,requested_by,created_"
          "at,updated_at) "
          "VALUES(?,?,?,?,?,?,?,?)")
          .Reset()
          .Bind(job.material)
          .Bind(job.fingertip)
          .Bind(job.state.empty() ? std::string("requested") : job.state)
          .Bind(job.plan_json)
          .Bind(job.detail)
          .Bind(job.requested_by)
          .Bind(now)
          .Bind(now)
          .Run();
      id = sqlite3_last_insert_rowid(db_);
    }
    tx.Commit();
    return *GetJobLocked(id);
  }

  bool UpdateJob(std::int64_t id,
                 const std::string& state,
                 const std::string& detail) override {
    std::lock_guard<std::mutex> lock(mu_);
    Stmt("UPDATE jobs SET state=?, detail=?, updated_at=? WHERE id=?")
        .Reset()
        .Bind(state)
        .Bind(detail)
        .Bind(NowIso8601())
        .Bind(id)
        .Run();
    return sqlite3_changes(db_) > 0;
  }

  std::optional<IdentificationJob> GetJob(std::int64_t id) override {
    std::lock_guard<std::mutex> lock(mu_);
    return GetJobLocked(id);
  }

  std::vector<IdentificationJob> ListJobs(bool open_only) override {
    std::lock_guard<std::mutex> lock(mu_);
    std::string sql =
        "SELECT "
        "id,material,fingertip,state,plan_json,detail,requested_by,created_at,"
        "updated_at FROM jobs";
    if (open_only) sql += std::string(" WHERE state IN ") + kOpenStates;
    sql += " ORDER BY id DESC";
    auto& s = Stmt(sql).Reset();
    std::vector<IdentificationJob> out;
    while (s.Step()) out.push_back(ReadJob(s));
    return out;
  }

  std::vector<IdentificationJob> ListJobsPage(bool open_only,
                                              std::int64_t after,
                                              int limit) override {
    std::lock_guard<std::mutex> lock(mu_);
    std::string sql =
        "SELECT "
        "id,material,fingertip,state,plan_json,detail,requested_by,created_at,"
        "updated_at FROM jobs WHERE id < ?";
    if (open_only) sql += std::string(" AND state IN ") + kOpenStates;
    sql += " ORDER BY id DESC LIMIT ?";
    auto& s = Stmt(sql).Reset().Bind(
        after > 0 ? after : std::numeric_limits<std::int64_t>::max());
    s.Bind(static_cast<std::int64_t>(std::max(limit, 1)));
    std::vector<IdentificationJob> out;
    while (s.Step()) out.push_back(ReadJob(s));
    s.Reset();
    return out;
  }

  bool PutJobStroke(std::int64_t job_id,
                    int stroke,
                    const std::string& csv) override {
    std::lock_guard<std::mutex> lock(mu_);
    if (!GetJobLocked(job_id)) return false;
    Stmt(
        "INSERT OR REPLACE INTO job_strokes(job_id,stroke,csv) "
        "VALUES(?,?,?)")
        .Reset()
        .Bind(job_id)
        .Bind(static_cast<std::int64_t>(stroke))
        .BindBlob(csv)
        .Run();
    return true;
  }

  std::vector<std::pair<int, std::string>> ListJobStrokes(
      std::int64_t job_id) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT stroke,csv FROM job_strokes WHERE job_id=? "
                  "ORDER BY stroke")
                  .Reset()
                  .Bind(job_id);
    std::vector<std::pair<int, std::string>> out;
    while (s.Step()) out.emplace_back(static_cast<int>(s.Int(0)), s.Text(1));
    return out;
  }

  void DeleteJobStrokes(std::int64_t job_id) override {
    std::lock_guard<std::mutex> lock(mu_);
    Stmt("DELETE FROM job_strokes WHERE job_id=?").Reset().Bind(job_id).Run();
  }

  std::int64_t AddImage(const ImageRecord& image) override {
    std::lock_guard<std::mutex> lock(mu_);
    Stmt(
        "INSERT INTO images(material,mime,features,created_at) VALUES(?,?,?,?)")
        .Reset()
        .Bind(image.material)
        .Bind(image.mime)
        .BindBlob(image.features)
        .Bind(NowIso8601())
        .Run();
    return sqlite3_last_insert_rowid(db_);
  }

  std::vector<ImageRecord> ListImages() override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,material,mime,features,created_at FROM images "
                  "ORDER BY id")
                  .Reset();
    std::vector<ImageRecord> out;
    while (s.Step())
      out.push_back(
          ImageRecord{s.Int(0), s.Text(1), s.Text(2), s.Text(3), s.Text(4)});
    return out;
  }

  std::optional<IdentificationJob> DoClaimJob(std::int64_t id,
                                              const std::string& worker,
                                              int lease_s) override {
    std::lock_guard<std::mutex> lock(mu_);
    Stmt(std::string("UPDATE jobs SET claimed_by=?, updated_at=? WHERE id=? "
                     "AND (claimed_by='' OR claimed_by=? OR updated_at < "
                     "strftime('%Y-%m-%dT%H:%M:%fZ','now',?)) "
                     "AND state IN ") +
         kOpenStates)
        .Reset()
        .Bind(worker)
        .Bind(NowIso8601())
        .Bind(id)
        .Bind(worker)
        .Bind("-" + std::to_string(lease_s) + " seconds")
        .Run();
    if (sqlite3_changes(db_) == 0) return std::nullopt;
    return GetJobLocked(id);
  }

  bool AddToken(const TokenRecord& tok) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    auto& exists = Stmt("SELECT 1 FROM tokens WHERE id=? OR hash=?")
                       .Reset()
                       .Bind(tok.id)
                       .Bind(tok.hash);
    const bool existed = exists.Step();
    exists.Reset();
    if (existed) return false;
    Stmt(
        "INSERT INTO tokens(id,name,role,hash,created_at,revoked_at) "
        "VALUES(?,?,?,?,?,'')")
        .Reset()
        .Bind(tok.id)
        .Bind(tok.name)
        .Bind(tok.role)
        .Bind(tok.hash)
        .Bind(NowIso8601())
        .Run();
    tx.Commit();
    return true;
  }

  std::optional<TokenRecord> FindTokenByHash(const std::string& hash) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,name,role,hash,created_at,revoked_at FROM tokens "
                  "WHERE hash=?")
                  .Reset()
                  .Bind(hash);
    std::optional<TokenRecord> out;
    if (s.Step()) out = ReadToken(s);
    s.Reset();
    return out;
  }

  std::vector<TokenRecord> ListTokens() override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,name,role,hash,created_at,revoked_at FROM tokens "
                  "ORDER BY created_at, rowid")
                  .Reset();
    std::vector<TokenRecord> out;
    while (s.Step()) out.push_back(ReadToken(s));
    return out;
  }

  bool RevokeToken(const std::string& id) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    Stmt("UPDATE tokens SET revoked_at=? WHERE id=? AND revoked_at=''")
        .Reset()
        .Bind(NowIso8601())
        .Bind(id)
        .Run();
    const bool changed = sqlite3_changes(db_) > 0;
    tx.Commit();
    return changed;
  }

  std::int64_t AppendAudit(const AuditEntry& e) override {
    std::lock_guard<std::mutex> lock(mu_);
    Transaction tx(this);
    Stmt(
        "INSERT INTO audit(at,actor,role,remote,action,material,detail) "
        "VALUES(?,?,?,?,?,?,?)")
        .Reset()
        .Bind(NowIso8601())
        .Bind(e.actor)
        .Bind(e.role)
        .Bind(e.remote)
        .Bind(e.action)
        .Bind(e.material)
        .Bind(e.detail)
        .Run();
    const std::int64_t id = sqlite3_last_insert_rowid(db_);
    tx.Commit();
    return id;
  }

  std::vector<AuditEntry> ListAudit(std::int64_t after_id,
                                    int limit,
                                    const std::string& material) override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt(
                  "SELECT id,at,actor,role,remote,action,material,detail "
                  "FROM audit WHERE id>? AND (?='' OR material=?) "
                  "ORDER BY id LIMIT ?")
                  .Reset()
                  .Bind(after_id)
                  .Bind(material)
                  .Bind(material)
                  .Bind(static_cast<std::int64_t>(limit < 0 ? 0 : limit));
    std::vector<AuditEntry> out;
    while (s.Step())
      out.push_back(AuditEntry{s.Int(0),
                               s.Text(1),
                               s.Text(2),
                               s.Text(3),
                               s.Text(4),
                               s.Text(5),
                               s.Text(6),
                               s.Text(7)});
    return out;
  }

  int SchemaVersion() override {
    std::lock_guard<std::mutex> lock(mu_);
    return SchemaVersionLocked();
  }

  std::string BackendName() const override { return "sqlite"; }

  std::string CheckIntegrity() override {
    std::lock_guard<std::mutex> lock(mu_);
    auto& s = Stmt("PRAGMA integrity_check").Reset();
    std::string out;
    while (s.Step()) {
      const std::string row = s.Text(0);
      if (row != "ok") out += row + "\n";
    }
    return out;
  }

 private:
  class Transaction {
   public:
    explicit Transaction(SqliteStore* s) : s_(s) {
      s_->Exec("BEGIN IMMEDIATE");
    }
    ~Transaction() {
      if (!done_) sqlite3_exec(s_->db_, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void Commit() {
      s_->Exec("COMMIT");
      done_ = true;
    }

   private:
    SqliteStore* s_;
    bool done_ = false;
  };

  void Exec(const std::string& sql) {
    char* err = nullptr;
    const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err);
    if (rc != SQLITE_OK) {
      std::string why = err ? err : "unknown error";
      sqlite3_free(err);
      ThrowSqliteError(rc, why);
    }
  }

  Statement& Stmt(const std::string& sql) {
    auto it = stmts_.find(sql);
    if (it == stmts_.end())
      it = stmts_.emplace(sql, std::make_unique<Statement>(db_, sql)).first;
    return *it->second;
  }

  int SchemaVersionLocked() {
    auto& s =
        Stmt("SELECT COALESCE(MAX(version),0) FROM schema_version").Reset();
    const int v = s.Step() ? static_cast<int>(s.Int(0)) : 0;
    s.Reset();
    return v;
  }

  void Migrate() {
    Exec(
        "CREATE TABLE IF NOT EXISTS schema_version(version INTEGER NOT NULL, "
        "applied_at TEXT NOT NULL)");
    const int have = SchemaVersionLocked();
    const int want =
        static_cast<int>(sizeof(kMigrations) / sizeof(kMigrations[0]));
    if (have > want) {
      throw std::runtime_error(
          "sqlite: database schema version " + std::to_string(have) +
          " is newer than this frictiond (" + std::to_string(want) + ")");
    }
    for (int v = have; v < want; ++v) {
      Transaction tx(this);
      Exec(kMigrations[v]);
      if (v == 0) {
        Stmt(
            "INSERT INTO fingertips(id,name,description,created_at) "
            "VALUES('default','default',"
            "'fingertip used when none is named',?)")
            .Reset()
            .Bind(NowIso8601())
            .Run();
      }
      Stmt("INSERT INTO schema_version(version, applied_at) VALUES(?,?)")
          .Reset()
          .Bind(std::int64_t{v + 1})
          .Bind(NowIso8601())
          .Run();
      tx.Commit();
    }
  }

  void EnsureFingertip(const std::string& id, const std::string& now) {
    Stmt(
        "INSERT OR IGNORE INTO fingertips(id,name,description,created_at) "
        "VALUES(?,?,'',?)")
        .Reset()
        .Bind(id)
        .Bind(id)
        .Bind(now)
        .Run();
  }

  int InsertModel(const ModelRecord& m, const std::string& now) {
    auto& q = Stmt(
                  "SELECT COALESCE(MAX(version),0) FROM models WHERE "
                  "material=? AND fingertip=?")
                  .Reset()
                  .Bind(m.material)
                  .Bind(m.fingertip);
    const int version = (q.Step() ? static_cast<int>(q.Int(0)) : 0) + 1;
    q.Reset();
    Stmt(
        "INSERT INTO "
        "models(material,fingertip,version,created_at,reason,stroke_id,json) "
        "VALUES(?,?,?,?,?,?,?)")
        .Reset()
        .Bind(m.material)
        .Bind(m.fingertip)
        .Bind(static_cast<std::int64_t>(version))
        .Bind(now)
        .Bind(m.reason)
        .Bind(m.stroke_id)
        .Bind(m.json)
        .Run();
    return version;
  }

  static TokenRecord ReadToken(const Statement& s) {
    return TokenRecord{
        s.Text(0), s.Text(1), s.Text(2), s.Text(3), s.Text(4), s.Text(5)};
  }
  static Material ReadMaterial(const Statement& s) {
    return Material{s.Text(0),
                    s.Text(1),
                    s.Text(2),
                    TagsFromJson(s.Text(3)),
                    s.Text(4),
                    s.Text(5)};
  }
  static ModelRecord ReadModel(const Statement& s, bool with_json) {
    return ModelRecord{s.Text(0),
                       s.Text(1),
                       static_cast<int>(s.Int(2)),
                       s.Text(3),
                       s.Text(4),
                       s.Int(5),
                       with_json ? s.Text(6) : std::string()};
  }
  static IdentificationJob ReadJob(const Statement& s) {
    return IdentificationJob{s.Int(0),
                             s.Text(1),
                             s.Text(2),
                             s.Text(3),
                             s.Text(4),
                             s.Text(5),
                             s.Text(6),
                             s.Text(7),
                             s.Text(8)};
  }
  std::optional<IdentificationJob> GetJobLocked(std::int64_t id) {
    auto& s = Stmt(
                  "SELECT "
                  "id,material,fingertip,state,plan_json,detail,requested_by,"
                  "created_at,updated_at FROM jobs "
                  "WHERE id=?")
                  .Reset()
                  .Bind(id);
    std::optional<IdentificationJob> out;
    if (s.Step()) out = ReadJob(s);
    s.Reset();
    return out;
  }

  sqlite3* db_ = nullptr;
  std::mutex mu_;
  std::map<std::string, std::unique_ptr<Statement>> stmts_;
};

}  // namespace internal

std::unique_ptr<Store> OpenStore(const std::string& url) {
  if (url.rfind("postgresql://", 0) == 0 || url.rfind("postgres://", 0) == 0) {
#ifdef FRICTIOND_HAVE_POSTGRES
    return internal::OpenPgStore(url);
#else
    throw std::invalid_argument(
        "--db " + url +
        ": the PostgreSQL back end is not built into this frictiond "
        "(FRICTIOND_WITH_POSTGRES=OFF or libpq missing)");
#endif
  }
  std::string path = url;
  if (path.rfind("sqlite://", 0) == 0) path = path.substr(9);
  if (path.empty()) throw std::invalid_argument("--db: empty path");
  return std::make_unique<internal::SqliteStore>(path);
}

}  // namespace frictiond
