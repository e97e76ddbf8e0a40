// PostgreSQL back end of Store (libpq), for a fleet of daemons sharing one
// library. Every statement is parameterised (PQexecParams); each mutating
// call is one transaction; model versions are appended under a row lock of
// the material (SELECT ... FOR UPDATE) with the primary key (material,
// fingertip, version) as a backstop, so concurrent uploads from several
// daemons get distinct consecutive versions. Every committed write NOTIFYs
// channel frictiond_changes; a listener thread (own connection) reports
// other processes' writes to the ChangeListener. Connection loss throws
// StoreUnavailable; the next call reconnects.
#ifdef FRICTIOND_HAVE_POSTGRES

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <limits>
#include <mutex>
#include <random>
#include <stdexcept>
#include <thread>
#include <type_traits>

#include <libpq-fe.h>
#include <nlohmann/json.hpp>
#include <poll.h>

#include "frictiond/storage/store.h"

namespace frictiond {
namespace internal {
namespace {

constexpr const char* kChannel = "frictiond_changes";
constexpr const char* kOpenStates =
    "('requested','stroking','enough_coverage')";
constexpr int kMaxConnections = 4;

// Schema migrations; index i brings the schema from version i to i + 1.
const char* const kPgMigrations[] = {
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

/// Statement parameters: text values, or bytes sent in binary format.
class Params {
 public:
  Params& Text(std::string v) {
    values_.push_back(std::move(v));
    binary_.push_back(0);
    return *this;
  }
  Params& Int(std::int64_t v) { return Text(std::to_string(v)); }
  Params& Bytes(std::string v) {
    values_.push_back(std::move(v));
    binary_.push_back(1);
    return *this;
  }
  int size() const { return static_cast<int>(values_.size()); }
  std::vector<const char*> Values() const {
    std::vector<const char*> out;
    for (const auto& v : values_) out.push_back(v.data());
    return out;
  }
  std::vector<int> Lengths() const {
    std::vector<int> out;
    for (const auto& v : values_) out.push_back(static_cast<int>(v.size()));
    return out;
  }
  const std::vector<int>& Formats() const { return binary_; }

 private:
  std::vector<std::string> values_;
  std::vector<int> binary_;
};

/// An owned query result.
class Result {
 public:
  explicit Result(PGresult* r) : r_(r) {}
  ~Result() { PQclear(r_); }
  Result(Result&& o) noexcept : r_(o.r_) { o.r_ = nullptr; }
  Result(const Result&) = delete;
  Result& operator=(const Result&) = delete;
  Result& operator=(Result&&) = delete;

  int Rows() const { return PQntuples(r_); }
  std::int64_t Affected() const {
    const char* n = PQcmdTuples(r_);
    return n && *n ? std::stoll(n) : 0;
  }
  std::string Text(int row, int col) const {
    return std::string(PQgetvalue(r_, row, col),
                       static_cast<std::size_t>(PQgetlength(r_, row, col)));
  }
  std::int64_t Int(int row, int col) const {
    return std::stoll(PQgetvalue(r_, row, col));
  }
  std::string Bytes(int row, int col) const {
    std::size_t n = 0;
    unsigned char* p = PQunescapeBytea(
        reinterpret_cast<const unsigned char*>(PQgetvalue(r_, row, col)), &n);
    if (!p) throw std::runtime_error("postgresql: cannot decode bytea");
    std::string out(reinterpret_cast<const char*>(p), n);
    PQfreemem(p);
    return out;
  }

 private:
  PGresult* r_;
};

/// True when an error means the server is unreachable rather than the
/// statement being wrong: connection exceptions (SQLSTATE class 08),
/// shutdown (57P01..57P03), or a dead connection.
bool IsUnavailable(PGconn* c, const PGresult* r) {
  if (PQstatus(c) != CONNECTION_OK) return true;
  const char* state = r ? PQresultErrorField(r, PG_DIAG_SQLSTATE) : nullptr;
  if (!state) return r == nullptr;
  return std::strncmp(state, "08", 2) == 0 ||
         std::strncmp(state, "57P0", 4) == 0;
}

std::string FirstLine(const char* s) {
  std::string m = s ? s : "";
  const auto nl = m.find('\n');
  return nl == std::string::npos ? m : m.substr(0, nl);
}

/// Opens a connection: `url` may override connect_timeout (default 3 s).
PGconn* Connect(const std::string& url) {
  const char* keys[] = {"connect_timeout", "dbname", nullptr};
  const char* values[] = {"3", url.c_str(), nullptr};
  PGconn* c = PQconnectdbParams(keys, values, 1);
  if (!c) throw StoreUnavailable("postgresql: out of memory");
  if (PQstatus(c) != CONNECTION_OK) {
    const std::string why = FirstLine(PQerrorMessage(c));
    PQfinish(c);
    throw StoreUnavailable("postgresql: cannot connect: " + why);
  }
  // Server notices ("... already exists, skipping") are not errors.
  PQsetNoticeProcessor(
      c, [](void*, const char*) {}, nullptr);
  return c;
}

Result Check(PGconn* c, PGresult* r) {
  const ExecStatusType st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK) return Result(r);
  const std::string why =
      FirstLine(r ? PQresultErrorMessage(r) : PQerrorMessage(c));
  const bool unavailable = IsUnavailable(c, r);
  PQclear(r);
  if (unavailable) throw StoreUnavailable("postgresql: " + why);
  throw std::runtime_error("postgresql: " + why);
}

/// Runs a constant multi-statement script (schema migrations only; never
/// built from input).
Result ExecScript(PGconn* c, const char* sql) {
  return Check(c, PQexec(c, sql));
}

Result Exec(PGconn* c, const std::string& sql, const Params& p = Params()) {
  const auto values = p.Values();
  const auto lengths = p.Lengths();
  PGresult* r = PQexecParams(c,
                             sql.c_str(),
                             p.size(),
                             nullptr,
                             p.size() ? values.data() : nullptr,
                             p.size() ? lengths.data() : nullptr,
                             p.size() ? p.Formats().data() : nullptr,
                             0);
  return Check(c, r);
}

}  // namespace

class PgStore final : public Store {
 public:
  explicit PgStore(std::string url) : url_(std::move(url)) {
    std::random_device rd;
    char buf[32];
    std::snprintf(buf,
                  sizeof buf,
                  "%08x%08x",
                  static_cast<unsigned>(rd()),
                  static_cast<unsigned>(rd()));
    origin_ = buf;
    Migrate();
  }

