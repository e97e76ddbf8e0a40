#pragma once
/// @file
/// The persistent friction library. `Store` is the interface the daemon
/// talks to; OpenStore() picks a back end from a URL (a SQLite file path
/// or `sqlite://PATH`; `postgresql://...` for the fleet back end, several
/// daemons sharing one library, see docs/fleet.md).
///
/// Guarantees of every back end:
/// - Each mutating call is one transaction: it either happens completely or
///   not at all, and once it returns it survives a crash (kill -9).
/// - Model versions are append-only: a refit adds version n+1; old versions
///   stay queryable.
/// - Thread-safe: calls may come from any thread.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace frictiond {

/// A surface material of the library.
struct Material {
  std::string id;  ///< [A-Za-z0-9._-]{1,64}
  std::string name;
  std::string description;
  std::vector<std::string> tags;
  std::string created_at;  ///< ISO-8601 UTC, set by the store
  std::string updated_at;  ///< ISO-8601 UTC, set by the store
};

/// A robot fingertip (friction belongs to a fingertip-surface pair). The
/// fingertip "default" always exists.
struct Fingertip {
  std::string id;
  std::string name;
  std::string description;
  std::string created_at;
};

/// A stroke upload: the raw samples exactly as uploaded, plus provenance.
struct StrokeRecord {
  std::int64_t id = 0;  ///< assigned by the store
  std::string material;
  std::string fingertip = "default";
  std::string robot;        ///< source robot (free text, may be empty)
  std::string received_at;  ///< set by the store
  std::int64_t samples = 0;
  std::string csv;  ///< raw body (empty in listings)
};

/// One model version of a (material, fingertip) pair.
struct ModelRecord {
  std::string material;
  std::string fingertip = "default";
  int version = 0;         ///< assigned by the store: 1, 2, ...
  std::string created_at;  ///< set by the store
  std::string
      reason;  ///< why it was made ("upload", "bundled", "diagnosis", ...)
  std::int64_t stroke_id = 0;  ///< stroke that triggered it (0: none)
  std::string json;            ///< model document (families keyed by name)
};

/// An identification job: the library asked a robot for a test stroke.
struct IdentificationJob {
  std::int64_t id = 0;
  std::string material;
  std::string fingertip = "default";
  std::string
      state;  ///< requested | stroking | enough_coverage | fitted | failed
  std::string plan_json;     ///< stroke plan sent to the robot
  std::string detail;        ///< last progress or failure reason
  std::string requested_by;  ///< robot or client that triggered it
  std::string created_at;
  std::string updated_at;
};

/// A registered reference image of a material (for recognition).
struct ImageRecord {
  std::int64_t id = 0;
  std::string material;
  std::string mime;
  std::string features;  ///< serialised feature vector (back-end neutral bytes)
  std::string created_at;
};

/// A robot description (kinematics, joint stiffness and joint friction
/// references) as a JSON document; the server validates it before storing.
struct RobotRecord {
  std::string id;  ///< [A-Za-z0-9._-]{1,64}
  std::string json;
  std::string created_at;  ///< set by the store
  std::string updated_at;  ///< set by the store
};

/// Result of Store::CommitUpload.
struct UploadCommit {
  std::int64_t stroke_id = 0;
  int version = 0;
  bool material_created = false;
  std::string created_at;  ///< the model version's created_at (ISO-8601 UTC)
};

/// An API token. Only a hash of its secret is stored.
struct TokenRecord {
  std::string id;          ///< public id ("tok_" + 12 hex), shown in lists
  std::string name;        ///< label given at creation
  std::string role;        ///< reader | robot | operator
  std::string hash;        ///< lowercase hex SHA-256 of the secret
  std::string created_at;  ///< set by the store
  std::string revoked_at;  ///< empty while the token is valid
};

/// One audit log entry: who changed what, when, from where.
struct AuditEntry {
  std::int64_t id = 0;   ///< assigned by the store, increasing
  std::string at;        ///< set by the store
  std::string actor;     ///< token id, "lcm:<robot>" or "system"
  std::string role;      ///< role of the actor ("" for system)
  std::string remote;    ///< remote address ("" when not from the network)
  std::string action;    ///< e.g. "PUT /v1/materials/{id}"
  std::string material;  ///< affected material ("" when none)
  std::string detail;    ///< JSON text (version, stroke id, status, ...)
};

/// Storage interface. Copy: no; move: no (held through unique_ptr).
class Store {
 public:
  virtual ~Store() = default;
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  // --- materials -----------------------------------------------------------
  /// Creates or updates a material (id, name, description, tags).
  /// @return true when it was created.
  virtual bool PutMaterial(const Material& material) = 0;
  virtual std::optional<Material> GetMaterial(const std::string& id) = 0;
  virtual std::vector<Material> ListMaterials() = 0;
  /// Deletes a material with its strokes, models, jobs and images.
  /// @return false when it did not exist.
  virtual bool DeleteMaterial(const std::string& id) = 0;

