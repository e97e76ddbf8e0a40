#!/usr/bin/env bash
# Installs the build tree into a temporary prefix and builds + runs the
# consumer project against it with find_package(frictiond).
set -euo pipefail
build_dir=$1
src_dir=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build_dir" --prefix "$work/prefix" >/dev/null
cmake -S "$src_dir" -B "$work/build" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/build" -j2 >/dev/null
"$work/build/robot_app"
if [ -x "$work/build/sim_app" ]; then "$work/build/sim_app"; fi
