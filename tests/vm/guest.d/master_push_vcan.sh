# vm-tools: cfgmgr
# Guest hook (busybox sh, run by guest-init.sh with vcan0/vcan1 up; vcan0 paced by tbf: about
# 125 kbit/s with a 10-frame transmit queue, so a burst meets ENOBUFS). Issue 22 on a kernel CAN
# stack, against the sample cell (samples/network/nodelist.cpj: nodes 2, 3, 4) simulated by
# `cfgmgr simulate` from the network's own DCFs:
#   1. `cfgmgr push` over vcan0 gives every node the same result, entries and bytes as the same
#      push on the simulated bus (sim:), and exits 0;
#   2. `cfgmgr master` over vcan0 is frozen for 2 s (SIGSTOP, SIGCONT) after start-up while the
#      slaves keep heartbeating (1000 ms and 500 ms, consumed with 1600 and 850 ms): no
#      heartbeat_lost, no NMT command, no boot-up follows; it still ends cleanly on SIGTERM.
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
# "node result entries bytes" per node of a cfgmgr push --json report, one line each.
per_node() {
  tr '{' '\n' <"$1" |
    sed -n 's/^"node_id": \([0-9]*\), "name": "[^"]*", "result": "\([^"]*\)".*"entries": \([0-9]*\), "bytes": \([0-9]*\).*/\1 \2 \3 \4/p'
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

# 1. push: the same report as on sim:.
cfgmgr push $net/nodelist.cpj --bus sim: --json $out/sim.json >$out/push_sim.out 2>&1 ||
  fail "cfgmgr push on sim: exited with $?"
cfgmgr push $net/nodelist.cpj --bus socketcan:$can_if --json $out/vcan.json \
  >$out/push_vcan.out 2>&1 || fail "cfgmgr push on $can_if exited with $?"
per_node $out/sim.json >$out/sim.nodes
per_node $out/vcan.json >$out/vcan.nodes
[ "$(wc -l <$out/sim.nodes)" -eq 3 ] || fail "the sim: report has not 3 nodes"
grep -qv ' configured ' $out/sim.nodes && fail "not every node configured on sim:"
cmp -s $out/sim.nodes $out/vcan.nodes || fail "push on $can_if reported otherwise than on sim:"
say "push on $can_if: $(tr '\n' ';' <$out/vcan.nodes)"
grep 'bus:' $out/push_vcan.out

# 2. master frozen for 2 s while the slaves heartbeat.
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
  for f in push_sim.out push_vcan.out sim.nodes vcan.nodes master.err events.jsonl sim.err; do
    say "--- $f"
    cat $out/$f
  done
  exit 1
fi
say "master stalled 2 s on $can_if: $(wc -l <$out/events.jsonl) events, none a loss or command"
exit 0
