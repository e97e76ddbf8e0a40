#!/usr/bin/env bash
# Configures and builds frictiond into build/ (Release, -j2). Extra
# arguments go to CMake's configure step.
set -euo pipefail
cd "$(dirname "$0")/.."
# ccache, when the machine has it, makes rebuilds of unchanged sources
# (a second build directory, a re-run of CI on the same machine) cache hits.
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B "${FRICTIOND_BUILD_DIR:-build}" -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@" >/dev/null
cmake --build "${FRICTIOND_BUILD_DIR:-build}" -j"${FRICTIOND_JOBS:-2}"
