#pragma once
/// @file
/// A throw-away PostgreSQL 15 server for tests and benchmarks: `initdb` into
/// a temporary directory (as the `postgres` system user when running as
/// root, since initdb refuses root), `postgres` listening on 127.0.0.1 only
/// on a free port with its unix socket inside the directory, fsync on, trust
/// authentication for user `postgres`. The destructor stops it with a fast
/// shutdown (SIGINT, as `pg_ctl stop -m fast`) and removes the directory.
/// The server also gets SIGINT when the thread that started it exits.
///
/// Binaries are taken from $FRICTIOND_PG_BIN or /usr/lib/postgresql/15/bin.
///
/// Example:
/// @code
///   if (!frictiond::testing::PgServer::RequireOrSkip()) GTEST_SKIP();
///   frictiond::testing::PgServer pg;
///   pg.Start();
///   const std::string url = pg.CreateDatabase("lib");  // postgresql://...
/// @endcode

#include <string>
#include <vector>

#include <sys/types.h>

namespace frictiond::testing {

class PgServer {
 public:
  PgServer();
  ~PgServer();
  PgServer(const PgServer&) = delete;
  PgServer& operator=(const PgServer&) = delete;

  /// Directory of initdb/postgres/psql/pg_isready; "" when not installed.
  static std::string BinDir();

  /// For tests: true when the binaries exist. When they are missing it
  /// records a gtest FAILURE naming the package to install, unless
  /// FRICTIOND_ALLOW_NO_POSTGRES=1 (then it returns false: skip).
  static bool RequireOrSkip();

  /// initdb (first call only) and start; waits until the server accepts
  /// connections. Calling it again after Stop() restarts on the same data
  /// directory and port. @throws std::runtime_error with the log's tail.
  void Start();
  /// Fast shutdown (SIGINT) and wait. No-op when not running.
  void Stop();
  /// Immediate shutdown (SIGQUIT: like a crash; recovery on next start).
  void Crash();
  bool running() const { return pid_ > 0; }

  int port() const { return port_; }
  /// postgresql://postgres@127.0.0.1:PORT/DB
  std::string Url(const std::string& db = "postgres") const;
  /// Creates database `name` (fresh; dropped first if it exists) and
  /// returns its URL.
  std::string CreateDatabase(const std::string& name);
  /// Runs SQL through psql on database `db`; returns its unaligned output.
  /// @throws std::runtime_error when psql fails.
  std::string Psql(const std::string& sql, const std::string& db = "postgres");
  /// Runs several commands, each in its own transaction (psql -c ... -c).
  std::string Psql(const std::vector<std::string>& commands,
                   const std::string& db = "postgres");
  /// The server's log so far.
  std::string ReadLog() const;

 private:
  int Run(const std::vector<std::string>& argv, std::string* output) const;
  void WaitReady(double timeout_s);

  std::string dir_;  // temp dir (data/, sock/, server.log)
  bool initialised_ = false;
  pid_t pid_ = -1;
  int port_ = 0;
  uid_t uid_ = 0;  // user the server runs as (postgres when we are root)
  gid_t gid_ = 0;
};

}  // namespace frictiond::testing
