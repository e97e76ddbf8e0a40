#pragma once
/// @file
/// The small interface between the store logic (sql_store.cc: schema, row
/// mapping, commit rules, written once) and a database driver
/// (sqlite_driver.cc, pg_driver.cc: connect, prepare/bind/step, type and
/// error mapping, pooling, notifications). Private to frictiond_storage
/// (and its tests); see docs/storage.md.
///
/// SQL given to a driver is written once for every dialect: parameters are
/// numbered `$1`, `$2`, ... (a parameter may repeat), upserts use
/// `INSERT ... ON CONFLICT ... DO NOTHING | DO UPDATE SET c=excluded.c`,
/// inserted keys come back through `RETURNING`. What differs between
/// dialects is data in `Dialect` (SQL fragments), never an `if` on the
/// back end in the store logic; the migration list (migrations.cc) may add
/// a per-dialect snippet to a step.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace frictiond {
namespace internal {

/// What the store logic needs to know about a dialect. Every field but
/// `family` is a fragment of SQL (empty when the dialect needs nothing
/// there); `family` only picks per-dialect snippets of the migration list.
struct Dialect {
  enum class Family { kSqlite, kPostgresql };
  Family family;
  /// Back end name, the prefix of its error messages ("sqlite", ...).
  const char* name;
  /// Column type of an auto-numbered 64-bit primary key (migrations only).
  const char* serial_primary_key;
  /// Column type of raw bytes (migrations only).
  const char* bytes_type;
  /// A statement that makes concurrent migrations wait for each other
  /// inside the migration's transaction ("" when a write transaction is
  /// already exclusive).
  const char* schema_lock_sql;
  /// A statement taking a transaction-scoped lock on the text key `$1`
  /// ("" when a write transaction is already exclusive).
  const char* key_lock_sql;
  /// Appended to a SELECT of a material row to lock it until commit
  /// before a version append ("" when a write transaction is exclusive).
  const char* row_lock;
  /// Appended to the SELECT of a job row when claiming it: locks it and
  /// skips it when another transaction holds it ("" when exclusive).
  const char* claim_lock;
  /// Appended to ORDER BY of a text key for byte-wise order.
  const char* binary_collation;
  /// ORDER BY expression listing tokens in insertion order.
  const char* token_order;
};

/// Statement parameters, bound in order to $1, $2, ... Text and bytes are
/// bound without copying when given as lvalues (they must outlive the
/// Execute call); rvalues are kept here. Copy: yes; move: yes.
class Params {
 public:
  enum class Kind { kText, kBytes, kInt };
  struct Value {
    Kind kind = Kind::kText;
    const std::string* ref = nullptr;  ///< borrowed text or bytes
    std::string owned;                 ///< owned text or bytes
    std::int64_t integer = 0;
    std::string_view bytes() const {
      return ref ? std::string_view(*ref) : std::string_view(owned);
    }
  };

  Params& Text(const std::string& v) { return Borrow(Kind::kText, v); }
  Params& Text(std::string&& v) { return Own(Kind::kText, std::move(v)); }
  Params& Text(const char* v) { return Own(Kind::kText, std::string(v)); }
  Params& Bytes(const std::string& v) { return Borrow(Kind::kBytes, v); }
  Params& Int(std::int64_t v) {
    Value x;
    x.kind = Kind::kInt;
    x.integer = v;
    values_.push_back(std::move(x));
    return *this;
  }
  const std::vector<Value>& values() const { return values_; }

 private:
  Params& Borrow(Kind kind, const std::string& v) {
    Value x;
    x.kind = kind;
    x.ref = &v;
    values_.push_back(std::move(x));
    return *this;
  }
  Params& Own(Kind kind, std::string&& v) {
    Value x;
    x.kind = kind;
    x.owned = std::move(v);
    values_.push_back(std::move(x));
    return *this;
  }
  std::vector<Value> values_;
};

/// The rows a statement returned, fully read, plus the number of rows an
/// INSERT/UPDATE/DELETE changed. Cells are text (or bytes) or integers;
/// a boolean is the integer 0 or 1. Copy: no; move: yes.
class Rows {
 public:
  Rows() = default;
  explicit Rows(int columns) : columns_(columns) { cells_.reserve(columns); }
  Rows(Rows&&) noexcept = default;
  Rows& operator=(Rows&&) noexcept = default;
  Rows(const Rows&) = delete;
  Rows& operator=(const Rows&) = delete;

