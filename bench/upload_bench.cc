// upload: stroke upload latency against a pair's history, and upload
// throughput of two clients on two materials, through the real daemon over
// HTTP loopback (POST /v1/materials/{id}/strokes, every family fitter the
// daemon registers, SQLite with synchronous=FULL).
//
// upload_history: median latency of a 250-sample stroke upload when the pair
//   already holds 1,000 strokes (value) against the same upload when it holds
//   10 strokes (baseline; one 10-stroke pair per timed upload, each warmed by
//   one untimed upload), uploads to the two sizes interleaved. The issue's
//   figure is value / baseline (goal <= 1.5); the contract's ratio is
//   baseline / value (goal >= 0.667). The history is seeded through the
//   store directly (one transaction per stroke, before the daemon starts);
//   one untimed upload per pair first loads the pair into the daemon's cache.
// upload_parallel: uploads per second of two clients uploading to two
//   materials at once, against one client uploading alone (baseline), each
//   pair holding 10 strokes first. Goal >= 1.6x. Each client is a
//   FrictionClient (the client library a robot uploads with: one kept-alive
//   connection); the note gives one client's milliseconds per upload.
//
// Usage: upload --only history|parallel [--uploads N] [--seconds S]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

#include "frictiond/client/client.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/library.h"
#include "frictiond/storage/store.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

#include "bench_json.h"

