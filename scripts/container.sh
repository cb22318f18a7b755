#!/usr/bin/env bash
# Builds the Dockerfile with Debian's podman and runs it for real, on a machine that reaches
# Debian's mirror but no container registry. Needs root. Idempotent; every step is timed.
#
#   1. apt-get installs podman, buildah, runc, debootstrap (+ uidmap, fuse-overlayfs, slirp4netns)
#   2. base image: `debootstrap --variant=minbase bookworm`, apt sources for bookworm,
#      bookworm-updates and bookworm-security on deb.debian.org, cached as
#      $EDGEPHYS_CACHE/rootfs.tar and imported as debian:bookworm and debian:bookworm-slim
#   3. `podman build --pull=never` of the Dockerfile (host network: the build stage runs
#      scripts/setup.sh, i.e. apt-get, against the mirror)
#   4. `podman run` of the image on a free loopback port, `curl /metrics`, check the
#      edgephys_ series, stop and remove the container
# and, for deploy/compose.yaml (all tagged as the compose file names them):
#   relay-image   localhost/edgephys-relay:0.1.0 from a build tree, no compile: `cpack -G DEB`
#                 in $EDGEPHYS_BUILD_DIR, then the Dockerfile's run stage installs that .deb
#                 (`--build-context deb=...`). Skipped when the image was made from the same
#                 binaries (label org.edgephys.binaries).
#   stack-images  base, then localhost/edgephys-redis:0.1.0 and localhost/edgephys-prometheus:0.1.0
#                 from deploy/images/* when missing, then relay-image (no deps step: the
#                 packages come from scripts/setup.sh)
#
# Quirks of this host that the flags below work around:
#   - crun fails on the hybrid (v1 + v2) cgroup setup: every podman call uses --runtime runc.
#   - podman raises nofile/nproc to its own defaults, above the host's hard limits, and runc
#     then refuses to start the container: build and run pass --ulimit at or under them.
#   - no systemd as PID 1: --cgroup-manager cgroupfs and --events-backend file.
#
# Usage: scripts/container.sh [all|deps|base|build|run|relay-image|stack-images]   (default: all)
# Environment:
#   EDGEPHYS_IMAGE   image tag (default edgephys-relay:dev)
#   EDGEPHYS_CACHE   where rootfs.tar is kept (default /var/cache/edgephys)
#   EDGEPHYS_REBUILD_BASE=1   rebuild rootfs.tar even if it is cached
#   EDGEPHYS_MIRROR  Debian mirror (default http://deb.debian.org/debian)
#   EDGEPHYS_BUILD_DIR  build tree for relay-image (default build/default)
#   EDGEPHYS_BRIDGE_CHECK=1   also run the default CMD behind -p mappings (podman bridge network)
set -euo pipefail

