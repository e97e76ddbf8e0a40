// The store's behaviour, written once for every back end: schema migration,
// row mapping, the commit rules of uploads, versions, jobs, tokens and
// audit, and the error texts. It talks to a database only through
// connection.h (a Driver and its Connections); sqlite_driver.cc and
// pg_driver.cc hold the driver code. docs/storage.md describes the layers.
//
// Adding a Store method: declare it in store.h, implement it here once
// (SQL that runs on every dialect; a dialect difference becomes a Dialect
// field), and add a TEST_P case to storage/test/store_test.cc.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include <nlohmann/json.hpp>

#include "frictiond/storage/job_state.h"
#include "frictiond/storage/store.h"

#include "connection.h"
#include "migrations.h"

namespace frictiond {

namespace {

std::string FormatIso8601(std::chrono::system_clock::time_point when) {
  using namespace std::chrono;
  const std::time_t t = system_clock::to_time_t(when);
  const int ms = static_cast<int>(
      duration_cast<milliseconds>(when.time_since_epoch()).count() % 1000);
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

}  // namespace

std::string NowIso8601() {
  return FormatIso8601(std::chrono::system_clock::now());
}

namespace internal {

// --- Rows --------------------------------------------------------------------

std::string Rows::Take(int row, int col) {
  Cell& c = cells_.at(static_cast<std::size_t>(row * columns_ + col));
  if (c.is_integer) return std::to_string(c.integer);
  return std::move(c.text);
}

std::int64_t Rows::Int(int row, int col) const {
  const Cell& c = cells_.at(static_cast<std::size_t>(row * columns_ + col));
  if (c.is_integer) return c.integer;
  try {
    std::size_t used = 0;
    const long long v = std::stoll(c.text, &used);
    if (used == c.text.size()) return v;
  } catch (const std::exception&) {
  }
  throw std::runtime_error("store: column " + std::to_string(col) +
                           " is not an integer: '" + c.text + "'");
}

namespace {

// The open job states, in job_state.h's one spelling.
const std::string& kOpenStates = OpenJobStatesSql();

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

// --- row mapping: column lists and the records they fill ------------------

#define FRICTIOND_MATERIAL_COLUMNS \
  "id,name,description,tags,created_at,updated_at"
Material ReadMaterial(Rows& r, int i) {
  return Material{r.Take(i, 0),
                  r.Take(i, 1),
                  r.Take(i, 2),
                  TagsFromJson(r.Take(i, 3)),
                  r.Take(i, 4),
                  r.Take(i, 5)};
}

#define FRICTIOND_FINGERTIP_COLUMNS "id,name,description,created_at"
Fingertip ReadFingertip(Rows& r, int i) {
  return Fingertip{r.Take(i, 0), r.Take(i, 1), r.Take(i, 2), r.Take(i, 3)};
}

/// Listings leave out the csv (an empty seventh column).
#define FRICTIOND_STROKE_COLUMNS \
  "id,material,fingertip,robot,received_at,samples"
StrokeRecord ReadStroke(Rows& r, int i) {
  return StrokeRecord{r.Int(i, 0),
                      r.Take(i, 1),
                      r.Take(i, 2),
                      r.Take(i, 3),
                      r.Take(i, 4),
                      r.Int(i, 5),
                      r.Take(i, 6)};
}

/// Listings select '' for the json.
#define FRICTIOND_MODEL_COLUMNS \
  "material,fingertip,version,created_at,reason,stroke_id"
ModelRecord ReadModel(Rows& r, int i) {
  return ModelRecord{r.Take(i, 0),
                     r.Take(i, 1),
                     static_cast<int>(r.Int(i, 2)),
                     r.Take(i, 3),
                     r.Take(i, 4),
                     r.Int(i, 5),
                     r.Take(i, 6)};
}

#define FRICTIOND_JOB_COLUMNS                                             \
  "id,material,fingertip,state,plan_json,detail,requested_by,created_at," \
  "updated_at"
IdentificationJob ReadJob(Rows& r, int i) {
  return IdentificationJob{r.Int(i, 0),
                           r.Take(i, 1),
                           r.Take(i, 2),
                           r.Take(i, 3),
                           r.Take(i, 4),
                           r.Take(i, 5),
                           r.Take(i, 6),
                           r.Take(i, 7),
                           r.Take(i, 8)};
}

#define FRICTIOND_IMAGE_COLUMNS "id,material,mime,features,created_at"
ImageRecord ReadImage(Rows& r, int i) {
  return ImageRecord{
      r.Int(i, 0), r.Take(i, 1), r.Take(i, 2), r.Take(i, 3), r.Take(i, 4)};
}

#define FRICTIOND_ROBOT_COLUMNS "id,json,created_at,updated_at"
RobotRecord ReadRobot(Rows& r, int i) {
  return RobotRecord{r.Take(i, 0), r.Take(i, 1), r.Take(i, 2), r.Take(i, 3)};
}

#define FRICTIOND_TOKEN_COLUMNS "id,name,role,hash,created_at,revoked_at"
TokenRecord ReadToken(Rows& r, int i) {
  return TokenRecord{r.Take(i, 0),
                     r.Take(i, 1),
                     r.Take(i, 2),
                     r.Take(i, 3),
                     r.Take(i, 4),
                     r.Take(i, 5)};
}

#define FRICTIOND_AUDIT_COLUMNS "id,at,actor,role,remote,action,material,detail"
AuditEntry ReadAudit(Rows& r, int i) {
  return AuditEntry{r.Int(i, 0),
                    r.Take(i, 1),
                    r.Take(i, 2),
                    r.Take(i, 3),
                    r.Take(i, 4),
                    r.Take(i, 5),
                    r.Take(i, 6),
                    r.Take(i, 7)};
}

template <typename T>
std::optional<T> First(Rows r, T (*read)(Rows&, int)) {
  if (r.empty()) return std::nullopt;
  return read(r, 0);
}

template <typename T>
std::vector<T> All(Rows r, T (*read)(Rows&, int)) {
  std::vector<T> out;
  out.reserve(static_cast<std::size_t>(r.size()));
  for (int i = 0; i < r.size(); ++i) out.push_back(read(r, i));
  return out;
}

// --- the store ---------------------------------------------------------------

/// Store over a Driver. Copy: no; move: no.
class SqlStore final : public Store {
 public:
  explicit SqlStore(std::unique_ptr<Driver> driver)
      : driver_(std::move(driver)), d_(driver_->dialect()) {
    Migrate();
  }
  ~SqlStore() override = default;

