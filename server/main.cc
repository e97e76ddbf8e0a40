// frictiond: the friction material-library daemon. Parses flags, builds the
// daemon, serves until SIGTERM/SIGINT.
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <iostream>
#include <mutex>
#include <thread>

#include <CLI/CLI.hpp>
#include <signal.h>
#include <sys/stat.h>

#include "frictiond/server/allocator.h"
#include "frictiond/server/daemon.h"

#ifndef FRICTIOND_DEFAULT_DATA_DIR
#define FRICTIOND_DEFAULT_DATA_DIR "data"
#endif

namespace {

/// Hands memory freed inside the allocator back to the system every
/// `period` (frictiond::ReleaseFreeHeap; with glibc, malloc_trim(0):
/// page-aligned free chunks anywhere in an arena, not only its top).
/// M_TRIM_THRESHOLD trims an arena's top only, so pages freed between live
/// blocks stayed resident: in a 40 s soak the heap in use was 22-90 MB while
/// the allocator kept 108 -> 269 MB free and RSS grew with it (GET /metrics
/// frictiond_heap_*). A trim every 30 s costs a walk of the arenas' free lists
/// and, for pages in use again, their page faults; per upload (stop 20) it cost
/// a quarter of the CPU, so it is not done there.
class HeapTrimmer {
 public:
  explicit HeapTrimmer(std::chrono::seconds period)
      : thread_([this, period] {
          std::unique_lock<std::mutex> lock(mu_);
          while (!cv_.wait_for(lock, period, [this] { return stop_; }))
            frictiond::ReleaseFreeHeap();
        }) {}
  ~HeapTrimmer() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;  // last: started after the members it uses
};

}  // namespace

