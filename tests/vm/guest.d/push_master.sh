# vm-tools: cfgmgr
# Guest hook (busybox sh, run by guest-init.sh with vcan0/vcan1 up): the NMT master of
# `cfgmgr push` and `cfgmgr master` over SocketCAN against `cfgmgr simulate` devices, on vcan0,
# which guest-init.sh paces with a token bucket (about 1000 frames/s, a 10-frame transmit queue,
# so bursts meet ENOBUFS as on a real controller: tests/vm/README.md). The master on a
# real CAN stack gives every node the same result as on the simulated bus (sim:).
#   1. The sample network (samples/network, three nodes): `cfgmgr push` configures every node
#      with the same entries and bytes as `cfgmgr push --bus sim:` in the same guest; a second
#      push skips every node (1020h matches 1F26h/1F27h, CiA 302-2 §3.5 a); `cfgmgr master
#      --run-for` boots every node without a download, starts them (CiA 302-2 §3.1 step l) and
#      reports no heartbeat loss, boot error or reset of a slave while the slaves heartbeat.
#   2. A larger network of 37 I/O modules (the sample's io_module_node4.dcf at node-IDs 4..40),
#      whose boot bursts overrun the 10-frame queue: every node configured, as on sim:.
# Exits non-zero on any failure, after printing what was seen.
set -u
can_if=vcan0
bus=socketcan:$can_if
samples=/opt/canopen/samples
net=$samples/network
out=/tmp/push_master
mkdir -p $out
failures=""
started=$(cut -d' ' -f1 /proc/uptime)

say() { echo "push_master: $*"; }
fail() {
  say "FAILED: $*"
  failures="$failures|$*"
}
elapsed() { awk -v s="$started" '{ printf "%.2f", $1 - s }' /proc/uptime; }
# One line per node of a `cfgmgr push --json` report: "NODE RESULT ENTRIES BYTES".
nodes_of() {
  sed 's/}, {/\n/g' "$1" | sed -n 's/.*"node_id": \([0-9]*\), .*"result": "\([a-z ]*\)", .*"entries": \([0-9]*\), "bytes": \([0-9]*\),.*/\1 \2 \3 \4/p'
}
# Runs `cfgmgr simulate` with the given devices in the background ($sim_pid) and waits until
# each of the node-IDs in $1 sent its boot-up (its "booted" line in the simulator's -v output
# would flood the console, so the hook watches candump instead).
start_devices() {
  ids=$1
  shift
  candump -L $can_if >$out/candump.log 2>&1 &
  candump_pid=$!
  sleep 0.5
  cfgmgr simulate --bus $bus "$@" --for 240 >$out/simulate.log 2>&1 &
  sim_pid=$!
  for id in $ids; do
    hex=$(printf '%03X' $((0x700 + id)))
    n=0
    while ! grep -q " $hex#00\$" $out/candump.log; do
      n=$((n + 1))
      if [ $n -gt 400 ] || ! kill -0 $sim_pid 2>/dev/null; then
        fail "no boot-up $hex#00 from the simulated node $id"
        return 1
      fi
      sleep 0.05
    done
  done
}
stop_devices() {
  if kill -0 $sim_pid 2>/dev/null; then
    kill -TERM $sim_pid
    wait $sim_pid || fail "cfgmgr simulate exited with $? after SIGTERM"
  else
    wait $sim_pid
    fail "cfgmgr simulate ended early with status $?"
    cat $out/simulate.log
  fi
  kill $candump_pid 2>/dev/null
  wait $candump_pid 2>/dev/null
}
# push NAME NETWORK BUS: `cfgmgr push` with --json $out/NAME.json; its exit status in $status.
push() {
  cfgmgr push "$2" --bus "$3" --json $out/$1.json >$out/$1.log 2>&1
  status=$?
  say "$1: cfgmgr push --bus $3 exited with $status after $(elapsed) s"
}

command -v cfgmgr >/dev/null || { say "FAILED: cfgmgr is not in the guest"; exit 1; }

