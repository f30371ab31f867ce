#!/usr/bin/env bash
# The README quick start: install what is missing, build, and run the main job on the bundled
# sample network (convert a node's DCF to a concise DCF and print it decoded).
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
