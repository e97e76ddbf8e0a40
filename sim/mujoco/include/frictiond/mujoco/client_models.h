#pragma once
/// @file
/// Geoms tagged with (material, fingertip) models fetched through the
/// client library (issue 21 item 1, docs/mujoco.md): each model comes from
/// FrictionClient::FetchModelWithInfo, so with ClientOptions::cache_dir
/// every fetched model is kept on disk and a simulation started without a
/// daemon gets the cached models (marked stale in the returned infos).
///
/// Usage:
/// @code
///   frictiond::ClientOptions o;
///   o.base_url = "http://127.0.0.1:8080";
///   o.cache_dir = "/var/cache/frictiond";
///   frictiond::FrictionClient client(o);
///   frictiond::mujoco::FrictionAdapter adapter;
///   TagGeomsFromClient(&adapter, m, client,
///                      {{"left_tip", "felt", "silicone"},
///                       {"right_tip", "felt", "silicone"}});
/// @endcode

#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "frictiond/client/client.h"
#include "frictiond/mujoco/friction_adapter.h"

namespace frictiond::mujoco {

/// One geom and the model it gets.
struct GeomModel {
  std::string geom;       ///< MuJoCo geom name
  std::string material;   ///< material id
  std::string fingertip;  ///< "" = the client's default fingertip
  int version = 0;        ///< 0 = newest
};

/// Fetches every geom's model (one request per distinct (material,
/// fingertip, version)) and tags the geoms; returns where each geom's model
/// came from, in the order of `geoms`. Nothing is tagged unless every model
/// was fetched and every geom exists.
/// @throws ClientError when a model is unavailable (no daemon and nothing
/// cached, 404, ...); std::invalid_argument for an unknown geom name or a
/// model set without a stochastic model.
std::vector<FetchInfo> TagGeomsFromClient(FrictionAdapter* adapter,
                                          const mjModel* m,
                                          FrictionClient& client,
                                          const std::vector<GeomModel>& geoms);

}  // namespace frictiond::mujoco
