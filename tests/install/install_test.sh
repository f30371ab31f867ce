#!/usr/bin/env bash
# Install tier (ctest -L install): installs a built tree into a temporary prefix and checks what a
# user of the installation meets:
#  - the files: libraries (static and shared), headers, CMake package, pkg-config files, tools,
#    man pages, schemas;
#  - every installed header compiles on its own include path;
#  - a program that links only canopen::nmt_core builds against the installation with the CMake
#    package (shared and static) and with pkg-config, runs, and links neither msgpack-c nor
#    libpcap;
#  - a program that writes a pcap trace with canopen::nmt_io (shared and static) runs without
#    linking libpcap, which the library loads when the trace is opened;
#  - samples/embed_master (a program embedding the NMT master on the simulated bus) builds with the
#    CMake package and with pkg-config and runs;
#  - samples/socketcan_master (the master on SocketCAN, called into from a console thread with
#    post()) builds with the CMake package and with pkg-config, and says so when its bus cannot be
#    opened (exit 1; no CAN interface is needed);
#  - the installed tree moved elsewhere: cfgmgr still finds its schemas; a lone copy of cfgmgr
#    says that it found none (exit 3) unless given them;
#  - the man pages render without warnings and name every option of the --help they come from.
# Usage: install_test.sh BUILD_DIR WORK_DIR CXX
set -euo pipefail
build=$1
work=$2
cxx=$3
here=$(cd "$(dirname "$0")" && pwd)
source_dir=$(cd "$here/../.." && pwd)

# shellcheck source=SCRIPTDIR/checks.sh
source "$here/checks.sh"

rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" >"$work/install.log"

# --- the files -----------------------------------------------------------------------------------
libdir=$(cd "$prefix" && dirname "$(find . -name canopenConfig.cmake)" | sed 's|^\./||; s|/cmake/canopen$||')
for f in bin/cfgmgr bin/dcf2concise \
         share/canopen/schemas/cia301_communication.eds share/canopen/schemas/cia302_manager.eds \
         include/canopen/cfg/device_file.hpp include/canopen/nmt/protocol/frame.hpp \
         include/canopen/nmt/sim/sim_bus.hpp include/canopen/nmt/io/trace.hpp \
         "$libdir/cmake/canopen/canopenConfigVersion.cmake"; do
  [ -f "$prefix/$f" ] || fail "installed: $f"
done
for lib in cfg nmt-core nmt-sim nmt-io; do
  [ -f "$prefix/$libdir/libcanopen-$lib.a" ] || fail "installed: libcanopen-$lib.a"
  [ -L "$prefix/$libdir/libcanopen-$lib.so" ] || fail "installed: libcanopen-$lib.so"
  [ -f "$prefix/$libdir/pkgconfig/canopen-$lib.pc" ] || fail "installed: canopen-$lib.pc"
done
[ -f "$prefix/$libdir/pkgconfig/canopen-nmt.pc" ] || fail "installed: canopen-nmt.pc"
for page in dcf2concise cfgmgr cfgmgr-check cfgmgr-fmt cfgmgr-simulate cfgmgr-master cfgmgr-push \
            cfgmgr-diff cfgmgr-build cfgmgr-verify cfgmgr-store cfgmgr-sdo cfgmgr-lss cfgmgr-scan; do
  [ -f "$prefix/share/man/man1/$page.1.gz" ] || fail "installed: man page $page.1.gz"
done
echo "ok: installed files checked"

# --- every public header stands alone ------------------------------------------------------------
export PKG_CONFIG_PATH=$prefix/$libdir/pkgconfig
: >"$work/all_headers.cpp"
(cd "$prefix/include/canopen" && find cfg nmt -name '*.hpp' | sort) |
  while read -r h; do echo "#include \"$h\"" >>"$work/all_headers.cpp"; done
# shellcheck disable=SC2046
check "every installed header compiles from the installed include path" \
  "$cxx" -std=c++20 -fsyntax-only $(pkg-config --cflags canopen-nmt canopen-cfg) \
  "$work/all_headers.cpp"

