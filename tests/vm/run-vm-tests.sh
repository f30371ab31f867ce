#!/usr/bin/env bash
# The VM test tier: our SocketCAN driver on a real Linux CAN stack.
#
# Boots Debian's own kernel (the package linux-image-amd64 depends on, never a hard-coded
# version) under qemu-system-x86_64 with software emulation and a small initramfs: busybox-static,
# the CAN modules (can, can-raw, vcan and what they need), our statically linked test binaries and
# can-utils. The guest (guest-init.sh) creates vcan0/vcan1, runs the tests, prints a marker line
# on the serial console and powers off. This script passes only when that marker says PASS: qemu's
# own exit status says nothing about the guest. The guest's console log is always printed.
#
# Exit status: 0 pass, 1 fail, 77 skipped (qemu, busybox-static, kmod or the kernel package
# cannot be had). With CANOPEN_VM_REQUIRED=1 a missing prerequisite fails instead of skipping, so
# CI cannot silently skip the tier; it is the default when CI=true (CANOPEN_VM_REQUIRED=0 turns
# it off).
#
# Usage: run-vm-tests.sh [--work DIR] [--static-build DIR] [--filter GTEST_FILTER]
#                        [--tools "target..."] [--tools-dir DIR] [--test-bin FILE]
#   --work          scratch and cache directory (default: <repo>/build-vm)
#   --static-build  build directory for the -static test binaries (default: <work>/static)
#   --filter        gtest filter for the guest run
#   --tools         extra static targets to build and put in /opt/canopen/bin for guest.d hooks
#                   (a hook script can also ask for them with a line "# vm-tools: cfgmgr")
#   --test-bin      run this ready-built gtest binary in the guest instead of building
#                   socketcan_vm_tests, e.g. a sanitizer build's io_tests (with --filter)
#   --tools-dir     take those tools ready-built from DIR (e.g. the regular build's tools/)
#                   instead of building them -static; they go in with their shared libraries
# Environment: CANOPEN_VM_CACHE (kernel download cache, default <work>/cache),
#              CANOPEN_VM_TIMEOUT (seconds the guest may run, default 300).
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
source_dir=$(cd "$here/../.." && pwd)
work=$source_dir/build-vm
static_build=""
filter=""
tools=""
tools_dir=""
test_bin=""
while [ $# -gt 0 ]; do
  case "$1" in
    --work) work=$2; shift 2 ;;
    --static-build) static_build=$2; shift 2 ;;
    --filter) filter=$2; shift 2 ;;
    --tools) tools=$2; shift 2 ;;
    --tools-dir) tools_dir=$2; shift 2 ;;
    --test-bin) test_bin=$(cd "$(dirname "$2")" && pwd)/$(basename "$2"); shift 2 ;;
    *) echo "run-vm-tests: unknown argument $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$work"
work=$(cd "$work" && pwd)
static_build=${static_build:-$work/static}
cache=${CANOPEN_VM_CACHE:-$work/cache}
guest_timeout=${CANOPEN_VM_TIMEOUT:-300}
started=$(date +%s)

required=${CANOPEN_VM_REQUIRED:-$([ "${CI:-}" = true ] && echo 1 || echo 0)}

log() { echo "run-vm-tests: $*"; }
# The first existing path among the arguments (a glob that matched nothing stays literal).
first_match() {
  for f in "$@"; do
    if [ -e "$f" ]; then echo "$f"; return; fi
  done
}
skip() {
  if [ "$required" = 1 ]; then
    log "FAIL: $* (CANOPEN_VM_REQUIRED=1, so this is not skipped)"
    exit 1
  fi
  log "SKIP: $*"
  exit 77
}

# --- Prerequisites ------------------------------------------------------------------------
packages_hint="apt-get install qemu-system-x86 busybox-static cpio kmod xz-utils can-utils iproute2"
for tool in qemu-system-x86_64 cpio depmod modprobe dpkg-deb apt-get apt-cache gzip timeout strip; do
  command -v "$tool" >/dev/null || skip "$tool not found ($packages_hint)"
done
busybox=""
for b in /bin/busybox /usr/bin/busybox; do
  if [ -x "$b" ] && file_out=$(LC_ALL=C ldd "$b" 2>&1 || true) && [[ $file_out == *"not a dynamic"* ]]; then
    busybox=$b
    break
  fi
