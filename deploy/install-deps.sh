#!/usr/bin/env bash
# Installs exactly what frictiond needs to build, test and benchmark, from
# Debian 12 packages. Idempotent: installs only what is missing. Run as root.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake pkg-config git clang-format
  clang-14 clang libclang-rt-14-dev   # libFuzzer + ASan/UBSan runtimes (deploy/fuzz.sh)
  # libraries (see README "Dependencies" for why each is here)
  libeigen3-dev libsqlite3-dev sqlite3 libpq-dev libcpp-httplib-dev nlohmann-json3-dev libcli11-dev
  liblcm-dev liblcm-bin libglib2.0-dev
  libopencv-dev
  libmujoco-dev        # MuJoCo 2.2 for the simulator adapter sim/mujoco
  libqhull-dev         # (mujoco::mujoco names /usr/include/libqhull_r in its include path)
  libssl-dev           # SHA-256 / HMAC-SHA256 (API tokens, signed LCM)
  libjemalloc-dev      # the daemon's allocator (server/include/frictiond/server/allocator.h)
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  libtinyxml2-dev      # XML parser that checks the MJCF/SDF/URDF exports
  python3-numpy python3-scipy
  python3-dev pybind11-dev python3-pytest   # the Python module (python/, FRICTIOND_WITH_PYTHON) and its tests
  gimp-data            # real texture images for the recognition tests
  iproute2 util-linux  # private network namespace for LCM multicast tests
  postgresql          # throw-away PostgreSQL 15 servers for the fleet tests
  curl
  chromium nodejs      # the console's browser test (tests/browser, docs/console.md)
)

# The browser test's npm packages (puppeteer-core, pinned by
# tests/browser/package-lock.json): npm ci when node_modules is stale.
npm_packages() {
  local here
  here="$(cd "$(dirname "$0")/.." && pwd)/tests/browser"
  if "$here/npm-ci.sh" --check; then
    echo "install-deps: npm packages of tests/browser present"
  else
    echo "install-deps: npm ci in tests/browser"
    # Not fatal: only the browser test needs it, and it says so when missing.
    "$here/npm-ci.sh" || echo "install-deps: npm ci in tests/browser failed; console_browser_test will fail" >&2
  fi
}

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# npm: Debian's package, unless the installed nodejs already brings it.
command -v npm >/dev/null || missing+=(npm)
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  npm_packages
  exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "install-deps: missing packages: ${missing[*]}; run as root (or install them)" >&2
  exit 1
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
npm_packages
echo "install-deps: done"