# --- consumers -------------------------------------------------------------------------------------
expected=$'000#0105\n1017h 0x0006'
# msgpack-c or libpcap named in a link line or a NEEDED entry (not a directory that happens to be
# called pcap, as a checkout may be).
io_library='msgpack|libpcap|-lpcap'
# needs_only_own_libraries FILE KIND: NEEDED entries of FILE have no msgpack-c or libpcap.
needs_no_io_libraries() {
  local needed
  needed=$(readelf -d "$1" | grep NEEDED || true)
  if grep -Eq "$io_library" <<<"$needed"; then
    echo "$1 needs: $needed" >&2
    return 1
  fi
}
cmake_consumer() {  # cmake_consumer NAME EXTRA_CMAKE_ARGS...
  local name=$1
  shift
  local dir=$work/consumer-$name
  cmake -S "$here/consumer" -B "$dir" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_COMPILER="$cxx" \
    "$@" >"$dir.configure.log" 2>&1 || { cat "$dir.configure.log" >&2; return 1; }
  cmake --build "$dir" --verbose >"$dir.build.log" 2>&1 || { cat "$dir.build.log" >&2; return 1; }
  [ "$("$dir/consumer")" = "$expected" ] || { echo "unexpected output of $dir/consumer" >&2; return 1; }
  if grep -Eq "$io_library" "$dir.build.log"; then
    echo "the link of $name mentions msgpack-c or libpcap" >&2
    return 1
  fi
  needs_no_io_libraries "$dir/consumer"
}
check "CMake package, shared: a canopen::nmt_core program builds and runs without msgpack/pcap" \
  cmake_consumer shared
readelf -d "$work/consumer-shared/consumer" | grep -q 'NEEDED.*libcanopen-nmt-core' ||
  fail "the shared consumer links libcanopen-nmt-core.so"
check "CMake package, static: a canopen::nmt_core program builds and runs without msgpack/pcap" \
  cmake_consumer static -DCANOPEN_USE_STATIC_LIBS=ON
if readelf -d "$work/consumer-static/consumer" | grep -q 'NEEDED.*libcanopen'; then
  fail "the static consumer needs no libcanopen shared object"
fi
# The version file: 0.x versions are compatible within a minor version only.
mkdir -p "$work/version-check"
cat >"$work/version-check/CMakeLists.txt" <<'EOF'
cmake_minimum_required(VERSION 3.22)
project(version_check NONE)
find_package(canopen 0.99 QUIET)
if(canopen_FOUND)
  message(FATAL_ERROR "canopen ${canopen_VERSION} accepted for 0.99")
endif()
EOF
version_check() {
  cmake -S "$work/version-check" -B "$work/version-check/build" -DCMAKE_PREFIX_PATH="$prefix" \
    >"$work/version-check.log" 2>&1 || { cat "$work/version-check.log" >&2; return 1; }
}
check "CMake package version file refuses another minor version" version_check

pkg_consumer() {
  local flags
  flags=$(pkg-config --cflags --libs canopen-nmt-core) || return 1
  # shellcheck disable=SC2086
  "$cxx" -std=c++20 "$here/consumer/main.cpp" -o "$work/consumer-pkg-config" $flags \
    -DSCHEMA_DIR="\"$prefix/share/canopen/schemas\"" -Wl,-rpath,"$prefix/$libdir" || return 1
  [ "$("$work/consumer-pkg-config")" = "$expected" ] || return 1
  needs_no_io_libraries "$work/consumer-pkg-config"
}
check "pkg-config: a canopen-nmt-core program builds and runs without msgpack/pcap" pkg_consumer
static_libs=$(pkg-config --static --libs canopen-nmt-core)
if grep -Eq "$io_library" <<<"$static_libs"; then
  fail "pkg-config --static canopen-nmt-core: $static_libs"
fi
# libnmt_io loads libpcap with dlopen() when a pcap trace is opened: a static link needs
# msgpack-c and the dynamic loader's library, not libpcap.
io_libs=$(pkg-config --static --libs canopen-nmt-io)
if ! grep -q -- '-lmsgpackc' <<<"$io_libs" || ! grep -q -- '-ldl' <<<"$io_libs" ||
   grep -q -- '-lpcap' <<<"$io_libs"; then
  fail "pkg-config --static canopen-nmt-io names msgpack-c and libdl, not libpcap: $io_libs"
