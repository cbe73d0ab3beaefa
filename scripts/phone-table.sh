#!/usr/bin/env bash
# The phone loaders against the Replica loader on the same frames
# (docs/guide/phone.md): the Replica room written out as each phone export, each
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
#
# With PAIRED=1 each phone loader's run is paired with a run of the Replica
# loader with the same seed, the two trained at the same time, each on a
# core of its own (taskset, one thread each): a change in the machine's
# speed then falls on both runs of a pair alike. OUT/phone_pairs.csv holds
# each pair's differences, and the table their mean and spread. Needs two
# idle cores.
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
# One training run and its two evaluations: `job LOADER DIR SEED TAG [CORE]`,
# on one core with one thread where CORE is given.
job() {
  local name=$1 dir=$2 seed=$3 tag=$4 pin=()
  [ -n "${5:-}" ] && pin=(env RAYON_NUM_THREADS=1 taskset -c "$5")
  local points=$ex/points_arkit.ply frame=capture
  if [ "$name" = replica ]; then
    points=$ex/points_replica.ply
    frame=scene
  fi
  echo "== $tag"
  [ -f "$out/runs/$tag/summary.json" ] || {
    # The processor each run trains on (OUT/runs/TAG.cpu): a table resumed
    # on another machine says so run by run.
    mkdir -p "$out/runs"
    lscpu | sed -n 's/^Model name: *//p; s/^CPU family: *\(.*\)/family \1/p; s/^Model: *\(.*\)/model \1/p' |
      paste -sd ' ' > "$out/runs/$tag.cpu"
    "${pin[@]}" "$bin/train" --data "$dir" \
      --features "$out/features/$name" --resolution 300x170 --holdout-every 5 "${length[@]}" \
      --seed "$seed" --no-final-render --quiet --out "$out/runs/$tag"
  }
  [ -f "$out/segment/$tag/segmentation.json" ] || "${pin[@]}" "$bin/eval" segment \
    --run "$out/runs/$tag" --points "$points" --frame "$frame" \
    --embeddings "$out/features/$name/classes/embeddings.npy" \
    --names "$out/features/$name/classes/names.txt" --max-views 10 --render-scale 0.5 \
    --out "$out/segment/$tag" > "$out/segment/$tag.log"
  # Held-out PSNR over every pixel of the four held-out frames.
  [ -f "$out/render/$tag/psnr.txt" ] || {
    mkdir -p "$out/render/$tag"
    "${pin[@]}" "$bin/eval" render --run "$out/runs/$tag" --cameras heldout \
      --out "$out/render/$tag" > "$out/render/$tag.log"
    grep "PSNR against" "$out/render/$tag.log" > "$out/render/$tag/psnr.txt"
  }
}
mkdir -p "$out/segment" "$out/render"
# OUT/manifest.txt: one line per run, "LOADER SEED TAG PAIRED_TAG" (the
# Replica run it is paired with, or - ).
: > "$out/manifest.txt"
if [ -n "${PAIRED:-}" ]; then
  # Which core gets the Replica run alternates from pair to pair, in case
  # the two cores differ.
  k=0
  for seed in $seeds; do
    for entry in $loaders; do
      name=${entry%%=*}
      [ "$name" = replica ] && continue
      own=$name-seed$seed
      partner=replica-with-$name-seed$seed
      echo "replica $seed $partner -" >> "$out/manifest.txt"
      echo "$name $seed $own $partner" >> "$out/manifest.txt"
      job replica "$replica" "$seed" "$partner" $((k % 2)) &
      a=$!
      job "$name" "${entry#*=}" "$seed" "$own" $(((k + 1) % 2)) &
      b=$!
      wait "$a"
      wait "$b"
      k=$((k + 1))
    done
  done
else
  # Seeds outside, loaders inside: a slow spell of the machine falls on
  # every loader alike.
  for seed in $seeds; do
    for entry in $loaders; do
      name=${entry%%=*}
      echo "$name $seed $name-seed$seed -" >> "$out/manifest.txt"
      job "$name" "${entry#*=}" "$seed" "$name-seed$seed"
    done
  done
fi
python3 - "$out" <<'EOF'
import json, statistics, sys, pathlib
out = pathlib.Path(sys.argv[1])
loaders = ["replica", "scanner-app", "polycam", "record3d"]
runs = {}
for line in (out / "manifest.txt").read_text().splitlines():
    name, seed, tag, partner = line.split()
    s = json.loads((out / "runs" / tag / "summary.json").read_text())
    g = json.loads((out / "segment" / tag / "segmentation.json").read_text())
    g = g.get("hybrid", g).get("all", g)
    text = (out / "render" / tag / "psnr.txt").read_text()
    whole = float(text.split("):")[1].split("dB")[0])
    cpu = out / "runs" / f"{tag}.cpu"
    cpu = cpu.read_text().strip().replace(",", " ") if cpu.exists() else "unrecorded"
    runs[tag] = dict(loader=name, seed=seed, tag=tag, partner=partner, cpu=cpu,
                     iterations=s["iterations"], sampled=s["heldout_interior"]["psnr"],
                     psnr=whole, miou=100 * g["miou"], macc=100 * g["macc"])
