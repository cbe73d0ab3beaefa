#!/usr/bin/env bash
# Two builds of `train` side by side on the same flags, each pinned to one
# core with one thread, so that a change is measured against the build
# before it on the same machine at the same seconds (docs/measurements/unbounded.md,
# "Lego and the bench room against the build before").
#
#   bash scripts/pair-builds.sh BEFORE_BIN AFTER_BIN OUT NAME TRAIN_FLAGS...
#
# BEFORE_BIN and AFTER_BIN are directories holding a `train` binary (e.g. a
# worktree's release directory); the runs go to OUT/NAME-before and
# OUT/NAME-after, what they print to OUT/NAME-before.log and
# OUT/NAME-after.log.
set -euo pipefail
usage="usage: bash scripts/pair-builds.sh BEFORE_BIN AFTER_BIN OUT NAME TRAIN_FLAGS..."
before=${1:?$usage}
after=${2:?$usage}
out=${3:?$usage}
name=${4:?$usage}
shift 4
for dir in "$before" "$after"; do
  if [ ! -x "$dir/train" ]; then
    echo "no train binary in $dir" >&2
    exit 2
  fi
done
mkdir -p "$out"
RAYON_NUM_THREADS=1 taskset -c 0 "$before/train" "$@" --out "$out/$name-before" \
  > "$out/$name-before.log" 2>&1 &
first=$!
RAYON_NUM_THREADS=1 taskset -c 1 "$after/train" "$@" --out "$out/$name-after" \
  > "$out/$name-after.log" 2>&1 &
second=$!
status=0
wait "$first" || status=$?
wait "$second" || status=$?
for side in before after; do
  echo "$name-$side: $(grep -E '^done' "$out/$name-$side.log" || echo 'no result')"
done
exit "$status"
