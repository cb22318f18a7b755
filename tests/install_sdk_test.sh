#!/usr/bin/env bash
# What a user runs after `cmake --install`: a C program built with pkg-config, the Python
# example with the package pip-installed from the prefix, and the C# example against the
# installed Edgephys.dll, each run from the fresh prefix with no environment variable that
# points at the library (env -i: no LD_LIBRARY_PATH, PYTHONPATH, MONO_PATH or EDGEPHYS_*),
# against the installed edgephys-relay on loopback, with a watcher client checking the poses
# (tests/sdk_examples_test.sh).
# Usage: install_sdk_test.sh <build dir> <source dir> <stack_and_grab_cpp watcher>
set -euo pipefail
build="$1"; src="$2"; watcher="$3"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"
clean_env=(env -i PATH=/usr/bin:/bin HOME="$work" LANG=C.UTF-8)
fail() { echo "FAIL: $*"; exit 1; }

cmake --install "$build" --prefix "$prefix" >"$work/install.log" || { cat "$work/install.log"; fail "cmake --install"; }
relay="$prefix/bin/edgephys-relay"
run_example() {  # NAME COMMAND...
  local name="$1"; shift
  echo "== $name from $prefix"
  bash "$src/tests/sdk_examples_test.sh" "$relay" "$watcher" "$@" >"$work/$name.log" 2>&1 ||
    { cat "$work/$name.log"; fail "$name"; }
  tail -1 "$work/$name.log"
}

# C: built out of the tree with pkg-config; the program finds libedgephys through its rpath.
mkdir -p "$work/c"
cp "$src/examples/c/"*.c "$work/c/"
# shellcheck disable=SC2046
"${clean_env[@]}" cc -std=c11 -O1 -o "$work/c/stack_and_grab" "$work/c/"*.c \
  $("${clean_env[@]}" PKG_CONFIG_PATH="$prefix/lib/pkgconfig" pkg-config --cflags --libs edgephys) -lm
run_example c "${clean_env[@]}" "$work/c/stack_and_grab"

# Python: a virtual environment (Debian's python3), the package pip-installed from the prefix
# offline; the example runs from a copy outside the source tree.
if command -v python3 >/dev/null; then
  "${clean_env[@]}" python3 -m venv --system-site-packages "$work/venv"
  cp -r "$prefix/share/edgephys/bindings/python" "$work/pysrc"
  "${clean_env[@]}" "$work/venv/bin/pip" install --quiet --no-build-isolation --no-index "$work/pysrc" \
    >"$work/pip.log" 2>&1 || { cat "$work/pip.log"; fail "pip install from the prefix"; }
  cp "$src/examples/python/stack_and_grab.py" "$work/"
  run_example python "${clean_env[@]}" "$work/venv/bin/python" "$work/stack_and_grab.py"
else
  echo "SKIPPED: python3 is not installed"
fi

# C#: the installed assembly and its dllmap, copied next to the application.
if command -v mcs >/dev/null && command -v mono >/dev/null; then
  dotnet="$prefix/lib/edgephys/dotnet"
  [ -e "$dotnet/Edgephys.dll" ] && [ -e "$dotnet/Edgephys.dll.config" ] || fail "Edgephys.dll(.config) not installed"
  mkdir -p "$work/cs"
  cp "$dotnet/Edgephys.dll" "$dotnet/Edgephys.dll.config" "$work/cs/"
  "${clean_env[@]}" mcs -nologo -r:"$work/cs/Edgephys.dll" -out:"$work/cs/StackAndGrab.exe" \
    "$src/examples/csharp/StackAndGrab.cs"
  run_example csharp "${clean_env[@]}" mono "$work/cs/StackAndGrab.exe"
else
  echo "SKIPPED: Mono (mcs, mono) is not installed"
fi
echo "PASS: the SDK runs from a fresh install prefix with no environment variables"
