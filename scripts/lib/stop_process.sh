# Sourced by the test and soak scripts that start processes in the background.
# stop <pid> [seconds]: SIGTERM, wait up to `seconds` (default 5) for the process to exit, then
# SIGKILL; reaps it when it is our child. Does nothing for an empty pid or a process already
# gone.
stop() {
  local p="$1" tenths=$(( ${2:-5} * 10 ))
  [ -n "$p" ] || return 0
  kill -TERM "$p" 2>/dev/null || return 0
  for _ in $(seq 1 "$tenths"); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
  kill -KILL "$p" 2>/dev/null || true
  wait "$p" 2>/dev/null || true
}
