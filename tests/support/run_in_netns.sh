#!/bin/sh
# Runs a command in a private network namespace whose only interface is lo, with the IPv4
# multicast route (224.0.0.0/4) on lo: multicast sent by tests cannot leave the machine, and
# parallel runs cannot hear each other. Sets CANOPEN_UDP_NETNS=1 for the tests that check it.
# Exits 77 (ctest SKIP_RETURN_CODE) when a namespace cannot be created (unshare -n needs root),
# 1 under CI=true (tests/support/prerequisite.sh).
if ! unshare -n true 2>/dev/null; then
  . "$(dirname "$0")/prerequisite.sh"
  prerequisite_missing run_in_netns "cannot create a network namespace (unshare -n needs root)"
fi
exec unshare -n sh -c \
  'ip link set lo up && ip route add 224.0.0.0/4 dev lo && CANOPEN_UDP_NETNS=1 exec "$@"' \
  sh "$@"