  // --- materials -------------------------------------------------------------
  bool PutMaterial(const Material& m) override {
    return Write([&](Connection& c) {
      const std::string now = NowIso8601();
      const std::string tags = TagsToJson(m.tags);
      const Params p = Params()
                           .Text(m.id)
                           .Text(m.name)
                           .Text(m.description)
                           .Text(tags)
                           .Text(now);
      const bool created = InsertIfAbsent(
          c,
          "INSERT INTO materials(" FRICTIOND_MATERIAL_COLUMNS
          ") VALUES($1,$2,$3,$4,$5,$5) ON CONFLICT(id) DO NOTHING RETURNING id",
          p);
      if (!created) {
        c.Execute(
            "UPDATE materials SET name=$2, description=$3, tags=$4, "
            "updated_at=$5 WHERE id=$1",
            p);
      }
      c.Notify(m.id, "");
      return created;
    });
  }

  std::optional<Material> GetMaterial(const std::string& id) override {
    return Read([&](Connection& c) {
      return First(c.Execute("SELECT " FRICTIOND_MATERIAL_COLUMNS
                             " FROM materials WHERE id=$1",
                             Params().Text(id)),
                   ReadMaterial);
    });
  }

  std::vector<Material> ListMaterials() override {
    const std::string sql = std::string("SELECT " FRICTIOND_MATERIAL_COLUMNS
                                        " FROM materials ORDER BY id") +
                            d_.binary_collation;
    return Read(
        [&](Connection& c) { return All(c.Execute(sql), ReadMaterial); });
  }

