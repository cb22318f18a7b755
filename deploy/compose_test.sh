#!/usr/bin/env bash
# ctest `compose_stack` (label `compose`): deploy/compose.yaml with Debian 12's podman-compose.
#  1. images, each only when missing (scripts/container.sh stack-images): the debian:bookworm
#     base (debootstrap, cached in /var/cache/edgephys), Redis and Prometheus from Debian's
#     packages, and the relay image from THIS build tree's .deb (cpack; no compile; rebuilt when
#     the binaries change);
#  2. `podman-compose up -d` on host ports picked here (17700-17799, under the ephemeral range,
#     so no other test's port), a client joins room "arena" through relay-a, the PhyS worker
#     attaches to relay-a, Prometheus scrapes both relays;
#  3. `podman kill -s KILL` of relay-a (and it stays down): arena comes back on relay-b with the
#     client's entity (Redis snapshot), and a client joins arena through relay-b;
#  4. down: containers, network (and a pod, if the compose tool made one), also on failure.
# Cold (no images, no cached base): about 3 minutes on 2 cores, half of it debootstrap; with
# the images present about 30 seconds. Every wait is bounded.
# Usage: compose_test.sh BUILD_DIR CLIENT_BIN   (CMAKE_BINARY_DIR, tests/admin/admin_test_client)
# Prints SKIPPED (ctest skips) without root, podman or podman-compose, or when podman cannot
# run a container here (the reason is printed).
set -euo pipefail
build=$(cd "$1" && pwd)
client="$2"
root=$(cd "$(dirname "$0")/.." && pwd)
t0=$SECONDS
step() { echo "[$((SECONDS - t0))s] $*"; }

[ "$(id -u)" -eq 0 ] || { echo "SKIPPED: needs root (rootful podman, debootstrap)"; exit 0; }
for tool in podman podman-compose debootstrap; do
  command -v "$tool" >/dev/null || { echo "SKIPPED: $tool is not installed (scripts/setup.sh installs it)"; exit 0; }
done
hard_nofile=$(ulimit -Hn)
if [ "$hard_nofile" != unlimited ] && [ "$hard_nofile" -lt 20000 ]; then
  echo "SKIPPED: the host's hard nofile limit ($hard_nofile) is under compose.yaml's ulimits (20000)"; exit 0
fi

