#!/usr/bin/env bash
# Starts a real edgephys-relay on a free loopback port, mints two join tokens for a fresh room,
# runs the given command with EDGEPHYS_RELAY, EDGEPHYS_ROOM and EDGEPHYS_TOKEN_1 .. _8 (players
# 1 .. 8; each token admits once) in its environment, and stops the relay. Exit status: the command's.
# Prints SKIPPED (exit 0) when the command's runtime (mono, python3) is missing.
# Usage: with_relay.sh <edgephys-relay> <command...>
set -euo pipefail
relay="$1"; shift
source "$(dirname "$0")/lib.sh"  # $work, relay_pid, stop_on_exit, start_relay
skip_unless_runtime "$1"
start_relay "$relay" "$work/relay.log" 300 || exit 1
EDGEPHYS_RELAY="$relay_address"
export EDGEPHYS_RELAY
export EDGEPHYS_ROOM="r$RANDOM"
EDGEPHYS_TOKEN_1=$("$relay" token --dev-secret --player 1 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_2=$("$relay" token --dev-secret --player 2 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_3=$("$relay" token --dev-secret --player 3 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_4=$("$relay" token --dev-secret --player 4 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_5=$("$relay" token --dev-secret --player 5 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_6=$("$relay" token --dev-secret --player 6 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_7=$("$relay" token --dev-secret --player 7 --room "$EDGEPHYS_ROOM" --ttl 600)
EDGEPHYS_TOKEN_8=$("$relay" token --dev-secret --player 8 --room "$EDGEPHYS_ROOM" --ttl 600)
export EDGEPHYS_TOKEN_1 EDGEPHYS_TOKEN_2 EDGEPHYS_TOKEN_3 EDGEPHYS_TOKEN_4 EDGEPHYS_TOKEN_5 EDGEPHYS_TOKEN_6
export EDGEPHYS_TOKEN_7 EDGEPHYS_TOKEN_8
status=0
"$@" || status=$?
[ "$status" -eq 0 ] || { echo "-- relay log"; tail -20 "$work/relay.log"; }
exit "$status"
