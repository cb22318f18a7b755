#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine (packages), builds edgephys-relay and starts it on its
# embedded defaults: UDP 0.0.0.0:7777, Prometheus metrics on http://0.0.0.0:9464/metrics.
# Extra arguments go to the relay (e.g. --secret, --config relay.toml, --help).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake --preset release -DEDGEPHYS_BUILD_BENCH=OFF >/dev/null
cmake --build --preset release --target edgephys-relay
exec ./build/release/relay/edgephys-relay "$@"
