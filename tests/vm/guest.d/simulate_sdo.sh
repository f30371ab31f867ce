# vm-tools: cfgmgr
# Guest hook (busybox sh, run by guest-init.sh with vcan0/vcan1 up): `cfgmgr simulate` runs two
# simulated devices on vcan0, and two independent SocketCAN users talk to them through the
# kernel's CAN stack:
#   - can-utils: candump sees their boot-up and (once cansend has set 1017h) heartbeat frames,
#     and an SDO upload request for 1000h sent by cansend is answered with the device type;
#   - our SDO client over our SocketCAN driver: SocketCanSdo.* (tests/io/socketcan_sdo_test.cpp)
#     in the test binaries, with CANOPEN_VM_SIMULATED_DEVICES naming the same devices.
# Expected values are read from the device files. Frame layouts: boot-up 700h+node #00 and
# heartbeat #7F in pre-operational (spec/002), SDO expedited upload response 43h idx sub data and
# download response 60h idx sub (CiA 301 §7.2.4.3, public knowledge). Exits non-zero on any
# failure, after printing what was seen.
set -u
can_if=vcan0
samples=/opt/canopen/samples
drive=$samples/drive.eds
io=$samples/io_module.eds
devices="$drive@5 $io@6"
out=/tmp/simulate_sdo
mkdir -p $out
failures=""
started=$(cut -d' ' -f1 /proc/uptime)

say() { echo "simulate_sdo: $*"; }
fail() {
  say "FAILED: $*"
  failures="$failures|$*"
}
# Seconds since the hook started, from /proc/uptime (busybox date has no sub-seconds).
elapsed() { awk -v s="$started" '{ printf "%.2f", $1 - s }' /proc/uptime; }
# Unfiltered CAN_RAW receivers on the interface (procfs, the kernel's can.rst "procfs content").
receivers() { awk -v i="$can_if" '$1 == i' /proc/net/can/rcvlist_all | wc -l; }
seen() { grep -q " $1\$" $out/candump.log; }
# Waits up to $2 seconds (default 10) until the candump log has the frame $1 (candump -L form);
# not at all once the simulator has ended.
wait_for_frame() {
  n=0
  while ! seen "$1"; do
    kill -0 "$sim_pid" 2>/dev/null || return 1
    n=$((n + 1))
    [ $n -le $((${2:-10} * 20)) ] || return 1
    sleep 0.05
  done
}
# DefaultValue of [INDEX] in a device file, as little-endian hex bytes of a 32-bit value.
le32_default() {
  v=$(sed -n "/^\[$1\]/,/^\[/ s/^DefaultValue=//p" "$2" | tr -d '\r ' | head -n1)
  [ -n "$v" ] || return 1
  printf '%08X' $((v)) | sed 's/\(..\)\(..\)\(..\)\(..\)/\4\3\2\1/'
}

for p in cfgmgr candump cansend; do
  command -v $p >/dev/null || { say "FAILED: $p is not in the guest"; exit 1; }
done

# candump first, so that it sees the boot-up frames. It opens its socket some time after it
# starts: wait for it in rcvlist_all rather than a fixed time (see tests/vm/README.md).
before=$(receivers)
candump -L $can_if >$out/candump.log 2>&1 &
candump_pid=$!
n=0
while [ "$(receivers)" -le "$before" ] && [ $n -lt 200 ]; do
  n=$((n + 1))
  sleep 0.05
done
[ "$(receivers)" -gt "$before" ] || fail "candump did not open its socket within 10 s"

# Stops the simulator and candump, prints what they saw and exits: 1 on any failure. The
# simulator must still be running (a bus error ends it with exit status 3) and stop cleanly on
# SIGTERM (exit status 0).
finish() {
  if kill -0 $sim_pid 2>/dev/null; then
    kill -TERM $sim_pid
    wait $sim_pid
    status=$?
    [ $status -eq 0 ] || fail "cfgmgr simulate exited with $status after SIGTERM"
  else
    wait $sim_pid
    fail "cfgmgr simulate ended early with status $?"
  fi
  kill $candump_pid 2>/dev/null
  wait $candump_pid 2>/dev/null
  say "cfgmgr simulate said:"
  cat $out/simulate.log
  say "candump saw $(wc -l <$out/candump.log) frames in $(elapsed) s"
  if [ -n "$failures" ]; then
    say "candump log (last 60 lines):"
    tail -n 60 $out/candump.log
    say "FAILED:$failures"
    exit 1
  fi
  say "PASS"
  exit 0
}

# --for bounds the run should the kill below never come; the guest's own timeout is 300 s.
# shellcheck disable=SC2086 # $devices is a list
cfgmgr simulate --bus socketcan:$can_if $devices --for 240 >$out/simulate.log 2>&1 &
sim_pid=$!

for node in 5 6; do
  wait_for_frame "70$node#00" || fail "no boot-up 70$node#00 from node $node"
done
# Without devices on the bus nothing below can pass: stop here with what was seen.
[ -z "$failures" ] || finish
say "devices booted after $(elapsed) s"

# can-utils -> simulator: SDO upload of 1000h from node 5; the answer carries drive.eds's
# device type.
if type_bytes=$(le32_default 1000 $drive); then
  cansend $can_if 605#4000100000000000 || fail "cansend 605#4000100000000000"
  wait_for_frame "585#43001000$type_bytes" 5 ||
    fail "no 585#43001000$type_bytes (1000h of drive.eds) answering 605#4000100000000000"
else
  fail "no DefaultValue of [1000] in $drive"
fi

# Heartbeat every 100 ms (1017h = 0x0064) on both nodes, acknowledged, then produced.
for node in 5 6; do
  cansend $can_if 60$node#2B17100064000000 || fail "cansend 60$node#2B17100064000000"
  wait_for_frame "58$node#6017100000000000" 5 ||
    fail "no 58$node#6017100000000000 answering the 1017h download to node $node"
done
# Three heartbeats (pre-operational, 7Fh) from each; at 100 ms they take 0.3 s, allow 5 s for a
# loaded host.
for node in 5 6; do
  n=0
  while [ "$(grep -c " 70$node#7F\$" $out/candump.log)" -lt 3 ] && [ $n -lt 100 ]; do
    n=$((n + 1))
    sleep 0.05
  done
  beats=$(grep -c " 70$node#7F\$" $out/candump.log)
  [ "$beats" -ge 3 ] || fail "node $node: only $beats heartbeat(s) 70$node#7F in 5 s at 1017h = 100 ms"
done
say "can-utils checks done after $(elapsed) s"

# Our SDO client over our SocketCAN driver (in every test binary of the guest). With the
# devices given the tests must run, not skip.
for t in /opt/canopen/tests/*; do
  [ -x "$t" ] || continue
  log=$out/$(basename "$t").log
  CANOPEN_VM_SIMULATED_DEVICES="$devices" "$t" --gtest_color=no --gtest_filter='SocketCanSdo.*' \
    >"$log" 2>&1
  status=$?
  cat "$log"
  [ $status -eq 0 ] || fail "$(basename "$t") SocketCanSdo.* exited with $status"
  grep -q '^\[  PASSED  \] [1-9]' "$log" || fail "$(basename "$t"): no SocketCanSdo test passed"
  if grep -q '^\[  SKIPPED \]' "$log"; then fail "$(basename "$t"): SocketCanSdo tests skipped"; fi
done
say "SDO client tests done after $(elapsed) s"

finish