  bool DeleteMaterial(const std::string& id) override {
    return Write([&](Connection& c) {
      c.Execute("DELETE FROM jobs WHERE material=$1", Params().Text(id));
      const bool deleted =
          c.Execute("DELETE FROM materials WHERE id=$1", Params().Text(id))
              .affected() > 0;
      c.Notify(id, "");
      return deleted;
    });
  }

  // --- fingertips ------------------------------------------------------------
  bool PutFingertip(const Fingertip& f) override {
    return Write([&](Connection& c) {
      const Params p = Params()
                           .Text(f.id)
                           .Text(f.name)
                           .Text(f.description)
                           .Text(NowIso8601());
      const bool created = InsertIfAbsent(
          c,
          "INSERT INTO fingertips(" FRICTIOND_FINGERTIP_COLUMNS
          ") VALUES($1,$2,$3,$4) ON CONFLICT(id) DO NOTHING RETURNING id",
          p);
      if (!created) {
        // $4 (the creation time) is unused here; bind only $1..$3.
        c.Execute("UPDATE fingertips SET name=$2, description=$3 WHERE id=$1",
                  Params().Text(f.id).Text(f.name).Text(f.description));
      }
      return created;
    });
  }

  std::optional<Fingertip> GetFingertip(const std::string& id) override {
    return Read([&](Connection& c) {
      return First(c.Execute("SELECT " FRICTIOND_FINGERTIP_COLUMNS
                             " FROM fingertips WHERE id=$1",
                             Params().Text(id)),
                   ReadFingertip);
    });
  }

  std::vector<Fingertip> ListFingertips() override {
    const std::string sql = std::string("SELECT " FRICTIOND_FINGERTIP_COLUMNS
                                        " FROM fingertips ORDER BY id") +
                            d_.binary_collation;
    return Read(
        [&](Connection& c) { return All(c.Execute(sql), ReadFingertip); });
  }

  // --- strokes and models ----------------------------------------------------
  using Store::CommitUpload;
  UploadCommit CommitUpload(const StrokeRecord& stroke,
                            const ModelRecord& model,
                            const AuditEntry* audit) override {
    // The audit detail is built before the transaction: a malformed one
    // throws here, before anything is written.
    nlohmann::json detail;
    if (audit) {
      detail = audit->detail.empty()
                   ? nlohmann::json::object()
                   : nlohmann::json::parse(audit->detail, nullptr, false);
      if (!detail.is_object())
        throw std::invalid_argument("audit detail: must be a JSON object");
    }
    return Write([&](Connection& c) {
      UploadCommit out;
      const std::string now = NowIso8601();
      out.material_created = InsertIfAbsent(
          c,
          "INSERT INTO materials(" FRICTIOND_MATERIAL_COLUMNS
          ") VALUES($1,$1,'','[]',$2,$2) ON CONFLICT(id) DO NOTHING "
          "RETURNING id",
          Params().Text(stroke.material).Text(now));
      EnsureFingertip(c, stroke.fingertip, now);
      out.stroke_id =
          c.Execute(
               "INSERT INTO strokes(material,fingertip,robot,received_at,"
               "samples,csv) VALUES($1,$2,$3,$4,$5,$6) RETURNING id",
               Params()
                   .Text(stroke.material)
                   .Text(stroke.fingertip)
                   .Text(stroke.robot)
                   .Text(now)
                   .Int(stroke.samples)
                   .Bytes(stroke.csv))
              .Int(0, 0);
      ModelRecord m = model;
      m.stroke_id = out.stroke_id;
      out.version = AppendModel(c, m, now);
      out.created_at = now;
      c.Execute(std::string("UPDATE jobs SET state='") +
                    JobStateName(JobState::kFitted) +
                    "', detail=$1, "
                    "updated_at=$2 WHERE material=$3 AND fingertip=$4 "
                    "AND state IN " +
                    kOpenStates,
                Params()
                    .Text("model version " + std::to_string(out.version) +
                          " from stroke " + std::to_string(out.stroke_id))
                    .Text(now)
                    .Text(stroke.material)
                    .Text(stroke.fingertip));
      if (audit) {
        AuditEntry e = *audit;
        nlohmann::json d = detail;
        d["stroke_id"] = out.stroke_id;
        d["version"] = out.version;
        d["material_created"] = out.material_created;
        e.detail = d.dump();
        InsertAudit(c, e, now);
      }
      c.Notify(stroke.material, stroke.fingertip);
      return out;
    });
  }

