#pragma once
/// @file
/// The schema migration list (migrations.cc), shared by every dialect.

#include <string>

#include "connection.h"

namespace frictiond {
namespace internal {

/// One schema step. The SQL (`sql` then the dialect's snippet) is a script
/// of statements without parameters in which `{serial_primary_key}` and
/// `{bytes}` stand for the dialect's column types.
struct Migration {
  const char* why;         ///< what the step adds, for readers
  const char* sql;         ///< for every dialect
  const char* sqlite;      ///< then, for SQLite only
  const char* postgresql;  ///< then, for PostgreSQL only
  /// Then, in the same transaction: rows the step seeds (may be null).
  void (*then)(Connection& c);
};

/// The step that brings the schema from version - 1 to `version`
/// (1 <= version <= LatestSchemaVersion()).
const Migration& MigrationTo(int version);

/// The script of `m` for dialect `d`.
std::string MigrationSql(const Migration& m, const Dialect& d);

}  // namespace internal
}  // namespace frictiond
