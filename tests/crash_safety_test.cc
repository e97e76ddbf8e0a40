// Crash safety (issue item 8; store.h: "once it returns it survives a crash
// (kill -9)"): a client uploads strokes while the daemon is SIGKILLed at
// random moments; after each restart on the same database every upload the
// daemon acknowledged (201) is there with its model version, and the
// database passes SQLite's integrity check.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sqlite3.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/storage/store.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::ExitStatus;
using testing::TempDir;

constexpr std::uint32_t kSeed = 20261122;  // kill moments and CSV choice
constexpr int kRounds = 12;
constexpr int kMinKillMs = 50;
constexpr int kMaxKillMs = 400;
const char* const kMaterials[] = {"crash-felt", "crash-steel"};

/// An upload the daemon acknowledged with 201.
struct Ack {
  std::string material;
  std::string robot;
  std::int64_t stroke_id = 0;
  int version = 0;
};

/// Runs `sql` and returns the first column of every row.
std::vector<std::string> Query(sqlite3* db, const char* sql) {
  std::vector<std::string> rows;
  sqlite3_stmt* stmt = nullptr;
  if (sqlite3_prepare_v2(db, sql, -1, &stmt, nullptr) != SQLITE_OK) {
    rows.push_back(std::string("prepare failed: ") + sqlite3_errmsg(db));
    return rows;
  }
  int rc;
  while ((rc = sqlite3_step(stmt)) == SQLITE_ROW) {
    const unsigned char* text = sqlite3_column_text(stmt, 0);
    rows.emplace_back(text ? reinterpret_cast<const char*>(text) : "NULL");
  }
  if (rc != SQLITE_DONE)
    rows.push_back(std::string("step failed: ") + sqlite3_errmsg(db));
  sqlite3_finalize(stmt);
  return rows;
}

/// Copies the database files exactly as the crash left them (so the
/// daemon's own recovery still starts from the crashed state) and runs
/// PRAGMA integrity_check and foreign_key_check on the copy.
void ExpectIntact(const std::string& db_path, const std::string& copy_dir) {
  namespace fs = std::filesystem;
  fs::remove_all(copy_dir);
  fs::create_directories(copy_dir);
  const std::string copy = copy_dir + "/copy.db";
  for (const char* suffix : {"", "-wal", "-shm"}) {
    if (fs::exists(db_path + suffix))
      fs::copy_file(db_path + suffix, copy + suffix);
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2(copy.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr),
            SQLITE_OK)
      << (db ? sqlite3_errmsg(db) : "out of memory");
  EXPECT_EQ(Query(db, "PRAGMA integrity_check"),
            std::vector<std::string>{"ok"});
  EXPECT_EQ(Query(db, "PRAGMA foreign_key_check"), std::vector<std::string>{});
  sqlite3_close(db);
}

/// Small distinct stroke files (2 strokes at 100 Hz, about 200 rows).
std::vector<std::string> MakeCsvPool(int n) {
  std::vector<std::string> pool;
  testing::SimulationSpec spec;
  spec.strokes = 2;
  spec.rate_hz = 100.0;
  for (int i = 0; i < n; ++i)
    pool.push_back(FormatStrokeCsv(testing::SimulateStrokes(spec, 100 + i)));
  return pool;
}

/// Checks that every acknowledged upload is served by the running daemon.
void ExpectAcknowledgedPresent(DaemonProcess& daemon,
                               const std::vector<Ack>& acks) {
  auto client = daemon.MakeClient();
  std::map<std::string, std::set<std::int64_t>> strokes;  // material -> ids
  std::map<std::string, std::map<int, std::int64_t>> versions;  // -> stroke
  for (const char* m : kMaterials) {
    auto res =
        client->Get((std::string("/v1/materials/") + m + "/strokes").c_str());
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    const json stroke_list = json::parse(res->body).at("strokes");
    for (const json& s : stroke_list)
      strokes[m].insert(s.at("id").get<std::int64_t>());
    res = client->Get((std::string("/v1/materials/") + m + "/models").c_str());
    ASSERT_TRUE(res);
    if (res->status == 404) continue;  // nothing stored yet
    ASSERT_EQ(res->status, 200) << res->body;
    const json version_list = json::parse(res->body).at("versions");
    for (const json& v : version_list)
      versions[m][v.at("version").get<int>()] =
          v.at("stroke_id").get<std::int64_t>();
  }
  for (const Ack& a : acks) {
    SCOPED_TRACE(a.material + " stroke " + std::to_string(a.stroke_id) +
                 " version " + std::to_string(a.version) + " robot " + a.robot);
    EXPECT_EQ(strokes[a.material].count(a.stroke_id), 1u)
        << "an acknowledged stroke is missing after SIGKILL";
    auto it = versions[a.material].find(a.version);
    ASSERT_NE(it, versions[a.material].end())
        << "an acknowledged model version is missing after SIGKILL";
    EXPECT_EQ(it->second, a.stroke_id) << "version made from another stroke";
  }
  // The newest acknowledged version of each material is served.
  std::map<std::string, int> newest;
  for (const Ack& a : acks)
    newest[a.material] = std::max(newest[a.material], a.version);
  for (const auto& [m, v] : newest) {
    auto res = client->Get(
        ("/v1/materials/" + m + "/model?version=" + std::to_string(v)).c_str());
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << res->body;
    res = client->Get(("/v1/materials/" + m + "/model").c_str());
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    EXPECT_GE(json::parse(res->body).value("version", 0), v);
  }
}

