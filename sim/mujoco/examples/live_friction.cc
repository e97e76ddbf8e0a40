// Live friction in MuJoCo: load an MJCF, tag a geom with a material model
// (the JSON of GET /v1/materials/{id}/model), optionally a joint with an
// identified actuator friction law (the model file of issue 20, e.g.
// data/actuator/xl330_pendulum.model.json), step with the adapter and print
// each tagged contact's mu and the joint's friction torque.
//   mujoco_live_friction scene.xml model.json fingertip_geom [steps
//                        [joint_name actuator_model.json]]
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

#include <mujoco/mujoco.h>

#include "frictiond/mujoco/friction_adapter.h"
#include "frictiond/mujoco/joint_friction.h"
#include "frictiond/proto/actuator_json.h"

int main(int argc, char** argv) {
  if (argc < 4) {
    std::cerr << "usage: " << argv[0]
              << " scene.xml model.json geom_name [steps [joint_name "
                 "actuator_model.json]]\n";
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
    frictiond::mujoco::JointFriction joints;
    if (argc > 6) {
      std::ifstream jin(argv[6]);
      std::stringstream jtext;
      jtext << jin.rdbuf();
      const nlohmann::json j = nlohmann::json::parse(jtext.str());
      const frictiond::ActuatorModel am = frictiond::ActuatorModelFromJson(
          j.contains("model") ? j["model"] : j);
      joints.TagJoint(m, argv[5], am.law, am.friction);
      adapter.SetJointFriction(&joints);
    }
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
      for (const auto& jt : joints.joints())
        std::printf("t=%.3f joint %d friction torque %.4f N m\n",
                    d->time,
                    jt.joint,
                    jt.torque_nm);
    }
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    rc = 1;
  }
  mj_deleteData(d);
  mj_deleteModel(m);
  return rc;
}
