#!/usr/bin/env bash
# The defaults of real photographed captures, each flipped on its own,
# measured on three captures: the statue and the cup (COLMAP, photographed
# objects) and fern (LLFF, forward-facing). For each capture, runs with
# the defaults and one per setting turned the other way: smaller batches
# (64 rays on objects, 128 on forward-facing captures), the hash encoding,
# appearance codes, the sparse points' depth (COLMAP only) and the field
# (box or unbounded). Each run trains SECONDS (default 600).
#
#   bash scripts/colmap-defaults.sh OUT [SECONDS] [CAPTURES]
#
# CAPTURES (default "statue cup fern") chooses among the three, and
# SETTINGS="rays hash ..." in the environment among the settings (default
# all: rays, hash, appearance, sparse_depth, field). The fast field is
# measured only when SETTINGS names it: `fast` (`--field-model fast` at
# the capture's own samples a ray, and on photographed objects at 16),
# `fast_samples24` (at 24, photographed objects), `fast_proposal` (with
# its hash-grid proposal networks), `fast_proposal_fewer` (with proposal
# rounds of 32 and 16 samples, then 24 on photographed objects and the
# capture's 16 on forward-facing ones).
#
# Two ways to use the machine:
# - default: one run at a time on every core, one run of the defaults per
#   capture;
# - SIDE_BY_SIDE=1: two runs at a time, each on a core of its own
#   (taskset, one thread each), and two runs of the defaults per capture,
#   trained side by side: how much they differ is how much a run differs
#   from itself. Takes half the time on a 2-core machine. REPEAT=0 keeps
#   one run of the defaults (when an earlier run measured the spread).
#
# Scoring: held-out PSNR over every pixel of the final render
# (`summary.json`'s `heldout_whole`), or with SAMPLE=N over N held-out
# pixels drawn once (the same for every run of a capture) from the
# interior of the held-out views, with no final render and no periodic
# evaluation in between (a full render of the cup's held-out views takes
# longer than the training).
#
# OUT/colmap_defaults.csv: a row per flipped run (capture, setting, value,
# held-out PSNR, iterations, the mean PSNR and iterations of the defaults'
# runs, the difference); OUT/colmap_defaults_runs.csv: a row per run;
# OUT/colmap_defaults.png: the differences as bars (`capture_defaults_plot`).
# QUICK=1 trains 20 iterations a run (a rehearsal). Nothing else should
# load the machine.
set -euo pipefail
out=${1:?usage: bash scripts/colmap-defaults.sh OUT [SECONDS] [CAPTURES]}
budget=${2:-600}
captures=${3:-statue cup fern}
data=${OPENNERF_DATA:-../shared/data}
length=(--time-budget "$budget")
[ -n "${QUICK:-}" ] && length=(--iters 20)
scoring=()
if [ -n "${SAMPLE:-}" ]; then
  mkdir -p "$out"
  echo "{\"logging\": {\"eval_pixels\": $SAMPLE, \"eval_every\": 0}}" >"$out/sample.json"
  scoring=(--no-final-render --config "$out/sample.json")
fi
. "$(dirname "$0")/frozen-bins.sh"
freeze_bins "$out"
mkdir -p "$out/runs"
out=$(cd "$out" && pwd)
echo '{"model": {"proposal": {"samples": [32, 16]}}}' >"$out/rounds_32_16.json"

# The capture directory and the flags that flip each setting from its
# default there (a photographed object: unbounded, codes, hash grid, no
# sparse depth, 256 rays; a forward-facing capture: box, no codes, hash
# grid, 256 rays).
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
    fern) printf '%s\n' "rays:--rays 128" "hash:--hash-grid off" "appearance:--appearance embedding" \
      "field:--field unbounded" "fast:--field-model fast" \
      "fast_proposal:--field-model fast --sampler proposal" \
      "fast_proposal_fewer:--field-model fast --sampler proposal --config $out/rounds_32_16.json" ;;
    *) printf '%s\n' "rays:--rays 64" "hash:--hash-grid off" "appearance:--appearance none" \
      "sparse_depth:--sparse-depth on" "field:--field box" \
      "fast:--field-model fast --samples 16" "fast_samples24:--field-model fast --samples 24" \
      "fast_proposal:--field-model fast --sampler proposal" \
      "fast_proposal_fewer:--field-model fast --sampler proposal --samples 24 --config $out/rounds_32_16.json" ;;
  esac
}

