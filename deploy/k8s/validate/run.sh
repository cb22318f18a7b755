#!/usr/bin/env bash
# ctest `k8s_manifests`: offline schema validation of deploy/k8s (validate.mjs). Installs the
# pinned npm modules (package-lock.json) with `npm ci` when they are missing or the lock file
# changed; after that it needs no network. Fails (does not skip) without node.
set -euo pipefail
cd "$(dirname "$0")"
command -v node >/dev/null || { echo "FAIL: node is not installed (scripts/setup.sh installs nodejs)"; exit 1; }
if ! cmp -s package-lock.json node_modules/.edgephys-lock 2>/dev/null; then
  exec 9>".npm-ci.lock"
  flock 9
  if ! cmp -s package-lock.json node_modules/.edgephys-lock 2>/dev/null; then
    npm ci --no-audit --no-fund --loglevel=error
    cp package-lock.json node_modules/.edgephys-lock
  fi
  flock -u 9
fi
exec timeout 60 node validate.mjs ../../..
