// Fleet over LCM: a model version made through another daemon of the fleet
// (shared PostgreSQL library) is broadcast as model_update_v1 by this
// daemon too, once per version.
#include <chrono>
#include <memory>
#include <string>
#include <thread>

// Eigen (robot_simulator.h) before httplib.h: <resolv.h> (via httplib)
// defines a macro _res that breaks Eigen's product kernels.
#include <Eigen/Dense>
#include <gtest/gtest.h>
#include <httplib.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/storage/store.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/pg_server.h"
#include "frictiond/testing/stroke_simulator.h"

#include "lcm_test_inbox.h"
#include "robot_simulator.h"

namespace frictiond {
namespace {

namespace ft = frictiond::testing;

bool PgBackendBuilt() {
  try {
    OpenStore("postgresql://postgres@127.0.0.1:1/x?connect_timeout=1");
  } catch (const std::invalid_argument&) {
    return false;
  } catch (const std::exception&) {
  }
  return true;
}

TEST(LcmFleetTest, RemoteVersionsAreBroadcastOncePerVersion) {
  const std::string lcm_url = ft::MakeTestLcmUrl(41);
  std::string why;
  if (!ft::CheckLcmLoopback(lcm_url, &why)) GTEST_SKIP() << why;
  if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
  if (!ft::PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
  ft::PgServer pg;
  pg.Start();
  const std::string db = pg.CreateDatabase("lcm_fleet");
  ft::TempDir dir("lcm_fleet");
  ft::DaemonOptions oa;
  oa.db = db;
  oa.data = "none";
  oa.lcm = lcm_url;                         // A talks to the robots
  oa.extra_args = {"--lcm-send-unsigned"};  // the inbox reads unsigned
  oa.log_path = dir.path() + "/a.log";
  ft::DaemonProcess a(oa);
  a.Start();
  ft::DaemonOptions ob = oa;
  ob.lcm = "none";  // B only serves HTTP
  ob.log_path = dir.path() + "/b.log";
  ft::DaemonProcess b(ob);
  b.Start();

  ft::LcmInbox inbox(lcm_url);
  ASSERT_TRUE(inbox.good());
  for (int version = 1; version <= 2; ++version) {
    ft::SimulationSpec spec;
    spec.strokes = 4;
    auto res = b.MakeClient()->Post(
        "/v1/materials/felt/strokes",
        FormatStrokeCsv(ft::SimulateStrokes(spec, 50 + version)),
        "text/csv");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    auto count = [&] {
      int n = 0;
      for (const auto& u : inbox.updates)
        n += u.model.material == "felt" && u.model.version == version;
      return n;
    };
    ASSERT_TRUE(inbox.WaitFor([&] { return count() >= 1; }, 3.0))
        << "daemon A did not broadcast version " << version
        << " made through daemon B\n"
        << a.ReadLog();
    inbox.WaitFor([] { return false; }, 0.5);  // any duplicate arrives now
    EXPECT_EQ(count(), 1) << "version " << version << " broadcast twice";
  }
}

}  // namespace
}  // namespace frictiond