# The runs, a line each: "NAME CAPTURE SETTING FLAGS..." (SETTING "-" for
# the defaults).
jobs=()
for c in $captures; do
  capture_dir "$c" >/dev/null
  jobs+=("$c-defaults $c -")
  [ -n "${SIDE_BY_SIDE:-}" ] && [ "${REPEAT:-1}" != 0 ] && jobs+=("$c-defaults-again $c -")
  while IFS= read -r flip; do
    setting=${flip%%:*}
    if [ -n "${SETTINGS:-}" ] && [[ " $SETTINGS " != *" $setting "* ]]; then
      continue
    fi
    if [ -z "${SETTINGS:-}" ] && [[ $setting == fast* ]]; then
      continue
    fi
    jobs+=("$c-$setting $c $setting ${flip#*:}")
  done < <(flips "$c")
done

# run JOB CORE: one run into OUT/runs/NAME (CORE empty: every core).
run() {
  local name capture setting flags pin=()
  read -r name capture setting flags <<<"$1"
  [ -n "$2" ] && pin=(env RAYON_NUM_THREADS=1 taskset -c "$2")
  rm -rf "$out/runs/$name"
  local config=("${scoring[@]}")
  # A setting's own configuration file and the scoring's go to `train`
  # as one file, the setting's keys laid over the scoring's.
  if [[ " $flags " == *" --config "* ]]; then
    local own=${flags##*--config }
    own=${own%% *}
    flags=${flags/--config $own/}
    if [ ${#scoring[@]} -gt 0 ]; then
      python3 - "$out/sample.json" "$own" "$out/runs/$name.config.json" <<'PY'
import json, sys
def lay(base, over):
    for k, v in over.items():
        base[k] = lay(base.get(k, {}), v) if isinstance(v, dict) and isinstance(base.get(k), dict) else v
    return base
merged = lay(json.load(open(sys.argv[1])), json.load(open(sys.argv[2])))
json.dump(merged, open(sys.argv[3], "w"))
PY
      config=(--no-final-render --config "$out/runs/$name.config.json")
    else
      config=(--config "$own")
    fi
  fi
  # shellcheck disable=SC2086
  "${pin[@]}" "$bin/train" "${length[@]}" "${config[@]}" --seed 0 --quiet \
    --data "$(capture_dir "$capture")" --out "$out/runs/$name" $flags \
    >"$out/runs/$name.log" 2>&1 </dev/null
  echo "done: $name"
}

if [ -n "${SIDE_BY_SIDE:-}" ]; then
  # Two workers, a core each, taking the runs in turn.
  for core in 0 1; do
    (
      for ((i = core; i < ${#jobs[@]}; i += 2)); do run "${jobs[$i]}" "$core"; done
    ) &
  done
  wait
else
  for job in "${jobs[@]}"; do run "$job" ""; done
fi

# The tables.
printf '%s\n' "${jobs[@]}" >"$out/jobs.txt"
python3 - "$out" <<'PY'
import csv, json, sys
from collections import defaultdict
out = sys.argv[1]
rows, defaults = [], defaultdict(list)
for line in open(f"{out}/jobs.txt"):
    name, capture, setting, *flags = line.split()
    s = json.load(open(f"{out}/runs/{name}/summary.json"))
    whole = s.get("heldout_whole") or s["heldout_interior"]
    # A configuration file is named without its directory (OUT).
    flags = [f.rsplit("/", 1)[-1] if f.endswith(".json") else f for f in flags]
    run = dict(run=name, capture=capture, setting=setting, value=" ".join(flags),
               psnr=round(whole["psnr"], 3), iterations=s["iterations"],
               pixels=whole.get("pixels", ""))
    rows.append(run)
    if setting == "-":
        defaults[capture].append(run)
with open(f"{out}/colmap_defaults_runs.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
with open(f"{out}/colmap_defaults.csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["capture", "setting", "value", "psnr", "iterations", "defaults_psnr",
                "defaults_iterations", "defaults_spread_db", "difference_db"])
    for r in rows:
        if r["setting"] == "-":
            continue
        d = defaults[r["capture"]]
        psnr = sum(x["psnr"] for x in d) / len(d)
        its = sum(x["iterations"] for x in d) / len(d)
        spread = max(x["psnr"] for x in d) - min(x["psnr"] for x in d)
        row = [r["capture"], r["setting"], r["value"], r["psnr"], r["iterations"],
               f"{psnr:.3f}", f"{its:.0f}", f"{spread:.3f}", f"{r['psnr'] - psnr:+.3f}"]
        w.writerow(row)
        print(",".join(map(str, row)))
print(f"wrote {out}/colmap_defaults.csv and {out}/colmap_defaults_runs.csv")
PY
cargo run -p bench --release -q --example capture_defaults_plot -- "$out"
