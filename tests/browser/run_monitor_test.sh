#!/usr/bin/env bash
# Runs tests/browser/monitor_test.mjs (headless Chromium + puppeteer-core) for ctest.
# Installs the pinned npm modules (package-lock.json) with `npm ci` when they are missing or
# the lock file changed. Prints SKIPPED (ctest then skips) when node or Chromium is missing.
# Usage: run_monitor_test.sh RELAY_BIN CLIENT_BIN [SCREENSHOT.png]
set -euo pipefail
cd "$(dirname "$0")"
command -v node >/dev/null || { echo "SKIPPED: node is not installed"; exit 0; }
chromium="${CHROMIUM:-/usr/bin/chromium}"
[ -x "$chromium" ] || { echo "SKIPPED: no Chromium at $chromium (scripts/setup.sh installs it)"; exit 0; }
source "../../scripts/lib/npm_ci.sh"
npm_ci_once
exec timeout 150 node monitor_test.mjs "$@"
