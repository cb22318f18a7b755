#!/usr/bin/env bash
# End-to-end test of the admin HTTP API (docs/admin-api.md) against a real edgephys-relay
# process on loopback, with real SDK clients (admin_test_client) joined over UDP: every
# endpoint (the room map with the clients' published positions), 401 on a missing or wrong
# key, bad JSON, unknown rooms, an oversized body (413),
# a kicked client seeing the operator's reason, /readyz 503 while draining, and the relay
# exiting after the drain (at its deadline with a client left; at once when empty).
# Usage: admin_api_test.sh path/to/edgephys-relay path/to/admin_test_client
set -euo pipefail
relay_bin="$1"
client_bin="$2"
command -v jq >/dev/null || { echo "FAIL: jq is needed (scripts/setup.sh installs it)"; exit 1; }
work=$(mktemp -d)
relay_pid=""
client_pids=()
cleanup() {
  for p in "${client_pids[@]}"; do kill "$p" 2>/dev/null || true; done
  [ -n "$relay_pid" ] && kill "$relay_pid" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; echo "--- relay log"; tail -n 40 "$work/relay.log" 2>/dev/null; exit 1; }

key="test-key-$RANDOM$RANDOM"
secret="admin-test-secret"

# Starts a relay with the admin API on a free port (extra relay flags as arguments); sets
# relay_pid, admin (host:port), udp.
start_relay() {
  EDGEPHYS_ADMIN_KEY="$key" "$relay_bin" --bind 127.0.0.1:0 --metrics off --secret "$secret" \
    --admin-addr 127.0.0.1:0 --physics-threads 1 --run-for 120 --log-level info "$@" \
    >"$work/relay.log" 2>&1 &
  relay_pid=$!
  admin=""; udp=""
  for _ in $(seq 1 100); do
    admin=$(sed -n 's|.*admin API on http://\([0-9.:]*\)/v1.*|\1|p' "$work/relay.log" | head -n1)
    udp=$(sed -n 's|.*listening on udp \([0-9.:]*\).*|\1|p' "$work/relay.log" | head -n1)
    [ -n "$admin" ] && [ -n "$udp" ] && break
    kill -0 "$relay_pid" 2>/dev/null || fail "relay exited at start"
    sleep 0.05
  done
  [ -n "$admin" ] && [ -n "$udp" ] || fail "no admin/udp address in the relay log"
}

# call METHOD PATH [BODY] [KEY]: prints the HTTP status, the body goes to $work/body.
call() {
  local method="$1" path="$2" body="${3:-}" k="${4-$key}"
  local args=(-sS -o "$work/body" -w '%{http_code}' -X "$method" --max-time 10)
  [ -n "$k" ] && args+=(-H "Authorization: Bearer $k")
  [ -n "$body" ] && args+=(-H 'Content-Type: application/json' --data-binary "$body")
  curl "${args[@]}" "http://$admin$path"
}
expect() {  # expect STATUS ERROR_CODE|- METHOD PATH [BODY] [KEY]
  local want="$1" code="$2"; shift 2
  local got; got=$(call "$@")
  [ "$got" = "$want" ] || fail "$1 $2: HTTP $got, want $want: $(cat "$work/body")"
  jq -e . "$work/body" >/dev/null || fail "$1 $2: body is not JSON: $(cat "$work/body")"
  if [ "$code" != "-" ]; then
    [ "$(jq -r .error.code "$work/body")" = "$code" ] || fail "$1 $2: error code $(jq -c .error "$work/body"), want $code"
    [ -n "$(jq -r .error.message "$work/body")" ] || fail "$1 $2: no error message"
  fi
}
# wait_for SECONDS COMMAND...: retries COMMAND every 0.2 s.
wait_for() {
  local deadline=$(( $(date +%s) + $1 )); shift
  until "$@"; do [ "$(date +%s)" -lt "$deadline" ] || return 1; sleep 0.2; done
}
start_client() {  # start_client ROOM PLAYER: output in $work/client-PLAYER.out
  "$client_bin" --relay "$udp" --secret "$secret" --room "$1" --player "$2" --run-for 60 \
    >"$work/client-$2.out" 2>&1 &
  client_pids+=($!)
}
client_says() { grep -qF -- "$2" "$work/client-$1.out"; }

