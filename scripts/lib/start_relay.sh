# Sourced by test scripts: start_relay RELAY_BINARY LOG RUN_FOR_S starts an edgephys-relay on a
# free loopback UDP port (metrics off) in the background, sets relay_pid and relay_address
# (HOST:PORT, read from its "listening on udp" log line); returns 1 (log printed) if it did not
# come up within 5 s.
start_relay() {
  local binary="$1" log="$2" run_for="$3"
  "$binary" --bind 127.0.0.1:0 --metrics off --run-for "$run_for" --log-level info >"$log" 2>&1 &
  relay_pid=$!
  relay_address=""
  for _ in $(seq 1 50); do
    relay_address=$(grep -o "listening on udp [0-9.:]*" "$log" | awk '{print $4}' || true)
    [ -n "$relay_address" ] && return 0
    kill -0 "$relay_pid" 2>/dev/null || break
    sleep 0.1
  done
  echo "FAIL: the relay did not start"
  cat "$log"
  return 1
}
