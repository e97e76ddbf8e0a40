#pragma once
/// @file
/// The frictiond daemon: configuration, wiring of store, library, HTTP and
/// LCM endpoints, start-up data loading and orderly shutdown.

#include <map>
#include <memory>
#include <string>

#include "frictiond/server/auth.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/lcm_endpoint.h"
#include "frictiond/server/library.h"

namespace frictiond {

/// Daemon configuration (flags, or a JSON file with the same keys).
struct DaemonConfig {
  std::string db = "frictiond.db";  ///< SQLite file (created if missing)
  int port = 8080;                  ///< HTTP port (0: any free port)
  std::string bind = "127.0.0.1";   ///< HTTP bind address
  std::string data_dir;  ///< bundled datasets for an empty library; "none"
                         ///< loads nothing
  std::string lcm_url = "none";  ///< LCM provider URL; "none" disables LCM
  int max_body_mb = 16;          ///< request body limit [MiB]
  int threads = 8;               ///< HTTP worker threads
  /// HTTP deadlines and connection limits (HttpOptions): headers complete
  /// within header_timeout_ms of a request's first byte, the whole request
  /// within request_timeout_ms; at most max_connections open connections.
  int header_timeout_ms = 10000;
  int request_timeout_ms = 60000;
  int max_connections = 512;
  StrokePlanOptions plan;  ///< test stroke asked of robots
  /// Per-robot LCM keys: robot id -> hex key (>= 32 hex digits), from the
  /// config file's "lcm_keys" object (docs/lcm.md "Signed writes").
  std::map<std::string, std::string> lcm_keys;
  /// JSON file {"robot-id": "hex key"} (--lcm-keys); its entries are added
  /// to lcm_keys (and win over them). "" = none.
  std::string lcm_keys_file;
  /// Accept unsigned stroke_chunk_v1 (--lcm-allow-unsigned). Off: only
  /// signed stroke_chunk_v2 from robots with a key is accepted.
  bool lcm_allow_unsigned = false;
  /// Timestamp window of signed LCM writes [s] (--lcm-max-skew-s).
  double lcm_max_skew_s = 30.0;
  /// Image recognition: calibrated score a material needs to be accepted
  /// (config key "recognition_operating_point", in [0, 1]); negative = the
  /// calibrated default (docs/recognition.md, "Operating point").
  double recognition_operating_point = -1.0;
  /// Also publish the unsigned replies, identification requests, progress
  /// and model updates (--lcm-send-unsigned; config "lcm_send_unsigned").
  /// Off: robots get them only signed, on the "_SIGNED" channels. Risk when
  /// on: any device on the multicast group can forge them (e.g. feed a
  /// robot a friction model); docs/security_lcm.md.
  bool lcm_send_unsigned = false;

  /// The LCM keys as raw bytes (lcm_keys plus lcm_keys_file).
  /// @throws std::invalid_argument naming the file or robot and the rule.
  std::map<std::string, std::string> LoadLcmKeys() const;

  /// Reader routes answer callers without a token; honoured only when
  /// `bind` is a loopback address (docs/auth.md).
  bool open_reads = true;
  /// Secret of the operator token created on the first start (no tokens in
  /// the store); empty = generate one and print it to stdout.
  std::string bootstrap_token;
  /// File holding the bootstrap secret (first line; --bootstrap-token-file),
  /// so the secret need not appear on a command line. Read by Validate()
  /// into bootstrap_token when that is empty.
  std::string bootstrap_token_file;

  /// Reads a JSON config file:
  /// {"db","port","bind","data","lcm","max_body_mb","threads","open_reads",
  /// "bootstrap_token", "bootstrap_token_file", "header_timeout_ms",
  /// "request_timeout_ms", "max_connections", "plan":
  /// {"fn_min_n","fn_max_n","v_min_mm_s","v_max_mm_s","max_duration_s","min_span_pct",
  /// "lugre_pair","lugre_fn_n","lugre_slow_accel_mm_s2","lugre_slow_peak_mm_s",
  /// "lugre_fast_strokes","lugre_fast_accel_mm_s2","lugre_fast_peak_mm_s",
  /// "lugre_rest_s"} (StrokePlanOptions),
  /// "lcm_keys": {"robot": "hex"}, "lcm_keys_file", "lcm_allow_unsigned",
  /// "lcm_max_skew_s", "recognition_operating_point"}.
  /// Keys not given keep their current value.
  /// @throws std::invalid_argument naming the file, key and rule.
  void LoadFile(const std::string& path);
  /// @throws std::invalid_argument naming the option, value and rule.
  void Validate() const;
  /// The bootstrap secret: bootstrap_token, else the first line of
  /// bootstrap_token_file ("" when neither is set).
  /// @throws std::invalid_argument when the file cannot be read.
  std::string BootstrapSecret() const;
};

/// A database URL fit for logs: the password of a postgresql:// URL
/// (user:PASSWORD@ or ?password=/&password=) and of a key=value conninfo
/// (password=...) replaced by "***". SQLite paths are returned unchanged.
std::string RedactDbUrl(const std::string& url);

/// Runs one daemon. Not copyable or movable.
class Daemon {
 public:
  explicit Daemon(DaemonConfig config);
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// Opens the store, loads bundled data into an empty library, binds HTTP
  /// and starts the LCM endpoint (unless lcm_url is "none").
  /// @throws std::invalid_argument for --lcm in a build without LCM,
  /// std::runtime_error when the LCM provider cannot be created.
  /// @return the bound HTTP port.
  int Start();
  /// Serves until Stop() (blocking).
  void Serve();
  /// Stops serving HTTP and LCM (any thread; idempotent).
  void Stop();

  FrictionLibrary& library();
  HttpServer& http();
  /// Token checks, route policy and audit log (valid after Start()).
  Authenticator& auth();
  const DaemonConfig& config() const { return config_; }

 private:
  DaemonConfig config_;
  std::unique_ptr<FrictionLibrary> library_;
  std::unique_ptr<Authenticator> auth_;  ///< outlives http_ (its hooks)
  std::unique_ptr<HttpServer> http_;
  std::unique_ptr<LcmEndpoint> lcm_;  ///< null when lcm_url is "none"
};

}  // namespace frictiond