start_relay
echo "relay: udp $udp, admin $admin"

# --- probes, key -----------------------------------------------------------------------------
expect 200 - GET /healthz "" ""
[ "$(jq -r .status "$work/body")" = ok ] || fail "healthz body"
expect 200 - GET /readyz "" ""
expect 401 unauthorized GET /v1/rooms "" ""
expect 401 unauthorized GET /v1/rooms "" "wrong-$key"
expect 401 unauthorized POST /v1/rooms '{"id":"x"}' "wrong"
expect 200 - GET /v1/rooms
[ "$(jq '.rooms | length' "$work/body")" = 0 ] || fail "rooms not empty at start"

# --- create ----------------------------------------------------------------------------------
expect 400 bad_json POST /v1/rooms '{"id": "arena",'
expect 400 bad_json POST /v1/rooms '["arena"]'
expect 400 invalid_request POST /v1/rooms '{"id":"arena","colour":"red"}'
expect 400 invalid_request POST /v1/rooms '{"id":"arena","capacity":0}'
expect 400 invalid_request POST /v1/rooms '{"id":"arena","tick_rate_hz":"fast"}'
expect 400 invalid_request POST /v1/rooms '{"capacity":4}'
head -c 100000 /dev/zero | tr '\0' 'a' | sed 's/^/{"id":"/; s/$/"}/' >"$work/big.json"
expect 413 body_too_large POST /v1/rooms "@$work/big.json"
expect 201 - POST /v1/rooms '{"id":"arena","capacity":4,"ttl_s":600,"tick_rate_hz":30,"physics":false,"bounds":{"half_extent_m":100},"send_rates_hz":{"critical":30,"normal":10,"ambient":5}}'
jq -e '.id == "arena" and .players == 0 and .config.capacity == 4 and .config.tick_rate_hz == 30
       and .config.physics == false and .config.bounds.half_extent_m == 100
       and .config.send_rates_hz.critical == 30' "$work/body" >/dev/null || fail "created room: $(cat "$work/body")"
expect 409 room_exists POST /v1/rooms '{"id":"arena"}'
expect 200 - GET /v1/rooms
jq -e '.rooms[] | select(.id == "arena") | .players == 0 and .capacity == 4 and .tick_rate_hz == 30
       and .physics.enabled == false and .state_format == 9' "$work/body" >/dev/null || fail "list: $(cat "$work/body")"
jq -e '.draining == false' "$work/body" >/dev/null || fail "list: draining"

# --- unknown rooms, members, routes ----------------------------------------------------------
expect 404 room_not_found GET /v1/rooms/nowhere
expect 404 room_not_found DELETE /v1/rooms/nowhere
expect 404 room_not_found POST /v1/rooms/nowhere/members/5/kick '{"reason":"x"}'
expect 404 member_not_found POST /v1/rooms/arena/members/5/kick '{"reason":"x"}'
expect 400 invalid_request POST /v1/rooms/arena/members/abc/kick '{}'
expect 404 not_found GET /v1/nothing

# --- real clients: members, RTT, rates -------------------------------------------------------
for p in 11 12 13; do start_client arena $p; done
wait_for 10 bash -c "grep -q joined '$work/client-11.out' && grep -q joined '$work/client-12.out' && grep -q joined '$work/client-13.out'" \
  || fail "clients did not join: $(cat "$work"/client-*.out)"
