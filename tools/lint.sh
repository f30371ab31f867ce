#!/usr/bin/env bash
# The project's lint: clang-format (.clang-format) on every tracked C++ file, then clang-tidy
# (.clang-tidy) on the C++ files changed since BASE (default main), or on every file with --all.
# clang-tidy reads the compile database of a build (BUILD_DIR, default build/; configure it
# first); that database is GCC's, so GCC-only warning flags are silenced for clang.
#   bash tools/lint.sh               # format check + clang-tidy on files changed since main
#   bash tools/lint.sh --base HEAD~3 # ... changed since HEAD~3
#   bash tools/lint.sh --all         # ... on every file (slow: about 15 s a file on 2 cores)
#   bash tools/lint.sh --format-only # the clang-format check alone (what the test suite runs)
# Exit 0 when clean, 1 with the findings printed, 77 without clang-format or a git checkout (1
# under CI=true: tests/support/prerequisite.sh).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
build=${BUILD_DIR:-$root/build}
base=main
mode=changed
while [ $# -gt 0 ]; do
  case "$1" in
    --base) base=$2; shift 2 ;;
    --all) mode=all; shift ;;
    --format-only) mode=format; shift ;;
    -h|--help) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "lint.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done

# Exit 77 (CTest's skip) when there is nothing to check with: no clang-format, or no git checkout.
if ! command -v clang-format > /dev/null || ! git rev-parse --git-dir > /dev/null 2>&1; then
  . tests/support/prerequisite.sh
  prerequisite_missing lint.sh "needs clang-format (apt-get install clang-format) and a git checkout"
fi
status=0
mapfile -t sources < <(git ls-files '*.cpp' '*.hpp')
if ! clang-format --dry-run --Werror "${sources[@]}"; then
  echo "lint.sh: clang-format: the files above are not formatted (clang-format -i FILE)" >&2
  status=1
fi
[ "$mode" = format ] && exit $status

if [ ! -f "$build/compile_commands.json" ]; then
  echo "lint.sh: no $build/compile_commands.json: configure the build first (cmake -S . -B build)" >&2
  exit 2
fi
if [ "$mode" = all ]; then
  mapfile -t tidy < <(git ls-files '*.cpp')
else
  mapfile -t tidy < <(git diff --name-only --diff-filter=d "$base" -- '*.cpp'; git ls-files --others --exclude-standard '*.cpp')
fi
# Only files the build compiles (fuzz targets need the clang build's database).
checked=()
for f in "${tidy[@]}"; do
  if grep -q "\"file\": \"$root/$f\"" "$build/compile_commands.json" ||
     grep -q "\"file\": \"$f\"" "$build/compile_commands.json"; then
    checked+=("$f")
  fi
done
if [ ${#checked[@]} -gt 0 ]; then
  out=$(clang-tidy -p "$build" --quiet --extra-arg=-Wno-unknown-warning-option "${checked[@]}" 2>/dev/null || true)
  if printf '%s\n' "$out" | grep -q "warning:\|error:"; then
    printf '%s\n' "$out"
    status=1
  fi
fi
echo "lint.sh: ${#sources[@]} files format-checked, ${#checked[@]} clang-tidy-checked: $([ $status = 0 ] && echo clean || echo findings)"
exit $status
