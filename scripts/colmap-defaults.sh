#!/usr/bin/env bash
# The defaults of real photographed captures, each flipped on its own,
# measured on three captures: the statue and the cup (COLMAP, photographed
# objects) and fern (LLFF, forward-facing). For each capture, a run with
# the defaults and one per setting turned the other way: 256 rays a batch,
# the hash encoding, appearance codes, sparse depth (COLMAP only) and the
# field (box or unbounded). Each run trains SECONDS (default 600) and is
# scored by held-out PSNR over every pixel (`summary.json`).
#
#   bash scripts/colmap-defaults.sh OUT [SECONDS] [CAPTURES]
#
# CAPTURES (default "statue cup fern") chooses among the three, and
# SETTINGS="rays hash ..." in the environment among the settings (default
# all: rays, hash, appearance, sparse_depth, field). Rows are appended to
# the CSV, so a table can be made over several invocations.
# OUT/colmap_defaults.csv holds a row per run: capture, setting, value,
# held-out PSNR, iterations, and the same of the run with the defaults it
# is compared with. Runs one after another (each is timed): nothing else
# should load the machine.
#
# With PAIRED=1 each flipped run is trained at the same time as a run of
# the defaults, each on a core of its own (taskset, one thread each): a
# change in the machine's speed falls on both runs of a pair alike, and
# the defaults' runs show how much a run differs from itself. Needs two
# idle cores. QUICK=1 trains 20 iterations a run instead, without the
# final render (a rehearsal: its PSNR is the interior pixel sample's).
set -euo pipefail
out=${1:?usage: bash scripts/colmap-defaults.sh OUT [SECONDS] [CAPTURES]}
budget=${2:-600}
captures=${3:-statue cup fern}
data=${OPENNERF_DATA:-../shared/data}
if [ -n "${QUICK:-}" ]; then
  length=(--iters 20 --no-final-render)
else
  length=(--time-budget "$budget")
fi
. "$(dirname "$0")/frozen-bins.sh"
freeze_bins "$out"
mkdir -p "$out/runs"
csv=$out/colmap_defaults.csv
[ -f "$csv" ] || echo "capture,setting,value,psnr,iterations,defaults_psnr,defaults_iterations,difference_db" >"$csv"

# The capture directory and the flags that flip each setting from its
# default there (a photographed object: unbounded, codes, hash grid,
# sparse depth, 64 rays; a forward-facing capture: box, no codes, no hash
# grid, 128 rays).
capture_dir() {
  case $1 in
    statue) echo "$data/colmap_statue" ;;
    cup) echo "$data/colmap_cup" ;;
    fern) echo "$data/llff_fern" ;;
    *) echo "unknown capture $1" >&2; exit 2 ;;
  esac
}
flips() {
  case $1 in
    fern) printf '%s\n' "rays:--rays 256" "hash:--hash-grid on" "appearance:--appearance embedding" \
      "field:--field unbounded" ;;
    *) printf '%s\n' "rays:--rays 256" "hash:--hash-grid off" "appearance:--appearance none" \
      "sparse_depth:--sparse-depth off" "field:--field box" ;;
  esac
}

# train NAME CORE FLAGS...: one run into OUT/runs/NAME (CORE empty: all cores).
train() {
  local name=$1 core=$2
  shift 2
  local pin=()
  [ -n "$core" ] && pin=(env RAYON_NUM_THREADS=1 taskset -c "$core")
  rm -rf "$out/runs/$name"
  "${pin[@]}" "$bin/train" "${length[@]}" --seed 0 --quiet --out "$out/runs/$name" "$@" \
    >"$out/runs/$name.log" 2>&1 </dev/null
}

# The held-out PSNR over every pixel and the iterations of a run.
score() {
  python3 - "$out/runs/$1/summary.json" <<'EOF'
import json, sys
s = json.load(open(sys.argv[1]))
whole = s.get("heldout_whole") or s["heldout_interior"]
print(f"{whole['psnr']:.3f},{s['iterations']}")
EOF
}

for c in $captures; do
  dir=$(capture_dir "$c")
  [ -n "${PAIRED:-}" ] || train "$c-defaults" "" --data "$dir"
  while IFS= read -r flip; do
    setting=${flip%%:*}
    if [ -n "${SETTINGS:-}" ] && [[ " $SETTINGS " != *" $setting "* ]]; then
      continue
    fi
    read -r -a flags <<<"${flip#*:}"
    if [ -n "${PAIRED:-}" ]; then
      train "$c-defaults-$setting" 0 --data "$dir" &
      train "$c-$setting" 1 --data "$dir" "${flags[@]}"
      wait
      base=$(score "$c-defaults-$setting")
    else
      train "$c-$setting" "" --data "$dir" "${flags[@]}"
      base=$(score "$c-defaults")
    fi
    got=$(score "$c-$setting")
    diff=$(python3 -c "print(f'{${got%%,*} - ${base%%,*}:+.3f}')")
    echo "$c,$setting,${flags[*]},$got,$base,$diff" | tee -a "$csv"
  done < <(flips "$c")
done
echo "wrote $csv"
