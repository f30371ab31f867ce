#!/usr/bin/env bash
# Install tier (ctest -L install), the firmware team's vendoring: the source tree configured with
# CANOPEN_CORE_ONLY=ON builds and installs canopen::cfg and canopen::nmt_core only, with CLI11,
# pkg-config (so msgpack-c and libpcap) and GoogleTest made unfindable
# (CMAKE_DISABLE_FIND_PACKAGE_*); no compile or link line of the build names CLI11, msgpack-c,
# libpcap or GoogleTest; the installation holds the two libraries, their headers and pkg-config
# files, nothing of sim/, io/ or the tools; and tests/install/consumer (a canopen::nmt_core
# program) builds against it (CMake package, shared and static; pkg-config) and runs.
# Usage: core_only_test.sh SOURCE_DIR WORK_DIR CXX
set -euo pipefail
source_dir=$(cd "$1" && pwd)
work=$2
cxx=$3
here=$(cd "$(dirname "$0")" && pwd)

# shellcheck source=SCRIPTDIR/checks.sh
source "$here/checks.sh"

rm -rf "$work"
mkdir -p "$work"
build=$work/build
prefix=$work/prefix
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
if ! cmake -S "$source_dir" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCANOPEN_CORE_ONLY=ON \
    -DCMAKE_CXX_COMPILER="$cxx" "${launcher[@]}" \
    -DCMAKE_DISABLE_FIND_PACKAGE_CLI11=ON -DCMAKE_DISABLE_FIND_PACKAGE_PkgConfig=ON \
    -DCMAKE_DISABLE_FIND_PACKAGE_GTest=ON >"$work/configure.log" 2>&1; then
  cat "$work/configure.log" >&2
  echo "core_only_test: configure with CANOPEN_CORE_ONLY=ON failed" >&2
  exit 1
fi
if ! cmake --build "$build" -j2 >"$work/build.log" 2>&1; then
  tail -50 "$work/build.log" >&2
  echo "core_only_test: build with CANOPEN_CORE_ONLY=ON failed" >&2
  exit 1
fi
cmake --install "$build" --prefix "$prefix" >"$work/install.log"
echo "ok: configured, built and installed with CANOPEN_CORE_ONLY=ON"

# No third-party library but zlib and yaml-cpp (libcfg) in any compile or link line.
third_party='cli11|msgpack|pcap|gtest|gmock'
no_third_party() {
  local found
  found=$(find "$build" \( -name flags.make -o -name link.txt -o -name compile_commands.json \) \
            -exec grep -Eil "$third_party" {} + || true)
  if [ -n "$found" ]; then
    echo "these name $third_party: $found" >&2
    return 1
  fi
}
check "no compile or link line names CLI11, msgpack-c, libpcap or GoogleTest" no_third_party

libdir=$(cd "$prefix" && dirname "$(find . -name canopenConfig.cmake)" | sed 's|^\./||; s|/cmake/canopen$||')
only_core_installed() {
  local libs
  libs=$(find "$prefix/$libdir" -maxdepth 1 -name 'libcanopen-*' -printf '%f\n' |
           sed 's/\..*//' | sort -u | tr '\n' ' ')
  [ "$libs" = "libcanopen-cfg libcanopen-nmt-core " ] || { echo "libraries: $libs" >&2; return 1; }
  local pcs
  pcs=$(find "$prefix/$libdir/pkgconfig" -type f -printf '%f\n' | sort | tr '\n' ' ')
  [ "$pcs" = "canopen-cfg.pc canopen-nmt-core.pc " ] || { echo "pkg-config: $pcs" >&2; return 1; }
  [ -f "$prefix/include/canopen/nmt/master/master_config.hpp" ] || return 1
  [ ! -e "$prefix/include/canopen/nmt/sim/sim_bus.hpp" ] || return 1
  [ ! -e "$prefix/include/canopen/nmt/io/bus_event_loop.hpp" ] || return 1
  [ ! -e "$prefix/bin" ] || { echo "programs installed: $(ls "$prefix/bin")" >&2; return 1; }
}
check "installed: cfg and nmt_core (libraries, headers, pkg-config), nothing else" only_core_installed

expected=$'000#0105\n1017h 0x0006'
consumer() {  # consumer NAME EXTRA_CMAKE_ARGS...
  local dir=$work/consumer-$1
  shift
  cmake -S "$here/consumer" -B "$dir" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_COMPILER="$cxx" \
    -DCMAKE_DISABLE_FIND_PACKAGE_PkgConfig=ON "$@" >"$dir.configure.log" 2>&1 ||
    { cat "$dir.configure.log" >&2; return 1; }
  cmake --build "$dir" >"$dir.build.log" 2>&1 || { cat "$dir.build.log" >&2; return 1; }
  [ "$("$dir/consumer")" = "$expected" ]
}
check "CMake package, shared: a canopen::nmt_core program builds and runs" consumer shared
check "CMake package, static: a canopen::nmt_core program builds and runs" \
  consumer static -DCANOPEN_USE_STATIC_LIBS=ON
pkg_consumer() {
  local flags
  flags=$(PKG_CONFIG_PATH=$prefix/$libdir/pkgconfig pkg-config --cflags --libs canopen-nmt-core) ||
    return 1
  # shellcheck disable=SC2086
  "$cxx" -std=c++20 "$here/consumer/main.cpp" -o "$work/consumer-pkg-config" $flags \
    -DSCHEMA_DIR="\"$prefix/share/canopen/schemas\"" -Wl,-rpath,"$prefix/$libdir" || return 1
  [ "$("$work/consumer-pkg-config")" = "$expected" ]
}
check "pkg-config: a canopen-nmt-core program builds and runs" pkg_consumer

if [ "$failures" -ne 0 ]; then
  echo "core_only_test: $failures failure(s)" >&2
  exit 1
fi
echo "core_only_test: all checks passed"
