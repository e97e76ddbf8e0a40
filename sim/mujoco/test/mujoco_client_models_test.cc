// Geoms tagged with models fetched through the client library and its
// offline cache (client_models.h), against the service on loopback: an
// in-process FrictionLibrary behind the HTTP routes on 127.0.0.1.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/mujoco/client_models.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/routes.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond::mujoco {
namespace {

// A sphere resting on a plane: one contact.
constexpr const char* kScene = R"(
<mujoco>
  <option timestep="0.002" integrator="Euler" cone="elliptic"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="ball" pos="0 0 0.0099">
      <freejoint/>
      <geom name="tip" type="sphere" size="0.01" mass="0.05"/>
    </body>
  </worldbody>
</mujoco>)";

// The service on 127.0.0.1 (port 0: a free one), serving in a thread.
class LoopbackService {
 public:
  LoopbackService() : lib_(OpenStore(":memory:")) {
    RegisterCoreRoutes(http_, lib_);
    port_ = http_.Bind("127.0.0.1", 0);
    thread_ = std::thread([this] { http_.Serve(); });
    for (int i = 0; i < 500 && !http_.running(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ~LoopbackService() { Stop(); }
  void Stop() {
    if (!thread_.joinable()) return;
    http_.Stop();
    thread_.join();
  }
  FrictionLibrary& lib() { return lib_; }
  std::string url() const {
    return "http://127.0.0.1:" + std::to_string(port_);
  }

 private:
  FrictionLibrary lib_;
  HttpServer http_;
  int port_ = 0;
  std::thread thread_;
};

TEST(ClientModels, TagsFromTheDaemonThenFromTheCacheOffline) {
  testing::TempDir dir("mujoco_client_models");
  const std::string xml = dir.path() + "/scene.xml";
  std::ofstream(xml) << kScene;
  char err[1000] = "";
  mjModel* m = mj_loadXML(xml.c_str(), nullptr, err, sizeof(err));
  ASSERT_TRUE(m) << err;
  mjData* d = mj_makeData(m);

  auto service = std::make_unique<LoopbackService>();
  testing::SimulationSpec spec;
  spec.b0 = 0.7;
  spec.strokes = 10;
  IngestOptions io;
  io.fingertip = "silicone";
  service->lib().IngestStrokes(
      "felt", FormatStrokeCsv(testing::SimulateStrokes(spec, 5)), io);

  ClientOptions o;
  o.base_url = service->url();
  o.timeout_s = 5.0;
  o.cache_dir = dir.path() + "/cache";
  FrictionClient client(o);
  const std::vector<GeomModel> geoms = {{"tip", "felt", "silicone", 0}};

  AdapterOptions mean;
  mean.mode = FrictionMode::kMean;
  FrictionAdapter online(mean);
  const std::vector<FetchInfo> a =
      TagGeomsFromClient(&online, m, client, geoms);
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].source, "daemon");
  EXPECT_FALSE(a[0].stale);
  EXPECT_EQ(a[0].version, 1);
  const auto served = service->lib().FindModel("felt", "silicone");
  ASSERT_TRUE(served && served->set.stochastic);
  for (int i = 0; i < 50; ++i) online.Step(m, d);
  ASSERT_EQ(online.episodes().size(), 1u) << "the tagged contact";
  const double mu_online = online.episodes().begin()->second.mu;
  EXPECT_NEAR(mu_online,
              online.CalcMu(*served->set.stochastic,
                            online.episodes().begin()->second.fn_n,
                            online.episodes().begin()->second.v_mm_s,
                            0.0),
              0.05);

  // The daemon goes away: the same geoms get the cached model, stale.
  service.reset();
  FrictionAdapter offline(mean);
  const std::vector<FetchInfo> b =
      TagGeomsFromClient(&offline, m, client, geoms);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].source, "cache");
  EXPECT_TRUE(b[0].stale);
  EXPECT_EQ(b[0].version, 1);
  mj_resetData(m, d);
  for (int i = 0; i < 50; ++i) offline.Step(m, d);
  ASSERT_EQ(offline.episodes().size(), 1u);
  EXPECT_EQ(offline.episodes().begin()->second.mu, mu_online)
      << "the same model, the same run";

  // Nothing cached for another pair and no daemon: an error, nothing tagged.
  FrictionAdapter none(mean);
  EXPECT_THROW(
      TagGeomsFromClient(&none, m, client, {{"tip", "cork", "silicone", 0}}),
      ClientError);
  EXPECT_THROW(
      TagGeomsFromClient(&none, m, client, {{"nope", "felt", "silicone", 0}}),
      std::invalid_argument);
  mj_resetData(m, d);
  for (int i = 0; i < 50; ++i) none.Step(m, d);
  EXPECT_TRUE(none.episodes().empty());
  mj_deleteData(d);
  mj_deleteModel(m);
}

}  // namespace
}  // namespace frictiond::mujoco