namespace frictiond::bench {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// One simulated 250-sample stroke (1 s at 250 Hz: 0.4 s rest, 0.6 s slip)
/// of the eq. (1) truth, as CSV.
std::string StrokeCsv(std::uint64_t seed) {
  testing::SimulationSpec spec;
  spec.strokes = 1;
  spec.rate_hz = 250.0;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

/// Stores `strokes` uploads of `material` through the store (no daemon), each
/// with the model of its first upload fitted by a FrictionLibrary.
void Seed(const std::string& db,
          const std::string& material,
          int strokes,
          std::uint64_t seed) {
  FrictionLibrary lib(OpenStore(db));
  const IngestResult first = lib.IngestStrokes(material, StrokeCsv(seed), {});
  ModelRecord model;
  model.material = material;
  model.reason = "upload";
  model.json = lib.store().GetLatestModel(material, "default")->json;
  for (int i = 1; i < strokes; ++i) {
    StrokeRecord s;
    s.material = material;
    s.robot = "bench-seed";
    s.csv = StrokeCsv(seed + static_cast<std::uint64_t>(i));
    s.samples = static_cast<std::int64_t>(ParseStrokeCsv(s.csv).size());
    lib.store().CommitUpload(s, model);
  }
  (void)first;
}

/// Posts one stroke CSV; returns seconds. @throws unless 201.
double Upload(httplib::Client& client,
              const std::string& material,
              const std::string& csv) {
  const std::string path = "/v1/materials/" + material + "/strokes";
  const auto t0 = Clock::now();
  auto res = client.Post(path.c_str(), csv, "text/csv");
  const double s = SecondsSince(t0);
  if (!res || res->status != 201)
    throw std::runtime_error(
        "upload to " + material + " failed: " +
        (res ? std::to_string(res->status) + " " + res->body.substr(0, 300)
             : httplib::to_string(res.error())));
  return s;
}

int History(int uploads) {
  testing::TempDir dir("bench_upload_history");
  const std::string db = dir.path() + "/library.db";
  auto t0 = Clock::now();
  // One 10-stroke pair per timed upload, so that every timed upload meets
  // exactly 10 stored strokes (+ the untimed one), never a grown history.
  for (int r = 0; r < uploads; ++r)
    Seed(db, "hist-10-" + std::to_string(r), 10, 1000 + 100 * r);
  Seed(db, "hist-1000", 1000, 500000);
  std::cerr << "upload_history: seeded " << uploads
            << " x 10 + 1000 strokes in " << SecondsSince(t0) << " s\n";
  testing::DaemonOptions options;
  options.db = db;
  options.data = "none";
  testing::DaemonProcess daemon(options);
  daemon.Start();
  auto client = daemon.MakeClient(60.0);
  // Untimed: the first upload of each pair loads its history into the cache.
  for (int r = 0; r < uploads; ++r)
    Upload(*client, "hist-10-" + std::to_string(r), StrokeCsv(90000));
  std::cerr << "upload_history: first upload to hist-1000 (loads the pair): "
            << Upload(*client, "hist-1000", StrokeCsv(90000)) * 1e3 << " ms\n";
  std::vector<double> small, large;
  for (int r = 0; r < uploads; ++r) {
    const std::string csv = StrokeCsv(100000 + static_cast<std::uint64_t>(r));
    // Alternate which pair goes first so drift in load hits both alike.
    const std::string small_pair = "hist-10-" + std::to_string(r);
    if (r % 2 == 0) {
      small.push_back(Upload(*client, small_pair, csv));
      large.push_back(Upload(*client, "hist-1000", csv));
    } else {
      large.push_back(Upload(*client, "hist-1000", csv));
      small.push_back(Upload(*client, small_pair, csv));
    }
  }
  std::cerr << "upload_history: medians " << Median(small) * 1e3 << " ms (10"
            << " strokes), " << Median(large) * 1e3 << " ms (1000 strokes)\n";
  daemon.Stop();
  BenchResult out;
  out.bench = "upload_history";
  out.value = Median(large) * 1e3;
  out.unit = "ms";
  out.baseline = Median(small) * 1e3;
  out.baseline_name = "same 250-sample upload when the pair holds 10 strokes";
  out.lower_is_better = true;
  out.goal = "value/baseline <= 1.5 (ratio >= 0.667)";
  out.note =
      "HTTP loopback to the daemon (all family fitters, SQLite "
      "synchronous=FULL); median of " +
      std::to_string(uploads) +
      " interleaved uploads per size, each pair warmed by one untimed upload "
      "(a fresh 10-stroke pair per timed upload); "
      "value/baseline = " +
      nlohmann::json(RoundSignificant(out.value / out.baseline, 3)).dump();
  PrintBenchLine(out);
  return 0;
}

/// CPU seconds (user + system) the process `pid` has used so far.
double ProcessCpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(in, line);
  // Fields after the command (which may hold spaces), from its ')':
  // 3 state ... 14 utime, 15 stime.
  std::istringstream rest(line.substr(line.rfind(')') + 2));
  std::string field;
  double ticks = 0;
  for (int k = 3; k <= 15 && rest >> field; ++k)
    if (k >= 14) ticks += std::atof(field.c_str());
  return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

/// CPU seconds this process (the clients) has used so far.
double SelfCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec +
         1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

/// Uploads per second of `materials.size()` clients, one per material, for
/// `seconds`. Prints the daemon's and the clients' CPU time per upload.
double Throughput(const testing::DaemonProcess& daemon,
                  const std::vector<std::string>& materials,
                  double seconds,
                  std::uint64_t seed) {
  const double daemon_cpu0 = ProcessCpuSeconds(daemon.pid());
  const double client_cpu0 = SelfCpuSeconds();
  std::atomic<int> done{0};
  std::atomic<bool> failed{false};
  std::string error;
  std::vector<std::thread> clients;
  const auto t0 = Clock::now();
  for (std::size_t c = 0; c < materials.size(); ++c) {
    clients.emplace_back([&, c] {
      // The client library a robot uploads with (one keep-alive connection).
      ClientOptions o;
      o.base_url = daemon.base_url();
      o.token = daemon.options().operator_token;
      o.timeout_s = 60.0;
      FrictionClient client(o);
      try {
        for (std::uint64_t i = 0; SecondsSince(t0) < seconds; ++i) {
          client.UploadStrokes(materials[c], StrokeCsv(seed + 1000 * c + i));
          ++done;
        }
      } catch (const std::exception& e) {
        if (!failed.exchange(true)) error = e.what();
      }
    });
  }
  for (auto& t : clients) t.join();
  const double wall = SecondsSince(t0);
  if (failed) throw std::runtime_error(error);
  std::cerr << "upload_parallel: " << materials.size() << " client(s): " << done
            << " uploads, wall " << wall * 1e3 / done
            << " ms/upload, CPU per upload: daemon "
            << (ProcessCpuSeconds(daemon.pid()) - daemon_cpu0) * 1e3 / done
            << " ms, clients " << (SelfCpuSeconds() - client_cpu0) * 1e3 / done
            << " ms\n";
  return done / wall;
}

/// The same comparison in-process through FrictionLibrary::IngestStrokes
/// (no HTTP, no token check or audit entry): the ingestor's own parallelism.
/// Diagnostic on stderr only.
void ParallelInProcess(double seconds) {
  testing::TempDir dir("bench_upload_parallel_lib");
  const std::string db = dir.path() + "/library.db";
  for (const char* m : {"par-a", "par-b", "solo"})
    Seed(db, m, 10, m[0] == 's' ? 7000 : (m[4] == 'a' ? 8000 : 9000));
  FrictionLibrary lib(OpenStore(db));
  for (const char* m : {"par-a", "par-b", "solo"})
    lib.IngestStrokes(m, StrokeCsv(90000), {});
  auto run = [&](const std::vector<std::string>& materials) {
    const double cpu0 = SelfCpuSeconds();
    std::atomic<int> done{0};
    std::vector<std::thread> threads;
    const auto t0 = Clock::now();
    for (std::size_t c = 0; c < materials.size(); ++c) {
      threads.emplace_back([&, c] {
        for (std::uint64_t i = 0; SecondsSince(t0) < seconds; ++i) {
          lib.IngestStrokes(materials[c], StrokeCsv(400000 + 1000 * c + i), {});
          ++done;
        }
      });
    }
    for (auto& t : threads) t.join();
    const double wall = SecondsSince(t0);
    std::cerr << "upload_parallel: in-process, " << materials.size()
              << " thread(s): CPU per upload "
              << (SelfCpuSeconds() - cpu0) * 1e3 / done << " ms, "
              << (SelfCpuSeconds() - cpu0) / wall << " cores busy\n";
    return done / wall;
  };
  const double one = run({"solo"});
  const double two = run({"par-a", "par-b"});
  std::cerr << "upload_parallel: in-process FrictionLibrary (no HTTP, no "
            << "audit): one client " << one << " uploads/s, two clients " << two
            << " uploads/s (" << two / one << "x)\n";
}

int Parallel(double seconds) {
  ParallelInProcess(seconds / 2);
  testing::TempDir dir("bench_upload_parallel");
  const std::string db = dir.path() + "/library.db";
  for (const char* m : {"par-a", "par-b", "solo"})
    Seed(db, m, 10, m[0] == 's' ? 7000 : (m[4] == 'a' ? 8000 : 9000));
  testing::DaemonOptions options;
  options.db = db;
  options.data = "none";
  testing::DaemonProcess daemon(options);
  daemon.Start();
  {
    auto client = daemon.MakeClient(60.0);
    for (const char* m : {"par-a", "par-b", "solo"})
      Upload(*client, m, StrokeCsv(90000));  // untimed: loads the pairs
  }
  // one, two, one, two: the medians of two rounds each.
  std::vector<double> one, two;
  for (int round = 0; round < 2; ++round) {
    one.push_back(Throughput(daemon, {"solo"}, seconds, 200000 + round));
    two.push_back(
        Throughput(daemon, {"par-a", "par-b"}, seconds, 300000 + round));
    std::cerr << "upload_parallel: round " << round << ": one client "
              << one.back() << " uploads/s, two clients " << two.back()
              << " uploads/s\n";
  }
  daemon.Stop();
  BenchResult out;
  out.bench = "upload_parallel";
  out.value = (two[0] + two[1]) / 2;
  out.unit = "uploads/s";
  out.baseline = (one[0] + one[1]) / 2;
  out.baseline_name = "one client uploading to one material";
  out.goal = ">= 1.6x one client";
  out.note =
      "HTTP loopback to the daemon, FrictionClient (keep-alive), 250-sample "
      "strokes, pairs holding 10+ strokes, two clients on two materials vs "
      "one client (" +
      nlohmann::json(RoundSignificant(1e3 / out.baseline, 3)).dump() +
      " ms per upload), " + std::to_string(static_cast<int>(seconds)) +
      " s each, two rounds alternated, mean; " +
      std::to_string(std::thread::hardware_concurrency()) +
      " hardware threads shared by daemon and clients";
  PrintBenchLine(out);
  return 0;
}

int Main(int argc, char** argv) {
  std::string only;
  int uploads = 31;
  double seconds = 4.0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--only")
      only = argv[i + 1];
    else if (flag == "--uploads")
      uploads = std::atoi(argv[i + 1]);
    else if (flag == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else
      throw std::invalid_argument("unknown flag " + flag);
  }
  if (!(uploads >= 3 && uploads <= 101))
    throw std::invalid_argument("--uploads must be in 3..101");
  if (!(seconds > 0 && seconds <= 10))
    throw std::invalid_argument("--seconds must be in (0, 10]");
  if (only == "history") return History(uploads);
  if (only == "parallel") return Parallel(seconds);
  throw std::invalid_argument("--only must be history or parallel");
}

}  // namespace
}  // namespace frictiond::bench

int main(int argc, char** argv) {
  try {
    return frictiond::bench::Main(argc, argv);
  } catch (const std::exception& e) {
    std::string which = "upload_history";
    for (int i = 1; i + 1 < argc; ++i)
      if (std::string(argv[i]) == "--only" &&
          std::string(argv[i + 1]) == "parallel")
        which = "upload_parallel";
    std::printf(
        "%s\n",
        frictiond::bench::FormatBenchError(which, e.what(), "").c_str());
    return 1;
  }
}