  // --- fingertips ----------------------------------------------------------
  virtual bool PutFingertip(const Fingertip& fingertip) = 0;
  virtual std::optional<Fingertip> GetFingertip(const std::string& id) = 0;
  virtual std::vector<Fingertip> ListFingertips() = 0;

  // --- strokes and models --------------------------------------------------
  /// Stores a stroke and the model refitted with it as one transaction,
  /// creating the material (name = id) if it does not exist. The model's
  /// version is the pair's newest + 1. Any identification job of the pair
  /// moves to `fitted`. When `audit` is not null, its entry is appended in
  /// the same transaction (one flush per upload; after kill -9 the log holds
  /// an entry exactly for each stored upload), with `stroke_id`, `version`
  /// and `material_created` added to its detail (a JSON object; "" = {}).
  virtual UploadCommit CommitUpload(const StrokeRecord& stroke,
                                    const ModelRecord& model,
                                    const AuditEntry* audit) = 0;
  /// CommitUpload without an audit entry.
  UploadCommit CommitUpload(const StrokeRecord& stroke,
                            const ModelRecord& model) {
    return CommitUpload(stroke, model, nullptr);
  }
  /// Appends a model version (e.g. an extended model found by diagnosis).
  /// @return the new version.
  virtual int AddModelVersion(const ModelRecord& model) = 0;
  /// Strokes of a pair, oldest first, without their csv.
  virtual std::vector<StrokeRecord> ListStrokes(
      const std::string& material, const std::string& fingertip) = 0;
  /// One stroke with its csv.
  virtual std::optional<StrokeRecord> GetStroke(std::int64_t id) = 0;
  /// Strokes of a pair whose id is above `after_id` (0: all), oldest first,
  /// in one query; with their csv when `with_csv`, else csv is empty. The
  /// ingestor loads a pair's history with it once and catches up with it.
  virtual std::vector<StrokeRecord> ListStrokesAfter(
      const std::string& material,
      const std::string& fingertip,
      std::int64_t after_id,
      bool with_csv) = 0;
  /// Newest model version of a pair.
  virtual std::optional<ModelRecord> GetLatestModel(
      const std::string& material, const std::string& fingertip) = 0;
  /// A given version.
  virtual std::optional<ModelRecord> GetModel(const std::string& material,
                                              const std::string& fingertip,
                                              int version) = 0;
  /// All versions of a pair, oldest first, without their json.
  virtual std::vector<ModelRecord> ListModels(const std::string& material,
                                              const std::string& fingertip) = 0;

  // --- identification jobs ------------------------------------------------
  /// Opens a job for the pair unless an open one (requested/stroking/
  /// enough_coverage) exists; returns the open job either way.
  virtual IdentificationJob RequestIdentification(
      const IdentificationJob& job) = 0;
  /// Updates state and detail of a job. @return false when it does not exist.
  virtual bool UpdateJob(std::int64_t id,
                         const std::string& state,
                         const std::string& detail) = 0;
  virtual std::optional<IdentificationJob> GetJob(std::int64_t id) = 0;
  /// Jobs, newest first; `open_only` keeps requested/stroking/enough_coverage.
  virtual std::vector<IdentificationJob> ListJobs(bool open_only) = 0;
  /// One page of ListJobs: jobs with id below `after` (0: from the newest),
  /// newest first, at most `limit` (>= 1). The default filters ListJobs;
  /// the back ends override it with a bounded query.
  virtual std::vector<IdentificationJob> ListJobsPage(bool open_only,
                                                      std::int64_t after,
                                                      int limit) {
    std::vector<IdentificationJob> out;
    for (IdentificationJob& j : ListJobs(open_only)) {
      if (static_cast<int>(out.size()) >= limit) break;
      if (after <= 0 || j.id < after) out.push_back(std::move(j));
    }
    return out;
  }
  /// Seconds after which a claim that was not renewed may be taken over.
  static constexpr int kClaimLeaseS = 60;
  /// Claims an open job for `worker` so that only one daemon of a fleet acts
  /// on it: succeeds when the job is open and unclaimed, already claimed by
  /// `worker` (this renews the claim), or its claim (or last update) is
  /// older than kClaimLeaseS (its daemon died), atomically against other
  /// daemons (PostgreSQL: SELECT ... FOR UPDATE SKIP LOCKED; SQLite: a
  /// conditional UPDATE).
  /// @return the claimed job, or nullopt when unknown, closed or claimed by
  /// another worker.
  std::optional<IdentificationJob> ClaimJob(std::int64_t id,
                                            const std::string& worker) {
    return ClaimJobWithLease(id, worker, kClaimLeaseS);
  }
  /// ClaimJob with another lease, e.g. a short one in tests.
  /// @throws std::invalid_argument when lease_s <= 0.
  std::optional<IdentificationJob> ClaimJobWithLease(std::int64_t id,
                                                     const std::string& worker,
                                                     int lease_s) {
    if (lease_s <= 0)
      throw std::invalid_argument("lease_s = " + std::to_string(lease_s) +
                                  " (must be > 0)");
    return DoClaimJob(id, worker, lease_s);
  }

