#!/usr/bin/env bash
# After a failed ctest run in BUILD_DIR: prints, last, why each failed test failed (its
# GoogleTest failures, TAP "not ok" entries or errors with a few lines after each, or the end
# of its output), so that the end of a long log says it without scrolling back through the
# inline outputs. Reads ctest's console log (ctest -O ctest-output.log, with
# --output-on-failure, as the Makefile runs it), else Testing/Temporary/LastTest.log.
# Usage: scripts/ctest-failures.sh BUILD_DIR
set -uo pipefail
dir=${1:?usage: ctest-failures.sh BUILD_DIR}
failed="$dir/Testing/Temporary/LastTestsFailed.log"
[[ -f $failed ]] || exit 0
console="$dir/ctest-output.log"
last="$dir/Testing/Temporary/LastTest.log"
echo "==== why the failed tests failed ===="
while IFS=: read -r _ name; do
  [[ -n $name ]] || continue
  output=""
  if [[ -f $console ]]; then
    # From the test's "Test #N: NAME ...***Failed" line to the next test's line.
    output=$(awk -v name="$name" '
      !inside && index($0, ": " name " ") && /\*\*\*|Failed|Timeout|Exception/ { inside = 1; next }
      inside && (/^ *Start +[0-9]+: / || /^ *[0-9]+\/[0-9]+ Test +#[0-9]+: /) { exit }
      inside { print }' "$console")
  fi
  if [[ -z $output && -f $last ]]; then
    # LastTest.log: from its "Test: NAME" line to the first "<end of output>" after it.
    output=$(awk -v name="$name" '
      $0 == ("Test: " name) || $0 ~ ("Test: " name "$") { inside = 1; next }
      inside && /^<end of output>/ { exit }
      inside { print }' "$last")
  fi
  echo "---- $name"
  reasons=$(grep -n -A8 -E '(: Failure$|^Failure$|not ok |ERROR: |WARNING: ThreadSanitizer|runtime error:|Timeout|Exception:)' \
    <<<"$output" | head -n 60)
  if [[ -n $reasons ]]; then
    printf '%s\n' "$reasons"
  else
    tail -n 25 <<<"$output"
  fi
done <"$failed"
