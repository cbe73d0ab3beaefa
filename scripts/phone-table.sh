#!/usr/bin/env bash
# The phone loaders against the Replica loader on the same frames
# (docs/phone.md): the Replica room written out as each phone export, each
# trained for the same seconds with simulated feature maps, held-out PSNR
# and the segmentation of labelled points compared.
#
#   bash scripts/phone-table.sh OUT [SECONDS] [SEEDS]
#
# SEEDS (default "0") is a space-separated list of training seeds: every
# loader is trained once per seed, so that a loader's difference can be told
# from the spread between runs of the same command. OUT/phone_runs.csv holds
# every run; OUT/phone_table.csv and OUT/phone_table.md the mean and standard
# deviation per loader. Runs one after another (each run is timed): nothing
# else should load the machine. With ITERS=N in the environment every run
# trains N iterations instead of SECONDS: an equal-iterations comparison,
# which a machine whose speed drifts (or a build beside it) does not bias.
set -euo pipefail
out=${1:?usage: bash scripts/phone-table.sh OUT [SECONDS] [SEEDS]}
budget=${2:-300}
seeds=${3:-0}
if [ -n "${ITERS:-}" ]; then length=(--iters "$ITERS"); else length=(--time-budget "$budget"); fi
data=${OPENNERF_DATA:-../shared/data}
replica=$data/replica_room0_20f
embeddings=$data/clip_text/scannet200_vitb_512.npy
names=$data/clip_text/scannet200_labels.txt
# The room's colours as the simulated VLM's classes (and the labels of the
# ground-truth points: each point takes the nearest colour's class).
classes="wall=#d8cdc2,floor=#58595b,cabinet=#6b5840,ottoman=#c5aa80,couch=#f2f0ee,door=#b48c50"
# train and eval run from OUT/bin, built and copied there once, so that a
# rerun after the code changed, or a build beside it, keeps the programs.
. "$(dirname "$0")/frozen-bins.sh"
freeze_bins "$out"
run() {
  case "$2" in
    train | eval) "$bin/$2" "${@:3}" ;;
    *) cargo run -q --release -p "$1" --bin "$2" -- "${@:3}" ;;
  esac
}
# Each step is skipped where its output is there already, so that the
# script can be run again after a failure without redoing a timed run.
[ -d "$out/exports" ] ||
  run bench phone_exports --replica "$replica" --out "$out/exports" --classes "$classes"
ex=$out/exports
# Record3D's EXR + JPG export (record3d/) loads into the very scene its R3D
# file does (bench/tests/phone_exports.rs), so the R3D file stands for both.
loaders="replica=$replica scanner-app=$ex/scanner-app polycam=$ex/polycam record3d=$ex/capture.r3d"
for entry in $loaders; do
  name=${entry%%=*}
  [ -d "$out/features/$name" ] || run train simulate_features --data "${entry#*=}" --embeddings "$embeddings" \
    --names "$names" --classes "$classes" --out "$out/features/$name"
done
# Seeds outside, loaders inside: a slow spell of the machine falls on every
# loader alike.
for seed in $seeds; do
  for entry in $loaders; do
    name=${entry%%=*}
    dir=${entry#*=}
    tag=$name-seed$seed
    if [ "$name" = replica ]; then
      points=$ex/points_replica.ply
      frame=scene
    else
      points=$ex/points_arkit.ply
      frame=capture
    fi
    echo "== $tag"
    [ -f "$out/runs/$tag/summary.json" ] || run train train --data "$dir" --features "$out/features/$name" \
      --resolution 300x170 --holdout-every 5 "${length[@]}" --seed "$seed" --no-final-render --quiet \
      --out "$out/runs/$tag"
    [ -f "$out/segment/$tag/segmentation.json" ] || run eval eval segment --run "$out/runs/$tag" --points "$points" \
      --frame "$frame" --embeddings "$out/features/$name/classes/embeddings.npy" \
      --names "$out/features/$name/classes/names.txt" --max-views 10 --render-scale 0.5 --out "$out/segment/$tag"
    # Held-out PSNR over every pixel of the four held-out frames.
    [ -f "$out/render/$tag/psnr.txt" ] || {
      mkdir -p "$out/render/$tag"
      run eval eval render --run "$out/runs/$tag" --cameras heldout --out "$out/render/$tag" | tee "$out/render/$tag.log"
      grep "PSNR against" "$out/render/$tag.log" > "$out/render/$tag/psnr.txt"
    }
  done
done
python3 - "$out" "$seeds" <<'EOF'
import json, statistics, sys, pathlib
out = pathlib.Path(sys.argv[1])
seeds = sys.argv[2].split()
loaders = ["replica", "scanner-app", "polycam", "record3d"]
runs = []
for name in loaders:
    for seed in seeds:
        tag = f"{name}-seed{seed}"
        s = json.loads((out / "runs" / tag / "summary.json").read_text())
        g = json.loads((out / "segment" / tag / "segmentation.json").read_text())
        g = g.get("hybrid", g).get("all", g)
        line = (out / "render" / tag / "psnr.txt").read_text()
        whole = float(line.split("):")[1].split("dB")[0])
        runs.append(dict(loader=name, seed=seed, iterations=s["iterations"],
                         sampled=s["heldout_interior"]["psnr"], psnr=whole,
                         miou=100 * g["miou"], macc=100 * g["macc"]))
lines = ["loader,seed,iterations,heldout_psnr_sampled_db,heldout_psnr_db,miou,macc"]
for r in runs:
    lines.append(f"{r['loader']},{r['seed']},{r['iterations']},{r['sampled']:.3f},"
                 f"{r['psnr']:.3f},{r['miou']:.2f},{r['macc']:.2f}")
(out / "phone_runs.csv").write_text("\n".join(lines) + "\n")


def stats(name, key):
    v = [r[key] for r in runs if r["loader"] == name]
    return statistics.mean(v), (statistics.stdev(v) if len(v) > 1 else 0.0)


base_psnr, base_miou = stats("replica", "psnr")[0], stats("replica", "miou")[0]
lines = ["loader,runs,iterations_mean,heldout_psnr_db_mean,heldout_psnr_db_std,"
         "miou_mean,miou_std,macc_mean,psnr_vs_replica_db,miou_vs_replica"]
md = ["| loader | runs | iterations (mean) | held-out PSNR, every pixel (mean ± std) "
      "| mIoU (mean ± std) | mAcc | PSNR vs Replica | mIoU vs Replica |",
      "|---|---|---|---|---|---|---|---|"]
for name in loaders:
    it = stats(name, "iterations")[0]
    p, ps = stats(name, "psnr")
    m, ms = stats(name, "miou")
    a = stats(name, "macc")[0]
    lines.append(f"{name},{len(seeds)},{it:.0f},{p:.3f},{ps:.3f},{m:.2f},{ms:.2f},{a:.2f},"
                 f"{p - base_psnr:+.3f},{m - base_miou:+.2f}")
    md.append(f"| {name} | {len(seeds)} | {it:.0f} | {p:.2f} ± {ps:.2f} dB | {m:.2f} ± {ms:.2f} "
              f"| {a:.2f} | {p - base_psnr:+.2f} dB | {m - base_miou:+.2f} |")
(out / "phone_table.csv").write_text("\n".join(lines) + "\n")
(out / "phone_table.md").write_text("\n".join(md) + "\n")
print("\n".join(md))
EOF
# The same runs as a picture, OUT/phone_table.png.
cargo run -q --release -p bench --example phone_table_plot -- "$out"
