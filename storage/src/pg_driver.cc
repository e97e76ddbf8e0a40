// PostgreSQL driver of the store (connection.h, libpq), for a fleet of
// daemons sharing one library: a pool of up to kMaxConnections connections,
// every statement parameterised (PQexecParams) with results in binary format
// (integers and booleans arrive typed, bytea without unescaping), SQLSTATE
// mapped to StoreUnavailable (server unreachable) or std::runtime_error. A
// pooled connection found dead before COMMIT was sent is replaced and the
// transaction retried once; a failure during COMMIT is reported, never
// retried. Every committed write that calls Notify sends NOTIFY on channel
// frictiond_changes; a listener thread (own connection) reports other
// processes' writes to the ChangeListener. Row locks, the claim's SKIP
// LOCKED and the advisory locks are SQL fragments in the dialect.
#ifdef FRICTIOND_HAVE_POSTGRES

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <libpq-fe.h>
#include <poll.h>

#include "frictiond/storage/store.h"

#include "connection.h"

namespace frictiond {
namespace internal {
namespace {

constexpr const char* kChannel = "frictiond_changes";
constexpr int kMaxConnections = 4;

// Type OIDs of PostgreSQL's catalog (pg_type.dat) that arrive as integers.
constexpr Oid kBoolOid = 16;
constexpr Oid kInt8Oid = 20;
constexpr Oid kInt2Oid = 21;
constexpr Oid kInt4Oid = 23;

const Dialect kPostgresDialect{
    Dialect::Family::kPostgresql,
    /*name=*/"postgresql",
    /*serial_primary_key=*/"BIGSERIAL PRIMARY KEY",
    /*bytes_type=*/"BYTEA",
    // One daemon at a time migrates; the others wait and find it done.
    /*schema_lock_sql=*/"SELECT pg_advisory_xact_lock(7406372511)",
    /*key_lock_sql=*/"SELECT pg_advisory_xact_lock(hashtext($1))",
    // FOR NO KEY UPDATE: compatible with the key-share locks that foreign
    // keys of strokes and models take, so no deadlock.
    /*row_lock=*/" FOR NO KEY UPDATE",
    // A job row locked by another daemon's claim is skipped, not waited for:
    // that daemon is taking it.
    /*claim_lock=*/" FOR UPDATE SKIP LOCKED",
    /*binary_collation=*/" COLLATE \"C\"",
    /*token_order=*/"seq",
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

/// Owns a PGresult.
struct ResultDeleter {
  void operator()(PGresult* r) const { PQclear(r); }
};
using ResultPtr = std::unique_ptr<PGresult, ResultDeleter>;

/// Throws unless `r` is a success.
ResultPtr Check(PGconn* c, PGresult* r) {
  ResultPtr owned(r);
  const ExecStatusType st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK) return owned;
  const std::string why =
      FirstLine(r ? PQresultErrorMessage(r) : PQerrorMessage(c));
  if (IsUnavailable(c, r)) throw StoreUnavailable("postgresql: " + why);
  throw std::runtime_error("postgresql: " + why);
}

std::int64_t BigEndian(const char* p, int n) {
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | static_cast<unsigned char>(p[i]);
  // Sign-extend from n bytes.
  const int shift = 64 - 8 * n;
  return static_cast<std::int64_t>(v << shift) >> shift;
}

/// Reads a binary-format result into Rows.
Rows ToRows(const PGresult* r) {
  const int columns = PQnfields(r);
  const int n = PQntuples(r);
  Rows rows(columns);
  std::vector<Oid> types(static_cast<std::size_t>(columns));
  for (int c = 0; c < columns; ++c) types[c] = PQftype(r, c);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < columns; ++c) {
      const char* p = PQgetvalue(r, i, c);
      const int len = PQgetlength(r, i, c);
      if (PQgetisnull(r, i, c)) {
        rows.AddText(std::string());
        continue;
      }
      switch (types[c]) {
        case kBoolOid:
        case kInt2Oid:
        case kInt4Oid:
        case kInt8Oid:
          if (len != 1 && len != 2 && len != 4 && len != 8)
            throw std::runtime_error("postgresql: integer of " +
                                     std::to_string(len) + " bytes");
          rows.AddInt(BigEndian(p, len));
          break;
        default:  // text, bytea, void, ...: the bytes themselves
          rows.AddText(std::string(p, static_cast<std::size_t>(len)));
      }
    }
  }
  // PQcmdTuples also counts a SELECT's rows; affected() is for writes only.
  const char* status = PQcmdStatus(const_cast<PGresult*>(r));
  const char* affected = PQcmdTuples(const_cast<PGresult*>(r));
  const bool write = status && (std::strncmp(status, "INSERT", 6) == 0 ||
                                std::strncmp(status, "UPDATE", 6) == 0 ||
                                std::strncmp(status, "DELETE", 6) == 0);
  if (write && affected && *affected) rows.set_affected(std::stoll(affected));
  return rows;
}

class PgConnection final : public Connection {
 public:
  PgConnection(PGconn* c, const std::string& origin) : c_(c), origin_(origin) {}