done
[ -n "$busybox" ] || skip "no statically linked busybox (apt-get install busybox-static)"
# Dynamically linked programs the guest uses: can-utils (an independent SocketCAN implementation
# to interoperate with) and tc from iproute2 (to pace vcan0 like a real bus). Without them the
# tests that need them skip inside the guest.
guest_programs=()
for u in candump cansend tc; do
  if p=$(PATH=$PATH:/usr/sbin:/sbin command -v "$u"); then
    guest_programs+=("$p")
  elif [ "$required" = 1 ]; then
    log "FAIL: $u not found (CANOPEN_VM_REQUIRED=1; $packages_hint)"
    exit 1
  else
    log "note: $u not found: the guest tests that need it will skip ($packages_hint)"
  fi
done

# --- The kernel: Debian's current package, downloaded once and cached ---------------------
find_kernel_pkg() {
  apt-cache depends linux-image-amd64 2>/dev/null |
    awk '/Depends: linux-image-[0-9]/ { print $2; exit }'
}
kernel_pkg=$(find_kernel_pkg)
if [ -z "$kernel_pkg" ] && [ "$(id -u)" -eq 0 ]; then
  log "apt knows no linux-image-amd64: running apt-get update"
  apt-get update -qq >/dev/null 2>&1 || true
  kernel_pkg=$(find_kernel_pkg)
fi
[ -n "$kernel_pkg" ] || skip "apt knows no linux-image-amd64 (run apt-get update)"
kernel_ver=$(apt-cache show --no-all-versions "$kernel_pkg" 2>/dev/null |
  awk '/^Version:/ { print $2; exit }')
[ -n "$kernel_ver" ] || skip "apt has no version of $kernel_pkg"
mkdir -p "$cache"
kdir=$cache/${kernel_pkg}_${kernel_ver}
# The marker names the extraction recipe: change it when the list of extracted files changes.
extracted_marker=$kdir/.extracted-v2
if [ ! -f "$extracted_marker" ]; then
  deb=$(first_match "$cache/${kernel_pkg}_${kernel_ver}_"*.deb)
  if [ -z "$deb" ]; then
    log "downloading $kernel_pkg $kernel_ver"
    # Older kernels' packages go: the cache keeps only the current one.
    rm -rf "$cache"/linux-image-*
    # As root apt warns that it downloads unsandboxed; that is expected here.
    (cd "$cache" && apt-get download -q "$kernel_pkg=$kernel_ver" 2>&1) |
      grep -v '^W: Download is performed unsandboxed' || true
    deb=$(first_match "$cache/${kernel_pkg}_${kernel_ver}_"*.deb)
    [ -n "$deb" ] || skip "could not download $kernel_pkg $kernel_ver"
  fi
  log "extracting vmlinuz and the CAN modules from $(basename "$deb")"
  rm -rf "$kdir"
  mkdir -p "$kdir"
  # Only what the guest needs; a pattern that matches nothing (e.g. a file an older kernel does
  # not have) is not an error, the checks below are.
  dpkg-deb --fsys-tarfile "$deb" |
    tar -x -C "$kdir" --wildcards --wildcards-match-slash \
      '*boot/vmlinuz-*' '*/kernel/net/can/*' '*/kernel/drivers/net/can/vcan.ko*' \
      '*/kernel/drivers/net/can/dev/*' '*/kernel/net/sched/sch_tbf.ko*' '*/modules.order' \
      '*/modules.builtin*' 2>/dev/null || true
  [ -d "$kdir/lib/modules" ] || { [ -d "$kdir/usr/lib/modules" ] && ln -s usr/lib "$kdir/lib"; }
  # Newer kernels ship modules compressed; busybox insmod needs them plain.
  find "$kdir" -name '*.ko.xz' -exec xz -d {} +
  find "$kdir" -name '*.ko.zst' -exec zstd -q -d --rm {} +
  find "$kdir" -name '*.ko.gz' -exec gzip -d {} +
  touch "$extracted_marker"
fi
vmlinuz=$(first_match "$kdir"/boot/vmlinuz-*)
[ -n "$vmlinuz" ] || { log "FAIL: no vmlinuz in $kernel_pkg"; exit 1; }
kver=${vmlinuz##*/vmlinuz-}
[ -d "$kdir/lib/modules/$kver" ] || { log "FAIL: no modules for $kver in $kernel_pkg"; exit 1; }
depmod -b "$kdir" "$kver"
# Dependency order, as modprobe would load them: "insmod /path/x.ko" lines, dependencies first.
modules=()
while read -r verb path _; do
  [ "$verb" = insmod ] || continue
  case " ${modules[*]-} " in *" $path "*) ;; *) modules+=("$path") ;; esac
