// Consumer of the installed MuJoCo adapter (find_package(frictiond
// COMPONENTS mujoco)): constructs the adapter and evaluates eq. (1).
#include <cstdio>

#include "frictiond/mujoco/friction_adapter.h"

int main() {
  frictiond::StochasticFrictionModel model;
  model.mu.terms = {frictiond::Term::Intercept()};
  model.mu.beta = Eigen::VectorXd::Constant(1, 0.7);
  frictiond::mujoco::FrictionAdapter adapter{
      frictiond::mujoco::AdapterOptions{}};
  adapter.TagGeom(0, model);
  const double mu = adapter.CalcMu(model, 2.0, 0.0, 0.0);
  std::printf("sim_app: mu %.2f, MuJoCo %d\n", mu, mj_version());
  return mu > 0.69 && mu < 0.71 ? 0 : 1;
}
