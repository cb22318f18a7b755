#!/usr/bin/env bash
# Starts a real edgephys-relay on a free loopback port, mints two join tokens for a fresh room,
# runs the given command with EDGEPHYS_RELAY, EDGEPHYS_ROOM, EDGEPHYS_TOKEN_1 and
# EDGEPHYS_TOKEN_2 in its environment, and stops the relay. Exit status: the command's.
# Prints SKIPPED (exit 0) when the command's runtime (mono, python3) is missing.
# Usage: with_relay.sh <edgephys-relay> <command...>
set -euo pipefail
relay="$1"; shift
source "$(dirname "$0")/../scripts/lib/stop_process.sh"
case "$1" in
  mono|python3) command -v "$1" >/dev/null || { echo "SKIPPED: $1 is not installed"; exit 0; } ;;
esac
work=$(mktemp -d)
relay_pid=""
cleanup() { stop "$relay_pid"; rm -rf "$work"; }
trap cleanup EXIT
"$relay" --bind 127.0.0.1:0 --metrics off --run-for 300 --log-level info >"$work/relay.log" 2>&1 &
relay_pid=$!
EDGEPHYS_RELAY=""
for _ in $(seq 1 50); do
  EDGEPHYS_RELAY=$(grep -o "listening on udp [0-9.:]*" "$work/relay.log" | awk '{print $4}' || true)
  [ -n "$EDGEPHYS_RELAY" ] && break
  kill -0 "$relay_pid" 2>/dev/null || break
  sleep 0.1
done
[ -n "$EDGEPHYS_RELAY" ] || { echo "FAIL: the relay did not start"; cat "$work/relay.log"; exit 1; }
export EDGEPHYS_RELAY
export EDGEPHYS_ROOM="r$RANDOM"
EDGEPHYS_TOKEN_1=$("$relay" token --player 1 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_2=$("$relay" token --player 2 --room "$EDGEPHYS_ROOM" --ttl 600)
export EDGEPHYS_TOKEN_1 EDGEPHYS_TOKEN_2
status=0
"$@" || status=$?
[ "$status" -eq 0 ] || { echo "-- relay log"; tail -20 "$work/relay.log"; }
exit "$status"
