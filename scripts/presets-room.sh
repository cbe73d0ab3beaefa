#!/usr/bin/env bash
# The speed/accuracy presets on the benchmark room, each against the room's
# strongest knob (128 rays a batch) at the same number of training seconds.
#
#   scripts/presets-room.sh [--seed S] [--out DIR] [--presets "fast ..."]
#
# Per preset P, three runs of the bench room (seed S, default 21):
#   P              P with the lego (object) settings: --preset P --rays 256
#                  --iters N, N the object iterations of P
#   P-rays-128     the default settings with --rays 128, given as many
#                  seconds of training as P took (--time-budget)
#   P+rays-128     --preset P: on a room, P's samples and grid with 128
#                  rays a batch and the iterations that fill those seconds
# Each run is segmented as the sweep segments its points (eval segment
# --max-views 20 --render-scale 0.5, hybrid mode) and the table
# (<out>/presets.md, presets.csv) gives seconds, iterations, the held-out
# PSNR and depth error of the final evaluation's pixel sample, and mIoU.
# Seconds are compared, so nothing else should run on the machine. Runs
# already finished are kept: a killed run continues where it stopped.
set -euo pipefail
cd "$(dirname "$0")/.."

seed=21
out=runs/presets-room
presets="fast balanced best"
while [ $# -gt 0 ]; do
  case "$1" in
    --seed) seed="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --presets) presets="$2"; shift 2 ;;
    -h|--help) sed -n '2,19p' "$0"; exit 0 ;;
    *) echo "error: unknown argument $1" >&2; exit 2 ;;
  esac
done
for p in $presets; do
  case "$p" in
    fast|balanced|best) ;;
    *) echo "error: unknown preset $p (fast, balanced, best)" >&2; exit 2 ;;
  esac
done

# The programs are built once and copied into <out>/bin.
source scripts/frozen-bins.sh
freeze_bins "$out"

# Seconds of training: the clock of the last training line of the log.
train_seconds() {
  jq -s '[.[] | select(.event == "train")] | last | .wall_seconds' "$1/metrics.jsonl"
}

one() { # name, flags...
  local run="$out/$1"
  shift
  if [ ! -f "$run/summary.json" ]; then
    rm -rf "$run"
    echo "== $(basename "$run"): train $*"
    "$bin/train" --scene-size bench --scene-seed "$seed" --no-final-render --quiet \
      --out "$run" "$@"
  fi
  if [ ! -f "$run/segmentation.json" ]; then
    "$bin/eval" segment --run "$run" --max-views 20 --render-scale 0.5 > /dev/null
  fi
}

for p in $presets; do
  case "$p" in
    fast) n=1600 ;;
    balanced) n=2300 ;;
    best) n=5000 ;;
  esac
  one "$p" --preset "$p" --rays 256 --iters "$n"
  t=$(train_seconds "$out/$p")
  one "$p-rays-128" --rays 128 --time-budget "$t"
  one "$p+rays-128" --preset "$p"
done
python3 scripts/presets-room-table.py "$out" $presets | tee "$out/presets.md"
