#!/usr/bin/env bash
# Novel-view ablation on benchmark-sized synthetic scenes: none, trajectory,
# random and guided views, the same iteration budget for all four (the views
# are counted in it), then 3D segmentation of each run.
#
#   scripts/novel-ablation.sh [--iters T] [--after A] [--views N] [--out DIR]
#                             [--modes "M..."] [--oracle renders|labels]
#                             [--set JQ --tag NAME] SEED...
#
# Per seed, one run trains to iteration A and stops; each mode continues a
# copy of it from that checkpoint with its own novel-view settings to T.
# Training is deterministic given the seed, so the four runs are exactly
# what four separate runs with `--novel-after A` would be, at less than half
# the cost. Steps already done (summary.json / segmentation_compare.json
# present) are skipped, so a killed ablation resumes where it stopped.
# Segmentation projects into the same captured cameras for every mode, so
# that only the field differs. The table is written by
# scripts/novel-ablation-table.py, the plot (<out>/ablation.png, with
# ablation.csv) by the example novel_ablation_plot of the bench crate. The programs are copied into
# <out>/bin on the first call and reused by later calls. --modes picks the
# modes (default: all four); --oracle takes the views from the synthetic
# scene's ground truth (train --novel-oracle) and names the runs
# <mode>-oracle-<which>, beside the plain ones. --set applies a jq update to
# the runs' config.json (e.g. '.novel.offset = 1.5') and --tag NAME, which
# it needs, is appended to their names.
set -euo pipefail
cd "$(dirname "$0")/.."

iters=2400
after=1200
views=24
out=runs/novel-ablation
modes="none trajectory random guided"
oracle=""
set_expr="."
tag=""
seeds=()
while [ $# -gt 0 ]; do
  case "$1" in
    --iters) iters="$2"; shift 2 ;;
    --after) after="$2"; shift 2 ;;
    --views) views="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --modes) modes="$2"; shift 2 ;;
    --oracle) oracle="$2"; shift 2 ;;
    --set) set_expr="$2"; shift 2 ;;
    --tag) tag="$2"; shift 2 ;;
    -h|--help) sed -n '2,26p' "$0"; exit 0 ;;
    -*) echo "error: unknown option $1" >&2; exit 2 ;;
    *) seeds+=("$1"); shift ;;
  esac
done
[ ${#seeds[@]} -gt 0 ] || seeds=(21 22 23)
if ! [ "$after" -ge 1 ] 2>/dev/null || ! [ "$iters" -gt "$after" ] 2>/dev/null; then
  echo "error: need 1 <= --after ($after) < --iters ($iters)" >&2
  exit 2
fi
for mode in $modes; do
  case "$mode" in
    none|trajectory|random|guided) ;;
    *) echo "error: unknown mode $mode (none, trajectory, random, guided)" >&2; exit 2 ;;
  esac
done
if [ "$set_expr" != "." ] && [ -z "$tag" ]; then
  echo "error: --set needs --tag NAME (the runs it changes are named after it)" >&2
  exit 2
fi
case "$tag" in
  */*|.*) echo "error: --tag $tag: a name without / and not starting with ." >&2; exit 2 ;;
esac
case "$oracle" in
  ""|renders|labels) ;;
  *) echo "error: --oracle must be renders or labels, got $oracle" >&2; exit 2 ;;
esac

# The programs are built once and copied into <out>/bin.
source scripts/frozen-bins.sh
freeze_bins "$out"

for seed in "${seeds[@]}"; do
  dir="$out/seed-$seed"
  base="$dir/base"
  if [ ! -f "$base/summary.json" ]; then
    rm -rf "$base"
    echo "== seed $seed: training to iteration $after"
    "$bin/train" --scene-size bench --scene-seed "$seed" --iters "$iters" \
      --stop-at "$after" --no-final-render --quiet --out "$base"
  fi
  for mode in $modes; do
    run="$dir/$mode"
    if [ -n "$oracle" ]; then
      # `none` adds no views: there is nothing for an oracle to replace.
      [ "$mode" != none ] || continue
      run="$dir/$mode-oracle-$oracle"
    fi
    if [ -n "$tag" ]; then
      [ "$mode" != none ] || continue
      run="$run-$tag"
    fi
    if [ ! -f "$run/done" ]; then
      echo "== seed $seed, $mode: iterations $after -> $iters"
      rm -rf "$run"
      cp -r "$base" "$run"
      if [ "$mode" != none ]; then
        jq --arg m "$mode" --argjson n "$views" --argjson a "$after" --arg o "$oracle" \
          '.novel.mode = $m | .novel.views = $n | .novel.after = $a
           | .novel.oracle = (if $o == "" then null else $o end) | '"$set_expr" \
          "$run/config.json" > "$run/config.json.new"
        mv "$run/config.json.new" "$run/config.json"
      fi
      "$bin/train" --resume "$run" --no-final-render --quiet
      touch "$run/done"
    fi
    if [ ! -f "$run/seg/segmentation_compare.json" ]; then
      echo "== seed $seed, $mode: segmentation"
      "$bin/eval" segment --run "$run" --compare --cameras captured \
        --max-views 20 --render-scale 0.5 --out "$run/seg"
    fi
  done
done
python3 scripts/novel-ablation-table.py "$out" | tee "$out/ablation.md"
cargo run -q --release -p bench --example novel_ablation_plot -- "$out"
