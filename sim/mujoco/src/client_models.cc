#include "frictiond/mujoco/client_models.h"

#include <map>
#include <stdexcept>
#include <tuple>

namespace frictiond::mujoco {

std::vector<FetchInfo> TagGeomsFromClient(FrictionAdapter* adapter,
                                          const mjModel* m,
                                          FrictionClient& client,
                                          const std::vector<GeomModel>& geoms) {
  if (!adapter) throw std::invalid_argument("adapter: null");
  if (!m) throw std::invalid_argument("m: no MuJoCo model");
  // Fetch and check everything first, then tag (all or nothing).
  std::map<std::tuple<std::string, std::string, int>, FetchResult> fetched;
  std::vector<int> ids;
  for (const GeomModel& g : geoms) {
    const int id = mj_name2id(m, mjOBJ_GEOM, g.geom.c_str());
    if (id < 0)
      throw std::invalid_argument("geom: no geom named '" + g.geom + "'");
    ids.push_back(id);
    const auto key = std::make_tuple(g.material, g.fingertip, g.version);
    if (fetched.count(key)) continue;
    FetchResult r =
        client.FetchModelWithInfo(g.material, g.version, g.fingertip);
    if (!r.model.stochastic)
      throw std::invalid_argument("stochastic: model set of '" + g.material +
                                  "' has no stochastic model");
    fetched.emplace(key, std::move(r));
  }
  std::vector<FetchInfo> infos;
  for (std::size_t i = 0; i < geoms.size(); ++i) {
    const FetchResult& r = fetched.at(std::make_tuple(
        geoms[i].material, geoms[i].fingertip, geoms[i].version));
    adapter->TagGeom(ids[i], *r.model.stochastic);
    infos.push_back(r.info);
  }
  return infos;
}

}  // namespace frictiond::mujoco