int main(int argc, char** argv) {
  frictiond::TuneHeapAllocator();
  frictiond::DaemonConfig config;
  config.data_dir = FRICTIOND_DEFAULT_DATA_DIR;
  CLI::App app{"frictiond: friction material-library daemon"};
  std::string config_file;
  app.add_option(
      "--config", config_file, "JSON config file (flags given override it)");
  // Flags are applied after the config file, so remember which were given.
  std::string db, bind, data, lcm;
  int port = -1, max_body_mb = -1, threads = -1;
  CLI::Option* db_opt =
      app.add_option("--db",
                     db,
                     "SQLite database file (created if missing) or "
                     "postgresql://USER@HOST:PORT/DB "
                     "(fleet, docs/fleet.md) [frictiond.db]");
  CLI::Option* port_opt = app.add_option("--port", port, "HTTP port [8080]");
  CLI::Option* bind_opt =
      app.add_option("--bind", bind, "HTTP bind address [127.0.0.1]");
  CLI::Option* data_opt = app.add_option(
      "--data",
      data,
      "bundled datasets loaded into an empty database, or 'none' "
      "[project data/]");
  CLI::Option* lcm_opt =
      app.add_option("--lcm", lcm, "LCM provider URL, or 'none' [none]");
  CLI::Option* max_body_opt = app.add_option(
      "--max-body-mb", max_body_mb, "request body limit in MiB [16]");
  CLI::Option* threads_opt =
      app.add_option("--threads", threads, "HTTP worker threads [8]");
  std::string lcm_keys;
  bool lcm_allow_unsigned = false;
  bool lcm_send_unsigned = false;
  double lcm_max_skew_s = -1;
  CLI::Option* lcm_keys_opt =
      app.add_option("--lcm-keys",
                     lcm_keys,
                     "JSON file {\"robot-id\": \"hex key\"} of the keys of "
                     "signed LCM writes");
  app.add_flag("--lcm-allow-unsigned",
               lcm_allow_unsigned,
               "accept unsigned stroke_chunk_v1 on LCM (off: dropped)");
  app.add_flag("--lcm-send-unsigned",
               lcm_send_unsigned,
               "also send unsigned replies, requests, progress and model "
               "updates on LCM (forgeable by any device on the group; off: "
               "signed only, docs/security_lcm.md)");
  CLI::Option* skew_opt =
      app.add_option("--lcm-max-skew-s",
                     lcm_max_skew_s,
                     "timestamp window of signed LCM writes in s [30]");
  std::string open_reads, bootstrap_token;
  app.add_option("--open-reads",
                 open_reads,
                 "answer lookups without a token when bound to loopback: "
                 "true or false [true]")
      ->check(CLI::IsMember({"true", "false"}));
  app.add_option("--bootstrap-token",
                 bootstrap_token,
                 "secret of the operator token created on the first start "
                 "(env FRICTIOND_BOOTSTRAP_TOKEN) [random, printed once]");
  std::string bootstrap_token_file;
  app.add_option("--bootstrap-token-file",
                 bootstrap_token_file,
                 "file whose first line is the bootstrap secret (keeps it off "
                 "the command line)");
  int header_timeout_ms = -1, request_timeout_ms = -1, max_connections = -1;
  CLI::Option* header_timeout_opt =
      app.add_option("--header-timeout-ms",
                     header_timeout_ms,
                     "HTTP: request line and headers must arrive within this "
                     "time of the request's first byte [10000]");
  CLI::Option* request_timeout_opt =
      app.add_option("--request-timeout-ms",
                     request_timeout_ms,
                     "HTTP: a whole request (headers and body) must arrive "
                     "within this time [60000]");
  CLI::Option* max_connections_opt =
      app.add_option("--max-connections",
                     max_connections,
                     "HTTP: open connections at most; more get 503 [512]");
  CLI11_PARSE(app, argc, argv);
  // Files the daemon creates (database, WAL, exports) are private.
  ::umask(077);

  // Block the stop signals in every thread; one thread waits for them.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  signal(SIGPIPE, SIG_IGN);

  try {
    if (!config_file.empty()) config.LoadFile(config_file);
    if (db_opt->count()) config.db = db;
    if (bind_opt->count()) config.bind = bind;
    // An empty path given was read as "not given" (the project's data/,
    // or no keys): refused, like the other flags.
    if (data_opt->count() && data.empty())
      throw std::invalid_argument("--data: empty (give a directory or none)");
    if (lcm_keys_opt->count() && lcm_keys.empty())
      throw std::invalid_argument("--lcm-keys: empty (give a JSON file)");
    if (data_opt->count()) config.data_dir = data;
    if (lcm_opt->count()) config.lcm_url = lcm;
    // A flag given is applied as given (a negative value is refused by
    // DaemonConfig::Validate, naming the flag; it was silently ignored).
    if (port_opt->count()) config.port = port;
    if (max_body_opt->count()) config.max_body_mb = max_body_mb;
    if (threads_opt->count()) config.threads = threads;
    if (lcm_keys_opt->count()) config.lcm_keys_file = lcm_keys;
    if (lcm_allow_unsigned) config.lcm_allow_unsigned = true;
    if (lcm_send_unsigned) config.lcm_send_unsigned = true;
    if (skew_opt->count()) config.lcm_max_skew_s = lcm_max_skew_s;
    if (!open_reads.empty()) config.open_reads = open_reads == "true";
    if (!bootstrap_token.empty()) {
      std::cerr << "frictiond: note: --bootstrap-token is visible to other "
                   "users of this host (ps); prefer --bootstrap-token-file "
                   "or FRICTIOND_BOOTSTRAP_TOKEN\n";
    } else if (bootstrap_token_file.empty()) {
      if (const char* env = std::getenv("FRICTIOND_BOOTSTRAP_TOKEN"))
        bootstrap_token = env;
    }
    // Not inherited by anything the daemon may start.
    ::unsetenv("FRICTIOND_BOOTSTRAP_TOKEN");
    if (!bootstrap_token.empty()) config.bootstrap_token = bootstrap_token;
    if (!bootstrap_token_file.empty())
      config.bootstrap_token_file = bootstrap_token_file;
    if (header_timeout_opt->count())
      config.header_timeout_ms = header_timeout_ms;
    if (request_timeout_opt->count())
      config.request_timeout_ms = request_timeout_ms;
    if (max_connections_opt->count()) config.max_connections = max_connections;
    frictiond::Daemon daemon(config);
    const int bound = daemon.Start();
    HeapTrimmer trimmer(std::chrono::seconds(30));
    std::thread waiter([&daemon, stop_signals] {
      int sig = 0;
      sigwait(&stop_signals, &sig);
      std::cerr << "frictiond: signal " << sig << ", shutting down\n";
      daemon.Stop();
    });
    std::cerr << "frictiond: serving http://" << config.bind << ":" << bound
              << " (db " << frictiond::RedactDbUrl(config.db) << ")\n";
    daemon.Serve();
    // Serve returned: either a signal arrived or the server failed. Wake the
    // waiter if it is still waiting.
    pthread_kill(waiter.native_handle(), SIGTERM);
    waiter.join();
    std::cerr << "frictiond: stopped\n";
  } catch (const std::exception& e) {
    std::cerr << "frictiond: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
