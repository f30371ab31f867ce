#!/bin/sh
# Runs a GoogleTest program (its path and arguments given) and exits with its status, or 1
# when it ran no test at all: a --gtest_filter that matches nothing (an inner suite renamed)
# passes in GoogleTest 1.12, which would drop a tier silently. The count is read from the
# program's own JSON report (--gtest_output=json, top-level "tests": the selected tests).
report=$(mktemp "${TMPDIR:-/tmp}/gtest-report.XXXXXX") || exit 1
trap 'rm -f "$report"' EXIT
"$@" --gtest_output="json:$report"
status=$?
[ $status -eq 0 ] || exit $status
tests=$(sed -n 's/^  "tests": \([0-9][0-9]*\),$/\1/p' "$report" | head -n 1)
if [ -z "$tests" ]; then
  echo "require_tests_ran: no test count in $1's JSON report" >&2
  exit 1
fi
if [ "$tests" -eq 0 ]; then
  echo "require_tests_ran: no test ran: $*" >&2
  exit 1
fi
exit 0