members_measured() {
  [ "$(call GET /v1/rooms/arena)" = 200 ] &&
  jq -e '(.members | length) == 3 and all(.members[]; .rtt_ms > 0 and .bytes_in_per_s > 0
          and .bytes_out_per_s > 0 and .pending_reliable_bytes >= 0 and .entities == 1)
         and .entities == 3 and ([.entities_by_owner[] | select(.owner == 11) | .count] == [1])' \
         "$work/body" >/dev/null
}
wait_for 10 members_measured || fail "members not measured: $(cat "$work/body")"
echo "room arena: $(jq -c '[.members[] | {player_id, rtt_ms: (.rtt_ms*10|round/10), loss, in: (.bytes_in_per_s|round), out: (.bytes_out_per_s|round)}]' "$work/body")"
expect 200 - GET /v1/rooms
jq -e '.rooms[] | select(.id == "arena") | .players == 3 and .entities == 3 and .bytes_in_per_s > 0' \
  "$work/body" >/dev/null || fail "list with players: $(cat "$work/body")"
jq -e '.clients == 3' "$work/body" >/dev/null || fail "clients count: $(cat "$work/body")"
# The map: each client's entity where it publishes it (a unit circle at 1 m height).
expect 200 - GET /v1/rooms/arena/map
jq -e '.total == 3 and .listed == 3 and .truncated == false and .players == [11, 12, 13]
       and ([.entities[].owner] | sort) == [11, 12, 13]
       and all(.entities[]; .kind == "object" and .simulated == false and .y > 0.99 and .y < 1.01
                            and (.x * .x + .z * .z) > 0.98 and (.x * .x + .z * .z) < 1.02)' \
  "$work/body" >/dev/null || fail "map: $(cat "$work/body")"
expect 200 - GET "/v1/rooms/arena/map?limit=1"
jq -e '.listed == 1 and .total == 3 and .truncated == true' "$work/body" >/dev/null || fail "capped map: $(cat "$work/body")"
expect 400 invalid_request GET "/v1/rooms/arena/map?limit=0"
expect 404 room_not_found GET /v1/rooms/nowhere/map
expect 400 invalid_request GET "/v1/rooms/$(printf 'x%.0s' $(seq 1 65))/map"
expect 405 method_not_allowed POST /v1/rooms/arena/map '{}'
expect 401 unauthorized GET /v1/rooms/arena/map "" ""

# A room named by a join token with bytes that are not UTF-8: the JSON stays valid.
start_client $'odd\xffname' 14
wait_for 10 client_says 14 joined || fail "client 14: $(cat "$work/client-14.out")"
expect 200 - GET /v1/rooms
[ "$(jq '.rooms | length' "$work/body")" = 2 ] || fail "rooms with the odd name: $(cat "$work/body")"
expect 200 - GET /v1/rooms/odd%FFname
jq -e '.members[0].player_id == 14' "$work/body" >/dev/null || fail "odd room: $(cat "$work/body")"
expect 200 - DELETE /v1/rooms/odd%FFname
wait_for 5 client_says 14 "disconnected 4" || fail "client 14: $(cat "$work/client-14.out")"

# --- kick: the client reports the reason -----------------------------------------------------
expect 400 invalid_request POST /v1/rooms/arena/members/12/kick "{\"reason\":\"$(printf 'r%.0s' $(seq 1 300))\"}"
expect 200 - POST /v1/rooms/arena/members/12/kick '{"reason":"spam in chat"}'
wait_for 5 client_says 12 "disconnected 4 spam in chat" || fail "kicked client: $(cat "$work/client-12.out")"
expect 404 member_not_found POST /v1/rooms/arena/members/12/kick '{}'
expect 200 - GET /v1/rooms/arena
jq -e '(.members | map(.player_id) | sort) == [11, 13]' "$work/body" >/dev/null || fail "after kick: $(cat "$work/body")"

