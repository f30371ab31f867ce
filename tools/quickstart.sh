#!/usr/bin/env bash
# The README quick start: install what is missing, build, and run the main job on the bundled
# sample network: convert a node's DCF to a concise DCF and print it decoded, then commission
# the whole network with the NMT master on the simulated bus.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$root/build}

bash "$root/tools/install-deps.sh"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build" -j"$(nproc)" --target dcf2concise cfgmgr

dcf="$root/samples/network/io_module_node2.dcf"
out="$build/io_module_node2.bin"
echo
echo "== dcf2concise $dcf -o $out"
"$build/tools/dcf2concise" "$dcf" -o "$out"
echo
echo "== dcf2concise --decode $out --dcf $dcf"
"$build/tools/dcf2concise" --decode "$out" --dcf "$dcf"

# The main job: commission the sample network (CiA 306-3 project file, three DCFs) with the
# CiA 302-2 NMT master against simulated devices built from those DCFs, in simulated time.
network="$root/samples/network/nodelist.cpj"
echo
echo "== cfgmgr push $network --bus sim:"
"$build/tools/cfgmgr" push "$network" --bus sim:
