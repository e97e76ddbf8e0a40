#include "frictiond/server/daemon.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>

#include <fcntl.h>
#include <unistd.h>

#include "frictiond/crypto/hmac.h"
#include "frictiond/proto/json_parse.h"
#include "frictiond/server/lcm_auth.h"
#include "frictiond/server/openapi.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/server/routes.h"

namespace frictiond {

using nlohmann::json;

namespace {

// The LuGre pair of the stroke plan (StrokePlanOptions, docs/lcm.md "Stroke
// plan"); `where` starts the message ("FILE: plan." or "plan: ").
void CheckLuGrePlan(const StrokePlanOptions& plan, const std::string& where) {
  auto plan_rule =
      [&where](bool ok, const char* key, double value, const char* rule) {
        if (ok) return;
        char text[32];
        std::snprintf(text, sizeof text, "%g", value);
        throw std::invalid_argument(where + key + " = " + text + " (must be " +
                                    rule + ")");
      };
  plan_rule(plan.lugre_fn_n >= 0,
            "lugre_fn_n",
            plan.lugre_fn_n,
            ">= 0; 0: the middle of the Fn span");
  plan_rule(plan.lugre_slow_accel_mm_s2 > 0 && plan.lugre_slow_accel_mm_s2 <= 3,
            "lugre_slow_accel_mm_s2",
            plan.lugre_slow_accel_mm_s2,
            "in (0, 3]: the quasi-static step");
  plan_rule(plan.lugre_slow_peak_mm_s > 0,
            "lugre_slow_peak_mm_s",
            plan.lugre_slow_peak_mm_s,
            "> 0");
  plan_rule(plan.lugre_fast_strokes >= 1 && plan.lugre_fast_strokes <= 12,
            "lugre_fast_strokes",
            plan.lugre_fast_strokes,
            "in 1..12");
  plan_rule(plan.lugre_fast_accel_mm_s2 >= 5,
            "lugre_fast_accel_mm_s2",
            plan.lugre_fast_accel_mm_s2,
            ">= 5: the dynamic step");
  plan_rule(plan.lugre_fast_peak_mm_s > 0,
            "lugre_fast_peak_mm_s",
            plan.lugre_fast_peak_mm_s,
            "> 0");
  plan_rule(plan.lugre_rest_s >= 0.6,
            "lugre_rest_s",
            plan.lugre_rest_s,
            ">= 0.6: strokes split at rests of 0.25 s, plus 0.1 s margins");
}

}  // namespace

std::map<std::string, std::string> DaemonConfig::LoadLcmKeys() const {
  std::map<std::string, std::string> keys =
      ParseLcmKeys(json(lcm_keys).dump(), "lcm_keys");
  if (!lcm_keys_file.empty()) {
    std::ifstream in(lcm_keys_file);
    if (!in)
      throw std::invalid_argument("--lcm-keys " + lcm_keys_file +
                                  ": cannot read");
    const std::string text((std::istreambuf_iterator<char>(in)),
                           std::istreambuf_iterator<char>());
    for (auto& [robot, key] : ParseLcmKeys(text, "--lcm-keys " + lcm_keys_file))
      keys[robot] = key;
  }
  return keys;
}

void DaemonConfig::LoadFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("--config " + path + ": cannot read");
  std::string text((std::istreambuf_iterator<char>(in)),
                   std::istreambuf_iterator<char>());
  const json j = ParseJson(text, ("--config " + path).c_str());
  if (!j.is_object())
    throw std::invalid_argument("--config " + path +
                                ": expected a JSON object");
  auto str = [&](const char* key, std::string* out) {
    if (!j.contains(key)) return;
    if (!j[key].is_string())
      throw std::invalid_argument(path + ": " + key + ": expected a string");
    *out = j[key].get<std::string>();
  };
  auto integer = [&](const json& obj, const char* key, int* out) {
    if (!obj.contains(key)) return;
    if (!obj[key].is_number_integer())
      throw std::invalid_argument(path + ": " + key + ": expected an integer");
    *out = obj[key].get<int>();
  };
  auto number = [&](const json& obj, const char* key, double* out) {
    if (!obj.contains(key)) return;
    if (!obj[key].is_number())
      throw std::invalid_argument(path + ": plan." + key +
                                  ": expected a number");
    *out = obj[key].get<double>();
  };
  for (auto it = j.begin(); it != j.end(); ++it) {
    static const char* kKeys[] = {"db",
                                  "port",
                                  "bind",
                                  "data",
                                  "lcm",
                                  "max_body_mb",
                                  "threads",
                                  "open_reads",
                                  "bootstrap_token",
                                  "plan",
                                  "lcm_keys",
                                  "lcm_keys_file",
                                  "lcm_allow_unsigned",
                                  "lcm_max_skew_s",
                                  "recognition_operating_point",
                                  "lcm_send_unsigned",
                                  "bootstrap_token_file",
                                  "header_timeout_ms",
                                  "request_timeout_ms",
                                  "max_connections"};
    if (std::find(std::begin(kKeys), std::end(kKeys), it.key()) ==
        std::end(kKeys)) {
      throw std::invalid_argument(path + ": unknown key '" + it.key() + "'");
    }
  }
  str("db", &db);
  str("bind", &bind);
  str("data", &data_dir);
  str("lcm", &lcm_url);
  str("bootstrap_token", &bootstrap_token);
  str("bootstrap_token_file", &bootstrap_token_file);
  integer(j, "header_timeout_ms", &header_timeout_ms);
  integer(j, "request_timeout_ms", &request_timeout_ms);
  integer(j, "max_connections", &max_connections);
  if (j.contains("open_reads")) {
    if (!j["open_reads"].is_boolean())
      throw std::invalid_argument(path +
                                  ": open_reads: expected true or false");
    open_reads = j["open_reads"].get<bool>();
  }
  integer(j, "port", &port);
  integer(j, "max_body_mb", &max_body_mb);
  integer(j, "threads", &threads);
  str("lcm_keys_file", &lcm_keys_file);
  if (j.contains("lcm_allow_unsigned")) {
    if (!j["lcm_allow_unsigned"].is_boolean())
      throw std::invalid_argument(
          path + ": lcm_allow_unsigned: expected true or false");
    lcm_allow_unsigned = j["lcm_allow_unsigned"].get<bool>();
  }
  if (j.contains("lcm_send_unsigned")) {
    if (!j["lcm_send_unsigned"].is_boolean())
      throw std::invalid_argument(
          path + ": lcm_send_unsigned: expected true or false");
    lcm_send_unsigned = j["lcm_send_unsigned"].get<bool>();
  }
  if (j.contains("lcm_max_skew_s")) {
    if (!j["lcm_max_skew_s"].is_number())
      throw std::invalid_argument(path + ": lcm_max_skew_s: expected a number");
    lcm_max_skew_s = j["lcm_max_skew_s"].get<double>();
  }
  if (j.contains("recognition_operating_point")) {
    if (!j["recognition_operating_point"].is_number())
      throw std::invalid_argument(
          path + ": recognition_operating_point: expected a number");
    recognition_operating_point =
        j["recognition_operating_point"].get<double>();
  }
  if (j.contains("lcm_keys")) {
    // Checked here (hex, length); kept as hex like the file.
    const auto raw = ParseLcmKeys(j["lcm_keys"].dump(), path + ": lcm_keys");
    for (const auto& [robot, key] : raw) lcm_keys[robot] = ToHex(key);
  }
  if (j.contains("plan")) {
    const json& p = j["plan"];
    if (!p.is_object())
      throw std::invalid_argument(path + ": plan: expected an object");
    number(p, "fn_min_n", &plan.fn_min_n);
    number(p, "fn_max_n", &plan.fn_max_n);
    number(p, "v_min_mm_s", &plan.v_min_mm_s);
    number(p, "v_max_mm_s", &plan.v_max_mm_s);
    number(p, "max_duration_s", &plan.max_duration_s);
    number(p, "min_span_pct", &plan.min_span_pct);
    if (p.contains("lugre_pair")) {
      if (!p["lugre_pair"].is_boolean())
        throw std::invalid_argument(
            path + ": plan.lugre_pair: expected true or false");
      plan.lugre_pair = p["lugre_pair"].get<bool>();
    }
    number(p, "lugre_fn_n", &plan.lugre_fn_n);
    number(p, "lugre_slow_accel_mm_s2", &plan.lugre_slow_accel_mm_s2);
    number(p, "lugre_slow_peak_mm_s", &plan.lugre_slow_peak_mm_s);
    integer(p, "lugre_fast_strokes", &plan.lugre_fast_strokes);
    number(p, "lugre_fast_accel_mm_s2", &plan.lugre_fast_accel_mm_s2);
    number(p, "lugre_fast_peak_mm_s", &plan.lugre_fast_peak_mm_s);
    number(p, "lugre_rest_s", &plan.lugre_rest_s);
    CheckLuGrePlan(plan, path + ": plan.");
  }
}

