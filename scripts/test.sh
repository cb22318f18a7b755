#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine (packages), builds everything with tests, runs the whole
# suite (unit, integration on loopback, real processes, the relay binary's metrics, a real
# Prometheus scrape), then every libFuzzer target for a bounded time under ASan and UBSan.
# Uses at most 2 parallel jobs. Exit status is the suite's.
#   EDGEPHYS_SKIP_FUZZ=1 bash scripts/test.sh   # skip the fuzzing step (local iterations)
#   EDGEPHYS_SKIP_DEB_CLEAN=1 ...               # skip the .deb on a clean Debian 12 chroot
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset default >/dev/null
cmake --build --preset default
ctest --preset default
# The .deb installed on a clean Debian 12 minbase chroot (~30 s; SKIPPED unless root).
if [ "${EDGEPHYS_SKIP_DEB_CLEAN:-0}" != "1" ]; then
  timeout 600 bash scripts/test_deb_clean.sh build/default
fi
if [ "${EDGEPHYS_SKIP_FUZZ:-0}" != "1" ]; then
  bash scripts/fuzz.sh
fi