  // --- strokes of open identification jobs ----------------------------------
  /// Keeps a complete stroke of an open job (CSV text, stroke_csv.h) until
  /// the job is fitted or fails, so that a daemon restart does not lose it;
  /// a second copy of the same stroke index replaces the first. Deleting the
  /// job deletes its strokes. @return false when the job does not exist.
  virtual bool PutJobStroke(std::int64_t job_id,
                            int stroke,
                            const std::string& csv) = 0;
  /// The kept strokes of a job as (stroke index, CSV), by stroke index.
  virtual std::vector<std::pair<int, std::string>> ListJobStrokes(
      std::int64_t job_id) = 0;
  /// Drops the kept strokes of a job (once they are ingested or useless).
  virtual void DeleteJobStrokes(std::int64_t job_id) = 0;

  // --- images ---------------------------------------------------------------
  virtual std::int64_t AddImage(const ImageRecord& image) = 0;
  virtual std::vector<ImageRecord> ListImages() = 0;

  // --- robots ----------------------------------------------------------------
  /// Creates or replaces a robot description. @return true when created.
  virtual bool PutRobot(const RobotRecord& robot) = 0;
  virtual std::optional<RobotRecord> GetRobot(const std::string& id) = 0;

  // --- tokens and audit -----------------------------------------------------
  /// Stores a new token. @return false when a token with this id exists.
  virtual bool AddToken(const TokenRecord& token) = 0;
  /// The token whose hash this is (revoked ones too), or nullopt.
  virtual std::optional<TokenRecord> FindTokenByHash(
      const std::string& hash) = 0;
  /// All tokens, oldest first.
  virtual std::vector<TokenRecord> ListTokens() = 0;
  /// Marks a token revoked. @return false when unknown or already revoked.
  virtual bool RevokeToken(const std::string& id) = 0;
  /// Appends an audit entry. @return its id.
  virtual std::int64_t AppendAudit(const AuditEntry& entry) = 0;
  /// Entries with id > after_id, oldest first, at most `limit`; a non-empty
  /// `material` keeps that material's entries only.
  virtual std::vector<AuditEntry> ListAudit(std::int64_t after_id,
                                            int limit,
                                            const std::string& material) = 0;

  // --- housekeeping ----------------------------------------------------------
  /// Schema version (number of applied migrations).
  virtual int SchemaVersion() = 0;
  /// Back end name ("sqlite", ...).
  virtual std::string BackendName() const = 0;
  /// Runs the back end's consistency check; empty string when fine.
  virtual std::string CheckIntegrity() = 0;

  // --- change notification (fleet) ------------------------------------------
  /// Called from a back-end thread after another process committed a write
  /// to the shared database: `material` and `fingertip` name the changed
  /// pair (`fingertip` empty: every pair of the material; both empty: anything
  /// may have changed, e.g. after a reconnect). The PostgreSQL back end
  /// delivers these through LISTEN/NOTIFY (channel frictiond_changes); the
  /// SQLite back end is single-process and never calls it (no-op).
  using ChangeListener = std::function<void(const std::string& material,
                                            const std::string& fingertip)>;
  /// Sets (or clears, with an empty function) the listener. Set it once,
  /// before serving.
  virtual void SetChangeListener(ChangeListener listener) { (void)listener; }

 protected:
  Store() = default;
  /// ClaimJobWithLease for a valid lease (> 0 s).
  virtual std::optional<IdentificationJob> DoClaimJob(std::int64_t id,
                                                      const std::string& worker,
                                                      int lease_s) = 0;
};

/// Opens a store: a SQLite database file (created if missing; ":memory:" for
/// a private in-memory database), or a PostgreSQL connection URI
/// ("postgresql://user@host:port/db?..."; needs FRICTIOND_WITH_POSTGRES).
/// @throws std::invalid_argument for an unsupported URL,
/// std::runtime_error when the database cannot be opened or migrated.
std::unique_ptr<Store> OpenStore(const std::string& url);

/// Thrown by a back end whose database server cannot be reached (connection
/// refused or lost). The call had no effect, or its transaction was not
/// acknowledged; retrying later may succeed. The HTTP layer answers 503.
class StoreUnavailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Current UTC time, ISO-8601 with milliseconds ("2026-11-22T21:05:07.123Z").
std::string NowIso8601();

}  // namespace frictiond
