# Sourced by test scripts.
#
# start_relay RELAY_BINARY LOG RUN_FOR_S starts an edgephys-relay on a free loopback UDP port
# (metrics off) in the background, sets relay_pid and relay_address (HOST:PORT, read from its
# "listening on udp" log line); returns 1 (log printed) if it did not come up within 5 s.
#
# start_relay_with_metrics RELAY_BINARY LOG RUN_FOR_S [RELAY_ARGS...] does the same with
# /metrics on an ephemeral loopback TCP port as well, and also sets metrics_address (HOST:PORT,
# from its "metrics on" log line) once /metrics answers. Both ports are bound by the relay
# itself (port 0), so no other process can take them between a check and the bind.
_wait_for_relay() {  # LOG WANT_METRICS
  local log="$1" want_metrics="$2"
  relay_address=""
  metrics_address=""
  for _ in $(seq 1 50); do
    relay_address=$(grep -o "listening on udp [0-9.:]*" "$log" | awk '{print $4}' || true)
    if [ "$want_metrics" = 1 ]; then
      metrics_address=$(grep -o "metrics on http://[0-9.:]*" "$log" | sed 's|.*http://||' || true)
      if [ -n "$relay_address" ] && [ -n "$metrics_address" ] &&
        curl -sf -m 1 "http://$metrics_address/metrics" >/dev/null; then
        return 0
      fi
    elif [ -n "$relay_address" ]; then
      return 0
    fi
    kill -0 "$relay_pid" 2>/dev/null || break
    sleep 0.1
  done
  echo "FAIL: the relay did not start"
  cat "$log"
  return 1
}

start_relay() {
  local binary="$1" log="$2" run_for="$3"
  "$binary" --bind 127.0.0.1:0 --metrics off --run-for "$run_for" --log-level info >"$log" 2>&1 &
  relay_pid=$!
  _wait_for_relay "$log" 0
}

start_relay_with_metrics() {
  local binary="$1" log="$2" run_for="$3"
  shift 3
  "$binary" --bind 127.0.0.1:0 --metrics 127.0.0.1:0 --run-for "$run_for" --log-level info \
    "$@" >"$log" 2>&1 &
  relay_pid=$!
  _wait_for_relay "$log" 1
}
