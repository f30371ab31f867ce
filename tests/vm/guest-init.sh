#!/bin/busybox sh
# /init of the VM tier's initramfs (busybox sh, run as PID 1 by the kernel). Loads the CAN
# modules, creates vcan0 and vcan1, runs our SocketCAN tests and the hook scripts, prints one
# result marker line on the serial console and powers off. run-vm-tests.sh built the initramfs
# and decides pass/fail from the marker; a guest that dies before printing it fails.
/bin/busybox --install -s /bin
export PATH=/bin:/usr/bin:/opt/canopen/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev 2>/dev/null
mount -t tmpfs tmp /tmp

failures=""
fail() {
  echo "vm-guest: FAILED: $*"
  failures="$failures $1"
}

# Modules do not load by themselves (no udev, no modprobe config): insmod in dependency order,
# as the host computed it with modprobe --show-depends.
while read -r ko; do
  insmod "/lib/modules/$ko" || fail "insmod-$ko"
done </etc/canopen-modules

# vcan forwards every frame at once: its qdisc is noqueue whatever txqueuelen says (measured on
# Debian's 6.1: `txqueuelen 1` never gave ENOBUFS), so an unpaced burst overruns the receivers
# instead. A token bucket on vcan0 makes it behave like a real bus: about 1000 frames/s, as a
# 125 kbit/s CAN bus (tbf counts the 16-byte struct can_frame, 128 bits), and a transmit queue of
# 10 frames (160 bytes) that fills under a burst, so the driver meets ENOBUFS
# (tests/io/socketcan_bus_test.cpp, *TransmitQueue*). vcan1 stays as vcan creates it.
ip link add dev vcan0 type vcan || fail "create-vcan0"
ip link set vcan0 up || fail "up-vcan0"
# iproute2's tc, not busybox's applet of that name (which cannot add a tbf).
tc=/usr/bin/tc
if [ -x $tc ]; then
  $tc qdisc add dev vcan0 root tbf rate 125kbit burst 80 limit 160 || fail "tbf-vcan0"
  export CANOPEN_TEST_CAN_IF_RATE_LIMITED=1
else
  echo "vm-guest: no tc in the initramfs: the transmit-queue tests will skip"
fi
ip link add dev vcan1 type vcan || fail "create-vcan1"
ip link set vcan1 up || fail "up-vcan1"
echo "vm-guest: kernel $(uname -r)"
ip link show vcan0
ip link show vcan1
[ -x $tc ] && $tc qdisc show dev vcan0

# Our statically linked test binaries. `run-vm-tests.sh --filter F` narrows the run by passing
# canopen.filter=F on the kernel command line.
filter=$(sed -n 's/.*canopen\.filter=\([^ ]*\).*/\1/p' /proc/cmdline)
# The host's tier is required (CI=true or CANOPEN_VM_REQUIRED=1): a test that misses a
# prerequisite here fails instead of skipping (tests/support/prerequisite.hpp). CANOPEN_VM_GUEST
# tells the SocketCAN tests that vcan0/vcan1 are theirs to expect.
if grep -q 'canopen\.ci=true' /proc/cmdline; then
  export CI=true
  echo "vm-guest: CI=true: a test that misses a prerequisite fails"
fi
export CANOPEN_VM_GUEST=1
for t in /opt/canopen/tests/*; do
  [ -x "$t" ] || continue
  echo "vm-guest: running $(basename "$t")"
  if "$t" --gtest_color=no ${filter:+--gtest_filter=$filter}; then
    :
  else
    fail "$(basename "$t")"
  fi
done

# Hook: every /opt/canopen/guest.d/*.sh (from tests/vm/guest.d/) runs here with vcan0/vcan1
# up, the tools in /opt/canopen/bin (a "# vm-tools: TARGET" line in the script says which) and
# the repository's samples/ and schemas/ in /opt/canopen. A script fails the tier by exiting
# non-zero. simulate_sdo.sh runs `cfgmgr simulate --bus socketcan:vcan0` against can-utils and
# our SDO client (SocketCanSdo.* of the test binaries above).
for s in /opt/canopen/guest.d/*.sh; do
  [ -f "$s" ] || continue
  echo "vm-guest: running hook $(basename "$s")"
  sh "$s" || fail "$(basename "$s")"
done

if [ -z "$failures" ]; then
  echo "CANOPEN-VM-RESULT: PASS"
else
  echo "CANOPEN-VM-RESULT: FAIL$failures"
fi
sync
poweroff -f
