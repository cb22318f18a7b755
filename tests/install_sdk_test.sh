#!/usr/bin/env bash
# The SDK from a fresh install prefix with no environment variables. cmake --install into a
# temporary prefix, start the installed edgephys-relay (with a secret) on loopback, then, each
# under `env -i PATH=/usr/bin:/bin HOME=<tmp>` (no LD_LIBRARY_PATH, PYTHONPATH or EDGEPHYS_*),
# exactly as README's "Use the SDK" shows:
#   C       the installed C example built with cc and pkg-config, run against the relay by host
#           name (localhost:PORT), the library found through the rpath edgephys.pc adds;
#   Python  the installed package pip-installed offline into a venv, the installed example run;
#   C#      the installed example built with mcs against the installed Edgephys.dll, run with
#           mono beside Edgephys.dll and its Edgephys.dll.config.
# Each example passes its own checks (it prints "ok"). The relay logs each disconnect by its
# reason's name. Python runs with the python3 this script finds on PATH (the CI's).
# Usage: install_sdk_test.sh <build dir> <source dir>
set -euo pipefail
build="$1"; src="$2"
source "$src/scripts/lib/stop_process.sh"
work=$(mktemp -d)
relay_pid=""
cleanup() { stop "$relay_pid"; rm -rf "$work"; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; [ -f "$work/relay.log" ] && { echo "-- relay log"; tail -20 "$work/relay.log"; }; exit 1; }
for tool in cc pkg-config mcs mono python3; do
  command -v "$tool" >/dev/null || fail "$tool is not installed (scripts/setup.sh installs it)"
done
clean=(env -i PATH=/usr/bin:/bin HOME="$work")
python=$(python3 -c 'import sys; print(sys.executable)')
prefix="$work/prefix"

cmake --install "$build" --prefix "$prefix" >"$work/install.log" 2>&1 || { cat "$work/install.log"; fail "cmake --install"; }
pc_dir=$(dirname "$(find "$prefix" -name edgephys.pc | head -1)")
share="$prefix/share/edgephys"
for f in "$share/bindings/python/pyproject.toml" "$share/bindings/python/edgephys/_libdir.py" \
         "$share/bindings/csharp/Edgephys.dll" "$share/bindings/csharp/Edgephys.dll.config" \
         "$share/examples/c/stack_and_grab.c" "$share/examples/python/stack_and_grab.py" \
         "$share/examples/csharp/StackAndGrab.cs"; do
  [ -e "$f" ] || fail "${f#"$prefix"/} not installed"
done

secret="install-$RANDOM$RANDOM"
"${clean[@]}" "$prefix/bin/edgephys-relay" --secret "$secret" --bind 127.0.0.1:0 --metrics off \
  --run-for 170 --log-level info >"$work/relay.log" 2>&1 &
relay_pid=$!
port=""
for _ in $(seq 1 50); do
  port=$(grep -o "listening on udp 127.0.0.1:[0-9]*" "$work/relay.log" | sed 's/.*://' || true)
  [ -n "$port" ] && break
  kill -0 "$relay_pid" 2>/dev/null || break
  sleep 0.1
done
[ -n "$port" ] || fail "the installed relay (run with no environment) did not start"
token() { "${clean[@]}" "$prefix/bin/edgephys-relay" token --secret "$secret" --player "$1" --room "$2" --ttl 300; }

# run_example NAME ADDRESS COMMAND...: the example with ADDRESS, a fresh room and its token.
run_example() {
  local name="$1" address="$2"; shift 2
  local room="$name$RANDOM" status=0
  timeout 90 "$@" "$address" "$(token 1 "$room")" "$room" >"$work/$name.log" 2>&1 || status=$?
  if [ "$status" -ne 0 ] || ! grep -q "^ok$" "$work/$name.log"; then
    cat "$work/$name.log"; fail "the $name example from the prefix (exit $status)"
  fi
  echo "$name example: ok"
}

echo "== C: cc + pkg-config, no LD_LIBRARY_PATH, relay by host name"
# shellcheck disable=SC2016
"${clean[@]}" sh -c 'cc -o "$1" "$2" $(PKG_CONFIG_PATH="$3" pkg-config --cflags --libs edgephys) -lm' \
  _ "$work/stack_and_grab" "$share/examples/c/stack_and_grab.c" "$pc_dir" || fail "cc with pkg-config"
"${clean[@]}" ldd "$work/stack_and_grab" | grep "libedgephys.so.1 => $prefix/" >/dev/null ||
  fail "the C program does not load libedgephys from the prefix: $("${clean[@]}" ldd "$work/stack_and_grab" | grep edgephys)"
run_example c "localhost:$port" "${clean[@]}" "$work/stack_and_grab"

echo "== Python: pip install (offline: --no-index) into a venv"
"${clean[@]}" "$python" -m venv "$work/venv" || fail "python3 -m venv"
"${clean[@]}" "$work/venv/bin/python" -m pip install --no-index --disable-pip-version-check -q \
  "$share/bindings/python" >"$work/pip.log" 2>&1 ||
  { cat "$work/pip.log"; fail "pip install $share/bindings/python"; }
run_example python "127.0.0.1:$port" "${clean[@]}" "$work/venv/bin/python" "$share/examples/python/stack_and_grab.py"

echo "== C#: mcs against the installed Edgephys.dll, mono"
mkdir "$work/cs"
cp "$share/bindings/csharp/Edgephys.dll" "$share/bindings/csharp/Edgephys.dll.config" "$work/cs/"
"${clean[@]}" mcs -nologo -r:"$work/cs/Edgephys.dll" -out:"$work/cs/StackAndGrab.exe" \
  "$share/examples/csharp/StackAndGrab.cs" || fail "mcs"
run_example csharp "127.0.0.1:$port" "${clean[@]}" mono "$work/cs/StackAndGrab.exe"

# The relay names why each of the three players left (e.g. "ClientLeft", "Timeout").
for _ in $(seq 1 100); do
  [ "$(grep -cE "player [0-9]+ disconnected \([A-Za-z]+\)" "$work/relay.log")" -ge 3 ] && break
  sleep 0.1
done
[ "$(grep -cE "player [0-9]+ disconnected \([A-Za-z]+\)" "$work/relay.log")" -ge 3 ] ||
  fail "the relay log does not name the disconnect reasons"
if grep -q "disconnected (reason [0-9]" "$work/relay.log"; then fail "a numeric disconnect reason in the relay log"; fi
echo "install sdk test passed"
