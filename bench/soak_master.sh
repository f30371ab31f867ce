#!/usr/bin/env bash
# Soak benchmark (long runs; a benchmark, not a test): `cfgmgr master` on the UDP
# bus with 20 `cfgmgr simulate` devices heartbeating every 100 ms and losing 1 % of their frames,
# for MINUTES (default 10) while two busy processes load the machine. It reports, from the
# master's --json-events: heartbeat losses (false ones: see the consumer time below), NMT
# commands after NMT start-up, and the master's RSS and open file descriptors once a minute.
#
#   bash bench/soak_master.sh [MINUTES] [BUILD_DIR]      # e.g. bash bench/soak_master.sh 10 build
#   SOAK_STALL_S=2 bash bench/soak_master.sh 10 build     # also freeze the master 2 s a minute
#
# SOAK_STALL_S=N freezes the master process for N seconds once a minute (SIGSTOP, SIGCONT: what
# a scheduler hiccup, a slow disk or a debugger does) while the devices go on heartbeating.
#
# Inside a private network namespace (tests/support/run_in_netns.sh: only lo, multicast stays on
# the machine). The devices are the sample's io_module_node4.dcf at node-IDs 2..21 with
# 1017h = 100 ms. The master DCF is `cfgmgr build`'s derived one with every 1016h consumer time
# set to 450 ms: a loss is then reported only after 4 heartbeats in a row were lost, which at 1 %
# independent loss happens with probability 1e-8 per heartbeat (20 x 10 x 600 = 120,000
# heartbeats in 10 minutes: 0.001 expected), so every reported loss is a false one. (The derived
# consumer time, 2 x 100 + 100 ms, reports two lost heartbeats in a row, a real loss under
# CiA 301 §7.2.8.3.2.2 that 1 % loss produces about 12 times in 10 minutes.)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
minutes=${1:-10}
build=$(cd "${2:-$root/build}" && pwd)
cfgmgr=$build/tools/cfgmgr
[ -x "$cfgmgr" ] || { echo "soak_master: no $cfgmgr (build the cfgmgr target)" >&2; exit 1; }

if [ "${CANOPEN_UDP_NETNS:-}" != 1 ]; then
  exec bash "$root/tests/support/run_in_netns.sh" bash "$0" "$minutes" "$build"
fi

work=$(mktemp -d /tmp/soak_master.XXXXXX)
trap 'kill $(jobs -p) 2>/dev/null; wait 2>/dev/null; rm -rf "$work"' EXIT
bus=udp://239.74.163.2:43113
seconds=$((minutes * 60))

# 20 devices: the sample's io_module_node4.dcf at node-IDs 2..21, heartbeat 100 ms.
{
  echo "[Topology]"
  echo "NetName=soak"
  echo "Nodes=0x14"
  for id in $(seq 2 21); do
    sed -e "s/^NodeID=.*/NodeID=$id/" \
      -e '/^\[1017\]/,/^\[/ s/^ParameterValue=.*/ParameterValue=100/' \
      "$root/samples/network/io_module_node4.dcf" >"$work/io$id.dcf"
    echo "Node${id}Present=0x01"
    echo "Node${id}DCFName=io$id.dcf"
  done
  echo "EDSBaseName=$root/samples"
} >"$work/nodelist.cpj"
"$cfgmgr" build "$work/nodelist.cpj" -o "$work/out" >/dev/null
# 1016h sub N = node << 16 | consumer time: 450 ms (0x01C2) for every node.
awk '/^\[/ {in1016 = /^\[1016sub/}
  in1016 && /^ParameterValue=0x00/ {sub(/=0x00....../, "=0x00" substr($0, 20, 2) "01C2")} {print}' \
  "$work/out/master.dcf" >"$work/master.dcf" && mv "$work/master.dcf" "$work/out/master.dcf"
grep -q 'ParameterValue=0x000201C2' "$work/out/master.dcf" ||
  { echo "soak_master: could not set 1016h in the master DCF" >&2; exit 1; }

devices=()
for id in $(seq 2 21); do devices+=("$work/io$id.dcf@$id"); done
"$cfgmgr" simulate --bus "$bus" --loss 0.01 --for $((seconds + 30)) "${devices[@]}" \
  >"$work/simulate.log" 2>&1 &
sleep 1
# Two busy processes, bounded by timeout(1).
for _ in 1 2; do timeout $((seconds + 20)) sh -c 'while :; do :; done' & done

start=$(date +%s.%N)
"$cfgmgr" master "$work/out/master.dcf" --bus "$bus" --node-id 1 --run-for "$((seconds + 5))" \
  --json-events "$work/events.jsonl" >"$work/master.log" 2>&1 &
master=$!

# NMT commands later than the start commands that end NMT start-up (CiA 302-2 §3.1 step l:
# they follow startup_complete in the same instant).
nmt_after_startup() {
  awk -F'"time_s": ' '/"event": "startup_complete"/ {split($2, t, ","); s = t[1] + 0.5; next}
    s && /"event": "nmt_command"/ {split($2, t, ","); if (t[1] + 0 > s) n++}
    END {print n + 0}' "$work/events.jsonl"
}

printf '%-8s %-10s %-6s %-8s %-9s\n' minute rss_kib fds losses nmt_after
samples=()
for m in $(seq 1 "$minutes"); do
  if [ "${SOAK_STALL_S:-0}" != 0 ]; then
    sleep 30 & wait $!
    kill -STOP $master 2>/dev/null || break
    sleep "$SOAK_STALL_S"
    kill -CONT $master
    sleep $((30 - SOAK_STALL_S)) & wait $!
  else
    sleep 60 & wait $!
  fi
  kill -0 $master 2>/dev/null || break
  rss=$(awk '/^VmRSS:/ {print $2}' /proc/$master/status)
  fds=$(find /proc/$master/fd -mindepth 1 -maxdepth 1 | wc -l)
  losses=$(grep -cE '"event": "(heartbeat_lost|guarding_lost)"' "$work/events.jsonl" || true)
  after=$(nmt_after_startup)
  printf '%-8s %-10s %-6s %-8s %-9s\n' "$m" "$rss" "$fds" "$losses" "$after"
  samples+=("$rss")
done
wait $master && status=0 || status=$?
elapsed=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN {printf "%.1f", e - s}')

booted=$(grep -c '"event": "slave_booted"' "$work/events.jsonl" || true)
losses=$(grep -cE '"event": "(heartbeat_lost|guarding_lost)"' "$work/events.jsonl" || true)
after=$(nmt_after_startup)
echo "cfgmgr master exit $status after $elapsed s; slaves booted: $booted; heartbeat losses: $losses;" \
  "NMT commands after start-up: $after; RSS minute 1 -> $minutes: ${samples[0]:-?} -> ${samples[${#samples[@]}-1]:-?} KiB"
grep -E '"event": "(heartbeat_lost|guarding_lost|boot_error)"' "$work/events.jsonl" | head -20 || true
tail -3 "$work/simulate.log"
