"""How much of a run's held-out error a colour change or a camera shift
could explain (docs/measurements/unbounded.md, "What holds the statue back").

    python3 scripts/heldout-alignment.py RUN IMAGES OUT_PREFIX [SPARSE]

For each held-out view rendered into RUN/renders/ (`NAME_rgb.png`, with
`NAME_depth.png` beside it), against its photograph IMAGES/NAME.jpg, over
the pixels at least 20 from the border: the PSNR as rendered; after the
best gain and offset per colour channel (least squares: what a per-image
exposure could at most recover); after the best shift of the photograph
by up to 16 pixels in each axis, in steps of 2 (to first order what a
rotation of the camera could recover); and after both. With SPARSE, a
COLMAP model's directory (`images.bin`), also the PSNR inside and outside
the convex hull of the view's registered sparse points (where the points
lie: on a captured object, the object), the share of the squared error
outside it, and the PSNR the view would have with the inside at 25 dB
and the outside as rendered. Writes
OUT_PREFIX.csv and OUT_PREFIX.png (photograph, render, rendered depth, one
row per view). Needs numpy and Pillow.
"""

import csv
import pathlib
import sys

import struct

import numpy as np
from PIL import Image, ImageDraw

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


def registered_points(sparse):
    """Per image stem, the pixel positions of its points with a 3D point,
    from COLMAP's binary `images.bin`."""
    points = {}
    with open(sparse / "images.bin", "rb") as f:
        (count,) = struct.unpack("<Q", f.read(8))
        for _ in range(count):
            f.read(4 + 56 + 4)  # image id, pose, camera id
            name = b""
            while (c := f.read(1)) != b"\0":
                name += c
            (n,) = struct.unpack("<Q", f.read(8))
            obs = [struct.unpack("<ddq", f.read(24)) for _ in range(n)]
            stem = pathlib.Path(name.decode()).stem
            points[stem] = [(x, y) for x, y, p in obs if p != -1]
    return points


def hull(points):
    """The convex hull of 2D points, counter-clockwise (monotone chain)."""
    pts = sorted(set(points))

    def turn(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and turn(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and turn(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def split_by_points(r, g, points):
    """PSNR inside and outside the hull of `points`, over the interior."""
    h, w = r.shape[:2]
    mask = Image.new("L", (w, h), 0)
    ImageDraw.Draw(mask).polygon(hull(points), fill=1)
    inside = np.asarray(mask).astype(bool)
    interior = np.zeros((h, w), bool)
    interior[BORDER : h - BORDER, BORDER : w - BORDER] = True
    err = ((r - g) ** 2).mean(2)
    a, b = err[inside & interior], err[~inside & interior]
    frac = a.size / (a.size + b.size)
    total = err[interior].mean()
    return dict(
        hull_pixels_percent=f"{100 * frac:.1f}",
        inside_db=f"{-10 * np.log10(a.mean()):.2f}",
        outside_db=f"{-10 * np.log10(b.mean()):.2f}",
        error_outside_percent=f"{100 * (1 - frac) * b.mean() / total:.1f}",
        inside_at_25db_db=f"{-10 * np.log10(frac * 10 ** -2.5 + (1 - frac) * b.mean()):.2f}",
    )


def load(path, size=None):
    img = Image.open(path).convert("RGB")
    if size is not None and img.size != size:
        img = img.resize(size, Image.BILINEAR)
    return np.asarray(img, dtype=np.float64) / 255


def main():
    run, images, prefix = map(pathlib.Path, sys.argv[1:4])
    points = registered_points(pathlib.Path(sys.argv[4])) if len(sys.argv) > 4 else None
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
        if points is not None:
            rows[-1].update(split_by_points(r, g, points[name]))
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
