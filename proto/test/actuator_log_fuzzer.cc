// libFuzzer harness of the actuator log parser (ParseActuatorLog,
// docs/actuator.md, docs/fuzzing.md). Any input must either parse or throw
// std::invalid_argument; what parses must satisfy the documented rules, and
// a closed-loop rollout on it must return a finite error.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string_view>

#include "frictiond/proto/actuator_json.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data,
                                      std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  frictiond::ActuatorLog log;
  try {
    log = frictiond::ParseActuatorLog(text, "fuzz");
  } catch (const std::invalid_argument&) {
    return 0;  // refused with a message: fine
  }
  const std::size_t n = log.size();
  if (n < 2 || n > frictiond::kMaxActuatorLogEntries) std::abort();
  if (!(log.dt_s > 0) || !(log.kp > 0) || !(log.mass_kg > 0)) std::abort();
  if (log.t_s.size() != n || log.goal_rad.size() != n ||
      log.torque_enable.size() != n || log.temp_c.size() != n)
    std::abort();
  for (std::size_t i = 1; i < n; ++i)
    if (!(log.t_s[i] > log.t_s[i - 1])) std::abort();
  if (n <= 5000) {
    const frictiond::ActuatorModel m = frictiond::MakeDefaultActuatorModel(
        frictiond::ActuatorFrictionLaw::kDirectional);
    if (!std::isfinite(frictiond::SimulateActuatorLog(m, log))) std::abort();
  }
  return 0;
}
