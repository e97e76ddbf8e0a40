#pragma once
// The LCM messages the endpoint sends, built from the service's types (the
// one place a model version, a stroke plan or a follow-up region becomes
// an LCM message; decoding and encoding of the bytes is proto/lcm's
// lcm_codec). Private to the server; needs FRICTIOND_HAVE_LCM.

#ifdef FRICTIOND_HAVE_LCM

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "frictiond/estimators/span_coverage.h"
#include "frictiond/friction_model_v1.hpp"
#include "frictiond/identification_request_v1.hpp"
#include "frictiond/identification_request_v2.hpp"
#include "frictiond/server/identification_jobs.h"
#include "frictiond/server/library.h"

namespace frictiond {
namespace internal {

/// Longest text field (request_id, robot) a reply repeats [bytes].
constexpr std::size_t kLcmMaxTextField = 128;

/// A model version as friction_model_v1 (NaN and 0 for what it lacks; the
/// LuGre family only when this build reads it).
friction_model_v1 ModelToLcm(const CachedModel& m);

/// The request for stroke `stroke` of job `job_id` as
/// identification_request_v1 and _v2 (v2 adds the LuGre pair; a plan stored
/// before the pair existed asks for none). `missing` narrows the span to a
/// follow-up region. request_id and robot are cut to kLcmMaxTextField.
struct IdentificationRequestMessages {
  identification_request_v1 v1;
  identification_request_v2 v2;
};
IdentificationRequestMessages IdentificationRequestToLcm(
    std::int64_t utime,
    std::int64_t job_id,
    const std::string& request_id,
    const std::string& robot,
    const std::string& material,
    const std::string& fingertip,
    const StrokePlan& plan,
    int stroke,
    const std::optional<SpanRect>& missing);

}  // namespace internal
}  // namespace frictiond

#endif  // FRICTIOND_HAVE_LCM