void DaemonConfig::Validate() const {
  if (db.empty())
    throw std::invalid_argument(
        "--db: empty (give a SQLite file path or a postgresql:// URL)");
  if (!(port >= 0 && port <= 65535))
    throw std::invalid_argument("--port " + std::to_string(port) +
                                ": must be in 0..65535");
  if (bind.empty()) throw std::invalid_argument("--bind: empty");
  if (!(max_body_mb >= 1 && max_body_mb <= 1024))
    throw std::invalid_argument("--max-body-mb " + std::to_string(max_body_mb) +
                                ": must be in 1..1024");
  if (!(threads >= 1 && threads <= 256))
    throw std::invalid_argument("--threads " + std::to_string(threads) +
                                ": must be in 1..256");
  if (!(plan.fn_min_n > 0 && plan.fn_min_n < plan.fn_max_n))
    throw std::invalid_argument(
        "plan: fn_min_n must be > 0 and below fn_max_n");
  if (!(plan.v_min_mm_s >= 0 && plan.v_min_mm_s < plan.v_max_mm_s))
    throw std::invalid_argument(
        "plan: v_min_mm_s must be >= 0 and below v_max_mm_s");
  if (!(plan.max_duration_s > 0))
    throw std::invalid_argument("plan: max_duration_s must be > 0");
  if (!(plan.min_span_pct > 0 && plan.min_span_pct <= 100))
    throw std::invalid_argument("plan: min_span_pct must be in (0, 100]");
  CheckLuGrePlan(plan, "plan: ");
  if (!(recognition_operating_point <= 1.0))
    throw std::invalid_argument(
        "recognition_operating_point = " +
        std::to_string(recognition_operating_point) +
        ": must be in [0, 1] (negative: the calibrated default)");
  if (lcm_url.empty())
    throw std::invalid_argument("--lcm: empty (give a provider URL or none)");
  if (!(lcm_max_skew_s > 0 && lcm_max_skew_s <= 3600))
    throw std::invalid_argument("--lcm-max-skew-s " +
                                std::to_string(lcm_max_skew_s) +
                                ": must be in (0, 3600]");
  LoadLcmKeys();  // throws naming the file or robot
  if (!(header_timeout_ms >= 100 && header_timeout_ms <= 600000))
    throw std::invalid_argument("--header-timeout-ms " +
                                std::to_string(header_timeout_ms) +
                                ": must be in 100..600000");
  if (!(request_timeout_ms >= header_timeout_ms &&
        request_timeout_ms <= 3600000))
    throw std::invalid_argument("--request-timeout-ms " +
                                std::to_string(request_timeout_ms) +
                                ": must be in --header-timeout-ms..3600000");
  if (!(max_connections >= 1 && max_connections <= 100000))
    throw std::invalid_argument("--max-connections " +
                                std::to_string(max_connections) +
                                ": must be in 1..100000");
  const std::string secret = BootstrapSecret();  // the value is never shown
  if (!secret.empty() && (secret.size() < 16 || secret.size() > 256 ||
                          std::any_of(secret.begin(), secret.end(), [](char c) {
                            return !(c > 0x20 && c < 0x7f);
                          })))
    throw std::invalid_argument(
        std::string(bootstrap_token.empty() ? "--bootstrap-token-file "
                                            : "--bootstrap-token") +
        (bootstrap_token.empty() ? bootstrap_token_file : std::string()) +
        ": must be 16..256 printable characters without spaces");
  if (lcm_url != "none" && !HaveLcmEndpoint())
    throw std::invalid_argument("--lcm " + lcm_url +
                                ": this build has no LCM support "
                                "(FRICTIOND_WITH_LCM=OFF); use --lcm none");
}

