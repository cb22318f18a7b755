#!/usr/bin/env bash
# The relay's command line: --help lists at most 35 options under the operators' groups, the
# tuning options it does not list are read from the config file (and the command line), and
# the options of deleted experiments are refused by name.
# Usage: relay_cli_test.sh path/to/edgephys-relay
set -euo pipefail
relay="$1"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

"$relay" --help >"$work/help.txt"
options=$(grep -cE '^  -' "$work/help.txt")
[ "$options" -le 35 ] || fail "--help lists $options options (at most 35)"
for group in "Network:" "Access:" "Rooms and limits:" "Replication:" "Physics:" \
             "Cluster (Redis):" "Admin API and metrics:" "Logging and process:"; do
  grep -qF "$group" "$work/help.txt" || fail "--help has no group '$group'"
done
# Every listed option shows its default (except those whose default is 'unset').
while read -r line; do
  case "$line" in
    *--secret*|*--redis*|*--relay-id*|*--public-address*|*--admin-key*|*--config*|*--help*) ;;
    *) [[ "$line" == *=* ]] || fail "no default shown: $line" ;;
  esac
done < <(grep -E '^  --' "$work/help.txt")
for tuning in --max-handshakes-per-s --cluster-ttl-ms --physics-idle \
              --max-reassembly-bytes; do
  ! grep -q -- "$tuning" "$work/help.txt" || fail "$tuning is a tuning option, not for --help"
done

# A tuning option from the config file is read: a bad value is refused with its name.
printf 'cluster-ttl-ms = 1\n' >"$work/bad.toml"
if "$relay" --config "$work/bad.toml" --bind 127.0.0.1:0 --metrics off --admin-addr off \
    --run-for 0.2 >"$work/bad.log" 2>&1; then
  fail "cluster-ttl-ms = 1 in the config file was accepted"
fi
grep -q -- "cluster-ttl-ms" "$work/bad.log" || fail "the refusal does not name cluster-ttl-ms: $(cat "$work/bad.log")"
# ... and a good one runs.
printf 'max-handshakes-per-s = 5\nmax-reassembly-bytes = 67108864\nlog-level = "warn"\n' >"$work/good.toml"
"$relay" --config "$work/good.toml" --bind 127.0.0.1:0 --metrics off --admin-addr off \
    --run-for 0.2 >"$work/good.log" 2>&1 || fail "a valid config file was refused: $(cat "$work/good.log")"

# Options of experiments that left the tree are unknown.
for gone in --batching --sleep-to-deadline --max-sleep --reliable-delay --velocities \
            --key-samples --stamp-state-time --extrapolation-threshold --shared-lockstep \
            --lockstep-ack-ticks --replication-mode; do
  if "$relay" "$gone" --bind 127.0.0.1:0 --metrics off --admin-addr off --run-for 0.1 \
      >/dev/null 2>&1; then
    fail "$gone was accepted"
  fi
done
echo "PASS: relay command line ($options options in --help)"
