#!/usr/bin/env bash
# The GPU's figures in one run (docs/guide/gpu.md), for the day a GPU machine is
# lent: the training step (`bench`) on wgpu at 1024, 4096 and 16384 rays a
# step, and the bench room trained on wgpu for 300 s; one table of rays/s,
# step time, the seconds of the first logged iterations (kernel compilation
# and autotuning), peak GPU memory and held-out PSNR and SSIM. About 7
# minutes on a GPU.
#
#     bash scripts/gpu-measure.sh OUT
#
# OUT/gpu_table.md is the table; OUT/bench_R.txt, OUT/bench-room/ (a run
# directory) and OUT/gpu_memory.csv (nvidia-smi's samples) hold what it was
# made from. QUICK=1 shrinks every size (bench's --quick at 128, 256 and 512
# rays, the CI room for 30 s logged every 5 iterations, no final render): a
# rehearsal on lavapipe
# (Vulkan on the CPU) that runs every step of the script in a few minutes.
# The binaries come from gpu-pack/ when it exists (scripts/gpu-pack.sh: a
# lent GPU machine reaches no registry to build from), else they are built
# first (release, default features); either way the timed steps compile
# nothing. Burn's CUDA backend is not a backend of this build (`--backend`
# takes flex, ndarray and wgpu), so wgpu is the GPU measured.
set -euo pipefail
out=${1:?usage: bash scripts/gpu-measure.sh OUT}
cd "$(dirname "$0")/.."
mkdir -p "$out"
out=$(cd "$out" && pwd)

if [ -n "${QUICK:-}" ]; then
  rays=(128 256 512)
  bench_size=(--quick --fit-steps 5 --steps 2)
  room=(--scene-size ci --time-budget 30 --no-final-render --log-every 5)
else
  rays=(1024 4096 16384)
  bench_size=(--fit-steps 20 --steps 5)
  room=(--scene-size bench --time-budget 300)
fi

# The binaries (`$bin`): unpacked from gpu-pack/ or built here; wgpu's
# environment.
# shellcheck source=scripts/gpu-binaries.sh
source scripts/gpu-binaries.sh

# GPU memory, sampled every half second while the script runs.
sampler=""
if command -v nvidia-smi >/dev/null 2>&1; then
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader > "$out/gpu.txt"
  nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 500 > "$out/gpu_memory.csv" &
  sampler=$!
  trap 'kill $sampler 2>/dev/null || true' EXIT
else
  echo "no nvidia-smi: wgpu's adapter, no GPU memory figures" > "$out/gpu.txt"
fi

for r in "${rays[@]}"; do
  echo "== bench, $r rays a step"
  start=$(date +%s.%N)
  "$bin/bench" --backend wgpu --rays "$r" "${bench_size[@]}" --cases plain,proposal \
    > "$out/bench_$r.txt" 2> "$out/bench_$r.log"
  end=$(date +%s.%N)
  echo "wall seconds: $(python3 -c "print(round($end - $start, 1))")" >> "$out/bench_$r.txt"
  cat "$out/bench_$r.txt"
done

echo "== the room on wgpu"
rm -rf "$out/bench-room"
"$bin/train" --backend wgpu "${room[@]}" --quiet --out "$out/bench-room" > "$out/bench-room.log" 2>&1
[ -n "$sampler" ] && kill "$sampler" 2>/dev/null || true

python3 - "$out" "${rays[@]}" <<'EOF'
import json
import sys
from pathlib import Path

out = Path(sys.argv[1])
rays = sys.argv[2:]
lines = ["# The GPU's figures (scripts/gpu-measure.sh)", ""]
lines.append(f"Device: {(out / 'gpu.txt').read_text().strip()}")
binaries = out / "binaries.txt"
if binaries.exists():
    lines.append(f"Binaries built from: {binaries.read_text().strip()}")
mem = out / "gpu_memory.csv"
if mem.exists() and mem.stat().st_size > 0:
    used = [float(v) for v in mem.read_text().split() if v.replace(".", "", 1).isdigit()]
    if used:
        lines.append(f"Peak GPU memory used while the script ran: {max(used):.0f} MiB")
lines += ["", "## The training step (`bench --backend wgpu`)", ""]
for r in rays:
    lines += [f"### {r} rays a step", "", "```", (out / f"bench_{r}.txt").read_text().rstrip(), "```", ""]
run = out / "bench-room"
summary = json.loads((run / "summary.json").read_text())
events = [json.loads(l) for l in (run / "metrics.jsonl").read_text().splitlines() if l.strip()]
train = [e for e in events if e.get("event") == "train"]
first = train[0] if train else {}
last = train[-1] if train else {}
h = summary["heldout_interior"]
lines += [
    "## The room on wgpu (`train --backend wgpu`)",
    "",
    "| figure | value |",
    "|---|---|",
    f"| iterations | {summary['iterations']} |",
    f"| training rays/s (mean) | {summary['rays_per_second']:.0f} |",
    f"| training rays/s (last log line) | {last.get('rays_per_second', float('nan')):.0f} |",
    f"| seconds to iteration {first.get('iteration', '?')} (compilation and autotuning included) | {first.get('wall_seconds', float('nan')):.1f} |",
    f"| final render rays/s | {summary.get('render_rays_per_second') or float('nan'):.0f} |",
    f"| held-out PSNR, interior | {h['psnr']:.2f} dB |",
    f"| held-out SSIM, interior | {h.get('ssim') if h.get('ssim') is not None else 'n/a (no final render)'} |",
    "",
]
(out / "gpu_table.md").write_text("\n".join(lines))
print("\n".join(lines))
EOF
echo "== wrote $out/gpu_table.md"
