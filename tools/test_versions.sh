#!/usr/bin/env bash
# Runs the tests against several Blender versions, one after another, each in its own environment
# (`make test BLENDER=X.Y` creates it from the pinned requirements when needed), then prints one
# summary line per version, so a failure always names its Blender. Exits non-zero if any failed.
# Usage: tools/test_versions.sh "5.0 5.3:all 4.2:tests/blender"  (VERSION[:all|PYTEST PATHS])
set -uo pipefail
cd "$(dirname "$0")/.."

status=0
summary=()
total_start=$SECONDS
for spec in $1; do
  version=${spec%%:*}
  what=${spec#*:}
  [ "$what" = "$spec" ] && what=all
  args=$what
  [ "$what" = all ] && args=
  start=$SECONDS
  if make --no-print-directory test BLENDER="$version" PYTEST_ARGS="$args"; then
    result=passed
  else
    result=FAILED
    status=1
  fi
  summary+=("Blender $version ($what): $result in $((SECONDS - start)) s")
done

echo
echo "== Summary: tests per Blender version =="
printf '%s\n' "${summary[@]}"
echo "total: $((SECONDS - total_start)) s"
exit $status