log=$(mktemp -d /tmp/edgephys-compose.XXXXXX)
project=edgephys-ctest-$$
# podman settings for this test only (podman-compose runs podman with this environment): runc
# (crun fails on hybrid cgroup hosts), cgroupfs and a file event log (no systemd needed), and
# default ulimits at or under the host's hard limits (podman's own exceed them in containers).
hard_nproc=$(ulimit -Hu); [ "$hard_nproc" = unlimited ] && hard_nproc=1048576
[ "$hard_nofile" = unlimited ] && hard_nofile=1048576
nofile=$(( hard_nofile < 65536 ? hard_nofile : 65536 )); nproc=$(( hard_nproc < 32768 ? hard_nproc : 32768 ))
cat >"$log/containers.conf" <<EOF
[containers]
default_ulimits = ["nofile=$nofile:$nofile", "nproc=$nproc:$nproc"]
[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
events_logger = "file"
EOF
export CONTAINERS_CONF="$log/containers.conf"

# Host ports: free ones in 17700-17799 (other tests take theirs from 20000-60000 or the kernel's
# ephemeral range).
used=$(ss -Htuan | awk '{print $5}' | sed 's/.*://' | sort -u)
free=()
for p in $(seq 17700 17799); do
  grep -qx "$p" <<<"$used" || free+=("$p")
  [ ${#free[@]} -ge 7 ] && break
done
[ ${#free[@]} -ge 7 ] || { echo "FAIL: fewer than 7 free ports in 17700-17799"; exit 1; }
export EDGEPHYS_RELAY_A_PORT=${free[0]} EDGEPHYS_RELAY_B_PORT=${free[1]} \
       EDGEPHYS_RELAY_A_METRICS_PORT=${free[2]} EDGEPHYS_RELAY_A_ADMIN_PORT=${free[3]} \
       EDGEPHYS_RELAY_B_METRICS_PORT=${free[4]} EDGEPHYS_RELAY_B_ADMIN_PORT=${free[5]} \
       EDGEPHYS_PROMETHEUS_PORT=${free[6]}
export EDGEPHYS_SECRET=$(openssl rand -hex 32) EDGEPHYS_ADMIN_KEY=$(openssl rand -hex 32)
pc=(podman-compose -p "$project" -f "$root/deploy/compose.yaml")

client_pid=""
cleanup() {
  local rc=$?
  set +e
  [ -n "$client_pid" ] && kill "$client_pid" 2>/dev/null
  if [ "$rc" -ne 0 ] && [ -d "$log" ]; then
    for c in redis relay-a relay-b phys prometheus; do
      podman container exists "${project}_${c}_1" 2>/dev/null || continue
      echo "--- podman logs ${project}_${c}_1 (last lines)"
      timeout 10 podman logs "${project}_${c}_1" 2>&1 | tail -n 15 || true
    done
  fi
  timeout 60 "${pc[@]}" down -t 2 >"$log/down.out" 2>&1 || true
  # Whatever `down` left: the project's containers, its network, a pod.
  local ids; ids=$(podman ps -aq --filter "label=io.podman.compose.project=$project" 2>/dev/null || true)
  [ -n "$ids" ] && timeout 60 podman rm -f -t 0 $ids >/dev/null 2>&1
  timeout 30 podman network rm -f "${project}_edgephys" >/dev/null 2>&1
  timeout 30 podman pod rm -f "pod_$project" >/dev/null 2>&1
  if [ -n "$(podman ps -aq --filter "label=io.podman.compose.project=$project" 2>/dev/null)" ]; then
    echo "FAIL: containers of $project are left"; rc=1
  fi
  rm -rf "$log"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 143' TERM INT HUP

# Stacks an earlier run left behind when it was killed outright (SIGKILL skips the cleanup).
for p in $(podman ps -a --format '{{index .Labels "io.podman.compose.project"}}' 2>/dev/null | grep '^edgephys-ctest-' | sort -u); do
  kill -0 "${p#edgephys-ctest-}" 2>/dev/null && continue
  echo "removing the leftover stack $p"
  ids=$(podman ps -aq --filter "label=io.podman.compose.project=$p")
  [ -n "$ids" ] && timeout 60 podman rm -f -t 0 $ids >/dev/null 2>&1
  timeout 30 podman network rm -f "${p}_edgephys" >/dev/null 2>&1 || true
done

step "images (scripts/container.sh stack-images, build tree $build)"
EDGEPHYS_BUILD_DIR="$build" timeout 600 bash "$root/scripts/container.sh" stack-images >"$log/images.out" 2>&1 \
  || { tail -n 40 "$log/images.out"; echo "FAIL: images"; exit 1; }
grep -E 'took|present|current|reusing' "$log/images.out" | sed 's/^/  /' || true

# Can podman run a container at all here (namespaces, cgroups)?
if ! timeout 60 podman run --rm --network none localhost/debian:bookworm true >"$log/probe.out" 2>&1; then
  echo "SKIPPED: podman cannot run a container on this host: $(grep -m1 -i error "$log/probe.out" || head -n1 "$log/probe.out")"
  exit 0
fi

step "podman-compose up -d (project $project, relay-a UDP $EDGEPHYS_RELAY_A_PORT, relay-b UDP $EDGEPHYS_RELAY_B_PORT)"
timeout 300 "${pc[@]}" up -d >"$log/up.out" 2>&1 || { tail -n 40 "$log/up.out"; echo "FAIL: podman-compose up"; exit 1; }

a_admin=http://127.0.0.1:$EDGEPHYS_RELAY_A_ADMIN_PORT b_admin=http://127.0.0.1:$EDGEPHYS_RELAY_B_ADMIN_PORT
a_metrics=http://127.0.0.1:$EDGEPHYS_RELAY_A_METRICS_PORT
api() { curl -sS -m 3 -H "Authorization: Bearer $EDGEPHYS_ADMIN_KEY" "$@"; }
arena_entities() {  # ADMIN_URL: the entity count of room arena there, empty if it has none
  api "$1/v1/rooms" 2>/dev/null | python3 -c '
import json, sys
try: rooms = json.load(sys.stdin)
except ValueError: sys.exit(0)
rooms = rooms.get("rooms", rooms) if isinstance(rooms, dict) else rooms
print(next((str(r.get("entities", "")) for r in rooms if r.get("id") == "arena"), ""))' || true
}
wait_http() {  # URL SECONDS
  for _ in $(seq 1 "$2"); do curl -fsS -m 2 "$1" >/dev/null 2>&1 && return 0; sleep 1; done
  return 1
}
for url in "$a_admin/healthz" "$b_admin/healthz"; do
  wait_http "$url" 60 || { echo "FAIL: $url never answered"; exit 1; }
done
step "both relays healthy"

# Room "arena" is made on relay-a (admin API; registered in Redis as relay-a's), so the join
# below is served there rather than placed on the less loaded relay.
code=$(api -o "$log/create.out" -w '%{http_code}' -d '{"id":"arena","capacity":8}' "$a_admin/v1/rooms" || true)
[ "$code" = 201 ] || { cat "$log/create.out" 2>/dev/null; echo "FAIL: POST /v1/rooms on relay-a answered $code"; exit 1; }
# A client joins arena through relay-a, spawns an entity and stays.
"$client" --relay "127.0.0.1:$EDGEPHYS_RELAY_A_PORT" --secret "$EDGEPHYS_SECRET" --room arena --player 7 \
  --run-for 120 >"$log/client.out" 2>&1 &
client_pid=$!
for _ in $(seq 1 50); do grep -q '^joined arena' "$log/client.out" && break; sleep 0.2; done
grep -q '^joined arena' "$log/client.out" || { cat "$log/client.out"; echo "FAIL: the client did not join through relay-a"; exit 1; }
grep -q 'redirect' "$log/client.out" && { cat "$log/client.out"; echo "FAIL: the client was redirected away from relay-a"; exit 1; }
[ -n "$(arena_entities "$a_admin")" ] || { echo "FAIL: relay-a does not list arena"; exit 1; }
step "client joined arena on relay-a"

workers() { curl -fsS -m 2 "$a_metrics/metrics" 2>/dev/null | awk '$1 == "edgephys_physics_workers" {print $2}'; }
for _ in $(seq 1 30); do [ "$(workers)" = 1 ] && break; sleep 1; done
[ "$(workers)" = 1 ] || { echo "FAIL: the PhyS worker did not attach to relay-a"; exit 1; }
step "PhyS worker attached to relay-a"

for _ in $(seq 1 60); do
  up=$(curl -fsS -m 2 "http://127.0.0.1:$EDGEPHYS_PROMETHEUS_PORT/api/v1/query?query=sum(up%7Bjob%3D%22edgephys%22%7D)" 2>/dev/null \
       | grep -o '"value":\[[^]]*\]' || true)
  case "$up" in *'"2"'*) break ;; esac; sleep 1
done
case "$up" in *'"2"'*) step "Prometheus scrapes both relays" ;; *) echo "FAIL: Prometheus does not see both relays up ($up)"; exit 1 ;; esac

# The room's state reaches Redis (snapshot every 500 ms): wait until arena has the entity.
for _ in $(seq 1 20); do
  entities=$(arena_entities "$a_admin")
  [ "${entities:-0}" -ge 1 ] && break; sleep 0.5
done
[ "${entities:-0}" -ge 1 ] || { api "$a_admin/v1/rooms/arena"; echo "FAIL: the client's entity is not in arena on relay-a"; exit 1; }
sleep 1.5

step "kill -9 relay-a"
podman kill -s KILL "${project}_relay-a_1" >/dev/null
podman stop -t 0 "${project}_relay-a_1" >/dev/null 2>&1 || true   # stays down (restart policy)
[ "$(podman inspect --format '{{.State.Running}}' "${project}_relay-a_1")" = false ] || { echo "FAIL: relay-a still runs"; exit 1; }
kill "$client_pid" 2>/dev/null || true
wait "$client_pid" 2>/dev/null || true
client_pid=""

for _ in $(seq 1 30); do
  [ -n "$(arena_entities "$b_admin")" ] && break; sleep 1
done
[ -n "$(arena_entities "$b_admin")" ] || { api "$b_admin/v1/rooms"; echo "FAIL: arena did not come back on relay-b"; exit 1; }
entities=$(arena_entities "$b_admin")
[ "${entities:-0}" -ge 1 ] || { api "$b_admin/v1/rooms/arena"; echo "FAIL: arena came back on relay-b without the client's entity"; exit 1; }
step "arena back on relay-b with $entities entities"

"$client" --relay "127.0.0.1:$EDGEPHYS_RELAY_B_PORT" --secret "$EDGEPHYS_SECRET" --room arena --player 8 \
  --run-for 5 >"$log/client2.out" 2>&1 || true
grep -q '^joined arena' "$log/client2.out" || { cat "$log/client2.out"; echo "FAIL: no join to arena through relay-b"; exit 1; }
step "a client joined arena through relay-b"
echo "compose stack: up, client joined on relay-a, relay-a killed, arena back on relay-b (${SECONDS}s)"
