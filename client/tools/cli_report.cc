// Placeholder: replaced by the report implementation.
#include "cli.h"

namespace frictiond::cli {

void RegisterReportCommand(CLI::App& /*app*/, Globals& /*g*/) {}

}  // namespace frictiond::cli
