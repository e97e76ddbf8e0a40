// Placeholder until the feature's routes land.
#include "frictiond/server/routes.h"

namespace frictiond {

void RegisterPaper000Routes(HttpServer& /*http*/,
                            FrictionLibrary& /*library*/) {}

}  // namespace frictiond
