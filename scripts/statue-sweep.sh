#!/usr/bin/env bash
# What moves the statue's held-out PSNR (docs/measurements/unbounded.md, "What holds the
# statue back") and fern's (docs/measurements/fern.md): runs of `train` side by side, each pinned to two cores
# (RAYON_NUM_THREADS=2, taskset), so that a machine of 16 cores runs eight
# at once and every run of a set gets the same seconds on the same CPU.
#
#   bash scripts/statue-sweep.sh SET OUT [SECONDS]
#
# appearance: the statue (box and unbounded field) and fern, with and
#   without --appearance exposure (450 s in the docs);
# knobs: the statue's box field with one setting changed per run (280 s);
# box: the statue's box field with the box grown by --box-margin 0.05 (the
#   default), 0.5 and 1.5, and with the distortion loss on the box field
#   (losses.box_distortion_weight 0.01, 0.1, 1) (300 s);
# fern: LLFF fern's box field with one setting changed per run (300 s);
# fern-samples: fern with fewer samples a ray, fewer rays a batch, or the
#   proposal sampler (300 s);
# fern-default: fern at the LLFF sampling default (16 samples, 128 rays)
#   with one setting changed per run (300 s);
# unbounded-near: the statue's box field beside the unbounded field whose
#   rays start at the scene box's distance (model.unbounded.near 1, in
#   multiples of the kept ball's radius) rather than next to the camera;
# unseen: the statue's box field with the unseen patches' depth smoothness
#   (--unseen-depth 0, 0.01, 0.1, 1, 10, 100; 0 and 1 also at seed 1);
# ranges: the statue's box field with IPE degrees 0..4 and 0..6, and the
#   unbounded field with other kept balls and ray ranges (radius 1.5 with
#   rays from 3 radii; rays from 1 radius to 4 or to 10 radii).
# ray-start: the statue's unbounded field with rays from the scene box
#   (the default) and from next to the camera (start_at_box false);
# unbounded-knobs: the unbounded field with one setting changed per run
#   (--unseen-depth 1, --appearance exposure, --lr 2e-3, distortion 0.1);
# photographs: the box and the unbounded field, each plain, with
#   --pose-refine on and with --appearance embedding; then fern the same.
# sparse-depth: the statue's default field (unbounded, appearance codes)
#   without and with --sparse-depth, then one setting changed per run
#   (the codes' penalty at 1e-3, the default, unless the run changes it).
# hash-grid: the statue's default field without and with the hash encoding
#   (--hash-grid off / on), and with 2^17 rows a level.
# CORES_PER_RUN (default 2) sets the cores and threads of each run: 1 runs
# two at a time on a 2-core machine. ITERS=N trains N iterations a run
# instead of SECONDS.
# Without feature maps: the colour and density do not depend on them.
# OUT/RUN/ is each run directory, OUT/RUN.log what it printed.
set -euo pipefail
usage="usage: bash scripts/statue-sweep.sh appearance|knobs|box|fern|fern-samples|fern-default|unbounded-near|unseen|ranges|ray-start|unbounded-knobs|photographs|sparse-depth|hash-grid OUT [SECONDS]"
set_name=${1:?$usage}
out=${2:?$usage}
data=${OPENNERF_DATA:-../shared/data}
statue=$data/colmap_statue
fern=$data/llff_fern
mkdir -p "$out"
case "$set_name" in
  appearance)
    budget=${3:-450}
    runs=(
      "statue-box-none-s0|--data $statue --field box --appearance none --seed 0"
      "statue-box-exposure-s0|--data $statue --field box --appearance exposure --seed 0"
      "statue-box-none-s1|--data $statue --field box --appearance none --seed 1"
      "statue-box-exposure-s1|--data $statue --field box --appearance exposure --seed 1"
      "statue-unbounded-none-s0|--data $statue --field unbounded --appearance none --seed 0"
      "statue-unbounded-exposure-s0|--data $statue --field unbounded --appearance exposure --seed 0"
      "fern-box-none-s0|--data $fern --field box --appearance none --seed 0"
      "fern-box-exposure-s0|--data $fern --field box --appearance exposure --seed 0"
    )
    ;;
  knobs)
    budget=${3:-280}
    for deg in 8 10; do
      echo "{\"model\": {\"mlp\": {\"max_deg\": $deg}}}" > "$out/deg$deg.json"
    done
    echo '{"model": {"mlp": {"viewdir_deg": 1}}}' > "$out/view1.json"
    runs=(
      "base|--data $statue --field box"
      "deg8|--data $statue --field box --config $out/deg8.json"
      "deg10|--data $statue --field box --config $out/deg10.json"
      "view1|--data $statue --field box --config $out/view1.json"
      "rays1024|--data $statue --field box --rays 1024"
      "lr2e-3|--data $statue --field box --lr 2e-3"
      "w256d8|--data $statue --field box --width 256 --depth 8"
      "unbounded-deg8|--data $statue --field unbounded --config $out/deg8.json"
    )
    ;;
  box)
    budget=${3:-300}
    runs=()
    for margin in 0.05 0.5 1.5; do
      runs+=("margin$margin|--data $statue --field box --box-margin $margin")
    done
    for w in 0.01 0.1 1; do
      echo "{\"losses\": {\"box_distortion_weight\": $w}}" > "$out/distortion$w.json"
      runs+=("distortion$w|--data $statue --field box --config $out/distortion$w.json")
    done
    ;;
  fern)
    budget=${3:-300}
    echo '{"model": {"mlp": {"max_deg": 10}}}' > "$out/deg10.json"
    echo '{"losses": {"box_distortion_weight": 0.01}}' > "$out/distortion.json"
    runs=(
      "base|--data $fern"
      "grid|--data $fern --occupancy-grid"
      "lr1e-2|--data $fern --lr 1e-2"
      "samples32|--data $fern --samples 32"
      "rays512|--data $fern --rays 512"
      "width128|--data $fern --width 128"
      "deg10|--data $fern --config $out/deg10.json"
      "distortion|--data $fern --config $out/distortion.json"
    )
    ;;
  fern-samples)
    budget=${3:-300}
    runs=(
      "samples16|--data $fern --samples 16"
      "samples24|--data $fern --samples 24"
      "rays128|--data $fern --rays 128"
      "samples24-rays128|--data $fern --samples 24 --rays 128"
      "samples16-rays128|--data $fern --samples 16 --rays 128"
      "proposal-samples32|--data $fern --sampler proposal --samples 32"
      "samples24-width128|--data $fern --samples 24 --width 128"
      "samples32-rays128|--data $fern --samples 32 --rays 128"
    )
    ;;
  fern-default)
    budget=${3:-300}
    echo '{"model": {"mlp": {"max_deg": 10}}}' > "$out/deg10.json"
    runs=(
      "default|--data $fern"
      "lr1e-2|--data $fern --lr 1e-2"
      "lr2e-3|--data $fern --lr 2e-3"
      "samples12|--data $fern --samples 12"
      "rays64|--data $fern --rays 64"
      "width128|--data $fern --width 128"
      "depth3|--data $fern --depth 3"
      "deg10|--data $fern --config $out/deg10.json"
    )
    ;;
  unbounded-near)
    budget=${3:-300}
    echo '{"model": {"unbounded": {"near": 1.0}}}' > "$out/near1.json"
    runs=(
      "box|--data $statue --field box"
      "unbounded-near1|--data $statue --field unbounded --config $out/near1.json"
    )
    ;;
  unseen)
    budget=${3:-600}
    runs=()
    for w in 0 0.01 0.1 1 10 100; do
      runs+=("unseen$w|--data $statue --field box --unseen-depth $w")
    done
    runs+=("unseen0-s1|--data $statue --field box --seed 1")
    runs+=("unseen1-s1|--data $statue --field box --unseen-depth 1 --seed 1")
    ;;
  ranges)
    budget=${3:-300}
    for deg in 4 6; do
      echo "{\"model\": {\"mlp\": {\"max_deg\": $deg}}}" > "$out/deg$deg.json"
    done
    echo '{"model": {"unbounded": {"radius": 1.5, "near": 3.0}}}' > "$out/radius1.5-near3.json"
    echo '{"model": {"unbounded": {"near": 1.0, "far": 4.0}}}' > "$out/near1-far4.json"
    echo '{"model": {"unbounded": {"near": 1.0, "far": 10.0}}}' > "$out/near1-far10.json"
    runs=(
      "box-deg4|--data $statue --field box --config $out/deg4.json"
      "box-deg6|--data $statue --field box --config $out/deg6.json"
      "unbounded-radius1.5-near3|--data $statue --field unbounded --config $out/radius1.5-near3.json"
      "unbounded-near1-far4|--data $statue --field unbounded --config $out/near1-far4.json"
      "unbounded-near1-far10|--data $statue --field unbounded --config $out/near1-far10.json"
    )
    ;;
  ray-start)
    budget=${3:-300}
    echo '{"model": {"unbounded": {"start_at_box": false}}}' > "$out/start-near.json"
    runs=(
      "unbounded-start-at-box|--data $statue --field unbounded"
      "unbounded-start-near|--data $statue --field unbounded --config $out/start-near.json"
    )
    ;;
  unbounded-knobs)
    budget=${3:-300}
    echo '{"losses": {"distortion_weight": 0.1}}' > "$out/distortion0.1.json"
    runs=(
      "unseen1|--data $statue --field unbounded --unseen-depth 1"
      "exposure|--data $statue --field unbounded --appearance exposure"
      "lr2e-3|--data $statue --field unbounded --lr 2e-3"
      "distortion0.1|--data $statue --field unbounded --config $out/distortion0.1.json"
    )
    ;;
  photographs)
    budget=${3:-300}
    runs=()
    for field in box unbounded; do
      runs+=("statue-$field-plain|--data $statue --field $field")
      runs+=("statue-$field-pose|--data $statue --field $field --pose-refine on")
      runs+=("statue-$field-embedding|--data $statue --field $field --appearance embedding")
    done
    runs+=("fern-plain|--data $fern")
    runs+=("fern-pose|--data $fern --pose-refine on")
    runs+=("fern-embedding|--data $fern --appearance embedding")
    runs+=("fern-unbounded|--data $fern --field unbounded")
    ;;
  sparse-depth)
    budget=${3:-300}
    # Each run's --config: the codes' penalty (1e-3, the default) and the
    # setting the run changes.
    cfg() { echo "{\"losses\": {\"appearance_penalty\": 0.001$2}$3}" > "$out/$1.json"; }
    cfg codes1e-3 "" ""
    cfg rays32 "" ', "sampler": {"depth_rays": 32}'
    cfg rays128 "" ', "sampler": {"depth_rays": 128}'
    cfg huber0.05 ', "huber_delta": 0.05' ""
    cfg distortion0 ', "distortion_weight": 0' ""
    cfg window0.1 ', "depth_window_weight": 0.1' ""
    cfg window1 ', "depth_window_weight": 1' ""
    cfg deg10 "" ', "model": {"mlp": {"max_deg": 10}}'
    echo '{"losses": {"appearance_penalty": 0.03}}' > "$out/codes3e-2.json"
    echo '{"losses": {"appearance_penalty": 0.1}}' > "$out/codes1e-1.json"
    base="--data $statue --config $out/codes1e-3.json"
    runs=(
      "off-s0|$base --sparse-depth off"
      "on-s0|$base"
      "on-s1|$base --seed 1"
      "lambda0.03|$base --lambda-depth 0.03"
      "lambda0.3|$base --lambda-depth 0.3"
      "lambda1|$base --lambda-depth 1"
      "lr2e-3|$base --lr 2e-3"
      "lr8e-3|$base --lr 8e-3"
      "unseen1|$base --unseen-depth 1"
      "width128|$base --width 128"
      "proposal|$base --sampler proposal"
    )
    for c in rays32 rays128 huber0.05 distortion0 deg10 window0.1 window1; do
      runs+=("$c|--data $statue --config $out/$c.json")
    done
    runs+=("huber0.05-s1|--data $statue --config $out/huber0.05.json --seed 1")
    echo '{"losses": {"appearance_penalty": 0.01}}' > "$out/codes1e-2.json"
    runs+=("codes1e-2-s0|--data $statue --config $out/codes1e-2.json")
    runs+=("codes1e-2-s1|--data $statue --config $out/codes1e-2.json --seed 1")
    runs+=("codes3e-2|--data $statue --config $out/codes3e-2.json")
    runs+=("codes1e-1|--data $statue --config $out/codes1e-1.json")
    ;;
  hash-grid)
    budget=${3:-600}
    echo '{"model": {"hash": {"log2_table": 17}}}' > "$out/rows17.json"
    runs=(
      "off|--data $statue --hash-grid off"
      "on|--data $statue --hash-grid on"
      "rows17|--data $statue --config $out/rows17.json"
    )
    ;;
  *)
    echo "unknown set $set_name: appearance, knobs, box, fern, fern-samples, fern-default, unbounded-near, unseen, ranges, ray-start, unbounded-knobs, photographs, sparse-depth or hash-grid" >&2
    exit 2
    ;;
esac
if [ -n "${ITERS:-}" ]; then
  length="--iters $ITERS"
else
  length="--time-budget $budget"
fi
. "$(dirname "$0")/frozen-bins.sh"
freeze_bins "$out"
# CORES_PER_RUN cores a run (two by default): as many runs at once as the
# machine has such groups of cores, in batches.
per=${CORES_PER_RUN:-2}
slots=$(($(nproc) / per))
[ "$slots" -ge 1 ] || slots=1
i=0
for r in "${runs[@]}"; do
  name=${r%%|*}
  slot=$((i % slots))
  if [ "$i" -gt 0 ] && [ "$slot" -eq 0 ]; then
    wait
  fi
  # shellcheck disable=SC2086 # the flags are words
  RAYON_NUM_THREADS=$per taskset -c "$((per * slot))-$((per * slot + per - 1))" "$bin/train" ${r#*|} \
    $length --no-final-render --out "$out/$name" > "$out/$name.log" 2>&1 &
  i=$((i + 1))
done
wait
for r in "${runs[@]}"; do
  name=${r%%|*}
  echo "$name: $(grep -E '^done' "$out/$name.log")"
done
