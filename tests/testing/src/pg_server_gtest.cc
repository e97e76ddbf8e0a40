// PgServer::RequireOrSkip, apart from pg_server.cc so that the benchmarks
// can use the server without GoogleTest.
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/testing/pg_server.h"

namespace frictiond::testing {

bool PgServer::RequireOrSkip() {
  if (!BinDir().empty()) return true;
  const char* allow = std::getenv("FRICTIOND_ALLOW_NO_POSTGRES");
  if (allow && std::string(allow) == "1") return false;
  ADD_FAILURE() << "PostgreSQL 15 server binaries not found in "
                   "/usr/lib/postgresql/15/bin (or $FRICTIOND_PG_BIN): "
                   "install Debian package 'postgresql' "
                   "(./deploy/install-deps.sh), or set "
                   "FRICTIOND_ALLOW_NO_POSTGRES=1 to skip these tests";
  return false;
}

}  // namespace frictiond::testing