cd "$(dirname "$0")/.."
ROOT=$(pwd)
IMAGE=${EDGEPHYS_IMAGE:-edgephys-relay:dev}
CACHE=${EDGEPHYS_CACHE:-/var/cache/edgephys}
MIRROR=${EDGEPHYS_MIRROR:-http://deb.debian.org/debian}
STEP=${1:-all}

if [ "$(id -u)" -ne 0 ]; then echo "container.sh: needs root (podman as root, debootstrap)" >&2; exit 1; fi

PODMAN=(podman --cgroup-manager cgroupfs --events-backend file --runtime runc)

# Host hard limits cap what the container may ask for.
hard_nofile=$(ulimit -Hn); [ "$hard_nofile" = unlimited ] && hard_nofile=1048576
hard_nproc=$(ulimit -Hu); [ "$hard_nproc" = unlimited ] && hard_nproc=1048576
nofile=$(( hard_nofile < 20000 ? hard_nofile : 20000 ))
nproc=$(( hard_nproc < 32768 ? hard_nproc : 32768 ))
ULIMITS=(--ulimit "nofile=$nofile:$nofile" --ulimit "nproc=$nproc:$nproc")

t_start=$(date +%s)
step_t=$t_start
log() { echo "container.sh [$(( $(date +%s) - t_start ))s] $*"; }
done_step() {
  local now; now=$(date +%s)
  log "$1 took $(( now - step_t ))s"
  step_t=$now
}

deps() {
  local pkgs=(podman buildah runc debootstrap uidmap fuse-overlayfs slirp4netns
              containernetworking-plugins ca-certificates curl iproute2) missing=() p
  for p in "${pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    log "installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    timeout 600 apt-get update
    timeout 900 apt-get install -y --no-install-recommends "${missing[@]}"
  else
    log "packages present"
  fi
  done_step deps
}

base() {
  local tar="$CACHE/rootfs.tar"
  if [ ! -s "$tar" ] || [ "${EDGEPHYS_REBUILD_BASE:-0}" = 1 ]; then
    mkdir -p "$CACHE"
    local rootfs; rootfs=$(mktemp -d "$CACHE/rootfs.XXXXXX")
    log "debootstrap --variant=minbase bookworm into $rootfs"
    if ! timeout 1200 debootstrap --variant=minbase bookworm "$rootfs" "$MIRROR" \
           >"$CACHE/debootstrap.log" 2>&1; then
      tail -n 30 "$CACHE/debootstrap.log"; rm -rf "$rootfs"; exit 1
    fi
    cat >"$rootfs/etc/apt/sources.list" <<'EOF'
deb http://deb.debian.org/debian bookworm main
deb http://deb.debian.org/debian bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
EOF
    # debootstrap installs the bookworm point release; the official images also carry the
    # updates and security fixes since then.
    mount -t proc proc "$rootfs/proc"
    if ! timeout 900 chroot "$rootfs" sh -c \
           'apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get -y -q upgrade && apt-get clean' \
           >>"$CACHE/debootstrap.log" 2>&1; then
      umount "$rootfs/proc"; tail -n 30 "$CACHE/debootstrap.log"; rm -rf "$rootfs"; exit 1
    fi
    umount "$rootfs/proc"
    # Like the official images: no package lists or caches in the layer.
    rm -rf "$rootfs"/var/lib/apt/lists/* "$rootfs"/var/cache/apt/*.bin \
           "$rootfs"/var/cache/apt/archives/*.deb
    tar --numeric-owner -C "$rootfs" -cf "$tar.tmp" .
    mv "$tar.tmp" "$tar"
    rm -rf "$rootfs"
    log "cached $tar ($(du -h "$tar" | cut -f1))"
  else
    log "reusing $tar"
  fi
  # Re-import when the cached tarball is newer than the image (or there is no image).
  local id; id=$(podman image inspect --format '{{.Id}}' localhost/debian:bookworm 2>/dev/null || true)
  if [ -z "$id" ] || [ "$tar" -nt "$CACHE/imported.stamp" ]; then
    "${PODMAN[@]}" import --quiet --change 'CMD ["bash"]' \
      --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
      "$tar" localhost/debian:bookworm >/dev/null
    touch "$CACHE/imported.stamp"
  fi
  # Short names in FROM resolve to localhost/ or docker.io/library/: tag both.
  for name in localhost/debian:bookworm-slim docker.io/library/debian:bookworm \
              docker.io/library/debian:bookworm-slim; do
    podman tag localhost/debian:bookworm "$name"
  done
  done_step base
}

build() {
  log "podman build -t $IMAGE (compiles the relay inside, -j2)"
  image_build -t "$IMAGE" -f "$ROOT/Dockerfile" "$ROOT"
  podman image ls "$IMAGE"
  done_step build
}

# Builds with the host's network (apt-get against the mirror) and ulimits it allows.
image_build() {
  "${PODMAN[@]}" build --pull=never --network host "${ULIMITS[@]}" --jobs 1 --layers "$@"
}

relay_image() {
  local bdir=${EDGEPHYS_BUILD_DIR:-$ROOT/build/default} tag=localhost/edgephys-relay:0.1.0 sum have pkg
  local bins=("$bdir/relay/edgephys-relay" "$bdir/physics_backend/edgephys-phys")
  [ -f "$bdir/CPackConfig.cmake" ] || { echo "container.sh: $bdir is not a configured build tree" >&2; exit 1; }
  for b in "${bins[@]}"; do [ -x "$b" ] || { echo "container.sh: $b not built" >&2; exit 1; }; done
  sum=$(cat "${bins[@]}" "$ROOT/Dockerfile" | sha256sum | cut -c1-16)
  have=$(podman image inspect --format '{{index .Labels "org.edgephys.binaries"}}' "$tag" 2>/dev/null || true)
  if [ "$have" = "$sum" ]; then log "$tag is current (binaries $sum)"; done_step relay-image; return; fi
  pkg="$CACHE/relay-deb"   # the package and logs of the last relay-image build (replaced each time)
  rm -rf "$pkg"; mkdir -p "$pkg"
  log "cpack -G DEB in $bdir"
  cpack --config "$bdir/CPackConfig.cmake" -G DEB -B "$pkg/out" >"$pkg/cpack.log" 2>&1 \
    || { tail -n 30 "$pkg/cpack.log"; exit 1; }
  mkdir "$pkg/deb"
  mv "$pkg"/out/edgephys_*_amd64.deb "$pkg/deb/" || { tail -n 30 "$pkg/cpack.log"; exit 1; }
  log "podman build $tag from $(basename "$pkg"/deb/*.deb)"
  image_build --build-context "deb=$pkg/deb" --label "org.edgephys.binaries=$sum" \
    -t "$tag" -f "$ROOT/Dockerfile" "$ROOT" >"$pkg/build.log" 2>&1 \
    || { tail -n 40 "$pkg/build.log"; exit 1; }
  rm -rf "$pkg/out" "$pkg/deb"
  done_step relay-image
}

stack_images() {
  local name
  mkdir -p "$CACHE"
  for name in redis prometheus; do
    if podman image exists "localhost/edgephys-$name:0.1.0"; then
      log "localhost/edgephys-$name:0.1.0 present"
    else
      log "podman build localhost/edgephys-$name:0.1.0 (deploy/images/$name)"
      image_build -t "localhost/edgephys-$name:0.1.0" "$ROOT/deploy/images/$name" >"$CACHE/$name-image.log" 2>&1 \
        || { tail -n 40 "$CACHE/$name-image.log"; exit 1; }
    fi
    done_step "$name image"
  done
  relay_image
}

free_port() {
  local p
  for _ in $(seq 1 50); do
    p=$(( 20000 + RANDOM % 40000 ))
    if ! ss -Htan "sport = :$p" | grep -q . && ! ss -Huan "sport = :$p" | grep -q .; then
      echo "$p"; return 0
    fi
  done
  return 1
}

run() {
  local name="edgephys-relay-check-$$" work port udp ok=""
  work=$(mktemp -d)
  # shellcheck disable=SC2064
  trap "podman rm -f -t 5 $name >/dev/null 2>&1 || true; rm -rf $work" EXIT
  port=$(free_port); udp=$(free_port)
  log "podman run $IMAGE: metrics 127.0.0.1:$port, UDP 127.0.0.1:$udp"
  "${PODMAN[@]}" run -d --name "$name" "${ULIMITS[@]}" --network host "$IMAGE" \
    --bind "127.0.0.1:$udp" --metrics "127.0.0.1:$port" --log-level info >/dev/null
  for _ in $(seq 1 600); do
    if curl -fsS --max-time 2 "http://127.0.0.1:$port/metrics" -o "$work/metrics.txt" 2>/dev/null; then
      ok=1; break
    fi
    [ "$(podman inspect --format '{{.State.Running}}' "$name" 2>/dev/null)" = true ] || break
    sleep 0.1
  done
  if [ -z "$ok" ]; then
    echo "FAIL: no /metrics from the container"; podman logs "$name" 2>&1 | tail -n 40; exit 1
  fi
  for m in edgephys_rooms edgephys_clients edgephys_entities edgephys_packets_received_total \
           edgephys_bytes_sent_total edgephys_rtt_seconds_bucket \
           edgephys_tick_duration_seconds_bucket; do
    grep -q "^$m" "$work/metrics.txt" || { echo "FAIL: $m missing"; cat "$work/metrics.txt"; exit 1; }
  done
  log "/metrics: $(grep -c '^edgephys_' "$work/metrics.txt") edgephys_ samples"
  local user; user=$(podman exec "$name" id -un)
  [ "$user" = edgephys ] || { echo "FAIL: relay runs as $user, not edgephys"; exit 1; }
  "${PODMAN[@]}" run --rm "${ULIMITS[@]}" --network none --entrypoint /usr/local/bin/edgephys-phys \
    "$IMAGE" --help >/dev/null || { echo "FAIL: edgephys-phys --help in the image"; exit 1; }
  podman stop -t 10 "$name" >/dev/null
  local code; code=$(podman inspect --format '{{.State.ExitCode}}' "$name")
  [ "$code" = 0 ] || { echo "FAIL: relay exited $code on SIGTERM"; podman logs "$name" 2>&1 | tail; exit 1; }
  podman rm "$name" >/dev/null
  if [ "${EDGEPHYS_BRIDGE_CHECK:-0}" = 1 ]; then
    # The documented way: default CMD (0.0.0.0:7777/udp, 0.0.0.0:9464) behind -p mappings.
    port=$(free_port); udp=$(free_port); ok=""
    log "podman run -p 127.0.0.1:$port:9464 -p 127.0.0.1:$udp:7777/udp (bridge network)"
    "${PODMAN[@]}" run -d --name "$name" "${ULIMITS[@]}" \
      -p "127.0.0.1:$port:9464" -p "127.0.0.1:$udp:7777/udp" "$IMAGE" >/dev/null
    for _ in $(seq 1 300); do
      if curl -fsS --max-time 2 "http://127.0.0.1:$port/metrics" -o "$work/metrics.txt" 2>/dev/null; then
        ok=1; break
      fi
      sleep 0.1
    done
    if [ -z "$ok" ] || ! grep -q '^edgephys_rooms' "$work/metrics.txt"; then
      echo "FAIL: no /metrics through -p"; podman logs "$name" 2>&1 | tail; exit 1
    fi
    podman rm -f -t 10 "$name" >/dev/null
  fi
  done_step run
  echo "container check passed: $IMAGE served /metrics and stopped cleanly"
}

case "$STEP" in
  deps) deps ;;
  base) deps; base ;;
  build) deps; base; build ;;
  run) run ;;
  all) deps; base; build; run ;;
  relay-image) relay_image ;;
  stack-images)  # packages from scripts/setup.sh (CI installs nothing during its tests)
    for tool in podman debootstrap cpack; do
      command -v "$tool" >/dev/null || { echo "container.sh: $tool missing (scripts/setup.sh)" >&2; exit 1; }
    done
    base; stack_images ;;
  *) echo "usage: $0 [all|deps|base|build|run|relay-image|stack-images]" >&2; exit 2 ;;
esac
log "total $(( $(date +%s) - t_start ))s"