fi

# --- a program that writes a pcap trace with the installed canopen::nmt_io -------------------------
# It links no libpcap (NEEDED); the installed library loads it when the trace is opened, shared and
# static. pcap-savefile(5): magic a1b2c3d4 (little-endian here), link type 227 at offset 20.
trace_consumer() {  # trace_consumer NAME EXTRA_CMAKE_ARGS...
  local name=$1
  shift
  local dir=$work/trace-consumer-$name
  cmake -S "$here/trace_consumer" -B "$dir" -DCMAKE_PREFIX_PATH="$prefix" \
    -DCMAKE_CXX_COMPILER="$cxx" "$@" >"$dir.configure.log" 2>&1 ||
    { cat "$dir.configure.log" >&2; return 1; }
  cmake --build "$dir" >"$dir.build.log" 2>&1 || { cat "$dir.build.log" >&2; return 1; }
  if readelf -d "$dir/trace_consumer" | grep NEEDED | grep -q libpcap; then
    echo "$dir/trace_consumer needs libpcap" >&2
    return 1
  fi
  "$dir/trace_consumer" "$dir/out.pcap" || return 1
  local magic link_type
  magic=$(od -An -tx1 -N4 "$dir/out.pcap" | tr -d ' ')
  link_type=$(od -An -tu1 -j20 -N1 "$dir/out.pcap" | tr -d ' ')
  if [ "$magic" != d4c3b2a1 ] || [ "$link_type" != 227 ]; then
    echo "$dir/out.pcap is not a LINKTYPE_CAN_SOCKETCAN pcap file ($magic, $link_type)" >&2
    return 1
  fi
}
check "CMake package, shared: a canopen::nmt_io program writes a pcap trace, libpcap not linked" \
  trace_consumer shared
check "CMake package, static: a canopen::nmt_io program writes a pcap trace, libpcap not linked" \
  trace_consumer static -DCANOPEN_USE_STATIC_LIBS=ON

# --- the sample that embeds the NMT master --------------------------------------------------------
sample=$source_dir/samples/embed_master
sample_cmake() {
  local dir=$work/embed-master
  cmake -S "$sample" -B "$dir" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_COMPILER="$cxx" \
    >"$dir.configure.log" 2>&1 || { cat "$dir.configure.log" >&2; return 1; }
  cmake --build "$dir" >"$dir.build.log" 2>&1 || { cat "$dir.build.log" >&2; return 1; }
  "$dir/embed_master" >"$dir.out" 2>&1 || { cat "$dir.out" >&2; return 1; }
}
check "samples/embed_master builds with the CMake package and runs" sample_cmake
sample_pkg_config() {
  local flags
  flags=$(pkg-config --cflags --libs canopen-nmt-sim) || return 1
  # shellcheck disable=SC2086
  "$cxx" -std=c++20 "$sample/main.cpp" -o "$work/embed-master-pkg-config" $flags \
    -Wl,-rpath,"$prefix/$libdir" || return 1
  "$work/embed-master-pkg-config" >"$work/embed-master-pkg-config.out" 2>&1 ||
    { cat "$work/embed-master-pkg-config.out" >&2; return 1; }
}
check "samples/embed_master builds with pkg-config (canopen-nmt-sim) and runs" sample_pkg_config

