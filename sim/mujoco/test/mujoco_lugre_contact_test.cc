// LuGre state per contact (FrictionAdapter::TagGeomLuGre, docs/mujoco.md):
// the pinch of drop_rate_test with LuGre fingertips. Static friction mu_s
// above the Coulomb level mu_c: a box held from rest at a load ratio
// between them stays (after microns of presliding), the same box already
// sliding keeps sliding, and above mu_s it breaks away.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <unistd.h>

#include "frictiond/mujoco/friction_adapter.h"

#include "pinch_scene.h"

namespace frictiond::mujoco {
namespace {

// mu_s 0.9, mu_c 0.6, v0 10 mm/s, sigma2 0, sigma0 50 /mm, sigma1 0.001 s/mm.
LuGreTheta Theta() { return MakeLuGreTheta(0.9, 0.6, 10.0, 0.0, 50.0, 0.001); }

struct Pinch {
  Pinch() {
    const std::string path = ::testing::TempDir() + "/lugre_pinch_" +
                             std::to_string(::getpid()) + ".xml";
    std::ofstream(path) << kPinchScene;
    char err[1000] = "";
    m = mj_loadXML(path.c_str(), nullptr, err, sizeof(err));
    std::remove(path.c_str());
    if (!m) ADD_FAILURE() << err;
    d = mj_makeData(m);
    box_z = m->jnt_qposadr[mj_name2id(m, mjOBJ_JOINT, "bz")];
    box_vz = m->jnt_dofadr[mj_name2id(m, mjOBJ_JOINT, "bz")];
    load = m->body_mass[mj_name2id(m, mjOBJ_BODY, "box")] * 9.81;
  }
  ~Pinch() {
    mj_deleteData(d);
    mj_deleteModel(m);
  }
  // Grip at load ratio L / (2 Fn) = ratio: 0.2 s without gravity, gravity
  // ramped in over 0.1 s (a load applied in 0.1 s, not in one step), held
  // until 1.2 s. initial_v_mm_s: the box's downward speed when the ramp
  // ends (already sliding). Returns the box's final z [mm].
  double Run(FrictionAdapter* adapter, double ratio, double initial_v_mm_s) {
    mj_resetData(m, d);
    adapter->Reset(1);
    d->ctrl[0] = d->ctrl[1] = load / (2.0 * ratio);
    for (int i = 0; i < 600; ++i) {
      const double t = i * m->opt.timestep;
      m->opt.gravity[2] = -9.81 * std::clamp((t - 0.2) / 0.1, 0.0, 1.0);
      if (i == 150 && initial_v_mm_s > 0)
        d->qvel[box_vz] = -initial_v_mm_s / 1000;
      adapter->Step(m, d);
      if (d->qpos[box_z] < -0.02) break;
    }
    return 1000 * d->qpos[box_z];
  }
  mjModel* m = nullptr;
  mjData* d = nullptr;
  int box_z = -1, box_vz = -1;
  double load = 0;
};

TEST(LuGreContact, StaticAboveCoulombHoldsAndSlidingKeepsSliding) {
  Pinch p;
  FrictionAdapter a;
  a.TagGeomLuGre(p.m, "tip_a", Theta());
  a.TagGeomLuGre(p.m, "tip_b", Theta());
  for (double ratio : {0.5, 0.75}) {
    const double z = p.Run(&a, ratio, 0.0);
    std::printf("ratio %.2f from rest: z %.4f mm, v %.4f mm/s\n",
                ratio,
                z,
                1000 * p.d->qvel[p.box_vz]);
    EXPECT_GT(z, -0.1) << "ratio " << ratio << ": presliding only";
    EXPECT_LT(std::fabs(p.d->qvel[p.box_vz]), 1e-4) << "ratio " << ratio;
  }
  // Already sliding at 20 mm/s >> v0: friction is near mu_c = 0.6 < 0.75.
  const double z_sliding = p.Run(&a, 0.75, 20.0);
  std::printf("ratio 0.75 sliding: z %.4f mm\n", z_sliding);
  EXPECT_LT(z_sliding, -10.0);
  // Above mu_s: breaks away from rest.
  const double z_above = p.Run(&a, 0.95, 0.0);
  std::printf("ratio 0.95 from rest: z %.4f mm\n", z_above);
  EXPECT_LT(z_above, -10.0);
  // The largest ratio held from rest with this load ramp (docs/mujoco.md):
  // below mu_s, because the soft contact's catches slip at about 1 mm/s,
  // a tenth of v0, where g(v) has already fallen.
  double held = 0.0;
  for (double ratio = 0.75; ratio < 0.9; ratio += 0.01)
    if (p.Run(&a, ratio, 0.0) > -0.1) held = ratio;
  std::printf("largest ratio held from rest: %.2f (mu_s 0.9)\n", held);
  EXPECT_GE(held, 0.75);
  EXPECT_LT(held, 0.9);
  // The state is per contact and starts at 0 each episode.
  EXPECT_EQ(a.episodes().size(), 2u);
}

TEST(LuGreContact, RefusesBadInput) {
  Pinch p;
  FrictionAdapter a;
  EXPECT_THROW(a.TagGeomLuGre(p.m, "nope", Theta()), std::invalid_argument);
  EXPECT_THROW(a.TagGeomLuGre(0, MakeLuGreTheta(-1, 0.6, 2, 0, 50, 0.001)),
               std::invalid_argument);
  EXPECT_THROW(a.TagGeomLuGre(p.m, "tip_a", ModelSet{}), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond::mujoco