  int AddModelVersion(const ModelRecord& model) override {
    return Write([&](Connection& c) {
      const std::string now = NowIso8601();
      EnsureFingertip(c, model.fingertip, now);
      const int version = AppendModel(c, model, now);
      c.Notify(model.material, model.fingertip);
      return version;
    });
  }

  std::vector<StrokeRecord> ListStrokes(const std::string& material,
                                        const std::string& fingertip) override {
    return Read([&](Connection& c) {
      return All(c.Execute("SELECT " FRICTIOND_STROKE_COLUMNS
                           ",'' FROM strokes WHERE material=$1 AND "
                           "fingertip=$2 ORDER BY id",
                           Params().Text(material).Text(fingertip)),
                 ReadStroke);
    });
  }

  std::optional<StrokeRecord> GetStroke(std::int64_t id) override {
    return Read([&](Connection& c) {
      return First(c.Execute("SELECT " FRICTIOND_STROKE_COLUMNS
                             ",csv FROM strokes WHERE id=$1",
                             Params().Int(id)),
                   ReadStroke);
    });
  }

  std::vector<StrokeRecord> ListStrokesAfter(const std::string& material,
                                             const std::string& fingertip,
                                             std::int64_t after_id,
                                             bool with_csv) override {
    return Read([&](Connection& c) {
      return All(
          c.Execute(std::string("SELECT " FRICTIOND_STROKE_COLUMNS) +
                        (with_csv ? ",csv" : ",''") +
                        " FROM strokes WHERE material=$1 AND "
                        "fingertip=$2 AND id>$3 ORDER BY id",
                    Params().Text(material).Text(fingertip).Int(after_id)),
          ReadStroke);
    });
  }

  std::optional<ModelRecord> GetLatestModel(
      const std::string& material, const std::string& fingertip) override {
    return Read([&](Connection& c) {
      return First(c.Execute("SELECT " FRICTIOND_MODEL_COLUMNS
                             ",json FROM models WHERE material=$1 AND "
                             "fingertip=$2 ORDER BY version DESC LIMIT 1",
                             Params().Text(material).Text(fingertip)),
                   ReadModel);
    });
  }

  std::optional<ModelRecord> GetModel(const std::string& material,
                                      const std::string& fingertip,
                                      int version) override {
    return Read([&](Connection& c) {
      return First(
          c.Execute("SELECT " FRICTIOND_MODEL_COLUMNS
                    ",json FROM models WHERE material=$1 AND fingertip=$2 "
                    "AND version=$3",
                    Params().Text(material).Text(fingertip).Int(version)),
          ReadModel);
    });
  }

  std::vector<ModelRecord> ListModels(const std::string& material,
                                      const std::string& fingertip) override {
    return Read([&](Connection& c) {
      return All(c.Execute("SELECT " FRICTIOND_MODEL_COLUMNS
                           ",'' FROM models WHERE material=$1 AND "
                           "fingertip=$2 ORDER BY version",
                           Params().Text(material).Text(fingertip)),
                 ReadModel);
    });
  }

