#!/usr/bin/env bash
# CTest entry of the console browser test: tests/browser/run.sh BUILD_DIR.
# Needs node, Debian's chromium and tests/browser/node_modules (npm ci,
# done by deploy/install-deps.sh; done here too when it is missing and the
# registry can be reached).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:?usage: run.sh BUILD_DIR}
command -v node >/dev/null || { echo "console browser test: node not found (deploy/install-deps.sh installs nodejs)" >&2; exit 1; }
chromium=${CHROMIUM:-/usr/bin/chromium}
[ -x "$chromium" ] || { echo "console browser test: $chromium not found (deploy/install-deps.sh installs chromium)" >&2; exit 1; }
if ! "$here/npm-ci.sh" --check; then
  echo "console browser test: node_modules missing or stale, running npm ci" >&2
  "$here/npm-ci.sh" || { echo "console browser test: npm ci failed (run deploy/install-deps.sh with network)" >&2; exit 1; }
fi
export CHROMIUM="$chromium"
# Chromium wants a writable HOME for its crash-handler and font caches.
export HOME=${HOME:-/tmp}
exec node "$here/console_test.mjs" --bin "$build/bin" --artifacts "$build/test-artifacts"
