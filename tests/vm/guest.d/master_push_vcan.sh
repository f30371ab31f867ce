# vm-tools: cfgmgr
# Guest hook (busybox sh, run by guest-init.sh with vcan0/vcan1 up; vcan0 paced by tbf: about
# 125 kbit/s with a 10-frame transmit queue, so a burst meets ENOBUFS). Field conditions on a
# kernel CAN stack, against the sample cell (samples/network/nodelist.cpj: nodes 2, 3, 4)
# simulated by `cfgmgr simulate` from the network's own DCFs (push over vcan0 is
# guest.d/push_master.sh's):
# `cfgmgr master` over vcan0 is frozen for 2 s (SIGSTOP, SIGCONT) after start-up while the
# slaves keep heartbeating (1000 ms and 500 ms, consumed with 1600 and 850 ms): no
# heartbeat_lost, no NMT command, no boot-up follows; it still ends cleanly on SIGTERM.
# Exits non-zero on any failure, after printing what was seen.
set -u
can_if=vcan0
net=/opt/canopen/samples/network
out=/tmp/master_push_vcan
mkdir -p $out
failures=""

say() { echo "master_push_vcan: $*"; }
fail() {
  say "FAILED: $*"
  failures="$failures|$*"
}
# Waits up to $2 tenths of a second for an event named $1 in the master's JSON events.
wait_for_event() {
  n=0
  while ! grep -q "\"event\": \"$1\"" $out/events.jsonl 2>/dev/null; do
    n=$((n + 1))
    [ $n -le "$2" ] || return 1
    sleep 0.1
  done
}

command -v cfgmgr >/dev/null || { say "FAILED: cfgmgr is not in the guest"; exit 1; }

cfgmgr simulate --bus socketcan:$can_if $net/io_module_node2.dcf $net/drive_node3.dcf \
  $net/io_module_node4.dcf >$out/sim.out 2>$out/sim.err &
sim_pid=$!
sleep 1

# The master frozen for 2 s while the slaves heartbeat.
cfgmgr master $net/nodelist.cpj --bus socketcan:$can_if --json-events $out/events.jsonl \
  >$out/master.out 2>$out/master.err &
master_pid=$!
if wait_for_event startup_complete 300; then
  sleep 1  # the start commands follow start-up's end
  before=$(wc -l <$out/events.jsonl)
  kill -STOP $master_pid
  sleep 2
  kill -CONT $master_pid
  sleep 2
  after=$(tail -n +$((before + 1)) $out/events.jsonl)
  for wrong in heartbeat_lost nmt_command boot_up boot_error; do
    echo "$after" | grep -q "\"event\": \"$wrong\"" && fail "$wrong after the stall"
  done
else
  fail "cfgmgr master: no startup_complete within 30 s"
fi
kill -TERM $master_pid
wait $master_pid
status=$?
[ $status -eq 0 ] || fail "cfgmgr master exited with $status after SIGTERM"

kill -TERM $sim_pid
wait $sim_pid
status=$?
[ $status -eq 0 ] || fail "cfgmgr simulate exited with $status after SIGTERM"

if [ -n "$failures" ]; then
  for f in master.err events.jsonl sim.err; do
    say "--- $f"
    cat $out/$f
  done
  exit 1
fi
say "master stalled 2 s on $can_if: $(wc -l <$out/events.jsonl) events, none a loss or command"
exit 0