  // --- identification jobs ---------------------------------------------------
  IdentificationJob RequestIdentification(
      const IdentificationJob& job) override {
    return Write([&](Connection& c) {
      // One open job per pair, also across daemons sharing the database.
      if (*d_.key_lock_sql)
        c.Execute(d_.key_lock_sql,
                  Params().Text("job\n" + job.material + "\n" + job.fingertip));
      Rows open = c.Execute(std::string("SELECT " FRICTIOND_JOB_COLUMNS
                                        " FROM jobs WHERE material=$1 AND "
                                        "fingertip=$2 AND state IN ") +
                                kOpenStates + " ORDER BY id DESC LIMIT 1",
                            Params().Text(job.material).Text(job.fingertip));
      if (!open.empty()) return ReadJob(open, 0);
      Rows created = c.Execute(
          "INSERT INTO jobs(material,fingertip,state,plan_json,detail,"
          "requested_by,created_at,updated_at) "
          "VALUES($1,$2,$3,$4,$5,$6,$7,$7) RETURNING " FRICTIOND_JOB_COLUMNS,
          Params()
              .Text(job.material)
              .Text(job.fingertip)
              .Text(job.state.empty() ? JobStateName(JobState::kRequested)
                                      : job.state)
              .Text(job.plan_json)
              .Text(job.detail)
              .Text(job.requested_by)
              .Text(NowIso8601()));
      return ReadJob(created, 0);
    });
  }

  bool UpdateJob(std::int64_t id,
                 const std::string& state,
                 const std::string& detail) override {
    return Write([&](Connection& c) {
      return c.Execute(
                  "UPDATE jobs SET state=$1, detail=$2, updated_at=$3 "
                  "WHERE id=$4",
                  Params().Text(state).Text(detail).Text(NowIso8601()).Int(id))
                 .affected() > 0;
    });
  }

  std::optional<IdentificationJob> GetJob(std::int64_t id) override {
    return Read([&](Connection& c) { return FindJob(c, id); });
  }

  std::vector<IdentificationJob> ListJobs(bool open_only) override {
    std::string sql = "SELECT " FRICTIOND_JOB_COLUMNS " FROM jobs";
    if (open_only) sql += std::string(" WHERE state IN ") + kOpenStates;
    sql += " ORDER BY id DESC";
    return Read([&](Connection& c) { return All(c.Execute(sql), ReadJob); });
  }

  std::vector<IdentificationJob> ListJobsPage(bool open_only,
                                              std::int64_t after,
                                              int limit) override {
    std::string sql =
        "SELECT " FRICTIOND_JOB_COLUMNS " FROM jobs WHERE id < $1";
    if (open_only) sql += std::string(" AND state IN ") + kOpenStates;
    sql += " ORDER BY id DESC LIMIT $2";
    return Read([&](Connection& c) {
      return All(
          c.Execute(
              sql,
              Params()
                  .Int(after > 0 ? after
                                 : std::numeric_limits<std::int64_t>::max())
                  .Int(std::max(limit, 1))),
          ReadJob);
    });
  }

  // --- strokes of open identification jobs -----------------------------------
  bool PutJobStroke(std::int64_t job_id,
                    int stroke,
                    const std::string& csv) override {
    return Write([&](Connection& c) {
      if (c.Execute("SELECT 1 FROM jobs WHERE id=$1", Params().Int(job_id))
              .empty())
        return false;
      c.Execute(
          "INSERT INTO job_strokes(job_id,stroke,csv) VALUES($1,$2,$3) "
          "ON CONFLICT(job_id,stroke) DO UPDATE SET csv=excluded.csv",
          Params().Int(job_id).Int(stroke).Bytes(csv));
      return true;
    });
  }

  std::vector<std::pair<int, std::string>> ListJobStrokes(
      std::int64_t job_id) override {
    return Read([&](Connection& c) {
      Rows r = c.Execute(
          "SELECT stroke,csv FROM job_strokes WHERE job_id=$1 ORDER BY stroke",
          Params().Int(job_id));
      std::vector<std::pair<int, std::string>> out;
      for (int i = 0; i < r.size(); ++i)
        out.emplace_back(static_cast<int>(r.Int(i, 0)), r.Take(i, 1));
      return out;
    });
  }

