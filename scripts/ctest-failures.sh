#!/usr/bin/env bash
# After a failed ctest run in BUILD_DIR: prints, last, why each failed test failed (its
# GoogleTest failures with a few lines after each, or the end of its output), so that the
# end of a long log says it without scrolling back through the inline outputs.
# Usage: scripts/ctest-failures.sh BUILD_DIR
set -uo pipefail
dir=${1:?usage: ctest-failures.sh BUILD_DIR}
failed="$dir/Testing/Temporary/LastTestsFailed.log"
log="$dir/Testing/Temporary/LastTest.log"
[[ -f $failed && -f $log ]] || exit 0
echo "==== why the failed tests failed (from $log) ===="
while IFS=: read -r _ name; do
  [[ -n $name ]] || continue
  # The test's output: from its "Test: NAME" line to the first "<end of output>" after it.
  output=$(awk -v name="$name" '
    index($0, "Test: " name) && $0 ~ ("Test: " name "$") { inside = 1; next }
    inside && /^<end of output>/ { exit }
    inside { print }' "$log")
  echo "---- $name"
  reasons=$(grep -n -A8 -E '(: Failure$|^Failure$|ERROR: |WARNING: ThreadSanitizer|runtime error:|Timeout|Exception:)' <<<"$output" | head -n 60)
  if [[ -n $reasons ]]; then
    printf '%s\n' "$reasons"
  else
    tail -n 25 <<<"$output"
  fi
done <"$failed"
