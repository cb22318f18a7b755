# Sourced by the .sh tests that run processes.
#
# Sources scripts/lib/stop_process.sh (stop PID [SECONDS]) and scripts/lib/start_relay.sh
# (start_relay, start_relay_with_metrics: they set relay_pid), makes $work, a fresh temporary
# directory, and on exit stops the processes whose PIDs relay_pid and the variables named to
# stop_on_exit then hold (the last named first, relay_pid last), then removes $work.
#
# stop_on_exit VAR...: adds variables (PID holders; empty: nothing to stop) to the exit list.
# skip_unless_runtime CMD: for CMD mono or python3 that is not installed, prints SKIPPED and
#   exits 0; any other CMD passes.
# wait_for_url URL PID TRIES: polls URL (curl, 2 s each) every 0.1 s up to TRIES times; 0 once
#   it answers, 1 when it never did or PID exited first.
_tests_lib_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=../scripts/lib/stop_process.sh
source "$_tests_lib_dir/../scripts/lib/stop_process.sh"
# shellcheck source=../scripts/lib/start_relay.sh
source "$_tests_lib_dir/../scripts/lib/start_relay.sh"

work=$(mktemp -d)
relay_pid=""
_stop_on_exit=(relay_pid)
stop_on_exit() { _stop_on_exit=("$@" "${_stop_on_exit[@]}"); }
_tests_lib_cleanup() {
  local v
  for v in "${_stop_on_exit[@]}"; do stop "${!v:-}"; done
  rm -rf "$work"
}
trap _tests_lib_cleanup EXIT

skip_unless_runtime() {
  case "$1" in
    mono|python3) command -v "$1" >/dev/null || { echo "SKIPPED: $1 is not installed"; exit 0; } ;;
  esac
}

wait_for_url() {
  local url="$1" pid="$2" tries="$3"
  for _ in $(seq 1 "$tries"); do
    curl -fsS --max-time 2 "$url" -o /dev/null 2>/dev/null && return 0
    kill -0 "$pid" 2>/dev/null || return 1
    sleep 0.1
  done
  return 1
}