# --- close: every member gets the reason, the room is gone ------------------------------------
expect 200 - DELETE /v1/rooms/arena '{"reason":"maintenance"}'
jq -e '.closed == "arena" and .disconnected == 2' "$work/body" >/dev/null || fail "close: $(cat "$work/body")"
wait_for 5 client_says 11 "disconnected 4 maintenance" || fail "client 11: $(cat "$work/client-11.out")"
wait_for 5 client_says 13 "disconnected 4 maintenance" || fail "client 13: $(cat "$work/client-13.out")"
expect 404 room_not_found GET /v1/rooms/arena

# --- drain: not ready, no new rooms or joins, exit at the deadline ----------------------------
start_client late 21
wait_for 10 client_says 21 joined || fail "client 21: $(cat "$work/client-21.out")"
expect 400 invalid_request POST /v1/drain '{"deadline_s":-1}'
expect 400 invalid_request POST /v1/drain '{"deadline":3}'
drain_start=$(date +%s)
expect 202 - POST /v1/drain '{"deadline_s":3}'
jq -e '.draining == true and .clients == 1' "$work/body" >/dev/null || fail "drain: $(cat "$work/body")"
expect 503 draining GET /readyz "" ""
expect 200 - GET /healthz "" ""
expect 503 draining POST /v1/rooms '{"id":"new-room"}'
expect 200 - GET /v1/rooms
jq -e '.draining == true' "$work/body" >/dev/null || fail "list while draining"
if "$client_bin" --relay "$udp" --secret "$secret" --room late --player 22 --run-for 5 >"$work/client-22.out" 2>&1; then
  fail "a client joined a draining relay: $(cat "$work/client-22.out")"
fi
grep -q "rejected 5" "$work/client-22.out" || fail "client 22 not rejected with ServerFull: $(cat "$work/client-22.out")"
wait_for 10 client_says 21 "disconnected 3 the relay is shutting down" || fail "client 21 at the deadline: $(cat "$work/client-21.out")"
wait_for 10 bash -c "! kill -0 $relay_pid 2>/dev/null" || fail "relay still running after the drain deadline"
wait "$relay_pid" || fail "relay exited non-zero after the drain"
relay_pid=""
elapsed=$(( $(date +%s) - drain_start ))
[ "$elapsed" -ge 2 ] && [ "$elapsed" -le 8 ] || fail "drain took ${elapsed}s for a 3 s deadline"
echo "drain with one client left: relay exited ${elapsed}s after POST /v1/drain (deadline 3 s)"

# --- drain of an empty relay: exits at once (its rooms announce format 2) ----------------------
start_relay --no-shared-encoding
expect 201 - POST /v1/rooms '{"id":"legacy"}'
jq -e '.state_format == 2' "$work/body" >/dev/null || fail "--no-shared-encoding room: $(cat "$work/body")"
expect 200 - DELETE /v1/rooms/legacy
drain_start=$(date +%s)
expect 202 - POST /v1/drain '{"deadline_s":60}'
wait_for 5 bash -c "! kill -0 $relay_pid 2>/dev/null" || fail "empty relay did not exit after drain"
wait "$relay_pid" || fail "relay exited non-zero"
relay_pid=""
grep -q "no client left" "$work/relay.log" || fail "no drain log line"

# --- flags: an open address needs a key; off disables the API --------------------------------
if "$relay_bin" --bind 127.0.0.1:0 --metrics off --admin-addr 0.0.0.0:0 --run-for 2 >"$work/open.log" 2>&1; then
  fail "relay served the admin API on 0.0.0.0 without a key"
fi
grep -q "needs a key" "$work/open.log" || fail "no clear refusal: $(cat "$work/open.log")"
"$relay_bin" --bind 127.0.0.1:0 --metrics off --admin-addr off --run-for 0.3 >"$work/off.log" 2>&1 \
  || fail "relay with --admin-addr off failed: $(cat "$work/off.log")"
if grep -q "admin API on" "$work/off.log"; then fail "--admin-addr off still served"; fi
echo "admin API test passed"