# --- the sample that runs the master on SocketCAN and posts into it from another thread ----------
socketcan_sample=$source_dir/samples/socketcan_master
# No interface of that name exists: the program must end at once with exit 1, naming the URL.
missing_bus=socketcan:nocanopen0
runs_without_bus() {  # runs_without_bus PROGRAM
  local out status=0
  out=$("$1" "$missing_bus" 2 </dev/null 2>&1) || status=$?
  if [ "$status" -ne 1 ] || ! grep -q "nocanopen0" <<<"$out"; then
    echo "$1 $missing_bus: exit $status: $out" >&2
    return 1
  fi
}
socketcan_sample_cmake() {
  local dir=$work/socketcan-master
  cmake -S "$socketcan_sample" -B "$dir" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_COMPILER="$cxx" \
    >"$dir.configure.log" 2>&1 || { cat "$dir.configure.log" >&2; return 1; }
  cmake --build "$dir" >"$dir.build.log" 2>&1 || { cat "$dir.build.log" >&2; return 1; }
  runs_without_bus "$dir/socketcan_master"
}
check "samples/socketcan_master builds with the CMake package and runs" socketcan_sample_cmake
socketcan_sample_pkg_config() {
  local flags
  flags=$(pkg-config --cflags --libs canopen-nmt-io) || return 1
  # shellcheck disable=SC2086
  "$cxx" -std=c++20 -pthread "$socketcan_sample/main.cpp" -o "$work/socketcan-master-pkg-config" \
    $flags -Wl,-rpath,"$prefix/$libdir" || return 1
  runs_without_bus "$work/socketcan-master-pkg-config"
}
check "samples/socketcan_master builds with pkg-config (canopen-nmt-io) and runs" \
  socketcan_sample_pkg_config

# --- relocated tools find their schemas, or say that they did not --------------------------------
moved=$work/moved
mv "$prefix" "$moved"
mismatch=$source_dir/tests/data/check/schema_mismatch.eds
# CiA 301 defines 1017h as UNSIGNED16; the file declares UNSIGNED32 (tests/data/check/README.md).
check "a moved installation's cfgmgr checks against its schemas" \
  bash -c '"$1" check "$2" 2>&1 | grep -q "1017h: DataType is UNSIGNED32"' _ \
  "$moved/bin/cfgmgr" "$mismatch"
mkdir -p "$work/lone"
cp "$moved/bin/cfgmgr" "$work/lone/cfgmgr"
set +e
"$work/lone/cfgmgr" check "$mismatch" >"$work/lone.out" 2>"$work/lone.err"
status=$?
set -e
if [ "$status" -ne 3 ] || ! grep -q "no schemas" "$work/lone.err" ||
   ! grep -q -- "--schema-dir" "$work/lone.err"; then
  fail "a lone cfgmgr without schemas exits 3 saying so (exit $status): $(cat "$work/lone.err")"
else
  echo "ok: a lone cfgmgr says it found no schemas: $(cat "$work/lone.err")"
fi
check "a lone cfgmgr uses CANOPEN_SCHEMA_DIR" \
  bash -c 'CANOPEN_SCHEMA_DIR="$1" "$2" check "$3" 2>&1 | grep -q "1017h: DataType"' _ \
  "$moved/share/canopen/schemas" "$work/lone/cfgmgr" "$mismatch"
check "a lone cfgmgr with --no-schema checks without them" \
  "$work/lone/cfgmgr" check --no-schema "$mismatch"

# --- man pages -----------------------------------------------------------------------------------
# man_page_covers PAGE COMMAND...: PAGE renders without groff warnings and names every long option
# COMMAND --help lists.
man_page_covers() {
  local page=$1
  shift
  local text warnings
  warnings=$(MANWIDTH=80 man --warnings -l "$page" 2>&1 >/dev/null)
  if [ -n "$warnings" ]; then
    echo "$page: $warnings" >&2
    return 1
  fi
  text=$(MANWIDTH=200 man -l "$page" 2>/dev/null | sed 's/\xe2\x80\x90/-/g')
  for option in $("$@" --help | grep -oE -- '--[a-z][a-z-]*' | sort -u); do
    if ! grep -q -- "$option" <<<"$text"; then
      echo "$page does not name $option" >&2
      return 1
    fi
  done
}
man1=$moved/share/man/man1
check "man dcf2concise covers --help" man_page_covers "$man1/dcf2concise.1.gz" "$moved/bin/dcf2concise"
check "man cfgmgr covers --help" man_page_covers "$man1/cfgmgr.1.gz" "$moved/bin/cfgmgr"
for sub in check fmt simulate master push diff build verify store sdo; do
  check "man cfgmgr-$sub covers --help" \
    man_page_covers "$man1/cfgmgr-$sub.1.gz" "$moved/bin/cfgmgr" "$sub"
done

if [ "$failures" -ne 0 ]; then
  echo "install_test: $failures failure(s)" >&2
  exit 1
fi
echo "install_test: all checks passed"
