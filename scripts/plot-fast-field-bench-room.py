#!/usr/bin/env python3
"""Held-out PSNR and mIoU against training rays a second of the bench-room
runs in docs/measurements/fast_field_bench_room_zen5_2core.csv, one marker
a run (needs matplotlib).

    python3 scripts/plot-fast-field-bench-room.py CSV PNG
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot-fast-field-bench-room.py CSV PNG")
    with open(sys.argv[1], newline="") as f:
        rows = list(csv.DictReader(f))
    fig, axes = plt.subplots(1, 2, figsize=(14, 5.5))
    for ax, key, label in [
        (axes[0], "heldout_psnr_db", "held-out PSNR, interior pixels (dB)"),
        (axes[1], "miou_hybrid", "mIoU, hybrid, 20 views at half size (%)"),
    ]:
        for r in rows:
            x, y = float(r["train_rays_per_s"]), float(r[key])
            colour = "tab:blue" if r["field"] == "mip" else "tab:orange"
            marker = "s" if r["seconds"] == "300" else "o"
            ax.scatter(x, y, c=colour, marker=marker, s=40)
            settings = r["settings"].replace("--sampler proposal", "proposal")
            name = settings + ", " + r["seconds"] + " s"
            ax.annotate(name, (x, y), fontsize=6, xytext=(4, 2), textcoords="offset points")
        ax.set_xlabel("training rays/s")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    fig.suptitle(
        "Bench room (seed 21): Mip-NeRF field (blue) and fast field (orange); "
        "squares 300 s, circles 100 s; 2-core AMD EPYC (Zen 5), flex"
    )
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
