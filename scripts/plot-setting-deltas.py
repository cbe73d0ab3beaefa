#!/usr/bin/env python3
"""Grouped bars: for each capture, each setting's difference from a
reference run, from a CSV with `capture`, `setting` and a difference
column (needs matplotlib).

    python3 scripts/plot-setting-deltas.py CSV COLUMN PNG "TITLE"

A setting whose difference is zero on every capture (the reference
itself) is left out, and so are rows with no difference.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    path, column, png, title = sys.argv[1:]
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for needed in ["capture", "setting", column]:
        if not rows or needed not in rows[0]:
            sys.exit(f"{path}: no column {needed!r} (or no rows)")
    rows = [r for r in rows if r[column].strip()]
    captures = list(dict.fromkeys(r["capture"] for r in rows))
    settings = list(dict.fromkeys(r["setting"] for r in rows if float(r[column]) != 0.0))
    value = {(r["capture"], r["setting"]): float(r[column]) for r in rows}
    fig, ax = plt.subplots(figsize=(10, 4.8))
    width = 0.8 / max(len(settings), 1)
    for i, s in enumerate(settings):
        xs = [c + (i - (len(settings) - 1) / 2) * width for c in range(len(captures))]
        ys = [value.get((cap, s), 0.0) for cap in captures]
        ax.bar(xs, ys, width, label=s)
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.set_xticks(range(len(captures)))
    ax.set_xticklabels(captures)
    ax.set_ylabel(column.replace("_", " "))
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


if __name__ == "__main__":
    main()