  ~PgStore() override {
    StopListener();
    std::lock_guard<std::mutex> lock(pool_mu_);
    for (PGconn* c : idle_) PQfinish(c);
    idle_.clear();
  }

  // --- materials -----------------------------------------------------------
  bool PutMaterial(const Material& m) override {
    return Write([&](Tx& tx) {
      const std::string now = NowIso8601();
      const Result r = tx.Exec(
          "INSERT INTO materials(id,name,description,tags,created_at,"
          "updated_at) VALUES($1,$2,$3,$4,$5,$5) ON CONFLICT(id) DO UPDATE "
          "SET name=EXCLUDED.name, description=EXCLUDED.description, "
          "tags=EXCLUDED.tags, updated_at=EXCLUDED.updated_at "
          "RETURNING (xmax = 0)",
          Params()
              .Text(m.id)
              .Text(m.name)
              .Text(m.description)
              .Text(TagsToJson(m.tags))
              .Text(now));
      tx.Notify(m.id, "");
      return r.Rows() == 1 && r.Text(0, 0) == "t";
    });
  }

  std::optional<Material> GetMaterial(const std::string& id) override {
    return Read([&](PGconn* c) -> std::optional<Material> {
      const Result r = Exec(c,
                            "SELECT id,name,description,tags,created_at,"
                            "updated_at FROM materials WHERE id=$1",
                            Params().Text(id));
      if (r.Rows() == 0) return std::nullopt;
      return ReadMaterial(r, 0);
    });
  }

  std::vector<Material> ListMaterials() override {
    return Read([&](PGconn* c) {
      const Result r = Exec(c,
                            "SELECT id,name,description,tags,created_at,"
                            "updated_at FROM materials ORDER BY id COLLATE "
                            "\"C\"");
      std::vector<Material> out;
      for (int i = 0; i < r.Rows(); ++i) out.push_back(ReadMaterial(r, i));
      return out;
    });
  }

  bool DeleteMaterial(const std::string& id) override {
    return Write([&](Tx& tx) {
      tx.Exec("DELETE FROM jobs WHERE material=$1", Params().Text(id));
      const Result r =
          tx.Exec("DELETE FROM materials WHERE id=$1", Params().Text(id));
      tx.Notify(id, "");
      return r.Affected() > 0;
    });
  }

