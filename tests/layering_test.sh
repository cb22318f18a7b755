#!/usr/bin/env bash
# The layers, enforced: each folder's production sources include only the folders below it
#   schema <- protocol <- client <- sdk;  protocol <- cluster, metrics;
#   protocol, client <- physics_backend <- relay <- loadgen
# (a test file, a testing/ folder or a *_testing.h header may reach further), no production
# source outside client/ and loadgen/ includes a *_testing.h header, and no production binary
# carries GoogleTest code.
# Usage: layering_test.sh SOURCE_DIR [BINARY...]
set -euo pipefail
src="$1"; shift
fail=0

# folder -> the folders its production sources may include ("edgephys" is the generated
# schema and the public header directory).
declare -A allowed=(
  [protocol]="protocol edgephys"
  [client]="client protocol edgephys"
  [cluster]="cluster protocol"
  [metrics]="metrics protocol edgephys"
  [physics_backend]="physics_backend protocol client edgephys"
  [relay]="relay protocol physics_backend cluster metrics edgephys"
  [sdk]="sdk client protocol edgephys"
)

is_test_file() {
  case "$1" in
    *_test.cc|*_test.h|*/testing/*|*_testing.h|*_bench.cc) return 0 ;;
  esac
  return 1
}

for folder in "${!allowed[@]}"; do
  while IFS= read -r -d '' file; do
    rel="${file#"$src"/}"
    is_test_file "$rel" && continue
    while IFS= read -r inc; do
      top="${inc%%/*}"
      ok=0
      for a in ${allowed[$folder]}; do [ "$top" = "$a" ] && ok=1; done
      if [ "$ok" -eq 0 ]; then
        echo "FAIL: $rel includes \"$inc\": $folder may include only: ${allowed[$folder]}"
        fail=1
      fi
      case "$inc" in
        *_testing.h|*/testing/*)
          if [ "$folder" != "client" ]; then
            echo "FAIL: $rel (production) includes the test-only header \"$inc\""
            fail=1
          fi ;;
      esac
    done < <(grep -hoE '^#include "[^"]+/[^"]+"' "$file" | sed -E 's/#include "(.*)"/\1/')
  done < <(find "$src/$folder" -type f \( -name '*.cc' -o -name '*.h' -o -name '*.hpp' \) -print0)
done

for bin in "$@"; do
  if [ ! -e "$bin" ]; then
    echo "FAIL: $bin not built"; fail=1; continue
  fi
  if nm -C "$bin" 2>/dev/null | grep -qE ' testing::(Test|internal)'; then
    echo "FAIL: $bin contains GoogleTest code (a production target links a testing library)"
    fail=1
  fi
done

if [ "$fail" -ne 0 ]; then exit 1; fi
echo "PASS: layers hold, no test code in ${#} production binaries"
