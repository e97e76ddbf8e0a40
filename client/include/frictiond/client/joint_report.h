#pragma once
/// @file
/// HTML report of a joint (paper 002): the f(S) Stribeck curve of the mixed
/// model with its contact dispersion band and the data span, the held-out
/// errors of the three models, and a repeatability field (largest ellipsoid
/// semi-axis over a workspace grid) as inline SVG. Pure string building.

#include <string>

#include <nlohmann/json.hpp>

#include "frictiond/proto/joint_json.h"

namespace frictiond {

/// Inline SVG of f(S) over S in [s_min_um, s_max_um] (log axis): mean curve,
/// +-2 sd contact dispersion band, data span shaded.
/// @throws std::invalid_argument unless 0 < s_min_um < s_max_um.
std::string RenderFrictionCurveSvg(const JointFamily& family,
                                   double s_min_um,
                                   double s_max_um);

/// Inline SVG of a repeatability grid (the body of GET
/// /v1/robots/{id}/repeatability-grid): one cell per point coloured by its
/// largest semi-axis [um], grey when unreachable, with a min/max legend.
/// @throws std::invalid_argument when `grid` lacks n or points.
std::string RenderRepeatabilityGridSvg(const nlohmann::json& grid);

/// A whole HTML page: title, joint section (curve, fit table) and, when
/// `grid` is an object, a repeatability section.
std::string RenderJointReportHtml(const std::string& material,
                                  const std::string& joint,
                                  const JointFamily& family,
                                  const nlohmann::json& grid);

}  // namespace frictiond
