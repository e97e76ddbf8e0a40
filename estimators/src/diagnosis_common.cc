// Model diagnosis: shared helpers (names, numbers)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>

#include <Eigen/Dense>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/estimators/regression.h"
#include "frictiond/estimators/stats.h"

#include "diagnosis_internal.h"

namespace frictiond::diagnosis_internal {

std::string Num(double x, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", digits, x);
  return buf;
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

/// Canonical term: Parse(Name()) so that numbers carry the name's precision
/// and the stored term list reproduces the tested model exactly.
Term Canonical(TermKind kind, const std::string& input, double a, double b) {
  Term t;
  t.kind = kind;
  t.input = input;
  t.a = a;
  t.b = b;
  return Term::Parse(t.Name());
}

/// Rounds to the 6 significant digits term names keep.
double RoundForName(double x) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return std::strtod(buf, nullptr);
}

std::vector<std::string> Names(const std::vector<Term>& terms) {
  std::vector<std::string> out;
  out.reserve(terms.size());
  for (const Term& t : terms) out.push_back(t.Name());
  return out;
}

}  // namespace frictiond::diagnosis_internal
