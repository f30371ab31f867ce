# Sourced by the scripts ctest runs (tests/support/prerequisite.hpp is the same for gtest):
# `prerequisite_missing NAME WHY` prints "NAME: WHY" on stderr and exits 77 (ctest's
# SKIP_RETURN_CODE: skipped) on a developer's machine, or exits 1 under CI=true, where
# tools/install-deps.sh has installed everything and a skip would hide a tier that never ran.
prerequisite_missing() {
  if [ "${CI:-}" = true ]; then
    echo "$1: CI=true: prerequisite missing: $2" >&2
    exit 1
  fi
  echo "$1: $2; skipping" >&2
  exit 77
}
