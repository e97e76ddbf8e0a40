#!/usr/bin/env bash
# Installs the browser test's npm packages (puppeteer-core) exactly as
# package-lock.json pins them. With --check, only says (exit 0/1) whether
# node_modules matches the lock file already.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
stamp="$here/node_modules/.frictiond-lock.sha256"
want=$(sha256sum "$here/package-lock.json" | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -d "$here/node_modules/puppeteer-core" ]; then
  exit 0
fi
[ "${1:-}" = "--check" ] && exit 1
command -v npm >/dev/null || { echo "npm-ci: npm not found" >&2; exit 1; }
(cd "$here" && npm ci --no-audit --no-fund --loglevel=error)
echo "$want" > "$stamp"
