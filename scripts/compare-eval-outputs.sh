#!/usr/bin/env bash
# Runs two builds of `eval` on copies of one stored run and compares every
# file they write, byte for byte: the check that a refactor of rendering or
# evaluation leaves the outputs as they were.
#
#     bash scripts/compare-eval-outputs.sh OLD_EVAL NEW_EVAL RUN_DIR
#
# OLD_EVAL and NEW_EVAL are `eval` binaries (for example one copied out of
# `target/release` before the change); RUN_DIR is left untouched. Each
# build runs `segment`, `render` (held-out views and a 6-camera path),
# `query --query sofa` and `uncertainty` on the flex backend. Exit 1 when
# a file differs, other than `stages.json` (wall time and memory).
set -euo pipefail
[ $# -eq 3 ] || { sed -n 2,12p "$0"; exit 2; }
old="$1" new="$2" run="$3"
[ -f "$run/config.json" ] || { echo "$run: no config.json, not a run directory" >&2; exit 2; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
for side in old new; do
  bin="$old"
  [ "$side" = new ] && bin="$new"
  d="$work/$side"
  cp -r "$run" "$d"
  {
    "$bin" segment --run "$d" --backend flex
    "$bin" render --run "$d" --backend flex
    "$bin" render --run "$d" --backend flex --camera-path 6 --out "$d/renders/path"
    "$bin" query --run "$d" --backend flex --query sofa
    "$bin" uncertainty --run "$d" --backend flex
  } >"$work/$side.log" 2>&1 || { echo "$side eval failed:"; tail -20 "$work/$side.log"; exit 1; }
done
same=0
differ=0
while IFS= read -r f; do
  if [ "$f" = ./stages.json ]; then continue; fi
  if cmp -s "$work/old/$f" "$work/new/$f"; then
    same=$((same + 1))
  else
    echo "differs: $f"
    differ=$((differ + 1))
  fi
done < <(cd "$work/old" && find . -type f | sort)
extra="$(cd "$work/new" && find . -type f | sort | while IFS= read -r f; do [ -e "$work/old/$f" ] || echo "$f"; done)"
[ -z "$extra" ] || { echo "only in the new outputs:"; echo "$extra"; differ=$((differ + 1)); }
echo "identical: $same files; different: $differ"
[ "$differ" -eq 0 ]
