#include "frictiond/estimators/number_text.h"

#include <cstdio>

namespace frictiond {

std::string NumberText(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

}  // namespace frictiond
