#!/usr/bin/env bash
# The .deb on a clean Debian 12: builds the package with CPack from a built tree, bootstraps a
# minimal bookworm userland (debootstrap --variant=minbase) in a temporary directory, installs
# the package there with apt-get (which pulls its Depends from the Debian mirror), then starts
# the installed edgephys-relay inside the chroot on a free loopback port and checks that it
# answers /metrics and mints a token. Everything is removed afterwards.
#
# Needs root (debootstrap, chroot, mount), debootstrap (scripts/setup.sh installs it) and the
# Debian mirror; takes a few minutes (download of ~100 packages), so it is not part of CI:
# docs/operations.md, "Packages". Prints SKIPPED (exit 0) without root or debootstrap.
#
# Usage: scripts/test_deb_clean.sh [build dir, default build/default]
# Environment: DEB_CLEAN_MIRROR (default http://deb.debian.org/debian), DEB_CLEAN_KEEP=1 keeps
# the chroot (its path is printed).
set -euo pipefail
root_dir=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root_dir/build/default}
mirror=${DEB_CLEAN_MIRROR:-http://deb.debian.org/debian}

[ "$(id -u)" -eq 0 ] || { echo "SKIPPED: needs root (debootstrap, chroot)"; exit 0; }
command -v debootstrap >/dev/null || { echo "SKIPPED: debootstrap is not installed"; exit 0; }
[ -f "$build/CPackConfig.cmake" ] || { echo "FAIL: $build is not a configured build tree"; exit 1; }

work=$(mktemp -d /tmp/edgephys-deb-clean.XXXXXX)
target="$work/bookworm"
relay_pid=""
cleanup() {
  if [ -n "$relay_pid" ]; then kill "$relay_pid" 2>/dev/null || true; fi
  if mountpoint -q "$target/proc" 2>/dev/null; then umount "$target/proc" || true; fi
  if [ "${DEB_CLEAN_KEEP:-0}" = "1" ]; then
    echo "kept: $work"
  else
    rm -rf "$work"
  fi
}
trap cleanup EXIT
start=$(date +%s)
# A child that exited stays a zombie until reaped, which kill -0 still finds.
alive() { local st; st=$(ps -o stat= -p "$1" 2>/dev/null) || return 1; [[ $st != Z* ]]; }
step() { echo "== [$(( $(date +%s) - start ))s] $*"; }

step "cpack -G DEB"
cpack --config "$build/CPackConfig.cmake" -G DEB -B "$work/pkg" >"$work/cpack.log" 2>&1 ||
  { cat "$work/cpack.log"; exit 1; }
deb=$(ls "$work"/pkg/edgephys_*_amd64.deb 2>/dev/null | head -1)
[ -n "$deb" ] || { echo "FAIL: no .deb produced"; cat "$work/cpack.log"; exit 1; }
echo "package: $(basename "$deb"), Depends: $(dpkg-deb -f "$deb" Depends)"

step "debootstrap --variant=minbase bookworm ($mirror)"
debootstrap --variant=minbase bookworm "$target" "$mirror" >"$work/debootstrap.log" 2>&1 ||
  { tail -30 "$work/debootstrap.log"; exit 1; }
# As a fresh Debian 12 install: the point release's updates and the security archive too.
cat >"$target/etc/apt/sources.list" <<EOF
deb $mirror bookworm main
deb $mirror bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
EOF
cp /etc/resolv.conf "$target/etc/resolv.conf"
mount -t proc proc "$target/proc"

step "apt-get install ./$(basename "$deb") inside the chroot"
cp "$deb" "$target/tmp/"
chroot "$target" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin DEBIAN_FRONTEND=noninteractive \
  bash -c "apt-get update -q && apt-get install -y -q --no-install-recommends /tmp/$(basename "$deb")" \
  >"$work/apt.log" 2>&1 || { tail -40 "$work/apt.log"; exit 1; }
grep -E "^(Setting up|Unpacking) edgephys" "$work/apt.log" | head -2
chroot "$target" dpkg -s edgephys | grep -E "^(Status|Version)"
for f in /usr/bin/edgephys-relay /usr/bin/edgephys-phys /usr/lib/libedgephys.so.1 \
         /usr/include/edgephys/edgephys.h /usr/lib/pkgconfig/edgephys.pc; do
  [ -e "$target$f" ] || { echo "FAIL: $f not installed"; exit 1; }
done
# Every shared library the binaries need resolves inside the clean system.
for f in /usr/bin/edgephys-relay /usr/bin/edgephys-phys /usr/lib/libedgephys.so.1; do
  if chroot "$target" ldd "$f" | grep -q "not found"; then
    echo "FAIL: $f has unresolved libraries:"; chroot "$target" ldd "$f" | grep "not found"; exit 1
  fi
done

step "edgephys-relay from the package, inside the chroot"
token=$(chroot "$target" /usr/bin/edgephys-relay token --player 7 --room lobby --ttl 60)
[[ "$token" =~ ^[A-Za-z0-9_-]{80,}$ ]] || { echo "FAIL: token looks wrong: $token"; exit 1; }
ok=""
for attempt in 1 2 3 4 5; do
  port=$(( 20000 + RANDOM % 40000 ))
  # The chroot shares the host's network: loopback only, a bounded run.
  chroot "$target" /usr/bin/edgephys-relay --bind 127.0.0.1:0 --metrics "127.0.0.1:$port" \
    --run-for 60 --log-level info >"$work/relay.log" 2>&1 &
  relay_pid=$!
  for _ in $(seq 1 50); do
    if curl -fsS "http://127.0.0.1:$port/metrics" -o "$work/metrics.txt" 2>/dev/null; then break; fi
    alive "$relay_pid" || break
    sleep 0.1
  done
  if [ -s "$work/metrics.txt" ]; then ok=1; break; fi
  kill "$relay_pid" 2>/dev/null || true
  relay_pid=""
done
[ -n "$ok" ] || { echo "FAIL: the installed relay did not answer /metrics"; cat "$work/relay.log"; exit 1; }
grep -q "^edgephys_rooms" "$work/metrics.txt" || { echo "FAIL: edgephys_rooms missing"; exit 1; }
grep -o "listening on udp [0-9.:]*" "$work/relay.log" | head -1
echo "metrics: $(grep -c '^edgephys_' "$work/metrics.txt") edgephys_ samples on 127.0.0.1:$port"
kill "$relay_pid"
for _ in $(seq 1 50); do alive "$relay_pid" || break; sleep 0.1; done
if alive "$relay_pid"; then echo "FAIL: the relay did not stop on SIGTERM"; exit 1; fi
wait "$relay_pid" 2>/dev/null || true  # reaps the exited relay (its pid only)
relay_pid=""

step "done"
echo "clean Debian 12 install test passed"
