#!/usr/bin/env bash
# Installs every Debian 12 package edgephys needs to build, test, benchmark and chart.
# Idempotent: packages already present are left as they are. Needs root (or sudo).
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git ca-certificates curl
  libasio-dev libbullet-dev libeigen3-dev flatbuffers-compiler libflatbuffers-dev
  libspdlog-dev libfmt-dev libgtest-dev libgmock-dev libbenchmark-dev
  prometheus-cpp-dev libcli11-dev nlohmann-json3-dev libssl-dev zlib1g-dev libcurl4-openssl-dev
  gnuplot-nox prometheus iproute2 iperf3 clang libclang-rt-14-dev jq
  libcpp-httplib-dev chromium
  libhiredis-dev redis-server
  linux-perf
  python3 python3-venv python3-setuptools python3-wheel mono-mcs mono-runtime dpkg-dev file debootstrap
  ccache  # optional: developers build with -DCMAKE_CXX_COMPILER_LAUNCHER=ccache
)
# deploy/: the compose stack (podman-compose 1.0.3; netavark + aardvark-dns so services find
# each other by name, iptables as netavark's firewall driver; runc as the OCI runtime) and its
# base image (debootstrap, above).
# EDGEPHYS_SETUP_NO_CONTAINERS=1 leaves them out (the Dockerfile's build stage does).
if [ "${EDGEPHYS_SETUP_NO_CONTAINERS:-0}" != 1 ]; then
  PACKAGES+=(podman podman-compose runc netavark aardvark-dns iptables uidmap)
fi

# The monitor page's browser test (tests/browser) runs on node with npm; a machine that has
# its own node (not from Debian) keeps it, one without gets Debian's.
if ! command -v node >/dev/null; then PACKAGES+=(nodejs npm); fi

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update
$SUDO apt-get install -y --no-install-recommends "${missing[@]}"
