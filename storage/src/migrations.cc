// The schema of the store: one list of migrations for every dialect.
// Migration i (0-based) brings a database from schema version i to i + 1;
// the versions applied are rows of schema_version. Append new steps at the
// end, never edit or reorder a released one (docs/storage.md).
//
// SQL is written once; `{serial_primary_key}` and `{bytes}` are replaced by
// the dialect's column types, and a step may add a snippet for one dialect.
//
// Databases made before the list was shared (up to frictiond 0.1 at commit
// da4cfb6) open unchanged: SQLite's five steps were these five. PostgreSQL
// had four: its step 1 already made jobs.claimed_by and its step 4 made
// job_strokes, so a PostgreSQL database at version k <= 3 differs from this
// list's version k only by claimed_by, and one at version 4 only by also
// having job_strokes. Steps 4 and 5 are therefore written so they do nothing
// where their result exists (IF NOT EXISTS), and every old PostgreSQL
// database reaches version 5 with the same schema as a new one.
#include "migrations.h"

#include <string>

#include "frictiond/storage/store.h"

namespace frictiond {
namespace internal {
namespace {

void InsertDefaultFingertip(Connection& c) {
  c.Execute(
      "INSERT INTO fingertips(id,name,description,created_at) "
      "VALUES('default','default','fingertip used when none is named',$1)",
      Params().Text(NowIso8601()));
}

const Migration kMigrations[] = {
    {/*why=*/"materials, fingertips, strokes, models, jobs, images",
     /*sql=*/R"sql(
CREATE TABLE materials(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, description TEXT NOT NULL,
  tags TEXT NOT NULL, created_at TEXT NOT NULL, updated_at TEXT NOT NULL);
CREATE TABLE fingertips(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, description TEXT NOT NULL,
  created_at TEXT NOT NULL);
CREATE TABLE strokes(
  id {serial_primary_key},
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  fingertip TEXT NOT NULL REFERENCES fingertips(id),
  robot TEXT NOT NULL, received_at TEXT NOT NULL, samples BIGINT NOT NULL,
  csv {bytes} NOT NULL);
CREATE INDEX strokes_pair ON strokes(material, fingertip);
CREATE TABLE models(
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  fingertip TEXT NOT NULL REFERENCES fingertips(id),
  version INTEGER NOT NULL, created_at TEXT NOT NULL, reason TEXT NOT NULL,
  stroke_id BIGINT NOT NULL, json TEXT NOT NULL,
  PRIMARY KEY(material, fingertip, version));
CREATE TABLE jobs(
  id {serial_primary_key}, material TEXT NOT NULL, fingertip TEXT NOT NULL,
  state TEXT NOT NULL, plan_json TEXT NOT NULL, detail TEXT NOT NULL,
  requested_by TEXT NOT NULL, created_at TEXT NOT NULL,
  updated_at TEXT NOT NULL);
CREATE INDEX jobs_pair ON jobs(material, fingertip, state);
CREATE TABLE images(
  id {serial_primary_key},
  material TEXT NOT NULL REFERENCES materials(id) ON DELETE CASCADE,
  mime TEXT NOT NULL, features {bytes} NOT NULL, created_at TEXT NOT NULL);
)sql",
     /*sqlite=*/"",
     /*postgresql=*/"",
     /*then=*/InsertDefaultFingertip},
    {"robot descriptions",
     R"sql(
CREATE TABLE robots(
  id TEXT PRIMARY KEY, json TEXT NOT NULL, created_at TEXT NOT NULL,
  updated_at TEXT NOT NULL);
)sql",
     "",
     "",
     nullptr},
    {"API tokens and the audit log",
     R"sql(
CREATE TABLE tokens(
  id TEXT PRIMARY KEY, name TEXT NOT NULL, role TEXT NOT NULL,
  hash TEXT NOT NULL UNIQUE, created_at TEXT NOT NULL,
  revoked_at TEXT NOT NULL DEFAULT '');
CREATE TABLE audit(
  id {serial_primary_key}, at TEXT NOT NULL, actor TEXT NOT NULL,
  role TEXT NOT NULL, remote TEXT NOT NULL, action TEXT NOT NULL,
  material TEXT NOT NULL, detail TEXT NOT NULL);
CREATE INDEX audit_material ON audit(material, id);
)sql",
     "",
     // Insertion order of tokens (Dialect::token_order; SQLite: rowid).
     "ALTER TABLE tokens ADD COLUMN seq BIGSERIAL;",
     nullptr},
    {"identification jobs claimed by one worker (ClaimJob)",
     "",
     "ALTER TABLE jobs ADD COLUMN claimed_by TEXT NOT NULL DEFAULT '';",
     // Old PostgreSQL databases have it from their first step.
     "ALTER TABLE jobs ADD COLUMN IF NOT EXISTS claimed_by TEXT NOT NULL "
     "DEFAULT '';",
     nullptr},
    {"complete strokes of open jobs (PutJobStroke), kept across restarts",
     // IF NOT EXISTS: old PostgreSQL databases at version 4 have it.
     R"sql(
CREATE TABLE IF NOT EXISTS job_strokes(
  job_id BIGINT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  stroke INTEGER NOT NULL, csv {bytes} NOT NULL, PRIMARY KEY(job_id, stroke));
)sql",
     "",
     "",
     nullptr},
};

void ReplaceAll(std::string& s, const std::string& from, const char* to) {
  for (std::size_t at = s.find(from); at != std::string::npos;
       at = s.find(from, at)) {
    s.replace(at, from.size(), to);
    at += std::char_traits<char>::length(to);
  }
}

}  // namespace

int LatestSchemaVersion() {
  return static_cast<int>(sizeof(kMigrations) / sizeof(kMigrations[0]));
}

const Migration& MigrationTo(int version) { return kMigrations[version - 1]; }

std::string MigrationSql(const Migration& m, const Dialect& d) {
  std::string sql = m.sql;
  sql += d.family == Dialect::Family::kSqlite ? m.sqlite : m.postgresql;
  ReplaceAll(sql, "{serial_primary_key}", d.serial_primary_key);
  ReplaceAll(sql, "{bytes}", d.bytes_type);
  return sql;
}

}  // namespace internal
}  // namespace frictiond
