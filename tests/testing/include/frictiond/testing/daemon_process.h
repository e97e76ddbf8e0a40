#pragma once
/// @file
/// Runs the real `frictiond` binary as a child process for end-to-end tests
/// and benchmarks (HTTP today, LCM beside it): a free loopback port, a
/// temporary directory, start with a health-check deadline, stop with a
/// signal and report how the process ended, and a fingerprint of the SQLite
/// files to prove that rejected requests stored nothing.
///
/// Example:
/// @code
///   frictiond::testing::TempDir dir("http_api");
///   frictiond::testing::DaemonOptions options;
///   options.db = dir.path() + "/lib.db";
///   frictiond::testing::DaemonProcess daemon(options);
///   daemon.Start();  // throws with the daemon's log on failure
///   auto client = daemon.MakeClient();
///   auto res = client->Get("/healthz");
///   const frictiond::testing::ExitStatus s = daemon.Stop();  // SIGTERM
///   EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
/// @endcode
///
/// Everything here talks to 127.0.0.1 only.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <httplib.h>
#include <sys/types.h>

namespace frictiond::testing {

/// A TCP port on 127.0.0.1 that was free a moment ago: binds a socket to
/// 127.0.0.1:0, reads the port the kernel chose and closes the socket.
/// (Another process may take it before it is used; DaemonProcess retries.)
/// @throws std::runtime_error when no socket can be bound.
int FindFreePort();

/// `$FRICTIOND_BIN_DIR/<name>`; @throws std::runtime_error when the variable
/// is unset (ctest sets it) or the file is missing.
std::string BinaryPath(const std::string& name);

/// `$FRICTIOND_SOURCE_DIR` (the repository root); @throws std::runtime_error
/// when unset.
std::string SourceDir();

/// A fresh directory under $TMPDIR (or /tmp), removed with its contents on
/// destruction. Not copyable; movable.
class TempDir {
 public:
  /// @param prefix readable part of the directory name.
  explicit TempDir(const std::string& prefix = "frictiond");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  TempDir(TempDir&& other) noexcept;
  TempDir& operator=(TempDir&& other) noexcept;

  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// How a child process ended.
struct ExitStatus {
  bool exited = false;     ///< true: exit() with `code`; false: see `signal`
  int code = -1;           ///< exit code when `exited`
  int signal = 0;          ///< terminating signal when killed (0: not killed)
  bool timed_out = false;  ///< it did not end in time and was SIGKILLed
  /// "exit 0", "signal 9", "timed out, then signal 9".
  std::string ToString() const;
};

/// Options of one daemon process. Fields left empty are not passed, so the
/// daemon's defaults apply.
struct DaemonOptions {
  std::string db;            ///< --db (required)
  std::string data = "";     ///< --data: "" = daemon default (repo data/),
                             ///< "none" loads nothing
  std::string lcm = "none";  ///< --lcm ("" = daemon default)
  std::string bind = "127.0.0.1";  ///< --bind; also the address clients use
  int port = 0;                    ///< --port; 0 picks a free port
  int threads = 0;                 ///< --threads (0: daemon default)
  int max_body_mb = 0;             ///< --max-body-mb (0: daemon default)
  /// --bootstrap-token: the secret of the operator token created on the
  /// first start of an empty database ("" = let the daemon generate one).
  /// MakeClient() sends it as the bearer token.
  std::string operator_token = "test-operator-0123456789abcdef0123456789abcdef";
  std::vector<std::string> extra_args;  ///< appended verbatim
  std::string binary;    ///< path of frictiond ("" = BinaryPath("frictiond"))
  std::string log_path;  ///< stdout+stderr of the daemon ("" = db + ".log")
  double start_timeout_s = 30.0;  ///< deadline for GET /healthz == 200
  /// The child gets SIGKILL when the thread that called Start() exits
  /// (PR_SET_PDEATHSIG), so a crashed test leaves no daemon behind. Turn it
  /// off when starting from a short-lived thread.
  bool kill_with_parent = true;
};

/// One `frictiond` child process. Not copyable or movable. The destructor
/// SIGKILLs and reaps a daemon that is still running.
class DaemonProcess {
 public:
  explicit DaemonProcess(DaemonOptions options);
  ~DaemonProcess();
  DaemonProcess(const DaemonProcess&) = delete;
  DaemonProcess& operator=(const DaemonProcess&) = delete;

  /// Starts the daemon (on a free port unless options.port is set) and waits
  /// until GET /healthz answers 200. Retries with another port when the
  /// chosen one was taken meanwhile.
  /// @throws std::runtime_error with the reason and the tail of the log when
  /// the daemon exits early or misses the deadline (it is killed then).
  void Start();

  /// Sends `signal` (default SIGTERM) and waits up to `timeout_s` for the
  /// process to end; SIGKILLs it after that (timed_out = true). Returns how
  /// it ended. A no-op returning the last status when not running.
  ExitStatus Stop(int signal = 15 /* SIGTERM */, double timeout_s = 15.0);

  /// SIGKILL now and reap (simulates a crash / power loss of the process).
  ExitStatus Kill();

  /// True while the child has not been reaped.
  bool running() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }
  /// The bound HTTP port (valid after Start()).
  int port() const { return port_; }
  /// "http://127.0.0.1:PORT".
  std::string base_url() const;
  const DaemonOptions& options() const { return options_; }

  /// The daemon's stdout+stderr so far (all runs since construction).
  std::string ReadLog() const;

  /// An HTTP client for this daemon (connection timeout 2 s, read timeout
  /// `read_timeout_s`). Keep-alive is off unless `keep_alive`. It sends
  /// options().operator_token as "Authorization: Bearer" when not empty.
  std::unique_ptr<httplib::Client> MakeClient(double read_timeout_s = 30.0,
                                              bool keep_alive = false) const;
  /// Like MakeClient() but with the bearer token `token` ("" = none).
  std::unique_ptr<httplib::Client> MakeClientWithToken(
      const std::string& token,
      double read_timeout_s = 30.0,
      bool keep_alive = false) const;

 private:
  bool SpawnAndWait(std::string* why);
  ExitStatus Reap(int signal, double timeout_s);

  DaemonOptions options_;
  pid_t pid_ = -1;
  int port_ = 0;
  ExitStatus last_;
};

/// 64-bit FNV-1a of a file's bytes; 0 when the file does not exist (the hash
/// of an empty file is the FNV offset basis, so the two differ).
std::uint64_t HashFile(const std::string& path);

/// Hashes of `db`, `db-wal` and `db-shm` (in that order). Equal fingerprints
/// before and after a batch of requests mean nothing was written. Readers do
/// not change these files once the WAL index is settled; a write does.
std::vector<std::uint64_t> DbFingerprint(const std::string& db);

}  // namespace frictiond::testing
