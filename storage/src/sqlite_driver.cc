// SQLite driver of the store (connection.h): one write connection behind a
// mutex, WAL journal and synchronous=FULL (an acknowledged write survives
// kill -9 and power loss), foreign keys on, prepared statements cached by
// their text, every value bound. A write transaction is BEGIN IMMEDIATE: it
// holds the database's write lock from its first statement, which is the
// row locking the store logic asks for (Dialect: no lock clauses needed).
// Reads of a database file run on read-only connections of their own (a
// small pool), each Read in one read transaction (a consistent snapshot):
// in WAL mode they neither wait for a write's commit and fsync nor block it,
// so one upload's read of its pair does not queue behind another upload's
// commit. A ":memory:" database has one connection for both. An unusable
// database file (busy, locked, read-only, full, I/O) throws
// StoreUnavailable, any other failure std::runtime_error.
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <sqlite3.h>

#include "frictiond/storage/store.h"

#include "connection.h"

namespace frictiond {
namespace internal {
namespace {

const Dialect kSqliteDialect{
    Dialect::Family::kSqlite,
    /*name=*/"sqlite",
    /*serial_primary_key=*/"INTEGER PRIMARY KEY AUTOINCREMENT",
    /*bytes_type=*/"BLOB",
    /*schema_lock_sql=*/"",
    /*key_lock_sql=*/"",
    /*row_lock=*/"",
    /*claim_lock=*/"",
    /*binary_collation=*/"",
    /*token_order=*/"created_at, rowid",
};

/// RETURNING (3.35) and ON CONFLICT without a target (3.35).
constexpr int kMinSqliteVersion = 3035000;
static_assert(SQLITE_VERSION_NUMBER >= kMinSqliteVersion,
              "the store needs SQLite >= 3.35 (RETURNING)");

/// A locked, read-only, full or failing database file is an outage of the
/// store (StoreUnavailable: HTTP 503, nothing stored), not a bug.
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

/// `$N` parameters as SQLite's `?N` (same index), outside string literals
/// and quoted identifiers.
std::string ToSqliteParameters(std::string_view sql) {
  std::string out;
  out.reserve(sql.size());
  char quote = 0;
  for (std::size_t i = 0; i < sql.size(); ++i) {
    const char c = sql[i];
    if (quote) {
      if (c == quote) quote = 0;
    } else if (c == '\'' || c == '"') {
      quote = c;
    } else if (c == '$' && i + 1 < sql.size() && sql[i + 1] >= '0' &&
               sql[i + 1] <= '9') {
      out += '?';
      continue;
    }
    out += c;
  }
  return out;
}

class Statement {
 public:
  Statement(sqlite3* db, std::string_view sql) : db_(db) {
    const std::string text = ToSqliteParameters(sql);
    if (sqlite3_prepare_v3(db,
                           text.c_str(),
                           static_cast<int>(text.size()),
                           SQLITE_PREPARE_PERSISTENT,
                           &stmt_,
                           nullptr) != SQLITE_OK) {
      throw std::runtime_error(std::string("sqlite: prepare: ") +
                               sqlite3_errmsg(db) + " in: " + text);
    }
    read_only_ = sqlite3_stmt_readonly(stmt_) != 0;
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Rows Run(const Params& params) {
    // Reset and unbind however this ends: bound bytes are borrowed.
    struct Cleanup {
      sqlite3_stmt* s;
      ~Cleanup() {
        sqlite3_reset(s);
        sqlite3_clear_bindings(s);
      }
    } cleanup{stmt_};
    int index = 1;
    for (const Params::Value& v : params.values()) {
      int rc = SQLITE_OK;
      const std::string_view b = v.bytes();
      switch (v.kind) {
        case Params::Kind::kInt:
          rc = sqlite3_bind_int64(stmt_, index, v.integer);
          break;
        case Params::Kind::kText:
          rc = sqlite3_bind_text64(
              stmt_, index, b.data(), b.size(), SQLITE_STATIC, SQLITE_UTF8);
          break;
        case Params::Kind::kBytes:
          rc = sqlite3_bind_blob64(
              stmt_, index, b.data(), b.size(), SQLITE_STATIC);
          break;
      }
      if (rc != SQLITE_OK)
        throw std::runtime_error("sqlite: bind $" + std::to_string(index) +
                                 ": " + sqlite3_errmsg(db_));
      ++index;
    }
    const int columns = sqlite3_column_count(stmt_);
    Rows rows(columns);
    for (;;) {
      const int rc = sqlite3_step(stmt_);
      if (rc == SQLITE_DONE) break;
      // (Cleanup resets the statement: one left failed "in progress" would
      // make every later COMMIT on this connection fail.)
      if (rc != SQLITE_ROW) ThrowSqliteError(rc, sqlite3_errmsg(db_));
      for (int c = 0; c < columns; ++c) {
        if (sqlite3_column_type(stmt_, c) == SQLITE_INTEGER) {
          rows.AddInt(sqlite3_column_int64(stmt_, c));
        } else {
          const auto* p =
              static_cast<const char*>(sqlite3_column_blob(stmt_, c));
          const int n = sqlite3_column_bytes(stmt_, c);
          rows.AddText(p ? std::string(p, static_cast<std::size_t>(n))
                         : std::string());
        }
      }
    }
    if (!read_only_) rows.set_affected(sqlite3_changes(db_));
    return rows;
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  bool read_only_ = true;
};

class SqliteConnection final : public Connection {
 public:
  enum class Mode { kReadWrite, kReadOnly };

  /// Opens `path`; kReadOnly opens an existing database for reads only
  /// (the write connection has made it WAL already).
  SqliteConnection(const std::string& path, Mode mode) {
    if (sqlite3_libversion_number() < kMinSqliteVersion) {
      throw std::runtime_error(std::string("sqlite: library ") +
                               sqlite3_libversion() +
                               " is older than 3.35 (needed for RETURNING)");
    }
    const int flags =
        mode == Mode::kReadOnly
            ? SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX
            : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
    const int rc = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
    if (rc != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      if (mode == Mode::kReadOnly)  // the file went away or is unreadable
        ThrowSqliteError(rc, "cannot open '" + path + "' to read: " + why);
      throw std::runtime_error("sqlite: cannot open '" + path + "': " + why);
    }
    sqlite3_busy_timeout(db_, 5000);
    try {
      ExecuteScript("PRAGMA foreign_keys=ON");
      if (mode == Mode::kReadWrite) {
        if (path != ":memory:") ExecuteScript("PRAGMA journal_mode=WAL");
        ExecuteScript("PRAGMA synchronous=FULL");
      }
    } catch (...) {
      sqlite3_close(db_);
      throw;
    }
  }
  ~SqliteConnection() override {
    statements_.clear();
    sqlite3_close(db_);
  }
  SqliteConnection(const SqliteConnection&) = delete;
  SqliteConnection& operator=(const SqliteConnection&) = delete;

  Rows Execute(std::string_view sql, const Params& params) override {
    auto it = statements_.find(sql);
    if (it == statements_.end()) {
      auto statement = std::make_unique<Statement>(db_, sql);
      it = statements_.emplace(std::string(sql), std::move(statement)).first;
    }
    return it->second->Run(params);
  }

  void ExecuteScript(const std::string& sql) override {
    char* err = nullptr;
    const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err);
    if (rc != SQLITE_OK) {
      const std::string why = err ? err : sqlite3_errmsg(db_);
      sqlite3_free(err);
      ThrowSqliteError(rc, why);
    }
  }

  void Rollback() { sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr); }

