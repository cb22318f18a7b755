#!/usr/bin/env bash
# ctest `k8s_manifests`: offline schema validation of deploy/k8s (validate.mjs). Installs the
# pinned npm modules (package-lock.json) with `npm ci` when they are missing or the lock file
# changed; after that it needs no network. Fails (does not skip) without node.
set -euo pipefail
cd "$(dirname "$0")"
command -v node >/dev/null || { echo "FAIL: node is not installed (scripts/setup.sh installs nodejs)"; exit 1; }
source "../../../scripts/lib/npm_ci.sh"
npm_ci_once
exec timeout 60 node validate.mjs ../../..