  void DeleteJobStrokes(std::int64_t job_id) override {
    Write([&](Connection& c) {
      c.Execute("DELETE FROM job_strokes WHERE job_id=$1",
                Params().Int(job_id));
    });
  }

  // --- images ----------------------------------------------------------------
  std::int64_t AddImage(const ImageRecord& image) override {
    return Write([&](Connection& c) {
      return c
          .Execute(
              "INSERT INTO images(material,mime,features,created_at) "
              "VALUES($1,$2,$3,$4) RETURNING id",
              Params()
                  .Text(image.material)
                  .Text(image.mime)
                  .Bytes(image.features)
                  .Text(NowIso8601()))
          .Int(0, 0);
    });
  }

  std::vector<ImageRecord> ListImages() override {
    return Read([&](Connection& c) {
      return All(c.Execute("SELECT " FRICTIOND_IMAGE_COLUMNS
                           " FROM images ORDER BY id"),
                 ReadImage);
    });
  }

  // --- robots ----------------------------------------------------------------
  bool PutRobot(const RobotRecord& robot) override {
    return Write([&](Connection& c) {
      const Params p =
          Params().Text(robot.id).Text(robot.json).Text(NowIso8601());
      const bool created = InsertIfAbsent(
          c,
          "INSERT INTO robots(" FRICTIOND_ROBOT_COLUMNS
          ") VALUES($1,$2,$3,$3) ON CONFLICT(id) DO NOTHING RETURNING id",
          p);
      if (!created)
        c.Execute("UPDATE robots SET json=$2, updated_at=$3 WHERE id=$1", p);
      return created;
    });
  }

  std::optional<RobotRecord> GetRobot(const std::string& id) override {
    return Read([&](Connection& c) {
      return First(c.Execute("SELECT " FRICTIOND_ROBOT_COLUMNS
                             " FROM robots WHERE id=$1",
                             Params().Text(id)),
                   ReadRobot);
    });
  }

  // --- tokens and audit ------------------------------------------------------
  bool AddToken(const TokenRecord& t) override {
    return Write([&](Connection& c) {
      // No conflict target: an existing id or hash both refuse the token.
      return InsertIfAbsent(
          c,
          "INSERT INTO tokens(" FRICTIOND_TOKEN_COLUMNS
          ") VALUES($1,$2,$3,$4,$5,'') ON CONFLICT DO NOTHING RETURNING id",
          Params().Text(t.id).Text(t.name).Text(t.role).Text(t.hash).Text(
              NowIso8601()));
    });
  }

  std::optional<TokenRecord> FindTokenByHash(const std::string& hash) override {
    return Read([&](Connection& c) {
      return First(c.Execute("SELECT " FRICTIOND_TOKEN_COLUMNS
                             " FROM tokens WHERE hash=$1",
                             Params().Text(hash)),
                   ReadToken);
    });
  }

  std::vector<TokenRecord> ListTokens() override {
    const std::string sql = std::string("SELECT " FRICTIOND_TOKEN_COLUMNS
                                        " FROM tokens ORDER BY ") +
                            d_.token_order;
    return Read([&](Connection& c) { return All(c.Execute(sql), ReadToken); });
  }

  bool RevokeToken(const std::string& id) override {
    return Write([&](Connection& c) {
      return c.Execute(
                  "UPDATE tokens SET revoked_at=$1 WHERE id=$2 AND "
                  "revoked_at=''",
                  Params().Text(NowIso8601()).Text(id))
                 .affected() > 0;
    });
  }

  std::int64_t AppendAudit(const AuditEntry& e) override {
    return Write(
        [&](Connection& c) { return InsertAudit(c, e, NowIso8601()); });
  }

