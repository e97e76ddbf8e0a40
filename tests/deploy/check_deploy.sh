#!/usr/bin/env bash
# Checks the deployment files: the installed tree has the daemon, the bundled
# data (with LICENSE and PROVENANCE) and the unit; the systemd unit passes
# `systemd-analyze verify` with its ExecStart pointed at the installed binary
# and keeps its hardening; the installed daemon serves /healthz from the
# installed data with the example config. Exit 77 (skip) only for the
# systemd-analyze part when systemd is not installed.
set -euo pipefail
build_dir=$1
src_dir=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
pid=
cleanup() { [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT
fail() { echo "check_deploy: $*" >&2; exit 1; }

cmake --install "$build_dir" --prefix "$work/prefix" >/dev/null
prefix=$work/prefix
[ -x "$prefix/bin/frictiond" ] || fail "frictiond not installed"
data=$prefix/share/frictiond/data
[ -f "$data/datasets.json" ] || fail "bundled data not installed"
find "$data" -name LICENSE* | grep -q . || fail "data LICENSE not installed"
find "$data" -name PROVENANCE* | grep -q . || fail "data PROVENANCE not installed"
unit=$prefix/share/frictiond/deploy/frictiond.service
[ -f "$unit" ] || fail "unit not installed"
for key in 'ProtectSystem=strict' 'User=frictiond' 'StateDirectory=frictiond' \
  'NoNewPrivileges=yes' 'ReadWritePaths=/var/lib/frictiond'; do
  grep -qx "$key" "$unit" || fail "unit lacks $key"
done

# The installed daemon with the example config (paths moved into $work).
sed -e "s#/var/lib/frictiond#$work/state#" -e "s#/usr/local/share/frictiond/data#$data#" \
  -e 's#"port": 8080#"port": 0#' "$src_dir/deploy/frictiond.example.json" > "$work/config.json"
mkdir -p "$work/state"
cd "$work"
"$prefix/bin/frictiond" --config "$work/config.json" > "$work/log" 2>&1 &
pid=$!
port=
for _ in $(seq 1 200); do
  port=$(grep -o 'serving http://[0-9.]*:[0-9]*' "$work/log" | sed 's/.*://' || true)
  [ -n "$port" ] && break
  kill -0 "$pid" 2>/dev/null || { cat "$work/log" >&2; fail "daemon exited"; }
  sleep 0.1
done
[ -n "$port" ] || { cat "$work/log" >&2; fail "daemon did not report its port"; }
curl -fsS "http://127.0.0.1:$port/healthz" > /dev/null || fail "/healthz failed"
curl -fsS "http://127.0.0.1:$port/v1/materials" | grep -q '"id"' || fail "bundled material not served"
[ -f "$work/state/frictiond.db" ] || fail "state not under the configured directory"
kill "$pid"; wait "$pid" || true; pid=

if ! command -v systemd-analyze > /dev/null; then
  echo "check_deploy: systemd-analyze not installed; unit syntax not verified"
  exit 77
fi
sed "s#/usr/local/bin/frictiond#$prefix/bin/frictiond#" "$unit" > "$work/frictiond.service"
out=$(systemd-analyze verify "$work/frictiond.service" 2>&1 || true)
# Only complaints about this unit count (the host's other units may warn).
if echo "$out" | grep 'frictiond.service' | grep -v 'User=frictiond\|Documentation'; then
  fail "systemd-analyze verify complained"
fi
echo "check_deploy: ok (port $port)"
