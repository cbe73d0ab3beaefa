#!/usr/bin/env python3
"""Table of the presets on the benchmark room (scripts/presets-room.sh).

    python3 scripts/presets-room-table.py runs/presets-room fast balanced best

Prints a Markdown table (and writes <dir>/presets.csv) with, per run:
seconds of training, iterations, peak memory, the held-out PSNR and depth
error of the final evaluation's pixel sample, and the hybrid mIoU over all
and over the tail classes.
"""
import csv
import json
import pathlib
import sys


def train_seconds(run):
    last = None
    for line in (run / "metrics.jsonl").read_text().splitlines():
        if not line.strip():
            continue
        event = json.loads(line)
        if event.get("event") == "train":
            last = event["wall_seconds"]
    return last


def row(run, name, flags):
    summary = json.loads((run / "summary.json").read_text())
    seg = json.loads((run / "segmentation.json").read_text())
    tail = seg.get("tail") or {}
    held = summary["heldout_interior"]
    return {
        "run": name,
        "flags": flags,
        "train_s": train_seconds(run),
        "iterations": summary["iterations"],
        "peak_mb": (summary.get("peak_memory_bytes") or 0) / 1e6,
        "psnr_sample": held["psnr"],
        "depth_mae_m": held.get("depth_mae"),
        "miou_all": 100 * seg["all"]["miou"],
        "miou_tail": None if tail.get("miou") is None else 100 * tail["miou"],
    }


def fmt(v, spec):
    return "-" if v is None else format(v, spec)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = pathlib.Path(sys.argv[1])
    rows = []
    for p in sys.argv[2:]:
        for name, flags in [
            (p, f"--preset {p}, lego settings"),
            (f"{p}-rays-128", "--rays 128, same seconds"),
            (f"{p}+rays-128", f"--preset {p}, room settings"),
        ]:
            run = out / name
            if (run / "segmentation.json").exists():
                rows.append(row(run, name, flags))
            else:
                print(f"({run}: not finished, left out)", file=sys.stderr)
    print("| run | flags | training s | iterations | peak MB | PSNR (sample) "
          "| depth MAE m | mIoU all | mIoU tail |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['run']} | `{r['flags']}` | {fmt(r['train_s'], '.0f')} "
              f"| {r['iterations']} | {fmt(r['peak_mb'], '.0f')} "
              f"| {fmt(r['psnr_sample'], '.2f')} | {fmt(r['depth_mae_m'], '.3f')} "
              f"| {fmt(r['miou_all'], '.1f')} | {fmt(r['miou_tail'], '.1f')} |")
    if rows:
        with open(out / "presets.csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
