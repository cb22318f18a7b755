#!/usr/bin/env bash
# Builds the Debian package with CPack (into a temporary directory) and checks its contents and
# control fields with dpkg-deb: the relay and worker binaries, libedgephys with its soname link,
# the C API headers, the CMake package and pkg-config file, and Depends filled in by
# dpkg-shlibdeps. (Installing it needs root: docs in README "Use the SDK".)
# Usage: deb_package_test.sh <build dir>
set -euo pipefail
build="$1"
command -v dpkg-deb >/dev/null || { echo "SKIPPED: dpkg-deb is not installed"; exit 0; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cpack --config "$build/CPackConfig.cmake" -G DEB -B "$work" >"$work/cpack.log" 2>&1 || { cat "$work/cpack.log"; exit 1; }
deb=$(ls "$work"/edgephys_*_amd64.deb 2>/dev/null | head -1)
[ -n "$deb" ] || { echo "FAIL: no .deb produced"; cat "$work/cpack.log"; exit 1; }
dpkg-deb -c "$deb" >"$work/contents"
for f in ./usr/bin/edgephys-relay ./usr/bin/edgephys-phys ./usr/include/edgephys/edgephys.h \
         ./usr/include/edgephys/edgephys.hpp ./usr/lib/libedgephys.so.1 ./usr/lib/libedgephys.so \
         ./usr/lib/cmake/edgephys/edgephysConfig.cmake ./usr/lib/pkgconfig/edgephys.pc; do
  grep -q " $f" "$work/contents" || { echo "FAIL: $f missing from the package"; cat "$work/contents"; exit 1; }
done
depends=$(dpkg-deb -f "$deb" Depends)
for dep in libspdlog libbullet libssl; do
  [[ "$depends" == *"$dep"* ]] || { echo "FAIL: Depends lacks $dep: $depends"; exit 1; }
done
echo "package $(basename "$deb"): $(wc -l <"$work/contents") entries; Depends: $depends"
echo "deb package test passed"
