#!/usr/bin/env bash
# Installs the build tree into a temporary prefix and builds + runs the
# consumer project against it with find_package(frictiond).
set -euo pipefail
build_dir=$1
src_dir=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build_dir" --prefix "$work/prefix" >/dev/null
# Built with LCM: the consumer must find the lcm component and run lcm_app.
require_lcm=OFF
if grep -q '^FRICTIOND_WITH_LCM:BOOL=ON' "$build_dir/CMakeCache.txt"; then require_lcm=ON; fi
cmake -S "$src_dir" -B "$work/build" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release \
  -DFRICTIOND_REQUIRE_LCM=$require_lcm >/dev/null
cmake --build "$work/build" -j2 >/dev/null
"$work/build/robot_app"
if [ -x "$work/build/sim_app" ]; then "$work/build/sim_app"; fi
if [ "$require_lcm" = ON ]; then "$work/build/lcm_app"; fi
