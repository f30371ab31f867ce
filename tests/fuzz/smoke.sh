#!/usr/bin/env bash
# Builds the libFuzzer targets with clang and runs each briefly on its seed corpus. A crash fails.
# Usage: smoke.sh BUILD_DIR [SECONDS_PER_TARGET]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:?build dir}
seconds=${2:-${FUZZ_SECONDS:-15}}
if ! command -v clang++ >/dev/null; then
  echo "fuzz smoke: SKIPPED, clang++ not installed (apt-get install clang libclang-rt-14-dev)"
  exit 0
fi
cmake -S "$root" -B "$build" -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCANOPEN_FUZZ=ON -DCANOPEN_BUILD_TESTS=OFF -DCANOPEN_BUILD_BENCH=OFF >/dev/null
targets=()
for src in "$root"/tests/fuzz/*.cpp; do targets+=("$(basename "$src" .cpp)"); done
cmake --build "$build" -j"$(nproc)" --target "${targets[@]}"
passed=0
failed=0
for t in "${targets[@]}"; do
  seeds="$root/tests/fuzz/seeds/${t#fuzz_}"
  work=$(mktemp -d)
  [ -d "$seeds" ] && cp -r "$seeds"/. "$work"/
  echo "fuzz smoke: $t for ${seconds}s"
  if "$build/tests/fuzz/$t" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 \
      -artifact_prefix="$build/$t-" "$work" >"$build/$t.log" 2>&1; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    echo "fuzz smoke: $t FAILED; last lines of $build/$t.log:"
    tail -40 "$build/$t.log"
  fi
  rm -rf "$work"
done
echo "fuzz smoke: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