std::string DaemonConfig::BootstrapSecret() const {
  if (!bootstrap_token.empty() || bootstrap_token_file.empty())
    return bootstrap_token;
  std::ifstream in(bootstrap_token_file);
  if (!in)
    throw std::invalid_argument("--bootstrap-token-file " +
                                bootstrap_token_file + ": cannot read");
  std::string line;
  std::getline(in, line);
  while (!line.empty() && (line.back() == '\r' || line.back() == ' '))
    line.pop_back();
  return line;
}

std::string RedactDbUrl(const std::string& url) {
  std::string out = url;
  const bool is_url =
      url.rfind("postgresql://", 0) == 0 || url.rfind("postgres://", 0) == 0;
  if (is_url) {
    // scheme://user:PASSWORD@host...
    const std::size_t start = url.find("://") + 3;
    const std::size_t at = url.find('@', start);
    const std::size_t slash = url.find('/', start);
    if (at != std::string::npos && (slash == std::string::npos || at < slash)) {
      const std::size_t colon = url.find(':', start);
      if (colon != std::string::npos && colon < at)
        out = url.substr(0, colon + 1) + "***" + url.substr(at);
    }
  }
  if (is_url || url.find('=') != std::string::npos) {
    // ?password=... or &password=... (URL), password=... (conninfo)
    std::size_t pos = 0;
    while ((pos = out.find("password=", pos)) != std::string::npos) {
      const bool starts = pos == 0 || out[pos - 1] == '?' ||
                          out[pos - 1] == '&' || out[pos - 1] == ' ';
      pos += 9;
      if (!starts) continue;
      std::size_t end = out.find_first_of("& ", pos);
      if (end == std::string::npos) end = out.size();
      out.replace(pos, end - pos, "***");
      pos += 3;
    }
  }
  return out;
}