TEST(CrashSafetyTest, AcknowledgedUploadsSurviveSigkill) {
  const auto t0 = std::chrono::steady_clock::now();
  TempDir dir("crash_safety_test");
  DaemonOptions options;
  options.db = dir.path() + "/library.db";
  options.data = "none";
  options.threads = 4;
  DaemonProcess daemon(options);
  const std::vector<std::string> pool = MakeCsvPool(16);
  std::mt19937 rng(kSeed);
  std::uniform_int_distribution<int> kill_ms(kMinKillMs, kMaxKillMs);
  std::cout << "seed " << kSeed << ", " << kRounds << " rounds\n";

  std::vector<Ack> acks;
  std::mutex acks_mu;
  int last_acked_description = -1;
  int upload_counter = 0;
  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    daemon.Start();
    if (round > 0) {
      // Everything acknowledged before the previous SIGKILL is served.
      std::lock_guard<std::mutex> lock(acks_mu);
      ExpectAcknowledgedPresent(daemon, acks);
      // The last acknowledged metadata update, or a later one, survived.
      auto res = daemon.MakeClient()->Get("/v1/materials/crash-meta");
      ASSERT_TRUE(res);
      if (last_acked_description >= 0) {
        ASSERT_EQ(res->status, 200) << res->body;
        EXPECT_GE(std::stoi(json::parse(res->body).value("description", "-1")),
                  last_acked_description);
      }
    }

    std::atomic<bool> stop{false};
    std::atomic<int> round_acks{0};
    std::atomic<int> unexpected{0};
    std::string unexpected_body;
    const int base = upload_counter;
    // Uploads strokes back to back; records each 201.
    std::thread uploader([&] {
      auto client = daemon.MakeClient(/*read_timeout_s=*/10.0);
      for (int i = base; !stop.load(); ++i) {
        const std::string material = kMaterials[i % 2];
        const std::string robot =
            "r" + std::to_string(round) + "-" + std::to_string(i);
        auto res = client->Post(
            ("/v1/materials/" + material + "/strokes?robot=" + robot).c_str(),
            pool[static_cast<std::size_t>(i) % pool.size()],
            "text/csv");
        if (!res) continue;  // killed mid-request: not acknowledged
        if (res->status != 201) {
          if (unexpected.fetch_add(1) == 0) unexpected_body = res->body;
          continue;
        }
        const json j = json::parse(res->body);
        std::lock_guard<std::mutex> lock(acks_mu);
        acks.push_back(Ack{material,
                           robot,
                           j.at("stroke_id").get<std::int64_t>(),
                           j.at("version").get<int>()});
        round_acks.fetch_add(1);
        upload_counter = i + 1;
      }
    });
    // Updates one material's metadata back to back.
    std::atomic<int> last_put{-1};
    std::thread updater([&] {
      auto client = daemon.MakeClient(/*read_timeout_s=*/10.0);
      for (int i = std::max(0, last_acked_description + 1); !stop.load(); ++i) {
        auto res = client->Put("/v1/materials/crash-meta",
                               json{{"description", std::to_string(i)}}.dump(),
                               "application/json");
        if (res && (res->status == 200 || res->status == 201))
          last_put.store(i);
        else if (res)
          unexpected.fetch_add(1);
      }
    });

    const int wait_ms = kill_ms(rng);
    std::this_thread::sleep_for(std::chrono::milliseconds(wait_ms));
    const ExitStatus killed = daemon.Kill();
    stop.store(true);
    uploader.join();
    updater.join();
    if (last_put.load() >= 0) last_acked_description = last_put.load();
    EXPECT_FALSE(killed.exited) << killed.ToString();
    EXPECT_EQ(killed.signal, SIGKILL) << killed.ToString();
    EXPECT_EQ(unexpected.load(), 0) << unexpected_body;
    std::cout << "round " << round << ": SIGKILL after " << wait_ms << " ms, "
              << round_acks.load() << " acknowledged uploads\n";

    ExpectIntact(options.db, dir.path() + "/copy");
  }

  // Final restart: everything acknowledged in all rounds is there.
  daemon.Start();
  ExpectAcknowledgedPresent(daemon, acks);
  const ExitStatus s = daemon.Stop(SIGTERM);
  EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
  ExpectIntact(options.db, dir.path() + "/copy");

  // The audit log has an entry for exactly the strokes that were stored:
  // an upload and its entry commit together, so a kill cannot keep one
  // without the other (acknowledged or not).
  {
    auto store = OpenStore(options.db);
    for (const char* m : kMaterials) {
      std::set<std::int64_t> stored, audited;
      for (const StrokeRecord& st : store->ListStrokes(m, "default"))
        stored.insert(st.id);
      for (std::int64_t after = 0;;) {
        const std::vector<AuditEntry> page = store->ListAudit(after, 1000, m);
        if (page.empty()) break;
        after = page.back().id;
        for (const AuditEntry& e : page) {
          if (e.action != "POST /v1/materials/{id}/strokes") continue;
          EXPECT_TRUE(
              audited
                  .insert(
                      json::parse(e.detail).at("stroke_id").get<std::int64_t>())
                  .second)
              << e.detail;
        }
      }
      EXPECT_EQ(stored, audited) << m;
    }
  }

  // Acknowledged stroke ids are distinct; versions rise per material.
  std::set<std::int64_t> ids;
  std::map<std::string, int> last_version;
  for (const Ack& a : acks) {
    EXPECT_TRUE(ids.insert(a.stroke_id).second) << a.stroke_id;
    EXPECT_GT(a.version, last_version[a.material]) << a.material;
    last_version[a.material] = a.version;
  }
  EXPECT_GE(acks.size(), static_cast<std::size_t>(kRounds))
      << "too few uploads were acknowledged to test anything";
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
          .count();
  std::cout << acks.size() << " acknowledged uploads in " << seconds << " s\n";
  EXPECT_LT(seconds, 60.0);
}

}  // namespace
}  // namespace frictiond
