#!/usr/bin/env python3
"""The fast field's training rays a second over the Mip-NeRF field's, each
with its defaults, per capture and CPU class, beside where the room's fast
step goes.

    scripts/plot-rays-ratio.py RATIO_CSV[,RATIO_CSV...] LABEL[,LABEL...] PROFILE_CSV OUT.png

Each RATIO_CSV has the columns `capture` and `fast_over_mip` (one row a
round); LABEL names its machine. PROFILE_CSV has `where` and
`share_percent`.
"""
import sys

from plot_csv import plt, rows


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    paths = sys.argv[1].split(",")
    labels = sys.argv[2].split(",")
    if len(paths) != len(labels):
        sys.exit("as many labels as ratio files, please")
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5), gridspec_kw={"width_ratios": [1, 1.4]})
    captures = []
    for path in paths:
        for r in rows(path):
            name = r["capture"].split(" (")[0]
            if name not in captures:
                captures.append(name)
    width = 0.8 / len(paths)
    for i, (path, label) in enumerate(zip(paths, labels)):
        for r in rows(path):
            x = captures.index(r["capture"].split(" (")[0]) + (i - (len(paths) - 1) / 2) * width
            left.scatter([x], [float(r["fast_over_mip"])], color=f"C{i}", label=label)
    handles, names = left.get_legend_handles_labels()
    unique = dict(zip(names, handles))
    left.axhline(5, color="grey", linestyle="--", linewidth=1)
    left.text(len(captures) - 0.5, 5.1, "5x", color="grey", ha="right")
    left.set_xticks(range(len(captures)), captures)
    left.set_xlim(-0.6, len(captures) - 0.4)
    left.set_ylim(0, None)
    left.set_ylabel("fast / Mip-NeRF training rays a second")
    left.set_title("Each field with its defaults", fontsize=10)
    left.legend(unique.values(), unique.keys())

    profile = rows(sys.argv[3])
    names = [r["where"] for r in profile][::-1]
    shares = [float(r["share_percent"]) for r in profile][::-1]
    right.barh(range(len(names)), shares, color="C2")
    right.set_yticks(range(len(names)), names, fontsize=8)
    right.set_xlabel("share of the step's samples, %")
    right.set_title("The bench room's fast step (perf)")
    fig.tight_layout()
    fig.savefig(sys.argv[4], dpi=110)


if __name__ == "__main__":
    main()
