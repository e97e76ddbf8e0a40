// Live friction in MuJoCo: load an MJCF, tag a geom with a material model
// (the JSON of GET /v1/materials/{id}/model), step with the adapter and print
// each tagged contact's mu.
//   mujoco_live_friction scene.xml model.json fingertip_geom [steps]
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

#include <mujoco/mujoco.h>

#include "frictiond/mujoco/friction_adapter.h"

int main(int argc, char** argv) {
  if (argc < 4) {
    std::cerr << "usage: " << argv[0]
              << " scene.xml model.json geom_name [steps]\n";
    return 2;
  }
  char error[1000] = "";
  mjModel* m = mj_loadXML(argv[1], nullptr, error, sizeof(error));
  if (!m) {
    std::cerr << "MJCF: " << error << "\n";
    return 1;
  }
  mjData* d = mj_makeData(m);
  int rc = 0;
  try {
    std::ifstream in(argv[2]);
    std::stringstream text;
    text << in.rdbuf();
    const frictiond::ModelSet set =
        frictiond::ModelSetFromJson(nlohmann::json::parse(text.str()));
    frictiond::mujoco::FrictionAdapter adapter{
        frictiond::mujoco::AdapterOptions{}};
    adapter.TagGeom(m, argv[3], set);
    const int steps = argc > 4 ? std::atoi(argv[4]) : 1000;
    for (int i = 0; i < steps; ++i) {
      adapter.Step(m, d);
      if (i % 100 != 0) continue;
      for (const auto& [pair, ep] : adapter.episodes())
        std::printf("t=%.3f geoms %d-%d Fn=%.3f N v=%.2f mm/s mu=%.3f\n",
                    d->time,
                    pair.first,
                    pair.second,
                    ep.fn_n,
                    ep.v_mm_s,
                    ep.mu);
    }
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    rc = 1;
  }
  mj_deleteData(d);
  mj_deleteModel(m);
  return rc;
}
