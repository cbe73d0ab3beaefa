#!/usr/bin/env python3
"""Tables of the novel-view ablation written by scripts/novel-ablation.sh.

    python3 scripts/novel-ablation-table.py runs/novel-ablation [--method hybrid]

Reads <dir>/seed-*/<mode>/seg/segmentation_compare.json and prints, per seed
and as the mean over seeds, mIoU / mAcc (percent) for all / head / common /
tail classes of one field mode per ablation mode, then the tail classes'
IoU per mode, and the views each run added (from its novel/views.json).
Further runs (<mode>-oracle-<which>, <mode>-<tag>: see
scripts/novel-ablation.sh --oracle and --tag) get rows of their own after
the four.
"""
import json
import pathlib
import struct
import sys

MODES = ["none", "trajectory", "random", "guided"]
GROUPS = ["all", "head", "common", "tail"]


def pct(v):
    return "-" if v is None else f"{100 * v:.1f}"


def load(run, method):
    path = run / "seg" / "segmentation_compare.json"
    if not path.exists():
        return None
    rows = json.loads(path.read_text())
    return next((r for r in rows if r["mode"] == method), None)


def cell(row, group):
    g = row.get(group)
    return (None, None) if g is None else (g["miou"], g["macc"])


def table(title, rows):
    out = [f"{title}", "", "| views | " + " | ".join(GROUPS) + " |", "|---" * 5 + "|"]
    for mode, cells in rows:
        out.append(
            f"| {mode} | "
            + " | ".join(f"{pct(i)} / {pct(a)}" for i, a in cells)
            + " |"
        )
    return "\n".join(out) + "\n"


def gt_points(seg_dir):
    """Positions and ground-truth labels from segment's *_error.ply."""
    path = next(iter(sorted(seg_dir.glob("segmentation_*_error.ply"))), None)
    if path is None:
        return []
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode()
    n = int(next(l.split()[2] for l in header.splitlines() if l.startswith("element vertex")))
    rec = struct.Struct("<fffBBBi")
    return [rec.unpack_from(data, end + i * rec.size) for i in range(n)]


def target_classes(seed, method):
    """Class of the labelled point nearest to each guided target."""
    record = seed / "guided" / "novel" / "views.json"
    base = load(seed / "none", method)
    pts = gt_points(seed / "none" / "seg")
    if not record.exists() or base is None or not pts:
        return None
    names = [c["name"] for c in base["per_class"]]
    counts = {}
    for v in json.loads(record.read_text())["views"]:
        t = v.get("target")
        if t is None:
            continue
        p = min(pts, key=lambda q: (q[0] - t[0]) ** 2 + (q[1] - t[1]) ** 2 + (q[2] - t[2]) ** 2)
        name = names[p[6]] if 0 <= p[6] < len(names) else "unlabelled"
        counts[name] = counts.get(name, 0) + 1
    return sorted(counts.items(), key=lambda kv: -kv[1])


def main():
    args = sys.argv[1:]
    method = "hybrid"
    if "--method" in args:
        k = args.index("--method")
        method = args[k + 1]
        del args[k : k + 2]
    if len(args) != 1:
        sys.exit(__doc__)
    root = pathlib.Path(args[0])
    seeds = sorted(p for p in root.glob("seed-*") if p.is_dir())
    extra = sorted(
        {p.name for s in seeds for p in s.iterdir() if (p / "seg").is_dir()} - set(MODES)
    )
    modes = MODES + extra
    sums = {m: [[0.0, 0.0, 0] for _ in GROUPS] for m in modes}
    print(f"Field mode `{method}`, mIoU / mAcc in percent.\n")
    for seed in seeds:
        rows = []
        for mode in modes:
            row = load(seed / mode, method)
            if row is None:
                continue
            cells = [cell(row, g) for g in GROUPS]
            for s, (i, a) in zip(sums[mode], cells):
                if i is not None:
                    s[0] += i
                    s[1] += a
                    s[2] += 1
            record = seed / mode / "novel" / "views.json"
            added = len(json.loads(record.read_text())["views"]) if record.exists() else 0
            rows.append((f"{mode} (+{added})", cells))
        print(table(f"{seed.name}", rows))
    mean = [
        (
            f"{m} ({sums[m][0][2]} seeds)",
            [(s[0] / s[2], s[1] / s[2]) if s[2] else (None, None) for s in sums[m]],
        )
        for m in modes
        if sums[m][0][2]
    ]
    print(table("mean over seeds", mean))
    for seed in seeds:
        tc = target_classes(seed, method)
        if tc:
            print(f"{seed.name}: guided targets by the class of the nearest labelled point: "
                  + ", ".join(f"{n} {c}" for n, c in tc) + "\n")
    # Every class per mode: where the views help or hurt.
    for seed in seeds:
        base = load(seed / "none", method)
        if base is None:
            continue
        names = [
            c["name"]
            for c in base["per_class"]
            if c["iou"] is not None
        ]
        per = {m: load(seed / m, method) for m in modes}
        print(f"{seed.name}: IoU per class (percent)\n")
        print("| class | points | " + " | ".join(modes) + " |")
        print("|---" * (2 + len(modes)) + "|")
        for n in names:
            pts = next(c["points"] for c in base["per_class"] if c["name"] == n)
            vals = []
            for m in modes:
                r = per[m]
                c = None if r is None else next(c for c in r["per_class"] if c["name"] == n)
                vals.append(pct(None if c is None else c["iou"]))
            print(f"| {n} | {pts} | " + " | ".join(vals) + " |")
        print()


if __name__ == "__main__":
    main()
