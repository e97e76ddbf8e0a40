#!/usr/bin/env bash
# Installs exactly what frictiond needs to build, test and benchmark, from
# Debian 12 packages. Idempotent: installs only what is missing. Run as root.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake pkg-config git clang-format
  # libraries (see README "Dependencies" for why each is here)
  libeigen3-dev libsqlite3-dev sqlite3 libpq-dev libcpp-httplib-dev nlohmann-json3-dev libcli11-dev
  liblcm-dev liblcm-bin libglib2.0-dev
  libopencv-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  libtinyxml2-dev      # XML parser that checks the MJCF/SDF/URDF exports
  python3-numpy python3-scipy
  gimp-data            # real texture images for the recognition tests
  iproute2 util-linux  # private network namespace for LCM multicast tests
  postgresql          # throw-away PostgreSQL 15 servers for the fleet tests
  curl
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
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
echo "install-deps: done"
