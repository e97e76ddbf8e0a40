#!/usr/bin/env bash
# Set-up command 1: installs what is missing, builds, and runs the daemon on
# its embedded default: a SQLite file (./frictiond.db) with the bundled
# measured datasets loaded on first start, HTTP on 127.0.0.1:8080.
# Environment: FRICTIOND_DB, FRICTIOND_PORT, FRICTIOND_BIND override. On the
# first start of a new database it prints "operator token: <secret>" once
# (FRICTIOND_BOOTSTRAP_TOKEN chooses that secret); see docs/auth.md.
set -euo pipefail
cd "$(dirname "$0")/.."
./deploy/install-deps.sh
FRICTIOND_BUILD_TESTS=OFF ./deploy/build.sh -DFRICTIOND_BUILD_TESTS=OFF -DFRICTIOND_BUILD_BENCHMARKS=OFF
exec ./build/bin/frictiond --db "${FRICTIOND_DB:-frictiond.db}" --port "${FRICTIOND_PORT:-8080}" \
  --bind "${FRICTIOND_BIND:-127.0.0.1}" "$@"