done < <(modprobe -d "$kdir" -S "$kver" --show-depends -a vcan can-raw sch_tbf)
[ ${#modules[@]} -ge 3 ] || { log "FAIL: modprobe found no CAN modules for $kver"; exit 1; }
log "kernel $kver ($kernel_pkg $kernel_ver); modules: $(for m in "${modules[@]}"; do basename "$m"; done | tr '\n' ' ')"

# --- Static test binaries ------------------------------------------------------------------
if compgen -G "$here/guest.d/*.sh" >/dev/null; then
  tools="$tools $(sed -n 's/^# vm-tools: *//p' "$here"/guest.d/*.sh | tr '\n' ' ')"
fi
# No -march=native anywhere: the emulated CPU (-cpu max under TCG) lacks AVX-512. The build type
# is the one tests/run.sh uses. Warnings are not errors here: the regular build already fails on
# them, and g++ 12's optimiser-dependent false positives (-Wrestrict, -Wmaybe-uninitialized)
# should not decide whether the driver works on a real CAN stack.
static_targets=""
[ -n "$test_bin" ] || static_targets="socketcan_vm_tests"
static_tools=""
[ -n "$tools_dir" ] || static_tools=$tools
if [ -n "${static_targets// /}${static_tools// /}" ]; then
  log "building static test binaries in $static_build"
  cmake -S "$source_dir" -B "$static_build" -DCANOPEN_STATIC=ON \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCANOPEN_WERROR=OFF -DCANOPEN_BUILD_BENCH=OFF \
    -DCMAKE_PROJECT_INCLUDE="$here/static.cmake" >"$work/static-configure.log" 2>&1 ||
    { cat "$work/static-configure.log"; log "FAIL: configuring the static build"; exit 1; }
fi
if [ -n "${static_targets// /}" ]; then
  # shellcheck disable=SC2086 # a space-separated list of targets
  nice cmake --build "$static_build" -j"$(nproc)" --target $static_targets \
    >"$work/static-build.log" 2>&1 ||
    { tail -n 60 "$work/static-build.log"; log "FAIL: building the static test binaries"; exit 1; }
fi
# Tools for the hooks: a tool that does not link -static (cfgmgr: see README) leaves out the
# hooks that need it, with a note, unless CANOPEN_VM_REQUIRED=1; ctest passes --tools-dir.
missing_tools=""
for t in $static_tools; do
  nice cmake --build "$static_build" -j"$(nproc)" --target "$t" >"$work/static-$t.log" 2>&1 &&
    continue
  if [ "$required" = 1 ]; then
    tail -n 20 "$work/static-$t.log"
    log "FAIL: $t does not link -static (CANOPEN_VM_REQUIRED=1); pass --tools-dir BUILD/tools"
    exit 1
  fi
  log "note: $t does not link -static ($work/static-$t.log): the hooks that need it do not run;" \
    "pass --tools-dir BUILD/tools (as ctest -L vm does)"
  missing_tools="$missing_tools $t"
done
if [ -z "$test_bin" ]; then
  test_bin=$(find "$static_build" -type f -name socketcan_vm_tests -perm -u+x | head -n1)
  [ -n "$test_bin" ] || { log "FAIL: socketcan_vm_tests was not built"; exit 1; }
fi
[ -x "$test_bin" ] || { log "FAIL: no test binary $test_bin"; exit 1; }

# --- The initramfs -------------------------------------------------------------------------
root=$work/initramfs
rm -rf "$root"
mkdir -p "$root"/{bin,dev,proc,sys,tmp,etc,lib/modules,usr/bin,opt/canopen/bin,opt/canopen/tests,opt/canopen/guest.d}
cp "$busybox" "$root/bin/busybox"
cp "$here/guest-init.sh" "$root/init"
chmod +x "$root/init"
: >"$root/etc/canopen-modules"
for m in "${modules[@]}"; do
  cp "$m" "$root/lib/modules/"
  basename "$m" >>"$root/etc/canopen-modules"
done
# Copies a program into the initramfs with the shared libraries it needs (none if static).
# Debug information stays in the build tree; the guest needs only the code.
copy_with_libs() {
  strip -o "$2/$(basename "$1")" "$1"
  for lib in $(ldd "$1" 2>/dev/null | grep -o '/[^ ]*' || true); do
    mkdir -p "$root$(dirname "$lib")"
    cp -L "$lib" "$root$lib"
  done
}
copy_with_libs "$test_bin" "$root/opt/canopen/tests"
for t in $tools; do
  case " $missing_tools " in *" $t "*) continue ;; esac
  if [ -n "$tools_dir" ]; then
    [ -x "$tools_dir/$t" ] || { log "FAIL: no tool $t in $tools_dir"; exit 1; }
    copy_with_libs "$tools_dir/$t" "$root/opt/canopen/bin"
  else
    bin=$(find "$static_build" -type f -name "$t" -perm -u+x | head -n1)
    [ -n "$bin" ] || { log "FAIL: tool $t was not built"; exit 1; }
    copy_with_libs "$bin" "$root/opt/canopen/bin"
  fi
done
for hook in "$here"/guest.d/*.sh; do
  [ -f "$hook" ] || continue
  needs_missing=""
  # shellcheck disable=SC2013 # the line lists targets, one word each
  for t in $(sed -n 's/^# vm-tools: *//p' "$hook"); do
    case " $missing_tools " in *" $t "*) needs_missing="$needs_missing $t" ;; esac
  done
  if [ -n "$needs_missing" ]; then
    log "note: hook $(basename "$hook") does not run (no$needs_missing)"
  else
    cp "$hook" "$root/opt/canopen/guest.d/"
  fi