  std::vector<AuditEntry> ListAudit(std::int64_t after_id,
                                    int limit,
                                    const std::string& material) override {
    return Read([&](Connection& c) {
      return All(c.Execute("SELECT " FRICTIOND_AUDIT_COLUMNS
                           " FROM audit WHERE id>$1 AND ($2='' OR "
                           "material=$2) ORDER BY id LIMIT $3",
                           Params().Int(after_id).Text(material).Int(
                               limit < 0 ? 0 : limit)),
                 ReadAudit);
    });
  }

  // --- housekeeping ----------------------------------------------------------
  int SchemaVersion() override {
    return Read([&](Connection& c) { return AppliedSchemaVersion(c); });
  }

  std::string BackendName() const override { return d_.name; }

  std::string CheckIntegrity() override {
    std::string out = driver_->CheckIntegrity();
    Read([&](Connection& c) {
      Rows r = c.Execute(
          "SELECT material,fingertip,MAX(version) FROM models GROUP BY "
          "material,fingertip HAVING COUNT(*) <> MAX(version)");
      for (int i = 0; i < r.size(); ++i) {
        out += "models of " + r.Take(i, 0) + "/" + r.Take(i, 1) +
               ": versions are not 1.." + std::to_string(r.Int(i, 2)) + "\n";
      }
    });
    return out;
  }

  void SetChangeListener(ChangeListener listener) override {
    driver_->SetChangeListener(std::move(listener));
  }

 protected:
  std::optional<IdentificationJob> DoClaimJob(std::int64_t id,
                                              const std::string& worker,
                                              int lease_s) override {
    return Write([&](Connection& c) -> std::optional<IdentificationJob> {
      Rows row = c.Execute(std::string("SELECT claimed_by,updated_at FROM "
                                       "jobs WHERE id=$1 AND state IN ") +
                               kOpenStates + d_.claim_lock,
                           Params().Int(id));
      if (row.empty()) return std::nullopt;
      const std::string by = row.Take(0, 0);
      const bool expired =
          row.Take(0, 1) < FormatIso8601(std::chrono::system_clock::now() -
                                         std::chrono::seconds(lease_s));
      if (!by.empty() && by != worker && !expired) return std::nullopt;
      Rows claimed = c.Execute(
          "UPDATE jobs SET claimed_by=$1, updated_at=$2 WHERE id=$3 "
          "RETURNING " FRICTIOND_JOB_COLUMNS,
          Params().Text(worker).Text(NowIso8601()).Int(id));
      return ReadJob(claimed, 0);
    });
  }

 private:
  /// Runs `f(Connection&)` through Driver::Read and returns its result.
  template <typename F>
  std::invoke_result_t<F&, Connection&> Read(F&& f) {
    return Run(&Driver::Read, f);
  }
  /// Runs `f(Connection&)` in one write transaction; returns its result.
  template <typename F>
  std::invoke_result_t<F&, Connection&> Write(F&& f) {
    return Run(&Driver::Write, f);
  }
  template <typename F>
  std::invoke_result_t<F&, Connection&> Run(
      void (Driver::*how)(const std::function<void(Connection&)>&), F& f) {
    using R = std::invoke_result_t<F&, Connection&>;
    if constexpr (std::is_void_v<R>) {
      (driver_.get()->*how)([&](Connection& c) { f(c); });
    } else {
      std::optional<R> out;
      (driver_.get()->*how)([&](Connection& c) { out.emplace(f(c)); });
      return std::move(*out);
    }
  }

  /// Runs an `INSERT ... ON CONFLICT DO NOTHING RETURNING ...`: true when it
  /// inserted the row.
  static bool InsertIfAbsent(Connection& c, const char* sql, const Params& p) {
    return !c.Execute(sql, p).empty();
  }

  static void EnsureFingertip(Connection& c,
                              const std::string& id,
                              const std::string& now) {
    c.Execute("INSERT INTO fingertips(" FRICTIOND_FINGERTIP_COLUMNS
              ") VALUES($1,$1,'',$2) ON CONFLICT(id) DO NOTHING",
              Params().Text(id).Text(now));
  }

