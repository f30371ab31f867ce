#!/usr/bin/env bash
# Builds and runs the whole test suite, every tier (CTest labels, tests/CMakeLists.txt): unit, io
# (drivers and traces; the UDP bus against python-can in a network namespace), interop (python-can,
# tshark, can-utils, the corpus in ../shared, skipped when absent), tools end to end, install (a
# temporary prefix, consumers of it, the Debian packages), the SocketCAN VM tier; then a short smoke
# run of every fuzz target. This is the command the README and .ci/run use.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$root/build}
jobs=$(nproc)

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCANOPEN_WERROR=ON
cmake --build "$build" -j"$jobs"

# The libraries and tools once more at -O3 (CMAKE_BUILD_TYPE=Release, what users and packagers
# build), with warnings as errors: GCC's warnings at -O3 differ from -O2's. Compile only.
if [ "${SKIP_RELEASE_BUILD:-0}" != 1 ]; then
  release=${RELEASE_BUILD_DIR:-$build-release}
  cmake -S "$root" -B "$release" -DCMAKE_BUILD_TYPE=Release -DCANOPEN_WERROR=ON \
    -DCANOPEN_BUILD_TESTS=OFF -DCANOPEN_BUILD_BENCH=OFF -DCANOPEN_MAN_PAGES=OFF >/dev/null
  cmake --build "$release" -j"$jobs"
fi
ctest --test-dir "$build" --output-on-failure -j"$jobs" --timeout 600

# Fuzz smoke run: every libFuzzer target for a few seconds on its seeds (needs clang).
if [ "${SKIP_FUZZ:-0}" != 1 ]; then
  bash "$root/tests/fuzz/smoke.sh" "${FUZZ_BUILD_DIR:-$build-fuzz}"
fi
