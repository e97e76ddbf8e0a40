#!/usr/bin/env bash
# Configures and builds frictiond into build/ (Release, -j2). Extra
# arguments go to CMake's configure step.
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B "${FRICTIOND_BUILD_DIR:-build}" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build "${FRICTIOND_BUILD_DIR:-build}" -j"${FRICTIOND_JOBS:-2}"
