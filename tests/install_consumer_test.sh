#!/usr/bin/env bash
# Installs the build tree into a temporary prefix (cmake --install) and checks what a user
# gets: headers, the shared libedgephys exporting only the C API, the relay and worker binaries,
# the CMake package and the pkg-config file. Then builds tests/consumer out of tree twice (CMake
# find_package, and plain cc with pkg-config) and runs both against the *installed*
# edgephys-relay on a free loopback port.
# Usage: install_consumer_test.sh <build dir> <source dir>
set -euo pipefail
build="$1"; src="$2"
source "$src/scripts/lib/stop_process.sh"
work=$(mktemp -d)
relay_pid=""
cleanup() { stop "$relay_pid"; rm -rf "$work"; }
trap cleanup EXIT
prefix="$work/prefix"

cmake --install "$build" --prefix "$prefix" >"$work/install.log"
libdir=$(dirname "$(find "$prefix" -name 'libedgephys.so' | head -1)")
for f in include/edgephys/edgephys.h include/edgephys/edgephys.hpp bin/edgephys-relay bin/edgephys-phys; do
  [ -e "$prefix/$f" ] || { echo "FAIL: $f not installed"; cat "$work/install.log"; exit 1; }
done
[ -n "$libdir" ] && [ -e "$libdir/libedgephys.so.1" ] || { echo "FAIL: libedgephys.so(.1) not installed"; exit 1; }
[ -e "$libdir/cmake/edgephys/edgephysConfig.cmake" ] || { echo "FAIL: CMake package not installed"; exit 1; }
[ -e "$libdir/pkgconfig/edgephys.pc" ] || { echo "FAIL: edgephys.pc not installed"; exit 1; }
# Only the C API is exported (no C++ symbols of the client, Asio or FlatBuffers leak out).
leaked=$(nm -D --defined-only "$libdir/libedgephys.so" | awk '$2 ~ /[TDBRW]/ && $3 !~ /^edgephys_/ && $3 != "EDGEPHYS_1"' | head -5)
[ -z "$leaked" ] || { echo "FAIL: libedgephys exports more than edgephys_*: $leaked"; exit 1; }

echo "== consumer with CMake find_package"
cmake -S "$src/tests/consumer" -B "$work/cmake-build" -DCMAKE_PREFIX_PATH="$prefix" >"$work/consumer-cmake.log" 2>&1 \
  || { cat "$work/consumer-cmake.log"; exit 1; }
cmake --build "$work/cmake-build" >>"$work/consumer-cmake.log" 2>&1 || { cat "$work/consumer-cmake.log"; exit 1; }

echo "== consumer with pkg-config"
export PKG_CONFIG_PATH="$libdir/pkgconfig"
# shellcheck disable=SC2046
cc -std=c11 -Wall -Wextra -Werror -o "$work/consumer-pc" "$src/tests/consumer/consumer.c" \
   $(pkg-config --cflags --libs edgephys)

"$prefix/bin/edgephys-relay" --bind 127.0.0.1:0 --metrics off --run-for 60 >"$work/relay.log" 2>&1 &
relay_pid=$!
address=""
for _ in $(seq 1 50); do
  address=$(grep -o "listening on udp [0-9.:]*" "$work/relay.log" | awk '{print $4}' || true)
  [ -n "$address" ] && break
  sleep 0.1
done
[ -n "$address" ] || { echo "FAIL: the installed relay did not start"; cat "$work/relay.log"; exit 1; }

"$work/cmake-build/consumer" "$address" "$("$prefix/bin/edgephys-relay" token --player 1 --room c)" c | tee "$work/a.log"
LD_LIBRARY_PATH="$libdir" "$work/consumer-pc" "$address" "$("$prefix/bin/edgephys-relay" token --player 2 --room c)" c | tee "$work/b.log"
grep -q "consumer ok" "$work/a.log" && grep -q "consumer ok" "$work/b.log" || { echo "FAIL: a consumer failed"; exit 1; }
echo "install consumer test passed"
