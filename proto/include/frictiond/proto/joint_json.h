#pragma once
/// @file
/// Wire formats of the joint-friction feature (paper 002, issue 9): the
/// "joint" model family stored in a model version of (material, joint id),
/// the joint-data CSV, and robot descriptions (DH kinematics, stiffness,
/// joint friction references). Documented in docs/joint.md.

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/joint_friction.h"
#include "frictiond/estimators/joint_identification.h"
#include "frictiond/estimators/repeatability.h"

namespace frictiond {

/// JSON key of the family in a model set.
inline constexpr const char* kJointFamilyKey = "joint";

/// The "joint" family: fixed joint properties, the three fits, their
/// held-out scores and the span of the data they came from. Copyable.
struct JointFamily {
  JointConfig config;
  WearParams wear;
  JointFitResult mixed;                 ///< kind kMixed
  JointFitResult stribeck;              ///< kind kStribeckViscous
  JointFitResult lugre;                 ///< kind kLuGreSteadyState
  std::vector<JointModelScore> scores;  ///< held-out, same order
  std::size_t samples = 0;
  double v_min_mm_s = 0, v_max_mm_s = 0;
  double load_min_n = 0, load_max_n = 0;
  double s_min_um = 0, s_max_um = 0;  ///< Sommerfeld span of the data
};

nlohmann::json JointConfigToJson(const JointConfig& config,
                                 const WearParams& wear);
/// Reads {"surface":{...},"contact":{...},"lubricant":{...},"wear":{...}};
/// missing keys keep their defaults. Validates.
/// @throws FieldError naming the field ("surface.salt_um = 0
/// (must be > 0)").
void JointConfigFromJson(const nlohmann::json& j,
                         JointConfig* config,
                         WearParams* wear);

nlohmann::json JointFamilyToJson(const JointFamily& family);
/// @throws FieldError naming the missing or malformed field.
JointFamily JointFamilyFromJson(const nlohmann::json& j);

/// Parses joint data: CSV with a header, '#' comment lines, columns
/// v_mm_s, load_n, mu (required) and temp_c or eta_pa_s (one required;
/// eta_pa_s wins when both are given, temp_c is then kept as a covariate);
/// viscosity from temp_c through `lubricant`. Other columns are ignored.
/// @throws FieldError "line N: column = value (rule)" or naming
/// the missing column; at most max_rows data rows.
JointData ParseJointCsv(const std::string& text,
                        const Lubricant& lubricant,
                        std::size_t max_rows = 1000000);

/// Where a robot joint's friction scatter comes from: a joint model of the
/// library at an operating state. Torque = mu * load_n * radius_mm / 1000
/// [N m] (revolute) or force = mu * load_n [N] (prismatic).
struct JointFrictionRef {
  std::string material;
  std::string joint = "default";
  double v_mm_s = 100;
  double load_n = 100;
  double temp_c = 40;
  double radius_mm = 20;  ///< friction radius (revolute joints)
};

/// A robot: arm (sigma_tau set directly or 0 when `friction` names a joint
/// model), per-joint optional friction references and a home configuration
/// (IK start). Copyable.
struct RobotDescription {
  SerialArm arm;
  std::vector<std::optional<JointFrictionRef>> friction;
  Eigen::VectorXd q_home;
};

/// JSON: {"joints": [{"type": "revolute"|"prismatic", "a_mm", "alpha_deg",
/// "d_mm", "theta_deg", "stiffness", "sigma_tau" | "friction": {"material",
/// "joint", "v_mm_s", "load_n", "temp_c", "radius_mm"}, "q_min", "q_max"}],
/// "q_home": [...]}. Angles in degrees on the wire (q of revolute joints in
/// degrees too), radians inside.
/// @throws FieldError naming the field ("joints[1].stiffness =
/// 0 (must be > 0)").
RobotDescription RobotFromJson(const nlohmann::json& j);
nlohmann::json RobotToJson(const RobotDescription& robot);

}  // namespace frictiond
