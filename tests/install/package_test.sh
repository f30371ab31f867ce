#!/usr/bin/env bash
# Install tier (ctest -L install): `cpack -G DEB` makes the Debian packages of
# cmake/CanopenPackaging.cmake; each has the files and the dependencies it should, and the tools
# unpacked from them run and find the schemas of the runtime package.
# Usage: package_test.sh BUILD_DIR WORK_DIR. Exits 77 (skip) without dpkg-deb/dpkg-shlibdeps (1
# under CI=true: tests/support/prerequisite.sh).
set -euo pipefail
build=$1
work=$2
here=$(cd "$(dirname "$0")" && pwd)
source_dir=$(cd "$here/../.." && pwd)
for tool in dpkg-deb dpkg-shlibdeps file; do
  if ! command -v "$tool" >/dev/null; then
    . "$(dirname "$0")/../support/prerequisite.sh"
    prerequisite_missing package_test "$tool missing (apt-get install dpkg-dev file)"
  fi
done

rm -rf "$work"
mkdir -p "$work"
(cd "$work" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work" >cpack.log 2>&1) || {
  cat "$work/cpack.log" >&2
  exit 1
}

failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}
package() {  # the .deb of package NAME
  local found
  found=$(find "$work" -maxdepth 1 -name "$1_*.deb" | head -n 1)
  [ -n "$found" ] || fail "no package $1 among: $(cd "$work" && ls ./*.deb)"
  echo "$found"
}
# has_depends DEB PATTERN...: the Depends field matches each (extended regex) pattern.
has_depends() {
  local deb=$1 depends
  shift
  depends=$(dpkg-deb -f "$deb" Depends)
  for pattern in "$@"; do
    grep -Eq "$pattern" <<<"$depends" || fail "$(basename "$deb") Depends lacks /$pattern/: $depends"
  done
}
has_files() {  # has_files DEB PATH...
  local deb=$1 listing
  shift
  listing=$(dpkg-deb -c "$deb")
  for path in "$@"; do
    grep -q " ./usr/$path" <<<"$listing" || fail "$(basename "$deb") lacks /usr/$path"
  done
}

version=$(grep -m1 -oE 'CPACK_PACKAGE_VERSION "[^"]+"' "$build/CPackConfig.cmake" | cut -d'"' -f2)
runtime=$(package 'libcanopen[0-9]*.[0-9]*')
dev=$(package libcanopen-dev)
tools=$(package canopen-tools)
runtime_name=$(dpkg-deb -f "$runtime" Package)

# Shared libraries with their SONAME, the schemas; what they link comes from dpkg-shlibdeps, and
# libpcap, which libnmt_io loads with dlopen() when a pcap trace is opened, from the package.
has_files "$runtime" "lib/libcanopen-cfg.so.$version" "lib/libcanopen-nmt-core.so.$version" \
  "lib/libcanopen-nmt-io.so.$version" share/canopen/schemas/cia301_communication.eds
has_depends "$runtime" '(^|, )libc6' 'libmsgpackc' 'libyaml-cpp' '(^|, )libpcap0'
# Headers, archives, .so links, CMake and pkg-config; a static link needs the deps' -dev packages
# (not libpcap-dev: no installed header includes pcap.h and no archive links libpcap).
has_files "$dev" include/canopen/cfg/device_file.hpp include/canopen/nmt/protocol/frame.hpp \
  lib/libcanopen-cfg.a lib/libcanopen-nmt-core.so lib/cmake/canopen/canopenConfig.cmake \
  lib/pkgconfig/canopen-nmt-core.pc
has_depends "$dev" "$runtime_name \(= $version\)" zlib1g-dev libyaml-cpp-dev libmsgpack-dev
# The tools and their man pages; the schemas come with the runtime package.
has_files "$tools" bin/cfgmgr bin/dcf2concise share/man/man1/cfgmgr-check.1.gz \
  share/man/man1/cfgmgr-simulate.1.gz share/man/man1/cfgmgr-master.1.gz \
  share/man/man1/cfgmgr-push.1.gz share/man/man1/cfgmgr-diff.1.gz \
  share/man/man1/cfgmgr-build.1.gz share/man/man1/cfgmgr-verify.1.gz \
  share/man/man1/cfgmgr-store.1.gz share/man/man1/cfgmgr-sdo.1.gz share/man/man1/cfgmgr-lss.1.gz share/man/man1/cfgmgr-scan.1.gz \
  share/man/man1/dcf2concise.1.gz
# cfgmgr is linked with the static libraries: its --trace loads libpcap, named by the package.
has_depends "$tools" "$runtime_name \(= $version\)" '(^|, )libc6' 'libstdc\+\+6' '(^|, )libpcap0'

# The tools as the packages lay them out: cfgmgr check uses the runtime package's schemas
# (CiA 301 defines 1017h as UNSIGNED16; tests/data/check/schema_mismatch.eds says UNSIGNED32).
root=$work/root
dpkg-deb -x "$runtime" "$root"
dpkg-deb -x "$tools" "$root"
checked=$("$root/usr/bin/cfgmgr" check "$source_dir/tests/data/check/schema_mismatch.eds" 2>&1)
if ! grep -q "1017h: DataType is UNSIGNED32" <<<"$checked"; then
  fail "the packaged cfgmgr checks against the packaged schemas"
fi

for deb in "$runtime" "$dev" "$tools"; do
  echo "$(dpkg-deb -f "$deb" Package): Depends: $(dpkg-deb -f "$deb" Depends)"
done
if [ "$failures" -ne 0 ]; then
  echo "package_test: $failures failure(s)" >&2
  exit 1
fi
echo "package_test: all checks passed"