  int size() const {
    return columns_ == 0 ? 0 : static_cast<int>(cells_.size()) / columns_;
  }
  bool empty() const { return size() == 0; }
  /// Rows changed by an INSERT, UPDATE or DELETE (0 for a SELECT).
  std::int64_t affected() const { return affected_; }

  /// A text or bytes cell, moved out (read each cell once).
  std::string Take(int row, int col);
  /// An integer cell (a text cell holding a decimal integer also works).
  /// @throws std::runtime_error when the cell is not an integer.
  std::int64_t Int(int row, int col) const;

  // --- for drivers -----------------------------------------------------------
  void AddText(std::string v) {
    Cell c;
    c.text = std::move(v);
    cells_.push_back(std::move(c));
  }
  void AddInt(std::int64_t v) {
    Cell c;
    c.is_integer = true;
    c.integer = v;
    cells_.push_back(std::move(c));
  }
  void set_affected(std::int64_t n) { affected_ = n; }

 private:
  struct Cell {
    bool is_integer = false;
    std::int64_t integer = 0;
    std::string text;
  };
  int columns_ = 0;
  std::vector<Cell> cells_;
  std::int64_t affected_ = 0;
};

/// One database session, used by one thread at a time, inside
/// Driver::Read or Driver::Write.
class Connection {
 public:
  virtual ~Connection() = default;
  /// Runs one parameterised statement ($1, $2, ...) and reads all its rows.
  /// @throws StoreUnavailable when the server cannot be reached,
  /// std::runtime_error for any other failure ("<dialect>: <why>").
  virtual Rows Execute(std::string_view sql, const Params& params) = 0;
  Rows Execute(std::string_view sql) { return Execute(sql, Params()); }
  /// Runs a constant script of several statements without parameters
  /// (schema migrations only; never built from input).
  virtual void ExecuteScript(const std::string& sql) = 0;
  /// Inside a write: tells other processes sharing the database, once the
  /// transaction commits, that this pair changed (Store::ChangeListener).
  /// No-op for a single-process back end.
  virtual void Notify(const std::string& material,
                      const std::string& fingertip) {
    (void)material;
    (void)fingertip;
  }
};

/// A database: its connections, their thread safety and transactions.
class Driver {
 public:
  virtual ~Driver() = default;
  virtual const Dialect& dialect() const = 0;
  /// Runs `f` (reads only) on a connection outside any write transaction;
  /// SQLite gives it a read-only connection and one snapshot, PostgreSQL
  /// runs each statement on its own.
  virtual void Read(const std::function<void(Connection&)>& f) = 0;
  /// Runs `f` in one write transaction and commits it; rolls back when `f`
  /// throws. `f` may run twice when the driver retries a transaction it
  /// knows was rolled back (a pooled connection found dead), so it must
  /// only write its results, never accumulate them.
  virtual void Write(const std::function<void(Connection&)>& f) = 0;
  /// The back end's own consistency check; empty when fine.
  virtual std::string CheckIntegrity() { return std::string(); }
  /// Store::SetChangeListener (fleet back ends).
  virtual void SetChangeListener(
      std::function<void(const std::string&, const std::string&)> listener) {
    (void)listener;
  }
};

/// Opens a SQLite database file (":memory:": a private one): WAL journal
/// (files only), synchronous=FULL, foreign keys on. No schema is created.
/// @throws std::runtime_error when it cannot be opened.
std::unique_ptr<Driver> OpenSqliteDriver(const std::string& path);

#ifdef FRICTIOND_HAVE_POSTGRES
/// Connects to PostgreSQL (libpq URI). No schema is created.
/// @throws StoreUnavailable when the server cannot be reached.
std::unique_ptr<Driver> OpenPostgresDriver(const std::string& url);
#endif

/// The number of schema migrations (Store::SchemaVersion of a migrated
/// database), equal for every dialect.
int LatestSchemaVersion();

}  // namespace internal
}  // namespace frictiond
