#!/usr/bin/env python3
"""One row per (render directory, view): the photograph, the render and the
rendered depth that `eval render` wrote, side by side at the render's size.

    python3 scripts/render-strip.py IMAGES OUT.png DIR:VIEW [DIR:VIEW ...]

IMAGES is the capture's image folder (the photographs, named VIEW.jpg or
VIEW.png); each DIR holds VIEW_rgb.png and VIEW_depth.png.
"""
import sys
from pathlib import Path

from PIL import Image

from photographs import photograph


def main() -> None:
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    images, out = Path(sys.argv[1]), Path(sys.argv[2])
    rows = []
    for spec in sys.argv[3:]:
        directory, _, view = spec.rpartition(":")
        if not directory or not view:
            sys.exit(f"{spec}: expected DIR:VIEW")
        d = Path(directory)
        try:
            rgb = Image.open(d / f"{view}_rgb.png").convert("RGB")
            depth = Image.open(d / f"{view}_depth.png").convert("RGB")
        except OSError as e:
            sys.exit(f"{d}: {e}")
        rows.append([photograph(images, view).resize(rgb.size, Image.BOX), rgb, depth])
    w, h = rows[0][1].size
    strip = Image.new("RGB", (3 * w, h * len(rows)))
    for i, row in enumerate(rows):
        for j, im in enumerate(row):
            strip.paste(im.resize((w, h)), (j * w, i * h))
    strip.save(out)
    print(f"wrote {out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
