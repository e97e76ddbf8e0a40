#pragma once
/// @file
/// Joint-friction part of the robot client (paper 002, issue 9): upload
/// joint data, ask for the friction of a joint at a state, register a robot
/// and ask for its repeatability ellipsoid; or take the "joint" family out
/// of a fetched model and evaluate the mixed model locally.
///
/// @code
///   frictiond::FrictionClient client({"http://127.0.0.1:8080"});
///   frictiond::UploadJointData(client, "steel-oil", "j2", csv);
///   const auto f = frictiond::FetchJointFriction(client, "steel-oil", "j2",
///                                                200.0, 100.0, 40.0);
///   frictiond::PutRobot(client, "arm1", robot_json);
///   const auto e = frictiond::FetchRepeatability(client, "arm1", 350, 150,
///   100);
/// @endcode

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "frictiond/client/client.h"
#include "frictiond/proto/joint_json.h"
#include "frictiond/proto/model_json.h"

namespace frictiond {

/// Uploads joint data (CSV: v_mm_s, load_n, mu, temp_c or eta_pa_s) for
/// (material, joint); `params` are the joint's fixed properties as query
/// parameters (area_mm2, salt_um, ...; docs/joint.md). Returns the reply
/// ({"material", "joint", "version", "family"}).
/// @throws ClientError (400 naming the field, 415, 422 too few samples).
nlohmann::json UploadJointData(
    FrictionClient& client,
    const std::string& material,
    const std::string& joint,
    const std::string& csv,
    const std::vector<std::pair<std::string, std::string>>& params = {});

/// Answer of GET /v1/materials/{id}/joint-friction.
struct JointFrictionReply {
  double mu = 0;             ///< mixed-model friction coefficient [-]
  double sigma = 0;          ///< its sd (contact scatter + parameters) [-]
  double sommerfeld_um = 0;  ///< S = eta V / p [um]
  std::string regime;        ///< boundary | mixed | full_film
  int version = 0;
  nlohmann::json body;  ///< full reply
};

/// @throws std::invalid_argument for non-positive v or load (nothing sent).
/// @throws ClientError (404 no joint model, 422 mixed model not identified).
JointFrictionReply FetchJointFriction(FrictionClient& client,
                                      const std::string& material,
                                      const std::string& joint,
                                      double v_mm_s,
                                      double load_n,
                                      double temp_c);

/// PUT /v1/robots/{id} with a robot description (RobotFromJson's shape).
/// @throws ClientError (400 naming the field).
nlohmann::json PutRobot(FrictionClient& client,
                        const std::string& robot,
                        const nlohmann::json& description);

/// Answer of GET /v1/robots/{id}/repeatability.
struct RepeatabilityReply {
  Eigen::Vector3d semi_axes_um = Eigen::Vector3d::Zero();  ///< ascending
  double probability = 0;
  nlohmann::json body;  ///< full reply (axes, covariance, q, joints)
};

/// @throws std::invalid_argument for a non-finite coordinate or a
/// probability outside (0, 1). @throws ClientError (404 unknown robot, 422
/// unreachable target or missing joint model).
RepeatabilityReply FetchRepeatability(FrictionClient& client,
                                      const std::string& robot,
                                      double x_mm,
                                      double y_mm,
                                      double z_mm,
                                      double probability = 0.95);

/// The "joint" family of a model set (fetch with fingertip = joint id), or
/// nullopt. @throws std::invalid_argument when malformed.
std::optional<JointFamily> JointFamilyFromModel(const ModelSet& set);

}  // namespace frictiond
