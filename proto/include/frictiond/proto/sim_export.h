#pragma once
/// @file
/// Text formats in which simulators take friction: MuJoCo MJCF, SDFormat,
/// URDF with Gazebo tags, USD (UsdPhysics material, usda text) and an Isaac
/// Lab style domain-randomisation range file (JSON). Pure formatting: the
/// numbers come from CalcSimFrictionValues (frictiond/estimators/
/// contact_friction.h); what they mean under each engine's combine rule is
/// in docs/export.md.
///
/// @code
///   SimExportInput in;
///   in.name = "felt"; in.material = "felt"; in.version = 3;
///   in.fn_n = 2.0; in.v_mm_s = 20.0; in.risk = 0.05;
///   in.mu = CalcMuDistribution(model, {{"fn_n", 2.0}, {"v_mm_s", 20.0}});
///   std::string mjcf = FormatSimExport(SimFormat::kMjcf, in);
/// @endcode

#include <string>

#include "frictiond/estimators/contact_friction.h"

namespace frictiond {

/// Export formats.
enum class SimFormat {
  kMjcf,   ///< MuJoCo: <default class=NAME><geom friction="s t r"/>
  kSdf,    ///< SDFormat: <surface><friction><ode><mu>, <mu2>
  kUrdf,   ///< URDF: <gazebo reference=NAME><mu1>, <mu2>
  kUsd,    ///< USD: Material prim with PhysicsMaterialAPI (usda 1.0 text)
  kIsaac,  ///< JSON with static_friction_range, dynamic_friction_range
};

/// "mjcf", "sdf", "urdf", "usd", "isaac".
const char* SimFormatName(SimFormat format);
/// Parses SimFormatName()'s output.
/// @throws std::invalid_argument naming "format", the value and the choices.
SimFormat ParseSimFormat(const std::string& name);
/// HTTP Content-Type of the format's text.
const char* SimFormatContentType(SimFormat format);
/// File name extension without the dot ("xml", "sdf", "urdf", "usda",
/// "json").
const char* SimFormatExtension(SimFormat format);

/// Everything one export says.
struct SimExportInput {
  std::string name;      ///< MJCF class, URDF link reference, SDF comment, USD
                         ///< prim (made a valid identifier); 1..128 printable
                         ///< ASCII characters
  std::string material;  ///< material id (for comments)
  std::string fingertip = "default";   ///< fingertip id (for comments)
  int version = 0;                     ///< model version (for comments)
  double fn_n = 0.0;                   ///< operating point: normal force [N]
  double v_mm_s = 0.0;                 ///< operating point: speed [mm/s]
  std::string operating_point_source;  ///< e.g. "query", "fitted means"
  double risk = 0.05;                  ///< slip risk of the sliding value (see
                                       ///< CalcSimFrictionValues)
  MuDistribution mu;                   ///< mu at the operating point
  std::string note;                    ///< extra comment line (may be empty)
};

/// MuJoCo's default torsional and rolling friction, exported unchanged
/// (the stochastic model measures sliding friction only).
inline constexpr double kMujocoTorsionalFriction = 0.005;
inline constexpr double kMujocoRollingFriction = 0.0001;

/// Formats the export.
/// @throws std::invalid_argument naming the field when name is empty, too
/// long or not printable ASCII, or risk is out of range.
std::string FormatSimExport(SimFormat format, const SimExportInput& in);

/// Escapes &, <, >, " and ' for XML text and attribute values (also used
/// for the HTML/SVG reports of the client tools).
std::string XmlEscape(const std::string& text);
/// Makes text safe inside <!-- -->: no "--" and no trailing '-'.
std::string XmlCommentText(const std::string& text);
/// A valid USD prim name ([A-Za-z_][A-Za-z0-9_]*): other characters become
/// '_', and a leading digit gets a '_' prefix. Empty input gives "_".
std::string MakeUsdIdentifier(const std::string& text);
/// Shortest decimal text that parses back to exactly `x` (at most 17
/// significant digits); "nan"/"inf" are never produced for finite x.
std::string FormatRoundTrip(double x);

}  // namespace frictiond
