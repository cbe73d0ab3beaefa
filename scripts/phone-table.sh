#!/usr/bin/env bash
# The phone loaders against the Replica loader on the same frames
# (docs/phone.md): the Replica room written out as each phone export, each
# trained for the same seconds with simulated feature maps, held-out PSNR
# and the segmentation of labelled points compared.
#
#   bash scripts/phone-table.sh OUT [SECONDS]
#
# OUT/phone_table.csv and OUT/phone_table.md hold the table. Runs one after
# another (each run is timed): nothing else should load the machine.
set -euo pipefail
out=${1:?usage: bash scripts/phone-table.sh OUT [SECONDS]}
budget=${2:-300}
data=${OPENNERF_DATA:-../shared/data}
replica=$data/replica_room0_20f
embeddings=$data/clip_text/scannet200_vitb_512.npy
names=$data/clip_text/scannet200_labels.txt
# The room's colours as the simulated VLM's classes (and the labels of the
# ground-truth points: each point takes the nearest colour's class).
classes="wall=#d8cdc2,floor=#58595b,cabinet=#6b5840,ottoman=#c5aa80,couch=#f2f0ee,door=#b48c50"
run() { cargo run -q --release -p "$1" --bin "$2" -- "${@:3}"; }

cargo build -q --release -p train -p eval -p bench --bins
# Each step is skipped where its output is there already, so that the
# script can be run again after a failure without redoing a timed run.
[ -d "$out/exports" ] ||
  run bench phone_exports --replica "$replica" --out "$out/exports" --classes "$classes"
ex=$out/exports
# Record3D's EXR + JPG export (record3d/) loads into the very scene its R3D
# file does (bench/tests/phone_exports.rs), so the R3D file stands for both.
for entry in "replica=$replica" "scanner-app=$ex/scanner-app" "polycam=$ex/polycam" \
  "record3d=$ex/capture.r3d"; do
  name=${entry%%=*}
  dir=${entry#*=}
  if [ "$name" = replica ]; then
    points=$ex/points_replica.ply
    frame=scene
  else
    points=$ex/points_arkit.ply
    frame=capture
  fi
  echo "== $name"
  [ -d "$out/features/$name" ] || run train simulate_features --data "$dir" --embeddings "$embeddings" --names "$names" \
    --classes "$classes" --out "$out/features/$name"
  [ -f "$out/runs/$name/summary.json" ] || run train train --data "$dir" --features "$out/features/$name" --resolution 300x170 \
    --holdout-every 5 --time-budget "$budget" --no-final-render --quiet --out "$out/runs/$name"
  [ -f "$out/segment/$name/segmentation.json" ] || run eval eval segment --run "$out/runs/$name" --points "$points" --frame "$frame" \
    --embeddings "$out/features/$name/classes/embeddings.npy" \
    --names "$out/features/$name/classes/names.txt" --max-views 10 --render-scale 0.5 \
    --out "$out/segment/$name"
  # Held-out PSNR over every pixel of the four held-out frames.
  [ -f "$out/render/$name/psnr.txt" ] || {
    mkdir -p "$out/render/$name"
    run eval eval render --run "$out/runs/$name" --cameras heldout --out "$out/render/$name" |
      tee "$out/render/$name.log"
    grep "PSNR against" "$out/render/$name.log" > "$out/render/$name/psnr.txt"
  }
done
python3 - "$out" <<'EOF'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
rows = []
for name in ["replica", "scanner-app", "polycam", "record3d"]:
    s = json.loads((out / "runs" / name / "summary.json").read_text())
    g = json.loads((out / "segment" / name / "segmentation.json").read_text())
    g = g.get("hybrid", g).get("all", g)
    line = (out / "render" / name / "psnr.txt").read_text()
    whole = float(line.split("):")[1].split("dB")[0])
    rows.append((name, s["iterations"], s["heldout_interior"]["psnr"], whole,
                 100 * g["miou"], 100 * g["macc"]))
base = rows[0]
lines = ["loader,iterations,heldout_psnr_sampled_db,heldout_psnr_db,miou,macc,psnr_vs_replica_db,miou_vs_replica"]
md = ["| loader | iterations | held-out PSNR, 1024 interior pixels | held-out PSNR, every pixel | mIoU | mAcc | PSNR vs Replica | mIoU vs Replica |",
      "|---|---|---|---|---|---|---|---|"]
for r in rows:
    d_psnr, d_miou = r[3] - base[3], r[4] - base[4]
    lines.append(f"{r[0]},{r[1]},{r[2]:.3f},{r[3]:.3f},{r[4]:.2f},{r[5]:.2f},{d_psnr:+.3f},{d_miou:+.2f}")
    md.append(f"| {r[0]} | {r[1]} | {r[2]:.2f} dB | {r[3]:.2f} dB | {r[4]:.1f} | {r[5]:.1f} | {d_psnr:+.2f} dB | {d_miou:+.1f} |")
(out / "phone_table.csv").write_text("\n".join(lines) + "\n")
(out / "phone_table.md").write_text("\n".join(md) + "\n")
print("\n".join(md))
EOF