  // --- fingertips ----------------------------------------------------------
  bool PutFingertip(const Fingertip& f) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "INSERT INTO fingertips(id,name,description,created_at) "
          "VALUES($1,$2,$3,$4) ON CONFLICT(id) DO UPDATE SET "
          "name=EXCLUDED.name, description=EXCLUDED.description "
          "RETURNING (xmax = 0)",
          Params()
              .Text(f.id)
              .Text(f.name)
              .Text(f.description)
              .Text(NowIso8601()));
      return r.Rows() == 1 && r.Text(0, 0) == "t";
    });
  }

  std::optional<Fingertip> GetFingertip(const std::string& id) override {
    return Read([&](PGconn* c) -> std::optional<Fingertip> {
      const Result r = Exec(c,
                            "SELECT id,name,description,created_at FROM "
                            "fingertips WHERE id=$1",
                            Params().Text(id));
      if (r.Rows() == 0) return std::nullopt;
      return Fingertip{r.Text(0, 0), r.Text(0, 1), r.Text(0, 2), r.Text(0, 3)};
    });
  }

  std::vector<Fingertip> ListFingertips() override {
    return Read([&](PGconn* c) {
      const Result r = Exec(c,
                            "SELECT id,name,description,created_at FROM "
                            "fingertips ORDER BY id COLLATE \"C\"");
      std::vector<Fingertip> out;
      for (int i = 0; i < r.Rows(); ++i)
        out.push_back(
            Fingertip{r.Text(i, 0), r.Text(i, 1), r.Text(i, 2), r.Text(i, 3)});
      return out;
    });
  }

  // --- strokes and models --------------------------------------------------
  UploadCommit CommitUpload(const StrokeRecord& stroke,
                            const ModelRecord& model) override {
    return Write([&](Tx& tx) {
      UploadCommit out;
      const std::string now = NowIso8601();
      const Result created = tx.Exec(
          "INSERT INTO materials(id,name,description,tags,created_at,"
          "updated_at) VALUES($1,$1,'','[]',$2,$2) ON CONFLICT(id) DO "
          "NOTHING RETURNING id",
          Params().Text(stroke.material).Text(now));
      out.material_created = created.Rows() == 1;
      EnsureFingertip(tx, stroke.fingertip, now);
      const Result s = tx.Exec(
          "INSERT INTO strokes(material,fingertip,robot,received_at,samples,"
          "csv) VALUES($1,$2,$3,$4,$5,$6) RETURNING id",
          Params()
              .Text(stroke.material)
              .Text(stroke.fingertip)
              .Text(stroke.robot)
              .Text(now)
              .Int(stroke.samples)
              .Bytes(stroke.csv));
      out.stroke_id = s.Int(0, 0);
      ModelRecord m = model;
      m.stroke_id = out.stroke_id;
      out.version = InsertModel(tx, m, now);
      tx.Exec(std::string("UPDATE jobs SET state='fitted', detail=$1, "
                          "updated_at=$2 WHERE material=$3 AND fingertip=$4 "
                          "AND state IN ") +
                  kOpenStates,
              Params()
                  .Text("model version " + std::to_string(out.version) +
                        " from stroke " + std::to_string(out.stroke_id))
                  .Text(now)
                  .Text(stroke.material)
                  .Text(stroke.fingertip));
      tx.Notify(stroke.material, stroke.fingertip);
      return out;
    });
  }

  int AddModelVersion(const ModelRecord& model) override {
    return Write([&](Tx& tx) {
      const std::string now = NowIso8601();
      EnsureFingertip(tx, model.fingertip, now);
      const int v = InsertModel(tx, model, now);
      tx.Notify(model.material, model.fingertip);
      return v;
    });
  }

  std::vector<StrokeRecord> ListStrokes(const std::string& material,
                                        const std::string& fingertip) override {
    return Read([&](PGconn* c) {
      const Result r = Exec(c,
                            "SELECT id,material,fingertip,robot,received_at,"
                            "samples FROM strokes WHERE material=$1 AND "
                            "fingertip=$2 ORDER BY id",
                            Params().Text(material).Text(fingertip));
      std::vector<StrokeRecord> out;
      for (int i = 0; i < r.Rows(); ++i)
        out.push_back(StrokeRecord{r.Int(i, 0),
                                   r.Text(i, 1),
                                   r.Text(i, 2),
                                   r.Text(i, 3),
                                   r.Text(i, 4),
                                   r.Int(i, 5),
                                   {}});
      return out;
    });
  }

  std::optional<StrokeRecord> GetStroke(std::int64_t id) override {
    return Read([&](PGconn* c) -> std::optional<StrokeRecord> {
      const Result r = Exec(c,
                            "SELECT id,material,fingertip,robot,received_at,"
                            "samples,csv FROM strokes WHERE id=$1",
                            Params().Int(id));
      if (r.Rows() == 0) return std::nullopt;
      return StrokeRecord{r.Int(0, 0),
                          r.Text(0, 1),
                          r.Text(0, 2),
                          r.Text(0, 3),
                          r.Text(0, 4),
                          r.Int(0, 5),
                          r.Bytes(0, 6)};
    });
  }

  std::optional<ModelRecord> GetLatestModel(
      const std::string& material, const std::string& fingertip) override {
    return Read([&](PGconn* c) -> std::optional<ModelRecord> {
      const Result r = Exec(c,
                            "SELECT material,fingertip,version,created_at,"
                            "reason,stroke_id,json FROM models WHERE "
                            "material=$1 AND fingertip=$2 ORDER BY version "
                            "DESC LIMIT 1",
                            Params().Text(material).Text(fingertip));
      if (r.Rows() == 0) return std::nullopt;
      return ReadModel(r, 0);
    });
  }

  std::optional<ModelRecord> GetModel(const std::string& material,
                                      const std::string& fingertip,
                                      int version) override {
    return Read([&](PGconn* c) -> std::optional<ModelRecord> {
      const Result r =
          Exec(c,
               "SELECT material,fingertip,version,created_at,reason,"
               "stroke_id,json FROM models WHERE material=$1 AND "
               "fingertip=$2 AND version=$3",
               Params().Text(material).Text(fingertip).Int(version));
      if (r.Rows() == 0) return std::nullopt;
      return ReadModel(r, 0);
    });
  }

  std::vector<ModelRecord> ListModels(const std::string& material,
                                      const std::string& fingertip) override {
    return Read([&](PGconn* c) {
      const Result r = Exec(c,
                            "SELECT material,fingertip,version,created_at,"
                            "reason,stroke_id,'' FROM models WHERE "
                            "material=$1 AND fingertip=$2 ORDER BY version",
                            Params().Text(material).Text(fingertip));
      std::vector<ModelRecord> out;
      for (int i = 0; i < r.Rows(); ++i) out.push_back(ReadModel(r, i));
      return out;
    });
  }

  // --- identification jobs ------------------------------------------------
  IdentificationJob RequestIdentification(
      const IdentificationJob& job) override {
    return Write([&](Tx& tx) {
      // Serialise job creation per pair across daemons.
      tx.Exec("SELECT pg_advisory_xact_lock(hashtext($1))",
              Params().Text("job\n" + job.material + "\n" + job.fingertip));
      const Result open =
          tx.Exec(std::string("SELECT ") + kJobColumns +
                      " FROM jobs WHERE material=$1 AND fingertip=$2 AND "
                      "state IN " +
                      kOpenStates + " ORDER BY id DESC LIMIT 1",
                  Params().Text(job.material).Text(job.fingertip));
      if (open.Rows() == 1) return ReadJob(open, 0);
      const std::string now = NowIso8601();
      const Result r = tx.Exec(
          std::string("INSERT INTO jobs(material,fingertip,state,plan_json,"
                      "detail,requested_by,created_at,updated_at) "
                      "VALUES($1,$2,$3,$4,$5,$6,$7,$7) RETURNING ") +
              kJobColumns,
          Params()
              .Text(job.material)
              .Text(job.fingertip)
              .Text(job.state.empty() ? std::string("requested") : job.state)
              .Text(job.plan_json)
              .Text(job.detail)
              .Text(job.requested_by)
              .Text(now));
      return ReadJob(r, 0);
    });
  }

  bool UpdateJob(std::int64_t id,
                 const std::string& state,
                 const std::string& detail) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "UPDATE jobs SET state=$1, detail=$2, updated_at=$3 WHERE id=$4",
          Params().Text(state).Text(detail).Text(NowIso8601()).Int(id));
      return r.Affected() > 0;
    });
  }

  std::optional<IdentificationJob> GetJob(std::int64_t id) override {
    return Read([&](PGconn* c) -> std::optional<IdentificationJob> {
      const Result r =
          Exec(c,
               std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id=$1",
               Params().Int(id));
      if (r.Rows() == 0) return std::nullopt;
      return ReadJob(r, 0);
    });
  }

  std::vector<IdentificationJob> ListJobs(bool open_only) override {
    return Read([&](PGconn* c) {
      std::string sql = std::string("SELECT ") + kJobColumns + " FROM jobs";
      if (open_only) sql += std::string(" WHERE state IN ") + kOpenStates;
      sql += " ORDER BY id DESC";
      const Result r = Exec(c, sql);
      std::vector<IdentificationJob> out;
      for (int i = 0; i < r.Rows(); ++i) out.push_back(ReadJob(r, i));
      return out;
    });
  }

  std::vector<IdentificationJob> ListJobsPage(bool open_only,
                                              std::int64_t after,
                                              int limit) override {
    return Read([&](PGconn* c) {
      std::string sql =
          std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id < $1";
      if (open_only) sql += std::string(" AND state IN ") + kOpenStates;
      sql += " ORDER BY id DESC LIMIT $2";
      const Result r = Exec(
          c,
          sql,
          Params()
              .Int(after > 0 ? after : std::numeric_limits<std::int64_t>::max())
              .Int(std::max(limit, 1)));
      std::vector<IdentificationJob> out;
      for (int i = 0; i < r.Rows(); ++i) out.push_back(ReadJob(r, i));
      return out;
    });
  }

  std::optional<IdentificationJob> DoClaimJob(std::int64_t id,
                                              const std::string& worker,
                                              int lease_s) override {
    return Write([&](Tx& tx) -> std::optional<IdentificationJob> {
      // A job row locked by another daemon's claim is skipped, not waited
      // for: that daemon is taking it.
      const Result row = tx.Exec(
          std::string("SELECT claimed_by, updated_at < to_char((now() AT "
                      "TIME ZONE 'UTC') - make_interval(secs => $2), "
                      "'YYYY-MM-DD\"T\"HH24:MI:SS.MS\"Z\"') FROM jobs WHERE "
                      "id=$1 AND state IN ") +
              kOpenStates + " FOR UPDATE SKIP LOCKED",
          Params().Int(id).Int(lease_s));
      if (row.Rows() == 0) return std::nullopt;
      const std::string by = row.Text(0, 0);
      const bool expired = row.Text(0, 1) == "t";
      if (!by.empty() && by != worker && !expired) return std::nullopt;
      const Result r = tx.Exec(
          std::string("UPDATE jobs SET claimed_by=$1, updated_at=$2 WHERE "
                      "id=$3 RETURNING ") +
              kJobColumns,
          Params().Text(worker).Text(NowIso8601()).Int(id));
      return ReadJob(r, 0);
    });
  }

  bool PutJobStroke(std::int64_t job_id,
                    int stroke,
                    const std::string& csv) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "INSERT INTO job_strokes(job_id,stroke,csv) SELECT $1,$2,$3 WHERE "
          "EXISTS (SELECT 1 FROM jobs WHERE id=$1) ON CONFLICT (job_id,stroke) "
          "DO UPDATE SET csv=EXCLUDED.csv RETURNING job_id",
          Params().Int(job_id).Int(stroke).Bytes(csv));
      return r.Rows() == 1;
    });
  }

  std::vector<std::pair<int, std::string>> ListJobStrokes(
      std::int64_t job_id) override {
    return Read([&](PGconn* c) {
      const Result r = Exec(c,
                            "SELECT stroke,csv FROM job_strokes WHERE "
                            "job_id=$1 ORDER BY stroke",
                            Params().Int(job_id));
      std::vector<std::pair<int, std::string>> out;
      for (int i = 0; i < r.Rows(); ++i)
        out.emplace_back(static_cast<int>(r.Int(i, 0)), r.Bytes(i, 1));
      return out;
    });
  }

  void DeleteJobStrokes(std::int64_t job_id) override {
    Write([&](Tx& tx) {
      tx.Exec("DELETE FROM job_strokes WHERE job_id=$1", Params().Int(job_id));
      return true;
    });
  }

  // --- images ---------------------------------------------------------------
  std::int64_t AddImage(const ImageRecord& image) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "INSERT INTO images(material,mime,features,created_at) "
          "VALUES($1,$2,$3,$4) RETURNING id",
          Params()
              .Text(image.material)
              .Text(image.mime)
              .Bytes(image.features)
              .Text(NowIso8601()));
      return r.Int(0, 0);
    });
  }

  std::vector<ImageRecord> ListImages() override {
    return Read([&](PGconn* c) {
      const Result r = Exec(c,
                            "SELECT id,material,mime,features,created_at FROM "
                            "images ORDER BY id");
      std::vector<ImageRecord> out;
      for (int i = 0; i < r.Rows(); ++i)
        out.push_back(ImageRecord{r.Int(i, 0),
                                  r.Text(i, 1),
                                  r.Text(i, 2),
                                  r.Bytes(i, 3),
                                  r.Text(i, 4)});
      return out;
    });
  }

  // --- robots ----------------------------------------------------------------
  bool PutRobot(const RobotRecord& robot) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "INSERT INTO robots(id,json,created_at,updated_at) "
          "VALUES($1,$2,$3,$3) ON CONFLICT(id) DO UPDATE SET "
          "json=EXCLUDED.json, updated_at=EXCLUDED.updated_at "
          "RETURNING (xmax = 0)",
          Params().Text(robot.id).Text(robot.json).Text(NowIso8601()));
      return r.Rows() == 1 && r.Text(0, 0) == "t";
    });
  }

  std::optional<RobotRecord> GetRobot(const std::string& id) override {
    return Read([&](PGconn* c) -> std::optional<RobotRecord> {
      const Result r = Exec(c,
                            "SELECT id,json,created_at,updated_at FROM robots "
                            "WHERE id=$1",
                            Params().Text(id));
      if (r.Rows() == 0) return std::nullopt;
      return RobotRecord{
          r.Text(0, 0), r.Text(0, 1), r.Text(0, 2), r.Text(0, 3)};
    });
  }

  // --- tokens and audit -----------------------------------------------------
  bool AddToken(const TokenRecord& t) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "INSERT INTO tokens(id,name,role,hash,created_at) "
          "VALUES($1,$2,$3,$4,$5) ON CONFLICT(id) DO NOTHING RETURNING id",
          Params().Text(t.id).Text(t.name).Text(t.role).Text(t.hash).Text(
              NowIso8601()));
      return r.Rows() == 1;
    });
  }

  std::optional<TokenRecord> FindTokenByHash(const std::string& hash) override {
    return Read([&](PGconn* c) -> std::optional<TokenRecord> {
      const Result r = Exec(c,
                            "SELECT id,name,role,hash,created_at,revoked_at "
                            "FROM tokens WHERE hash=$1",
                            Params().Text(hash));
      if (r.Rows() == 0) return std::nullopt;
      return ReadToken(r, 0);
    });
  }

  std::vector<TokenRecord> ListTokens() override {
    return Read([&](PGconn* c) {
      const Result r = Exec(c,
                            "SELECT id,name,role,hash,created_at,revoked_at "
                            "FROM tokens ORDER BY seq");
      std::vector<TokenRecord> out;
      for (int i = 0; i < r.Rows(); ++i) out.push_back(ReadToken(r, i));
      return out;
    });
  }

  bool RevokeToken(const std::string& id) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "UPDATE tokens SET revoked_at=$1 WHERE id=$2 AND revoked_at=''",
          Params().Text(NowIso8601()).Text(id));
      return r.Affected() > 0;
    });
  }

  std::int64_t AppendAudit(const AuditEntry& e) override {
    return Write([&](Tx& tx) {
      const Result r = tx.Exec(
          "INSERT INTO audit(at,actor,role,remote,action,material,detail) "
          "VALUES($1,$2,$3,$4,$5,$6,$7) RETURNING id",
          Params()
              .Text(NowIso8601())
              .Text(e.actor)
              .Text(e.role)
              .Text(e.remote)
              .Text(e.action)
              .Text(e.material)
              .Text(e.detail));
      return r.Int(0, 0);
    });
  }

  std::vector<AuditEntry> ListAudit(std::int64_t after_id,
                                    int limit,
                                    const std::string& material) override {
    return Read([&](PGconn* c) {
      const Result r = Exec(
          c,
          "SELECT id,at,actor,role,remote,action,material,detail FROM "
          "audit WHERE id>$1 AND ($2='' OR material=$2) ORDER BY id "
          "LIMIT $3",
          Params().Int(after_id).Text(material).Int(limit < 0 ? 0 : limit));
      std::vector<AuditEntry> out;
      for (int i = 0; i < r.Rows(); ++i)
        out.push_back(AuditEntry{r.Int(i, 0),
                                 r.Text(i, 1),
                                 r.Text(i, 2),
                                 r.Text(i, 3),
                                 r.Text(i, 4),
                                 r.Text(i, 5),
                                 r.Text(i, 6),
                                 r.Text(i, 7)});
      return out;
    });
  }

  // --- housekeeping ----------------------------------------------------------
  int SchemaVersion() override {
    return Read([&](PGconn* c) {
      return static_cast<int>(
          Exec(c, "SELECT COALESCE(MAX(version),0) FROM schema_version")
              .Int(0, 0));
    });
  }

  std::string BackendName() const override { return "postgresql"; }

  std::string CheckIntegrity() override {
    return Read([&](PGconn* c) {
      std::string out;
      const Result r = Exec(c,
                            "SELECT material,fingertip,COUNT(*),MAX(version) "
                            "FROM models GROUP BY material,fingertip HAVING "
                            "COUNT(*) <> MAX(version)");
      for (int i = 0; i < r.Rows(); ++i)
        out += "models of " + r.Text(i, 0) + "/" + r.Text(i, 1) +
               ": versions are not 1.." + r.Text(i, 3) + "\n";
      return out;
    });
  }

  void SetChangeListener(ChangeListener listener) override {
    StopListener();
    if (!listener) return;
    listener_ = std::move(listener);
    listen_stop_ = false;
    listen_thread_ = std::thread([this] { ListenLoop(); });
  }

 private:
  static constexpr const char* kJobColumns =
      "id,material,fingertip,state,plan_json,detail,requested_by,created_at,"
      "updated_at";

  /// One transaction on a leased connection; rolled back unless committed.
  class Tx {
   public:
    Tx(PGconn* c, const std::string& origin) : c_(c), origin_(origin) {}
    ~Tx() {
      if (open_) PQclear(PQexec(c_, "ROLLBACK"));
    }
    Tx(const Tx&) = delete;
    Tx& operator=(const Tx&) = delete;
    void Begin() {
      internal::Exec(c_, "BEGIN");
      open_ = true;
    }
    Result Exec(const std::string& sql, const Params& p = Params()) {
      return internal::Exec(c_, sql, p);
    }
    void Script(const char* sql) { internal::ExecScript(c_, sql); }
    /// Queues a change notification, delivered at commit.
    void Notify(const std::string& material, const std::string& fingertip) {
      Exec("SELECT pg_notify($1,$2)",
           Params().Text(kChannel).Text(origin_ + "\n" + material + "\n" +
                                        fingertip));
    }
    void Commit() {
      commit_sent_ = true;
      internal::Exec(c_, "COMMIT");
      open_ = false;
    }
    bool commit_sent() const { return commit_sent_; }

   private:
    PGconn* c_;
    const std::string& origin_;
    bool open_ = false;
    bool commit_sent_ = false;
  };

  /// A pooled connection, returned (or closed when broken) on destruction.
  class Lease {
   public:
    Lease(PgStore* s, PGconn* c, bool fresh) : s_(s), c_(c), fresh_(fresh) {}
    ~Lease() { s_->Release(c_); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    PGconn* get() const { return c_; }
    bool fresh() const { return fresh_; }

   private:
    PgStore* s_;
    PGconn* c_;
    bool fresh_;
  };

  Lease Acquire() {
    std::unique_lock<std::mutex> lock(pool_mu_);
    pool_cv_.wait(lock,
                  [&] { return !idle_.empty() || open_ < kMaxConnections; });
    if (!idle_.empty()) {
      PGconn* c = idle_.back();
      idle_.pop_back();
      return Lease(this, c, false);
    }
    ++open_;
    lock.unlock();
    try {
      return Lease(this, Connect(url_), true);
    } catch (...) {
      lock.lock();
      --open_;
      pool_cv_.notify_one();
      throw;
    }
  }

  void Release(PGconn* c) {
    const bool healthy =
        PQstatus(c) == CONNECTION_OK && PQtransactionStatus(c) == PQTRANS_IDLE;
    if (!healthy) PQfinish(c);
    std::lock_guard<std::mutex> lock(pool_mu_);
    if (healthy)
      idle_.push_back(c);
    else
      --open_;
    pool_cv_.notify_one();
  }

  /// Closes the idle connections (after one was found dead: the server
  /// restarted, so the next call connects afresh).
  void DropIdle() {
    std::lock_guard<std::mutex> lock(pool_mu_);
    for (PGconn* c : idle_) PQfinish(c);
    open_ -= static_cast<int>(idle_.size());
    idle_.clear();
    pool_cv_.notify_all();
  }

  /// Runs a read; a pooled connection that turns out dead (server
  /// restarted meanwhile) is replaced once by a fresh one.
  template <typename F>
  std::invoke_result_t<F&, PGconn*> Read(F&& f) {
    for (int attempt = 0;; ++attempt) {
      Lease lease = Acquire();
      try {
        return f(lease.get());
      } catch (const StoreUnavailable&) {
        if (lease.fresh() || attempt > 0) throw;
        DropIdle();  // the others are as dead as this one
      }
    }
  }

  /// Runs `f` in a transaction and commits. Retried once on a fresh
  /// connection when a pooled one was dead before COMMIT was sent (the
  /// server then rolled the transaction back); a failure during COMMIT is
  /// reported (not acknowledged), never retried.
  template <typename F>
  std::invoke_result_t<F&, Tx&> Write(F&& f) {
    for (int attempt = 0;; ++attempt) {
      Lease lease = Acquire();
      Tx tx(lease.get(), origin_);
      try {
        tx.Begin();
        auto out = f(tx);
        tx.Commit();
        return out;
      } catch (const StoreUnavailable&) {
        if (lease.fresh() || attempt > 0 || tx.commit_sent()) {
          DropIdle();
          throw;
        }
        DropIdle();  // the others are as dead as this one
      }
    }
  }

  void Migrate() {
    Write([&](Tx& tx) {
      // One daemon at a time migrates; the others wait and find it done.
      tx.Exec("SELECT pg_advisory_xact_lock(7406372511)");
      tx.Exec(
          "CREATE TABLE IF NOT EXISTS schema_version(version INTEGER NOT "
          "NULL, applied_at TEXT NOT NULL)");
      const int have = static_cast<int>(
          tx.Exec("SELECT COALESCE(MAX(version),0) FROM schema_version")
              .Int(0, 0));
      const int want =
          static_cast<int>(sizeof(kPgMigrations) / sizeof(kPgMigrations[0]));
      if (have > want) {
        throw std::runtime_error(
            "postgresql: database schema version " + std::to_string(have) +
            " is newer than this frictiond (" + std::to_string(want) + ")");
      }
      for (int v = have; v < want; ++v) {
        tx.Script(kPgMigrations[v]);
        if (v == 0) {
          tx.Exec(
              "INSERT INTO fingertips(id,name,description,created_at) "
              "VALUES('default','default','fingertip used when none is "
              "named',$1)",
              Params().Text(NowIso8601()));
        }
        tx.Exec("INSERT INTO schema_version(version,applied_at) VALUES($1,$2)",
                Params().Int(v + 1).Text(NowIso8601()));
      }
      return 0;
    });
  }

  static void EnsureFingertip(Tx& tx,
                              const std::string& id,
                              const std::string& now) {
    tx.Exec(
        "INSERT INTO fingertips(id,name,description,created_at) "
        "VALUES($1,$1,'',$2) ON CONFLICT(id) DO NOTHING",
        Params().Text(id).Text(now));
  }

  /// Appends version newest + 1 of the pair. The material row lock (FOR NO
  /// KEY UPDATE: compatible with the key-share locks that foreign keys of
  /// strokes and models take, so no deadlock) orders concurrent writers of a
  /// material across daemons: the second waits for the first to commit and
  /// then sees its version. The primary key is the backstop.
  static int InsertModel(Tx& tx, const ModelRecord& m, const std::string& now) {
    const Result locked =
        tx.Exec("SELECT 1 FROM materials WHERE id=$1 FOR NO KEY UPDATE",
                Params().Text(m.material));
    if (locked.Rows() == 0)
      throw std::runtime_error("postgresql: no material '" + m.material + "'");
    const int version =
        static_cast<int>(tx.Exec("SELECT COALESCE(MAX(version),0) FROM models "
                                 "WHERE material=$1 AND fingertip=$2",
                                 Params().Text(m.material).Text(m.fingertip))
                             .Int(0, 0)) +
        1;
    tx.Exec(
        "INSERT INTO models(material,fingertip,version,created_at,reason,"
        "stroke_id,json) VALUES($1,$2,$3,$4,$5,$6,$7)",
        Params()
            .Text(m.material)
            .Text(m.fingertip)
            .Int(version)
            .Text(now)
            .Text(m.reason)
            .Int(m.stroke_id)
            .Text(m.json));
    return version;
  }

  static Material ReadMaterial(const Result& r, int i) {
    return Material{r.Text(i, 0),
                    r.Text(i, 1),
                    r.Text(i, 2),
                    TagsFromJson(r.Text(i, 3)),
                    r.Text(i, 4),
                    r.Text(i, 5)};
  }
  static ModelRecord ReadModel(const Result& r, int i) {
    return ModelRecord{r.Text(i, 0),
                       r.Text(i, 1),
                       static_cast<int>(r.Int(i, 2)),
                       r.Text(i, 3),
                       r.Text(i, 4),
                       r.Int(i, 5),
                       r.Text(i, 6)};
  }
  static IdentificationJob ReadJob(const Result& r, int i) {
    return IdentificationJob{r.Int(i, 0),
                             r.Text(i, 1),
                             r.Text(i, 2),
                             r.Text(i, 3),
                             r.Text(i, 4),
                             r.Text(i, 5),
                             r.Text(i, 6),
                             r.Text(i, 7),
                             r.Text(i, 8)};
  }
  static TokenRecord ReadToken(const Result& r, int i) {
    return TokenRecord{r.Text(i, 0),
                       r.Text(i, 1),
                       r.Text(i, 2),
                       r.Text(i, 3),
                       r.Text(i, 4),
                       r.Text(i, 5)};
  }

  // --- change listener -------------------------------------------------------
  void StopListener() {
    listen_stop_ = true;
    if (listen_thread_.joinable()) listen_thread_.join();
  }

  /// Waits on its own connection for notifications and reports those of
  /// other processes. On connection loss it reconnects every 200 ms and then
  /// reports ("", "") since notifications may have been missed meanwhile.
  void ListenLoop() {
    PGconn* c = nullptr;
    bool missed = false;
    while (!listen_stop_) {
      if (!c) {
        try {
          c = Connect(url_);
          Exec(c, std::string("LISTEN ") + kChannel);
          if (missed) listener_("", "");
          missed = false;
        } catch (const std::exception&) {
          if (c) PQfinish(c);
          c = nullptr;
          missed = true;
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
          continue;
        }
      }
      pollfd pfd{PQsocket(c), POLLIN, 0};
      const int n = ::poll(&pfd, 1, 100);
      if (n < 0) continue;
      if (PQconsumeInput(c) == 0 || PQstatus(c) != CONNECTION_OK) {
        PQfinish(c);
        c = nullptr;
        missed = true;
        continue;
      }
      while (PGnotify* note = PQnotifies(c)) {
        const std::string payload = note->extra ? note->extra : "";
        PQfreemem(note);
        const auto a = payload.find('\n');
        const auto b = a == std::string::npos ? a : payload.find('\n', a + 1);
        if (b == std::string::npos) continue;
        if (payload.compare(0, a, origin_) == 0) continue;  // our own write
        try {
          listener_(payload.substr(a + 1, b - a - 1), payload.substr(b + 1));
        } catch (const std::exception&) {
          // A failing listener must not stop the notifications.
        }
      }
    }
    if (c) PQfinish(c);
  }

  const std::string url_;
  std::string origin_;  // random id of this store, in every notification
  std::mutex pool_mu_;
  std::condition_variable pool_cv_;
  std::vector<PGconn*> idle_;
  int open_ = 0;  // connections handed out or idle
  ChangeListener listener_;
  std::atomic<bool> listen_stop_{false};
  std::thread listen_thread_;
};

std::unique_ptr<Store> OpenPgStore(const std::string& url) {
  return std::make_unique<PgStore>(url);
}

}  // namespace internal
}  // namespace frictiond

#endif  // FRICTIOND_HAVE_POSTGRES