runs = sorted(runs.values(), key=lambda r: (loaders.index(r["loader"]), r["tag"]))
lines = ["loader,seed,run,iterations,heldout_psnr_sampled_db,heldout_psnr_db,miou,macc,cpu"]
for r in runs:
    lines.append(f"{r['loader']},{r['seed']},{r['tag']},{r['iterations']},{r['sampled']:.3f},"
                 f"{r['psnr']:.3f},{r['miou']:.2f},{r['macc']:.2f},{r['cpu']}")
(out / "phone_runs.csv").write_text("\n".join(lines) + "\n")
by_tag = {r["tag"]: r for r in runs}
paired = any(r["partner"] != "-" for r in runs)
if paired:
    lines = ["loader,seed,iterations,replica_iterations,psnr_vs_replica_db,miou_vs_replica,cpu"]
    for r in runs:
        if r["partner"] == "-":
            continue
        q = by_tag[r["partner"]]
        r["dpsnr"], r["dmiou"] = r["psnr"] - q["psnr"], r["miou"] - q["miou"]
        lines.append(f"{r['loader']},{r['seed']},{r['iterations']},{q['iterations']},"
                     f"{r['dpsnr']:+.3f},{r['dmiou']:+.2f},{r['cpu']}")
    (out / "phone_pairs.csv").write_text("\n".join(lines) + "\n")


def stats(name, key):
    v = [r[key] for r in runs if r["loader"] == name]
    return statistics.mean(v), (statistics.stdev(v) if len(v) > 1 else 0.0), len(v)


base_psnr, base_miou = stats("replica", "psnr")[0], stats("replica", "miou")[0]
vs = "paired difference with Replica (mean ± std)" if paired else "vs Replica"
lines = ["loader,runs,iterations_mean,heldout_psnr_db_mean,heldout_psnr_db_std,"
         "miou_mean,miou_std,macc_mean,psnr_vs_replica_db,psnr_vs_replica_std,"
         "miou_vs_replica,miou_vs_replica_std"]
md = ["| loader | runs | iterations (mean) | held-out PSNR, every pixel (mean ± std) "
      f"| mIoU (mean ± std) | mAcc | PSNR {vs} | mIoU {vs} |",
      "|---|---|---|---|---|---|---|---|"]
for name in loaders:
    it, _, n = stats(name, "iterations")
    p, ps, _ = stats(name, "psnr")
    m, ms, _ = stats(name, "miou")
    a = stats(name, "macc")[0]
    if name == "replica":
        dp = dps = dm = dms = 0.0
    elif paired:
        dp, dps, _ = stats(name, "dpsnr")
        dm, dms, _ = stats(name, "dmiou")
    else:
        dp, dps, dm, dms = p - base_psnr, 0.0, m - base_miou, 0.0
    lines.append(f"{name},{n},{it:.0f},{p:.3f},{ps:.3f},{m:.2f},{ms:.2f},{a:.2f},"
                 f"{dp:+.3f},{dps:.3f},{dm:+.2f},{dms:.2f}")
    pm = "" if not paired or name == "replica" else f" ± {dps:.2f}"
    mm = "" if not paired or name == "replica" else f" ± {dms:.2f}"
    md.append(f"| {name} | {n} | {it:.0f} | {p:.2f} ± {ps:.2f} dB | {m:.2f} ± {ms:.2f} "
              f"| {a:.2f} | {dp:+.2f}{pm} dB | {dm:+.2f}{mm} |")
if paired:
    # The Replica loader against itself: its runs of one seed (one beside
    # each phone loader) differ only by what the machine did to their
    # timing; their spread is what a loader's paired difference cannot be
    # told from.
    for key, unit in (("psnr", " dB"), ("miou", "")):
        spreads = []
        for seed in sorted({r["seed"] for r in runs}):
            v = [r[key] for r in runs if r["loader"] == "replica" and r["seed"] == seed]
            if len(v) > 1:
                spreads.append(max(v) - min(v))
        if spreads:
            md.append(f"\nReplica runs of one seed, largest minus smallest {key}: "
                      + ", ".join(f"{x:.2f}{unit}" for x in spreads))
(out / "phone_table.csv").write_text("\n".join(lines) + "\n")
(out / "phone_table.md").write_text("\n".join(md) + "\n")
print("\n".join(md))
EOF
# The same runs as a picture, OUT/phone_table.png.
cargo run -q --release -p bench --example phone_table_plot -- "$out"
