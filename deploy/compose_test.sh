#!/usr/bin/env bash
# ctest `compose_stack` (label `compose`): brings deploy/compose.yaml up with podman-compose,
# joins a client through relay-a, kills relay-a with SIGKILL (and keeps it down), sees the
# client's room come back on relay-b, and tears the stack down. Needs root, podman,
# podman-compose and the images (built by `podman-compose build` when missing; the relay
# image compiles the tree: ~5-15 minutes on 2 cores the first time, seconds when cached).
# With the images present the test takes about a minute.
# Usage: compose_test.sh CLIENT_BIN   (tests/admin/admin_test_client)
# Prints SKIPPED (ctest skips) without podman/podman-compose or without root.
set -euo pipefail
client="$1"
cd "$(dirname "$0")"
command -v podman-compose >/dev/null || { echo "SKIPPED: podman-compose not installed (scripts/setup.sh)"; exit 0; }
[ "$(id -u)" -eq 0 ] || { echo "SKIPPED: needs root (rootful podman)"; exit 0; }
for port in 7777 7778; do
  if ss -Huan "sport = :$port" | grep -q .; then echo "FAIL: UDP port $port is in use on the host"; exit 1; fi
done
for port in 9464 9465 9474 9475 9090; do
  if ss -Htln "sport = :$port" | grep -q .; then echo "FAIL: TCP port $port is in use on the host"; exit 1; fi
done

export EDGEPHYS_SECRET=$(openssl rand -hex 32) EDGEPHYS_ADMIN_KEY=$(openssl rand -hex 32)
project=edgephys-ctest
pc=(podman-compose -p "$project" -f compose.yaml)
log=$(mktemp -d)
cleanup() {
  "${pc[@]}" down -t 2 >"$log/down.out" 2>&1 || true
  podman network rm -f "${project}_edgephys" >/dev/null 2>&1 || true
  rm -rf "$log"
}
trap cleanup EXIT

t0=$SECONDS
step() { echo "[$((SECONDS - t0))s] $*"; }
if ! podman image exists localhost/edgephys-relay:0.1.0 || ! podman image exists localhost/edgephys-redis:0.1.0 \
   || ! podman image exists localhost/edgephys-prometheus:0.1.0; then
  step "building images (podman-compose build)"
  timeout 2400 "${pc[@]}" build >"$log/build.out" 2>&1 || { tail -n 40 "$log/build.out"; echo "FAIL: build"; exit 1; }
fi
step "up"
timeout 300 "${pc[@]}" up -d >"$log/up.out" 2>&1 || { tail -n 40 "$log/up.out"; echo "FAIL: up"; exit 1; }

api() { curl -sS -m 3 -H "Authorization: Bearer $EDGEPHYS_ADMIN_KEY" "$@"; }
wait_http() {  # URL SECONDS
  for _ in $(seq 1 "$2"); do curl -fsS -m 2 "$1" >/dev/null 2>&1 && return 0; sleep 1; done
  return 1
}
for url in http://127.0.0.1:9465/healthz http://127.0.0.1:9475/healthz; do
  wait_http "$url" 60 || { podman logs "${project}_relay-a_1" 2>&1 | tail -20; echo "FAIL: $url never answered"; exit 1; }
done
step "relays healthy"

# A client joins room "arena" through relay-a and stays for 60 s.
"$client" --relay 127.0.0.1:7777 --secret "$EDGEPHYS_SECRET" --room arena --player 7 --run-for 60 \
  >"$log/client.out" 2>&1 &
client_pid=$!
for _ in $(seq 1 50); do grep -q '^joined arena' "$log/client.out" && break; sleep 0.2; done
grep -q '^joined arena' "$log/client.out" || { cat "$log/client.out"; kill "$client_pid" 2>/dev/null; echo "FAIL: the client did not join through relay-a"; exit 1; }
api http://127.0.0.1:9465/v1/rooms | grep -q '"id": *"arena"' || { echo "FAIL: relay-a does not list arena"; exit 1; }
step "client joined arena on relay-a"

# The worker attached to relay-a by name.
for _ in $(seq 1 30); do
  curl -fsS -m 2 http://127.0.0.1:9464/metrics | grep -q '^edgephys_physics_workers 1' && break; sleep 1
done
curl -fsS -m 2 http://127.0.0.1:9464/metrics | grep -q '^edgephys_physics_workers 1' || { echo "FAIL: the PhyS worker did not attach to relay-a"; exit 1; }
step "PhyS worker attached to relay-a"

# Prometheus scrapes both relays by name.
for _ in $(seq 1 40); do
  up=$(curl -fsS -m 2 'http://127.0.0.1:9090/api/v1/query?query=sum(up%7Bjob%3D%22edgephys%22%7D)' 2>/dev/null | grep -o '"value":\[[^]]*\]' || true)
  case "$up" in *'"2"'*) break ;; esac; sleep 1
done
case "$up" in *'"2"'*) step "Prometheus scrapes both relays" ;; *) echo "FAIL: Prometheus does not see both relays up ($up)"; exit 1 ;; esac

step "kill -9 relay-a"
podman kill -s KILL "${project}_relay-a_1" >/dev/null
podman stop -t 0 "${project}_relay-a_1" >/dev/null 2>&1 || true   # keep it down (restart policy)
kill "$client_pid" 2>/dev/null || true
wait "$client_pid" 2>/dev/null || true

for _ in $(seq 1 30); do
  api http://127.0.0.1:9475/v1/rooms 2>/dev/null | grep -q '"id": *"arena"' && break; sleep 1
done
api http://127.0.0.1:9475/v1/rooms | grep -q '"id": *"arena"' || { api http://127.0.0.1:9475/v1/rooms; echo "FAIL: arena did not come back on relay-b"; exit 1; }
step "arena restored on relay-b"
# A player joins arena again through relay-b.
"$client" --relay 127.0.0.1:7778 --secret "$EDGEPHYS_SECRET" --room arena --player 8 --run-for 5 >"$log/client2.out" 2>&1 || true
grep -q '^joined arena' "$log/client2.out" || { cat "$log/client2.out"; echo "FAIL: no join to arena on relay-b"; exit 1; }
step "client joined arena on relay-b"
echo "compose stack: up, client joined, relay-a killed, arena back on relay-b (${SECONDS}s)"
