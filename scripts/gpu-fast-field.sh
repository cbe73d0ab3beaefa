#!/usr/bin/env bash
# The fast field against the Mip-NeRF field on a GPU, in one run, for the
# day a GPU machine is lent (docs/measurements/fast-field.md): the training
# step (`bench`, the reference step's sizes) of both fields on wgpu at 4096
# and 16384 rays a step, then the bench room trained on wgpu for 90 s with
# each field, each with its own sampling (the fast field with its hash-grid
# proposal networks); one table of rays/s, step time and held-out PSNR.
# About 7 minutes on a GPU.
#
#     bash scripts/gpu-fast-field.sh OUT
#
# OUT/fast_field_gpu.md is the table; OUT/bench_R.txt and OUT/room-FIELD/
# (run directories) hold what it was made from. QUICK=1 shrinks every size
# (bench's --quick at 256 and 512 rays, the CI room for 20 s): a rehearsal on
# lavapipe (Vulkan on the CPU) that runs every step in a few minutes. The
# binaries come from gpu-pack/ when it exists (scripts/gpu-pack.sh), else
# they are built first.
set -euo pipefail
out=${1:?usage: bash scripts/gpu-fast-field.sh OUT}
cd "$(dirname "$0")/.."
mkdir -p "$out"
out=$(cd "$out" && pwd)

if [ -n "${QUICK:-}" ]; then
  rays=(256 512)
  bench_size=(--quick --fit-steps 5 --steps 2)
  room=(--scene-size ci --time-budget 20 --log-every 5)
else
  rays=(4096 16384)
  bench_size=(--fit-steps 20 --steps 5)
  room=(--scene-size bench --scene-seed 21 --time-budget 90)
fi

# The binaries (`$bin`): unpacked from gpu-pack/ or built here; wgpu's
# environment.
# shellcheck source=scripts/gpu-binaries.sh
source scripts/gpu-binaries.sh

for r in "${rays[@]}"; do
  echo "== bench, $r rays a step"
  "$bin/bench" --backend wgpu --rays "$r" "${bench_size[@]}" \
    --cases composited,fast,fast-proposal > "$out/bench_$r.txt" 2> "$out/bench_$r.log"
  cat "$out/bench_$r.txt"
done

for field in mip fast; do
  echo "== the room on wgpu, the $field field"
  flags=(--field-model "$field")
  if [ "$field" = fast ]; then
    flags+=(--sampler proposal)
  fi
  rm -rf "$out/room-$field"
  "$bin/train" --backend wgpu "${room[@]}" "${flags[@]}" --no-final-render --quiet \
    --out "$out/room-$field" > "$out/room-$field.log" 2>&1
done

python3 - "$out" "${rays[@]}" <<'PY'
import json
import sys
from pathlib import Path

out = Path(sys.argv[1])
lines = ["# The fast field on a GPU (scripts/gpu-fast-field.sh)", ""]
binaries = out / "binaries.txt"
if binaries.exists():
    lines.append(f"Binaries built from: {binaries.read_text().strip()}")
lines += ["", "## The training step (`bench --backend wgpu`)", ""]
for r in sys.argv[2:]:
    lines += [f"### {r} rays a step", "", "```", (out / f"bench_{r}.txt").read_text().rstrip(), "```", ""]
lines += [
    "## The room on wgpu (`train --backend wgpu`)",
    "",
    "| field | iterations | training rays/s | held-out PSNR (interior, sample) |",
    "|---|---|---|---|",
]
for field in ["mip", "fast"]:
    s = json.loads((out / f"room-{field}" / "summary.json").read_text())
    lines.append(
        f"| {field} | {s['iterations']} | {s['rays_per_second']:.0f} | "
        f"{s['heldout_interior']['psnr']:.2f} dB |"
    )
(out / "fast_field_gpu.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
PY
echo "== wrote $out/fast_field_gpu.md"
