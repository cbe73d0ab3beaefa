#!/usr/bin/env python3
"""Held-out PSNR of renders at any size against the photographs resized to
it (docs/measurements/unbounded.md, "Smaller batches").

    python3 scripts/heldout-psnr.py IMAGES DIR [DIR ...]

For each DIR, every `NAME_rgb.png` in it against IMAGES/NAME.jpg (or .png),
the photograph resized to the render's size by Pillow's bilinear filter:
each view's PSNR over every pixel, and the pooled PSNR (from the mean of
the views' mean squared errors).
"""
import sys
from pathlib import Path

import numpy as np
from PIL import Image

from photographs import photograph


def main() -> None:
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    images = Path(sys.argv[1])
    for directory in map(Path, sys.argv[2:]):
        renders = sorted(directory.glob("*_rgb.png"))
        if not renders:
            sys.exit(f"{directory}: no NAME_rgb.png renders")
        errors, parts = [], []
        for r in renders:
            name = r.name[: -len("_rgb.png")]
            a = np.asarray(Image.open(r).convert("RGB"), dtype=np.float64) / 255
            b = photograph(images, name).resize((a.shape[1], a.shape[0]), Image.BILINEAR)
            b = np.asarray(b, dtype=np.float64) / 255
            mse = float(((a - b) ** 2).mean())
            errors.append(mse)
            parts.append(f"{name} {-10 * np.log10(mse):.2f}")
        pooled = -10 * np.log10(np.mean(errors))
        print(f"{directory}: {', '.join(parts)}; pooled {pooled:.2f} dB")


if __name__ == "__main__":
    main()
