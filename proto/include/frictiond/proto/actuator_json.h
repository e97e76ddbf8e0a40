#pragma once
/// @file
/// Wire formats of the actuator feature (issue 20, docs/actuator.md): the
/// measured log JSON (format of data/bam_xl330/logs), the actuator model
/// file, BAM's published parameter files, and the MJCF export of a joint's
/// friction.
///
/// ParseActuatorLog is hostile-input code: it reads from memory, bounds the
/// text (kMaxActuatorLogBytes) and the entries (kMaxActuatorLogEntries), and
/// throws std::invalid_argument naming the field for anything else (missing
/// or mistyped fields, NaN, non-monotone time, empty). It is the function a
/// fuzzer calls.

#include <cstddef>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/actuator_sim.h"
#include "frictiond/estimators/field_error.h"

namespace frictiond {

/// Largest accepted log text [bytes] and entry count.
inline constexpr std::size_t kMaxActuatorLogBytes = 32u << 20;
inline constexpr std::size_t kMaxActuatorLogEntries = 200000;

/// Parses and validates one log. `dt` may be absent: then the median
/// timestamp step is used. Entries need `timestamp`, `position`,
/// `goal_position`, `torque_enable`; `speed` (else differentiated
/// positions) and `temp` (else 30 C) are optional.
/// @throws FieldError "FIELD: reason" (e.g. "entries[3].position:
/// missing", "dt = -1 (must be finite and > 0)").
ActuatorLog ParseActuatorLog(std::string_view text,
                             const std::string& name = "");
/// The same validation of a log already parsed (an element of an upload's
/// `logs` array: the text is parsed once). The caller bounded its size.
ActuatorLog ActuatorLogFromJson(const nlohmann::json& log,
                                const std::string& name = "");

/// Model file: {"format": "frictiond-actuator-model", "version": 1, "law":
/// name, "params": {name: value, ...}, ...}.
nlohmann::json ActuatorModelToJson(const ActuatorModel& model);
/// @throws FieldError naming the field (unknown law, a
/// parameter outside its bounds or not a finite number).
ActuatorModel ActuatorModelFromJson(const nlohmann::json& j);

/// A BAM parameter file (keys kt, R, armature, q_offset, friction_*,
/// load_friction_*, dtheta_stribeck, alpha; "model": m1..m6) as our model:
/// m1 -> coulomb_viscous, m2 -> stribeck, m4 -> load_dependent, m5 ->
/// directional, m6 -> m6.
/// @throws FieldError naming the field.
ActuatorModel ParseBamParams(std::string_view text);

/// MJCF fragment for the joint: a <joint> with frictionloss (the law's
/// budget at rest and zero load), damping (f_v plus the back-EMF kt^2 / R)
/// and armature, and an XML comment listing what MJCF cannot hold (the
/// Stribeck, load-dependent, directional and temperature terms).
std::string ExportActuatorMjcf(const ActuatorModel& model,
                               const std::string& joint_name);

}  // namespace frictiond