# 1. The sample network.
push sample_sim $net/nodelist.cpj sim:
[ $status -eq 0 ] || fail "cfgmgr push --bus sim: of the sample network exited with $status"
if start_devices "2 3 4" $net/io_module_node2.dcf@2 $net/drive_node3.dcf@3 $net/io_module_node4.dcf@4; then
  push sample_can $net/nodelist.cpj $bus
  [ $status -eq 0 ] || fail "cfgmgr push over $can_if exited with $status"
  nodes_of $out/sample_sim.json >$out/sample_sim.nodes
  nodes_of $out/sample_can.json >$out/sample_can.nodes
  [ "$(grep -c ' configured ' $out/sample_sim.nodes)" -eq 3 ] ||
    fail "sim: did not configure the 3 sample nodes: $(cat $out/sample_sim.nodes)"
  cmp -s $out/sample_sim.nodes $out/sample_can.nodes ||
    fail "over $can_if the report differs from sim:'s: $(cat $out/sample_can.nodes) / $(cat $out/sample_sim.nodes)"

  push sample_again $net/nodelist.cpj $bus
  [ $status -eq 0 ] || fail "the second cfgmgr push over $can_if exited with $status"
  nodes_of $out/sample_again.json >$out/sample_again.nodes
  [ "$(grep -c ' skipped 0 0$' $out/sample_again.nodes)" -eq 3 ] ||
    fail "the second push did not skip every node: $(cat $out/sample_again.nodes)"
  say "sample network over $can_if (node result entries bytes): $(tr '\n' ';' <$out/sample_can.nodes)" \
    "then $(tr '\n' ';' <$out/sample_again.nodes)"

  cfgmgr master $net/nodelist.cpj --bus $bus --run-for 4 --json-events $out/events.jsonl \
    >$out/master.log 2>&1
  status=$?
  [ $status -eq 0 ] || fail "cfgmgr master --run-for 4 over $can_if exited with $status"
  for id in 2 3 4; do
    grep -q "\"event\": \"slave_booted\", \"node_id\": $id, \"configured\": false" $out/events.jsonl ||
      fail "cfgmgr master: no slave_booted without download for node $id"
    grep -q "\"command\": \"start\", \"text\": \"start node $id\"" $out/events.jsonl ||
      fail "cfgmgr master: node $id not started"
  done
  grep -q '"event": "startup_complete"' $out/events.jsonl || fail "cfgmgr master: no startup_complete"
  if grep -E '"event": "(heartbeat_lost|guarding_lost|boot_error)"|"command": "reset node"' \
    $out/events.jsonl; then
    fail "cfgmgr master reported a loss, a boot error or reset a slave of a running network"
  fi
  stop_devices
fi
[ -z "$failures" ] || {
  for f in sample_sim sample_can sample_again master; do
    [ -f $out/$f.log ] && { say "$f.log:"; cat $out/$f.log; }
  done
}

# 2. 37 I/O modules: io_module_node4.dcf at node-IDs 4..40 (its COB-IDs are $NODEID formulas).
big=/tmp/push_master_net
mkdir -p $big
{
  echo "[Topology]"
  echo "NetName=paced"
  echo "Nodes=0x25"
  id=4
  while [ $id -le 40 ]; do
    sed "s/^NodeID=.*/NodeID=$id/" $net/io_module_node4.dcf >$big/io$id.dcf
    echo "Node${id}Present=0x01"
    echo "Node${id}DCFName=io$id.dcf"
    id=$((id + 1))
  done
  echo "EDSBaseName=$samples"
} >$big/nodelist.cpj
devices=""
ids=""
id=4
while [ $id -le 40 ]; do
  devices="$devices $big/io$id.dcf@$id"
  ids="$ids $id"
  id=$((id + 1))
done
push big_sim $big/nodelist.cpj sim:
[ $status -eq 0 ] || fail "cfgmgr push --bus sim: of 37 nodes exited with $status"
# shellcheck disable=SC2086 # lists
if start_devices "$ids" $devices; then
  push big_can $big/nodelist.cpj $bus
  [ $status -eq 0 ] || fail "cfgmgr push of 37 nodes over $can_if exited with $status"
  nodes_of $out/big_sim.json >$out/big_sim.nodes
  nodes_of $out/big_can.json >$out/big_can.nodes
  [ "$(grep -c ' configured ' $out/big_sim.nodes)" -eq 37 ] ||
    fail "sim: did not configure the 37 nodes: $(cat $out/big_sim.nodes)"
  cmp -s $out/big_sim.nodes $out/big_can.nodes || {
    fail "37 nodes over $can_if: the report differs from sim:'s"
    diff $out/big_sim.nodes $out/big_can.nodes
    cat $out/big_can.log
  }
  grep 'bus:' $out/big_can.log
  say "37 nodes: $(grep -c ' configured ' $out/big_can.nodes) configured, $(wc -l <$out/candump.log) frames on $can_if"
  stop_devices
fi

if [ -n "$failures" ]; then
  say "FAILED:$failures"
  exit 1
fi
say "PASS after $(elapsed) s"
exit 0