  Rows Execute(std::string_view sql, const Params& params) override {
    const auto& in = params.values();
    const std::size_t n = in.size();
    std::vector<std::string> integers(n);
    std::vector<const char*> values(n);
    std::vector<int> lengths(n);
    std::vector<int> formats(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (in[i].kind == Params::Kind::kInt) {
        integers[i] = std::to_string(in[i].integer);
        values[i] = integers[i].c_str();
        lengths[i] = static_cast<int>(integers[i].size());
      } else {
        // Text parameters are NUL-terminated strings to libpq (a borrowed
        // std::string is; an owned one too); bytes go as binary.
        const std::string_view b = in[i].bytes();
        values[i] = b.data();
        lengths[i] = static_cast<int>(b.size());
        formats[i] = in[i].kind == Params::Kind::kBytes ? 1 : 0;
      }
    }
    const std::string text(sql);
    const ResultPtr r = Check(c_,
                              PQexecParams(c_,
                                           text.c_str(),
                                           static_cast<int>(n),
                                           nullptr,
                                           n ? values.data() : nullptr,
                                           n ? lengths.data() : nullptr,
                                           n ? formats.data() : nullptr,
                                           /*resultFormat=*/1));
    return ToRows(r.get());
  }

  void ExecuteScript(const std::string& sql) override {
    Check(c_, PQexec(c_, sql.c_str()));
  }

  void Notify(const std::string& material,
              const std::string& fingertip) override {
    Execute("SELECT pg_notify($1,$2)",
            Params().Text(kChannel).Text(origin_ + "\n" + material + "\n" +
                                         fingertip));
  }

 private:
  PGconn* c_;
  const std::string& origin_;
};

class PostgresDriver final : public Driver {
 public:
  explicit PostgresDriver(std::string url) : url_(std::move(url)) {
    std::random_device rd;
    char buf[32];
    std::snprintf(buf,
                  sizeof buf,
                  "%08x%08x",
                  static_cast<unsigned>(rd()),
                  static_cast<unsigned>(rd()));
    origin_ = buf;
  }

  ~PostgresDriver() override {
    StopListener();
    std::lock_guard<std::mutex> lock(pool_mu_);
    for (PGconn* c : idle_) PQfinish(c);
    idle_.clear();
  }

  const Dialect& dialect() const override { return kPostgresDialect; }

  /// Runs a read; a pooled connection that turns out dead (server
  /// restarted meanwhile) is replaced once by a fresh one.
  void Read(const std::function<void(Connection&)>& f) override {
    for (int attempt = 0;; ++attempt) {
      Lease lease = Acquire();
      PgConnection connection(lease.get(), origin_);
      try {
        f(connection);
        return;
      } catch (const StoreUnavailable&) {
        if (lease.fresh() || attempt > 0) throw;
        DropIdle();  // the others are as dead as this one
      }
    }
  }

  void Write(const std::function<void(Connection&)>& f) override {
    for (int attempt = 0;; ++attempt) {
      Lease lease = Acquire();
      PgConnection connection(lease.get(), origin_);
      Transaction tx(lease.get());
      try {
        tx.Begin();
        f(connection);
        tx.Commit();
        return;
      } catch (const StoreUnavailable&) {
        DropIdle();  // the others are as dead as this one
        if (lease.fresh() || attempt > 0 || tx.commit_sent()) throw;
      }
    }
  }

  void SetChangeListener(
      std::function<void(const std::string&, const std::string&)> listener)
      override {
    StopListener();
    if (!listener) return;
    listener_ = std::move(listener);
    listen_stop_ = false;
    listen_thread_ = std::thread([this] { ListenLoop(); });
  }

 private:
  /// One transaction on a leased connection; rolled back unless committed.
  class Transaction {
   public:
    explicit Transaction(PGconn* c) : c_(c) {}
    ~Transaction() {
      if (open_) PQclear(PQexec(c_, "ROLLBACK"));
    }
    Transaction(const Transaction&) = delete;
    Transaction& operator=(const Transaction&) = delete;
    void Begin() {
      Check(c_, PQexec(c_, "BEGIN"));
      open_ = true;
    }
    void Commit() {
      commit_sent_ = true;
      Check(c_, PQexec(c_, "COMMIT"));
      open_ = false;
    }
    bool commit_sent() const { return commit_sent_; }

   private:
    PGconn* c_;
    bool open_ = false;
    bool commit_sent_ = false;
  };

  /// A pooled connection, returned (or closed when broken) on destruction.
  class Lease {
   public:
    Lease(PostgresDriver* d, PGconn* c, bool fresh)
        : d_(d), c_(c), fresh_(fresh) {}
    ~Lease() { d_->Release(c_); }
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    PGconn* get() const { return c_; }
    bool fresh() const { return fresh_; }

   private:
    PostgresDriver* d_;
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
          Check(c, PQexec(c, (std::string("LISTEN ") + kChannel).c_str()));
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
  std::function<void(const std::string&, const std::string&)> listener_;
  std::atomic<bool> listen_stop_{false};
  std::thread listen_thread_;
};

}  // namespace

std::unique_ptr<Driver> OpenPostgresDriver(const std::string& url) {
  return std::make_unique<PostgresDriver>(url);
}

}  // namespace internal
}  // namespace frictiond

#endif  // FRICTIOND_HAVE_POSTGRES
