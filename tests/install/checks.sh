# The install tier's check helpers, sourced by its scripts: `check DESCRIPTION COMMAND...` runs
# the command and prints "ok: DESCRIPTION" or counts a failure ("FAIL: ..."); `fail TEXT` counts
# one; `failures` is the count, which each script turns into its exit status.
failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}
check() {  # check DESCRIPTION COMMAND...: the command must succeed
  local what=$1
  shift
  if "$@"; then echo "ok: $what"; else fail "$what"; fi
}
