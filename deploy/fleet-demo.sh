#!/usr/bin/env bash
# Fleet recipe: one PostgreSQL database and two frictiond daemons sharing it.
#
#   ./deploy/fleet-demo.sh                       # throw-away PostgreSQL 15
#   FRICTIOND_PG_URL=postgresql://user@db:5432/frictiond ./deploy/fleet-demo.sh
#
# Daemon A listens on 127.0.0.1:${PORT_A:-8081}, daemon B on
# 127.0.0.1:${PORT_B:-8082}. A write through one is served by the other
# within a second (LISTEN/NOTIFY). Ctrl-C stops the daemons (and the
# throw-away server, whose files are removed). Build first (./deploy/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=./build/bin/frictiond
[ -x "$bin" ] || { echo "fleet-demo: $bin missing; run ./deploy/build.sh" >&2; exit 1; }
port_a=${PORT_A:-8081}
port_b=${PORT_B:-8082}
pids=()
tmp=""
pgbin=${FRICTIOND_PG_BIN:-/usr/lib/postgresql/15/bin}

cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  [ -n "$tmp" ] && rm -rf "$tmp"
}
trap cleanup EXIT INT TERM

url=${FRICTIOND_PG_URL:-}
if [ -z "$url" ]; then
  [ -x "$pgbin/initdb" ] || { echo "fleet-demo: no PostgreSQL 15 in $pgbin (apt-get install postgresql)" >&2; exit 1; }
  tmp=$(mktemp -d /tmp/frictiond-fleet.XXXXXX)
  as=()
  if [ "$(id -u)" -eq 0 ]; then  # initdb and postgres refuse root
    chown postgres: "$tmp"
    as=(runuser -u postgres --)
  fi
  pg_port=${PG_PORT:-55432}
  "${as[@]}" "$pgbin/initdb" -D "$tmp/data" -U postgres -A trust -E UTF8 --locale=C --no-instructions --no-sync >/dev/null
  "${as[@]}" "$pgbin/postgres" -D "$tmp/data" -p "$pg_port" -c listen_addresses=127.0.0.1 \
    -c unix_socket_directories="$tmp" -c fsync=on >"$tmp/postgres.log" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do
    "$pgbin/pg_isready" -q -h 127.0.0.1 -p "$pg_port" && break
    sleep 0.1
  done
  "$pgbin/psql" -X -q -h 127.0.0.1 -p "$pg_port" -U postgres -c "CREATE DATABASE frictiond"
  url="postgresql://postgres@127.0.0.1:$pg_port/frictiond"
  echo "fleet-demo: throw-away PostgreSQL at $url (log $tmp/postgres.log)"
fi

# Daemon A creates the schema and loads the bundled datasets into the empty
# library; B starts once A serves (so the data is loaded only once).
"$bin" --db "$url" --port "$port_a" --lcm none "$@" &
pids+=($!)
for _ in $(seq 300); do
  curl -fsS "http://127.0.0.1:$port_a/healthz" >/dev/null 2>&1 && break
  sleep 0.1
done
"$bin" --db "$url" --port "$port_b" --lcm none --data none "$@" &
pids+=($!)
for _ in $(seq 300); do
  curl -fsS "http://127.0.0.1:$port_b/healthz" >/dev/null 2>&1 && break
  sleep 0.1
done
echo "fleet-demo: daemon A http://127.0.0.1:$port_a, daemon B http://127.0.0.1:$port_b (Ctrl-C stops)"
wait -n "${pids[@]}"