  /// Inserts an audit entry stamped `now`. @return its id.
  static std::int64_t InsertAudit(Connection& c,
                                  const AuditEntry& e,
                                  const std::string& now) {
    return c
        .Execute(
            "INSERT INTO audit(at,actor,role,remote,action,material,detail) "
            "VALUES($1,$2,$3,$4,$5,$6,$7) RETURNING id",
            Params()
                .Text(now)
                .Text(e.actor)
                .Text(e.role)
                .Text(e.remote)
                .Text(e.action)
                .Text(e.material)
                .Text(e.detail))
        .Int(0, 0);
  }

  /// Appends version newest + 1 of the pair. The material's row lock
  /// (Dialect::row_lock) orders concurrent writers of a material across
  /// processes: the second waits for the first to commit and then sees its
  /// version. The primary key (material, fingertip, version) is the
  /// backstop.
  int AppendModel(Connection& c, const ModelRecord& m, const std::string& now) {
    if (c.Execute(
             std::string("SELECT 1 FROM materials WHERE id=$1") + d_.row_lock,
             Params().Text(m.material))
            .empty())
      throw std::runtime_error(std::string(d_.name) + ": no material '" +
                               m.material + "'");
    const int version =
        static_cast<int>(c.Execute("SELECT COALESCE(MAX(version),0) FROM "
                                   "models WHERE material=$1 AND fingertip=$2",
                                   Params().Text(m.material).Text(m.fingertip))
                             .Int(0, 0)) +
        1;
    c.Execute("INSERT INTO models(" FRICTIOND_MODEL_COLUMNS
              ",json) VALUES($1,$2,$3,$4,$5,$6,$7)",
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

  static std::optional<IdentificationJob> FindJob(Connection& c,
                                                  std::int64_t id) {
    return First(
        c.Execute("SELECT " FRICTIOND_JOB_COLUMNS " FROM jobs WHERE id=$1",
                  Params().Int(id)),
        ReadJob);
  }

  static int AppliedSchemaVersion(Connection& c) {
    return static_cast<int>(
        c.Execute("SELECT COALESCE(MAX(version),0) FROM schema_version")
            .Int(0, 0));
  }

  /// Applies the missing migrations, all in one transaction.
  void Migrate() {
    Write([&](Connection& c) {
      if (*d_.schema_lock_sql) c.Execute(d_.schema_lock_sql);
      c.ExecuteScript(
          "CREATE TABLE IF NOT EXISTS schema_version(version INTEGER NOT "
          "NULL, applied_at TEXT NOT NULL)");
      const int have = AppliedSchemaVersion(c);
      const int want = LatestSchemaVersion();
      if (have > want) {
        throw std::runtime_error(
            std::string(d_.name) + ": database schema version " +
            std::to_string(have) + " is newer than this frictiond (" +
            std::to_string(want) + ")");
      }
      for (int v = have + 1; v <= want; ++v) {
        const Migration& m = MigrationTo(v);
        c.ExecuteScript(MigrationSql(m, d_));
        if (m.then) m.then(c);
        c.Execute(
            "INSERT INTO schema_version(version,applied_at) VALUES($1,$2)",
            Params().Int(v).Text(NowIso8601()));
      }
    });
  }

  std::unique_ptr<Driver> driver_;
  const Dialect& d_;
};

}  // namespace

std::unique_ptr<Store> OpenStoreOn(std::unique_ptr<Driver> driver) {
  return std::make_unique<SqlStore>(std::move(driver));
}

}  // namespace internal

std::unique_ptr<Store> OpenStore(const std::string& url) {
  if (url.rfind("postgresql://", 0) == 0 || url.rfind("postgres://", 0) == 0) {
#ifdef FRICTIOND_HAVE_POSTGRES
    return internal::OpenStoreOn(internal::OpenPostgresDriver(url));
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
  return internal::OpenStoreOn(internal::OpenSqliteDriver(path));
}

}  // namespace frictiond