 private:
  sqlite3* db_ = nullptr;
  /// Prepared statements by SQL text (std::less<>: found by string_view).
  std::map<std::string, std::unique_ptr<Statement>, std::less<>> statements_;
};

class SqliteDriver final : public Driver {
 public:
  explicit SqliteDriver(const std::string& path)
      : path_(path),
        connection_(path, SqliteConnection::Mode::kReadWrite),
        separate_readers_(path != ":memory:") {}

  const Dialect& dialect() const override { return kSqliteDialect; }

  void Read(const std::function<void(Connection&)>& f) override {
    if (!separate_readers_) {
      std::lock_guard<std::mutex> lock(mu_);
      f(connection_);
      return;
    }
    std::unique_ptr<SqliteConnection> reader = TakeReader();
    reader->ExecuteScript("BEGIN");  // the snapshot starts at the first read
    try {
      f(*reader);
      reader->ExecuteScript("COMMIT");
    } catch (...) {
      reader->Rollback();
      throw;  // the reader is closed, not pooled
    }
    GiveBackReader(std::move(reader));
  }

  void Write(const std::function<void(Connection&)>& f) override {
    std::lock_guard<std::mutex> lock(mu_);
    connection_.ExecuteScript("BEGIN IMMEDIATE");
    try {
      f(connection_);
      connection_.ExecuteScript("COMMIT");
    } catch (...) {
      connection_.Rollback();
      throw;
    }
  }

  std::string CheckIntegrity() override {
    std::string out;
    Read([&](Connection& c) {
      Rows r = c.Execute("PRAGMA integrity_check");
      for (int i = 0; i < r.size(); ++i) {
        std::string row = r.Take(i, 0);
        if (row != "ok") out += row + "\n";
      }
    });
    return out;
  }

 private:
  /// Idle read connections kept open (more are opened while more threads
  /// read at once, and closed after).
  static constexpr std::size_t kIdleReaders = 4;

  std::unique_ptr<SqliteConnection> TakeReader() {
    {
      std::lock_guard<std::mutex> lock(readers_mu_);
      if (!readers_.empty()) {
        std::unique_ptr<SqliteConnection> r = std::move(readers_.back());
        readers_.pop_back();
        return r;
      }
    }
    return std::make_unique<SqliteConnection>(
        path_, SqliteConnection::Mode::kReadOnly);
  }

  void GiveBackReader(std::unique_ptr<SqliteConnection> reader) {
    std::lock_guard<std::mutex> lock(readers_mu_);
    if (readers_.size() < kIdleReaders) readers_.push_back(std::move(reader));
  }

  const std::string path_;
  std::mutex mu_;  // the write connection
  SqliteConnection connection_;
  const bool separate_readers_;
  std::mutex readers_mu_;
  std::vector<std::unique_ptr<SqliteConnection>> readers_;
};

}  // namespace

std::unique_ptr<Driver> OpenSqliteDriver(const std::string& path) {
  return std::make_unique<SqliteDriver>(path);
}

}  // namespace internal
}  // namespace frictiond
