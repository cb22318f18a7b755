#!/usr/bin/env bash
# The Dockerfile, built and run for real with Debian's podman (scripts/container.sh does the
# work: local debootstrap base image, `podman build --pull=never`, `podman run`, curl /metrics).
# Slow on a cold cache (debootstrap + compiling the relay inside the build stage), so CTest
# registers it DISABLED unless configured with -DEDGEPHYS_CONTAINER_TESTS=ON.
# Skips (exit 0, prints SKIPPED) when not root: podman as root and debootstrap need it.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
if [ "$(id -u)" -ne 0 ]; then
  echo "SKIPPED: the container test needs root (podman as root, debootstrap, apt-get)"
  exit 0
fi
exec bash "$here/../scripts/container.sh" all
