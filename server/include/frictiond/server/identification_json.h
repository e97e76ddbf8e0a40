#pragma once
/// @file
/// JSON form of the identification types (identification_jobs.h): the
/// stroke plan as the HTTP answers show it and as the store keeps it
/// (IdentificationJob::plan_json; CONTRACT.md), and the identification
/// request the HTTP 404 answers carry. The one place these are converted.

#include <nlohmann/json.hpp>

#include "frictiond/server/identification_jobs.h"

namespace frictiond {

/// {"material","fingertip","fn_n":[min,max],"v_mm_s":[min,max],
///  "max_duration_s","min_span_pct","instructions"[,"lugre":{"fn_n",
///  "slow":{"accel_mm_s2","peak_mm_s"},"fast":{"strokes","accel_mm_s2",
///  "peak_mm_s"},"rest_s","instructions"}]}
nlohmann::json StrokePlanToJson(const StrokePlan& plan);

/// Reads a plan written by StrokePlanToJson (or by an older daemon): fn_n
/// and v_mm_s are required; max_duration_s (120), min_span_pct (50), the
/// texts ("") and the LuGre pair's fields (NaN; strokes 0) default.
/// @throws std::invalid_argument naming the field.
StrokePlan StrokePlanFromJson(const nlohmann::json& plan);

/// {"requested": true, "job_id", "state", "created_at", "stroke"} or
/// {"requested": false, "reason", "stroke"}.
nlohmann::json IdentificationRequestToJson(const IdentificationRequest& r);

}  // namespace frictiond
