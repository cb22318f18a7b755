#!/usr/bin/env bash
# The client SDK's public C++ headers must not pull in Asio, FlatBuffers, generated schema
# headers or codec internals (issue 13). For each header given, the compiler lists every header
# it includes (-M -MG: transitively, with the include path of the client library, so that a
# forbidden header would be found and listed rather than fail to resolve); any forbidden one
# fails the test and is named.
#
# To prove the scan can see what it looks for, canaries (headers that do include forbidden
# ones, e.g. protocol/datagram_socket.h) must be reported as failing; if the scan stops seeing
# them (a changed include path, a compiler that lists nothing) the test fails too.
#
# Usage: public_header_test.sh CXX "-I..;-I..;-D.." HEADER... [--canary HEADER...]
set -u

cxx=$1
IFS=';' read -r -a flags <<< "$2"
shift 2

headers=() canaries=()
target=headers
for a in "$@"; do
  if [[ $a == --canary ]]; then target=canaries; continue; fi
  if [[ $target == headers ]]; then headers+=("$a"); else canaries+=("$a"); fi
done
if (( ${#headers[@]} == 0 )); then
  echo "usage: $0 CXX FLAGS HEADER... [--canary HEADER...]" >&2
  exit 2
fi

# Headers a public SDK header may not reach, as they appear in the dependency list.
# A header that was not found (-MG) is listed as written, hence (^|/).
forbidden='((^|/)asio/|(^|/)asio\.hpp$|(^|/)flatbuffers/|_generated\.h$|(^|/)protocol/(datagram_socket|udp_socket|endpoint|connection|container_builder|state_codec|delta_codec|shared_delta_codec|soft_body_codec|emulation_codec|replication_tracker|packet_seal|handshake|bit_stream|quantize)\.h$)'

# Prints the forbidden headers $1 reaches; returns 0 if none, 1 if some, 2 if the compiler
# failed.
scan() {
  local deps
  if ! deps=$("$cxx" -std=c++20 -x c++ -M -MG "${flags[@]}" "$1" 2>&1); then
    echo "$deps" | head -20
    return 2
  fi
  # One path per line (depfile: "target: dep dep \" lines).
  local found
  # The scanned header itself is not one of its includes.
  found=$(echo "$deps" | tr ' \\' '\n\n' | grep -vxF "$1" | grep -E "$forbidden" | sort -u)
  if [[ -n $found ]]; then
    echo "$found"
    return 1
  fi
  return 0
}

failed=0
for h in "${headers[@]}"; do
  out=$(scan "$h"); rc=$?
  if (( rc == 0 )); then
    echo "ok: $h includes no Asio, FlatBuffers, generated or codec header"
  elif (( rc == 1 )); then
    asio=$(echo "$out" | grep -cE '(^|/)asio(/|\.hpp$)')
    echo "FAIL: $h includes $(echo "$out" | wc -l) forbidden headers ($asio of Asio):"
    echo "$out" | grep -vE '(^|/)asio(/|\.hpp$)' | head -20 | sed 's/^/  /'
    (( asio > 0 )) && echo "$out" | grep -E '(^|/)asio(/|\.hpp$)' | head -3 | sed 's/^/  /'
    failed=1
  else
    echo "FAIL: could not preprocess $h:"
    echo "$out" | sed 's/^/  /'
    failed=1
  fi
done

for c in "${canaries[@]}"; do
  out=$(scan "$c"); rc=$?
  if (( rc == 1 )); then
    echo "ok: canary $c is caught ($(echo "$out" | wc -l) forbidden headers)"
  else
    echo "FAIL: canary $c was not caught (rc $rc): the scan cannot see forbidden headers"
    echo "$out" | sed 's/^/  /'
    failed=1
  fi
done
exit $failed
