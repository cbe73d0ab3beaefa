#!/usr/bin/env python3
"""Where a field's point segmentation is won or lost: the hybrid mIoU on
the points a rendered view saw (their features projected from the views)
and on the others (their features sampled at the point), and how often a
point's predicted class is that of its nearest neighbours.

    python3 scripts/segment-seen-split.py HYBRID_DIR PROJECT_DIR [LABEL]

HYBRID_DIR holds `eval segment`'s outputs in the default hybrid mode
(`segmentation.json`, `segmentation_hybrid_pred.ply` and `_error.ply`),
PROJECT_DIR those of the same run with `--mode project --out PROJECT_DIR`
(a point no view saw is predicted -1 there). Prints one CSV row: label,
points seen, mIoU seen, mIoU unseen, mIoU all, the share of each point's
8 nearest neighbours predicted its class, and the same share for the
ground truth. Needs numpy.
"""
import csv
import json
import os
import sys

import numpy as np

NEIGHBOURS = 8


def read_ply(path):
    """Positions and labels of a segmentation PLY (x, y, z, rgb, label)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii")
    if "property int label" not in header:
        sys.exit(f"{path}: no label property; not an `eval segment` PLY")
    dt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("r", "u1"), ("g", "u1"),
                   ("b", "u1"), ("label", "<i4")])
    rows = np.frombuffer(data[end:], dtype=dt)
    return np.stack([rows["x"], rows["y"], rows["z"]], 1).astype(np.float64), rows["label"]


def miou(gt, pred, mask, classes):
    """Mean IoU over the classes with a labelled point under `mask`."""
    ious = []
    for c in range(classes):
        g = (gt == c) & mask
        if not g.any():
            continue
        p = (pred == c) & mask
        ious.append((g & p).sum() / (g | p).sum())
    return 100.0 * float(np.mean(ious)) if ious else float("nan")


def neighbours(points, k):
    """Indices of each point's k nearest other points (brute force, in
    blocks of rows)."""
    sq = (points ** 2).sum(1)
    out = np.empty((len(points), k), dtype=np.int64)
    for start in range(0, len(points), 1024):
        block = points[start:start + 1024]
        d = sq[start:start + 1024, None] - 2.0 * block @ points.T + sq[None, :]
        d[np.arange(len(block)), np.arange(start, start + len(block))] = np.inf
        out[start:start + len(block)] = np.argpartition(d, k, axis=1)[:, :k]
    return out


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    hybrid, project = sys.argv[1], sys.argv[2]
    label = sys.argv[3] if len(sys.argv) == 4 else os.path.basename(os.path.normpath(hybrid))
    for path in [os.path.join(hybrid, "segmentation.json"),
                 os.path.join(hybrid, "segmentation_hybrid_pred.ply"),
                 os.path.join(hybrid, "segmentation_hybrid_error.ply"),
                 os.path.join(project, "segmentation_project_pred.ply")]:
        if not os.path.isfile(path):
            sys.exit(f"{path}: not found (run `eval segment` there first)")
    with open(os.path.join(hybrid, "segmentation.json")) as f:
        scores = json.load(f)
    if scores.get("mode") != "hybrid":
        sys.exit(f"{hybrid}/segmentation.json: mode {scores.get('mode')!r}, expected hybrid")
    classes = len(scores["per_class"])
    points, pred = read_ply(os.path.join(hybrid, "segmentation_hybrid_pred.ply"))
    _, gt = read_ply(os.path.join(hybrid, "segmentation_hybrid_error.ply"))
    _, projected = read_ply(os.path.join(project, "segmentation_project_pred.ply"))
    if not (len(pred) == len(gt) == len(projected)):
        sys.exit("the hybrid and project outputs hold different points")
    seen = projected >= 0
    near = neighbours(points, NEIGHBOURS)
    agree = (pred[near] == pred[:, None]).mean()
    truth = (gt[near] == gt[:, None]).mean()
    everything = np.ones_like(seen)
    out = csv.writer(sys.stdout, lineterminator="\n")
    out.writerow(["label", "points_seen", "miou_seen", "miou_unseen", "miou_all",
                  "neighbour_agreement", "neighbour_agreement_truth"])
    out.writerow([label, int(seen.sum()), f"{miou(gt, pred, seen, classes):.1f}",
                  f"{miou(gt, pred, ~seen, classes):.1f}",
                  f"{miou(gt, pred, everything, classes):.1f}", f"{agree:.3f}", f"{truth:.3f}"])


if __name__ == "__main__":
    main()
