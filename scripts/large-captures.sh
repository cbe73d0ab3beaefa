#!/usr/bin/env bash
# Captures at a phone's own size (docs/guide/large-captures.md): Record3D
# exports of 345 and 2000 frames at 1920 x 1440 written from the Replica
# frames (`record3d_export`, one frame in each run of 4 sharp, the others
# blurred), loaded and trained 100 iterations with the defaults and with
# every frame kept, the sharpest of each window, and full resolution (which
# is refused before loading). Each run's seconds and peak memory while
# loading (`stages.json`), its peak resident memory (`/usr/bin/time`), the
# frames and training size it took.
#
#   bash scripts/large-captures.sh OUT
#
# OUT/large_captures.csv holds a row per run; the exports (about 0.75 GB)
# stay in OUT/exports. Runs one after another: nothing else should load the
# machine.
set -euo pipefail
out=${1:?usage: bash scripts/large-captures.sh OUT}
data=${OPENNERF_DATA:-../shared/data}
. "$(dirname "$0")/frozen-bins.sh"
freeze_bins "$out"
if [ ! -x "$bin/record3d_export" ]; then
  cargo build --release -q -p bench --bin record3d_export
  cp "$CARGO_TARGET_DIR/release/record3d_export" "$bin/"
fi
mkdir -p "$out/exports" "$out/runs"
for n in 345 2000; do
  [ -d "$out/exports/r$n" ] || "$bin/record3d_export" --replica "$data/replica_room0_20f" \
    --out "$out/exports/r$n" --frames "$n" --size 1920x1440 --blur-window 4
done
csv=$out/large_captures.csv
echo "export,flags,exit,frames,training_size,load_s,load_peak_mb,max_rss_mb,wall_s,rays_per_s" >"$csv"
run() {
  local n=$1 name=$2
  shift 2
  local dir=$out/runs/r$n-$name
  rm -rf "$dir"
  local code=0
  /usr/bin/time -f "%M %e" -o "$dir.time" "$bin/train" --data "$out/exports/r$n" \
    --iters 100 --no-final-render --out "$dir" "$@" >"$dir.log" 2>&1 || code=$?
  python3 - "$dir" "$n" "$*" "$code" >>"$csv" <<'EOF'
import json, re, sys
from pathlib import Path
d, n, flags, code = Path(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4]
rss, wall = Path(f"{d}.time").read_text().split()[-2:]
stages = json.loads((d / "stages.json").read_text()) if (d / "stages.json").exists() else []
scene = next((s for s in stages if s["stage"] == "scene"), None)
log = Path(f"{d}.log").read_text()
m = re.search(r"scene \S+: (\d+) frames", log)
size = re.search(r"training resolution (\d+x\d+)", log)
rays = re.findall(r"([\d.]+) rays/s training", log)
split = d / "split.json"
print(",".join([
    f"r{n}", flags or "(defaults)", code,
    m.group(1) if m else "",
    size.group(1) if size else ("refused" if code != "0" else "1920x1440"),
    f"{scene['seconds']:.1f}" if scene else "",
    f"{scene['peak_mb']:.0f}" if scene else "",
    f"{int(rss) / 1024:.0f}", wall,
    rays[-1] if rays else "",
]))
EOF
  tail -1 "$csv"
}
for n in 345 2000; do
  run "$n" defaults
  run "$n" stride1 --stride 1
  run "$n" sharpest20 --sharpest-of 20
  run "$n" fullres --stride 1 --resolution 1920x1440
done
echo "wrote $csv"
