"""How much of a run's held-out error a colour change or a camera shift
could explain (docs/unbounded.md, "What holds the statue back").

    python3 scripts/heldout-alignment.py RUN IMAGES OUT_PREFIX

For each held-out view rendered into RUN/renders/ (`NAME_rgb.png`, with
`NAME_depth.png` beside it), against its photograph IMAGES/NAME.jpg, over
the pixels at least 20 from the border: the PSNR as rendered; after the
best gain and offset per colour channel (least squares: what a per-image
exposure could at most recover); after the best shift of the photograph
by up to 16 pixels in each axis, in steps of 2 (to first order what a
rotation of the camera could recover); and after both. Writes
OUT_PREFIX.csv and OUT_PREFIX.png (photograph, render, rendered depth, one
row per view). Needs numpy and Pillow.
"""

import csv
import pathlib
import sys

import numpy as np
from PIL import Image

BORDER = 20
MAX_SHIFT = 16


def psnr(a, b):
    return float(-10 * np.log10(((a - b) ** 2).mean()))


def crop(a, dx=0, dy=0):
    h, w = a.shape[:2]
    return a[BORDER + dy : h - BORDER + dy, BORDER + dx : w - BORDER + dx]


def affine_fit(x, y):
    """x mapped by the least-squares gain and offset of each channel onto y."""
    out = np.empty_like(x)
    for c in range(3):
        a = np.stack([x[..., c].ravel(), np.ones(x[..., c].size)], 1)
        coef, *_ = np.linalg.lstsq(a, y[..., c].ravel(), rcond=None)
        out[..., c] = (a @ coef).reshape(x.shape[:2])
    return out


def load(path, size=None):
    img = Image.open(path).convert("RGB")
    if size is not None and img.size != size:
        img = img.resize(size, Image.BILINEAR)
    return np.asarray(img, dtype=np.float64) / 255


def main():
    run, images, prefix = map(pathlib.Path, sys.argv[1:4])
    rows, strips = [], []
    for render in sorted((run / "renders").glob("*_rgb.png")):
        name = render.name[: -len("_rgb.png")]
        r = load(render)
        size = (r.shape[1], r.shape[0])
        g = load(images / f"{name}.jpg", size)
        raw = psnr(crop(r), crop(g))
        colour = psnr(affine_fit(crop(r), crop(g)), crop(g))
        best = (raw, 0, 0)
        steps = range(-MAX_SHIFT, MAX_SHIFT + 1, 2)
        for dx in steps:
            for dy in steps:
                p = psnr(crop(r), crop(g, dx, dy))
                if p > best[0]:
                    best = (p, dx, dy)
        shifted, dx, dy = best
        both = psnr(affine_fit(crop(r), crop(g, dx, dy)), crop(g, dx, dy))
        rows.append(
            dict(view=name, psnr_db=f"{raw:.2f}", colour_fitted_db=f"{colour:.2f}",
                 best_shift_x=dx, best_shift_y=dy, shifted_db=f"{shifted:.2f}",
                 shifted_and_colour_fitted_db=f"{both:.2f}")
        )
        depth = load(run / "renders" / f"{name}_depth.png", size)
        strips.append(np.concatenate([g, r, depth], 1))
    if not rows:
        sys.exit(f"no held-out renders in {run / 'renders'}")
    with open(f"{prefix}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    width = 900
    pics = []
    for s in strips:
        img = Image.fromarray((s * 255).astype(np.uint8))
        pics.append(img.resize((width, round(width * img.height / img.width))))
    sheet = Image.new("RGB", (width, sum(p.height for p in pics)))
    y = 0
    for p in pics:
        sheet.paste(p, (0, y))
        y += p.height
    # A palette keeps the page light; the figures are in the CSV.
    sheet.quantize(256).save(f"{prefix}.png", optimize=True)
    for row in rows:
        print(row)


if __name__ == "__main__":
    main()