Daemon::Daemon(DaemonConfig config) : config_(std::move(config)) {
  config_.Validate();
}

Daemon::~Daemon() { Stop(); }

int Daemon::Start() {
  LibraryOptions lo;
  lo.plan = config_.plan;
  {
    // Database and its WAL/SHM files are private to the daemon's user:
    // SQLite gives the -wal and -shm files the mode of the database file.
    const bool sqlite_file = config_.db.rfind("postgres", 0) != 0 &&
                             config_.db != ":memory:" &&
                             config_.db.rfind("file:", 0) != 0;
    if (sqlite_file) {
      std::string path = config_.db;
      if (path.rfind("sqlite://", 0) == 0) path = path.substr(9);
      const int fd =
          ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
      if (fd >= 0) ::close(fd);
    }
  }
  library_ = std::make_unique<FrictionLibrary>(OpenStore(config_.db), lo);
  if (!config_.data_dir.empty() && config_.data_dir != "none") {
    const int n = library_->LoadBundledData(config_.data_dir);
    if (n > 0)
      std::cerr << "frictiond: loaded " << n << " bundled dataset(s) from "
                << config_.data_dir << "\n";
  }
  HttpOptions ho;
  ho.max_body_bytes = static_cast<std::size_t>(config_.max_body_mb) << 20;
  ho.threads = config_.threads;
  ho.header_timeout_ms = config_.header_timeout_ms;
  ho.request_timeout_ms = config_.request_timeout_ms;
  ho.max_connections = config_.max_connections;
  http_ = std::make_unique<HttpServer>(ho);
  AuthOptions ao;
  ao.open_reads = config_.open_reads && IsLoopbackAddress(config_.bind);
  auth_ =
      std::make_unique<Authenticator>(library_->store(), http_->metrics(), ao);
  const std::string boot_secret = config_.BootstrapSecret();
  if (auto boot = auth_->BootstrapIfEmpty(boot_secret)) {
    if (boot_secret.empty()) {
      std::cout << "operator token: " << boot->secret << std::endl;
      std::cerr << "frictiond: created operator token " << boot->record.id
                << " (secret printed once on stdout; keep it)\n";
    } else {
      std::cerr << "frictiond: created operator token " << boot->record.id
                << " with the secret given by --bootstrap-token, "
                   "--bootstrap-token-file or FRICTIOND_BOOTSTRAP_TOKEN "
                   "(not shown)\n";
    }
  }
  if (config_.open_reads && !ao.open_reads)
    std::cerr << "frictiond: bound to " << config_.bind
              << " (not loopback): reads need a reader token\n";
  RegisterCoreRoutes(*http_, *library_);
  RegisterModelQueryRoutes(*http_, *library_);
  RegisterLuGreFeature(*http_, *library_);
  RegisterDiagnosisRoutes(*http_, *library_);
  RegisterJointRoutes(*http_, *library_);
  RegisterActuatorRoutes(*http_, *library_);
  RecognizeImageFn recognize = RegisterRecognitionRoutes(
      *http_, *library_, config_.recognition_operating_point);
  RegisterExportRoutes(*http_, *library_);
  RegisterConsoleRoutes(*http_, *library_);
  RegisterAuthRoutes(*http_, *auth_, library_->store());
  RegisterOpenApiRoute(*http_);  // last: it describes every route above
  auth_->Install(*http_);
  InstallQueryCheck(*http_);  // the names openapi.json documents, no others
  const int port = http_->Bind(config_.bind, config_.port);
  // Fleet: writes of other daemons on a shared database (PostgreSQL)
  // invalidate this daemon's cache and are broadcast on LCM.
  library_->WatchStoreChanges();
  if (config_.lcm_url != "none") {
    LcmEndpointOptions lo_lcm;
    lo_lcm.url = config_.lcm_url;
    lo_lcm.recognize = recognize;
    lo_lcm.security.keys = config_.LoadLcmKeys();
    lo_lcm.security.allow_unsigned = config_.lcm_allow_unsigned;
    lo_lcm.security.max_skew_s = config_.lcm_max_skew_s;
    lo_lcm.security.send_unsigned = config_.lcm_send_unsigned;
    lo_lcm.metrics = &http_->metrics();
    if (lo_lcm.security.keys.empty() && !lo_lcm.security.allow_unsigned)
      std::cerr << "frictiond: LCM: no lcm_keys and lcm_allow_unsigned off: "
                   "robots can query but every stroke chunk is dropped\n";
    {
      char host[256] = {0};
      if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
      lo_lcm.worker_id = std::string(host) + ":" + std::to_string(port);
    }
    lcm_ = std::make_unique<LcmEndpoint>(*library_, lo_lcm);
    lcm_->Start();
    std::cerr << "frictiond: LCM endpoint on " << config_.lcm_url << " ("
              << lo_lcm.security.keys.size() << " robot key(s), unsigned "
              << (lo_lcm.security.allow_unsigned ? "allowed" : "rejected")
              << ")\n";
  }
  return port;
}

void Daemon::Serve() { http_->Serve(); }

void Daemon::Stop() {
  if (lcm_) lcm_->Stop();
  if (http_) http_->Stop();
}

FrictionLibrary& Daemon::library() { return *library_; }
HttpServer& Daemon::http() { return *http_; }
Authenticator& Daemon::auth() { return *auth_; }

}  // namespace frictiond
