#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine (packages), builds everything with tests and runs the
# whole suite (unit, integration on loopback, the relay binary's metrics smoke test).
# Uses at most 2 parallel jobs. Exit status is the suite's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset default >/dev/null
cmake --build --preset default
ctest --preset default
