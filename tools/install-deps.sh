#!/usr/bin/env bash
# Installs, from Debian packages only, what building and testing this project needs on a fresh
# Debian 12 machine. Run as root. Installs nothing that is already there.
set -euo pipefail

packages=(
  # build; man pages from --help; clang-format for the lint.clang_format test (tools/lint.sh)
  g++ cmake make pkg-config help2man clang-format
  # libraries the product uses
  zlib1g-dev libyaml-cpp-dev libcli11-dev libmsgpack-dev libpcap-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # bench_ini_vs_inih: our INI scanner against inih, which the product's first plan named
  libinih-dev
  # install tier: Debian packages with CPack (dpkg-shlibdeps, file), man pages rendered
  dpkg-dev file man-db
  # fuzzing (libFuzzer ships with clang's runtime) and the sanitizer build
  clang libclang-rt-14-dev
  # bus tests: python-can as an independent peer, can-utils, network namespaces
  python3 python3-can python3-msgpack can-utils iproute2 util-linux
  # an independent decoder of our pcap traces (CANopen dissector)
  tshark
  # a real browser for push --report's page: /usr/bin/chromium-headless-shell (--dump-dom,
  # --screenshot; tests/tools/push_report_test.cpp)
  chromium-headless-shell
  # VM tier: a real Linux CAN stack under qemu
  qemu-system-x86 busybox-static cpio kmod xz-utils
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: everything is installed"
  exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "install-deps: missing packages: ${missing[*]}" >&2
  echo "install-deps: run as root (or: sudo apt-get install ${missing[*]})" >&2
  exit 1
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"
