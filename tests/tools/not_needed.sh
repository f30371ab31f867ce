#!/bin/sh
# Usage: not_needed.sh SONAME FILE...: each FILE is an ELF object whose dynamic section lists the
# libraries it needs (readelf -d: NEEDED), and SONAME is not among them.
set -u
soname=$1
shift
status=0
for file in "$@"; do
  needed=$(readelf -d "$file" | grep '(NEEDED)') || { echo "FAIL: no NEEDED entries in $file" >&2; exit 1; }
  if printf '%s\n' "$needed" | grep -qF "[$soname]"; then
    echo "FAIL: $file needs $soname:" >&2
    printf '%s\n' "$needed" >&2
    status=1
  else
    echo "ok: $file does not need $soname"
  fi
done
exit $status