done
# Device files and object definitions for hooks that run simulated devices (small).
for d in samples schemas; do
  if [ -d "$source_dir/$d" ]; then cp -r "$source_dir/$d" "$root/opt/canopen/"; fi
done
# Debian links these dynamically.
for u in "${guest_programs[@]}"; do copy_with_libs "$u" "$root/usr/bin"; done
initrd=$work/initramfs.cpio.gz
(cd "$root" && find . | LC_ALL=C sort | cpio -o -H newc --quiet | gzip -1) >"$initrd"
log "initramfs $(du -h "$initrd" | cut -f1) ready after $(($(date +%s) - started)) s"

# --- Boot ----------------------------------------------------------------------------------
# TCG, not KVM: /dev/kvm may exist where -accel kvm hangs. panic=-1 and -no-reboot turn a guest
# panic into a qemu exit; the hard timeout bounds everything else.
console=$work/console.log
append="console=ttyS0 panic=-1 quiet"
[ -z "$filter" ] || append="$append canopen.filter=$filter"
# A required tier is required inside the guest too: its tests fail where a prerequisite (vcan,
# can-utils, the simulated devices) is missing instead of skipping (tests/support/prerequisite.hpp).
[ "$required" != 1 ] || append="$append canopen.ci=true"
boot_start=$(date +%s)
set +e
timeout -k 5 "$guest_timeout" qemu-system-x86_64 -accel tcg -cpu max -m 256 -smp 1 -nodefaults \
  -display none -no-reboot -nic none -serial stdio -kernel "$vmlinuz" -initrd "$initrd" \
  -append "$append" </dev/null >"$console" 2>&1
qemu_status=$?
set -e
boot_seconds=$(($(date +%s) - boot_start))

echo "----- guest console ($console) -----"
tr -d '\r' <"$console"
echo "----- end of guest console -----"
log "qemu exited with $qemu_status after ${boot_seconds} s (total $(($(date +%s) - started)) s)"
if [ $qemu_status -eq 124 ] || [ $qemu_status -eq 137 ]; then
  log "FAIL: the guest did not power off within ${guest_timeout} s"
  exit 1
fi
if tr -d '\r' <"$console" | grep -q '^CANOPEN-VM-RESULT: PASS$'; then
  log "PASS"
  exit 0
fi
if tr -d '\r' <"$console" | grep -q '^CANOPEN-VM-RESULT: FAIL'; then
  log "FAIL: $(tr -d '\r' <"$console" | grep '^CANOPEN-VM-RESULT: FAIL')"
else
  log "FAIL: the guest printed no result marker (it crashed or never ran the tests)"
fi
exit 1
