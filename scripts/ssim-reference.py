#!/usr/bin/env python3
"""SSIM of the fixed image pairs of `field-ops/tests/ssim.rs`, by
scikit-image, the values that test holds:

    python3 -m pip install scikit-image
    python3 scripts/ssim-reference.py

The images are made from integers and `sin` exactly as the test makes them
(then rounded to float32 as the test's images are), so both sides compare
the same pixels.
"""
import math

import numpy as np
from skimage.metrics import structural_similarity

MASK = (1 << 64) - 1


def smooth(w, h, shift):
    """0.5 + 0.4 sin(0.3 (x + shift) + 0.2 y + c): a smooth colour image."""
    img = np.zeros((h, w, 3), dtype=np.float32)
    for y in range(h):
        for x in range(w):
            for c in range(3):
                img[y, x, c] = np.float32(0.5 + 0.4 * math.sin(0.3 * (x + shift) + 0.2 * y + c))
    return img


def noisy(img, seed, amplitude):
    """`img` plus uniform noise in [-amplitude, amplitude] from a 64-bit LCG,
    clamped to [0, 1]."""
    out = img.copy()
    state = seed
    h, w, _ = img.shape
    for y in range(h):
        for x in range(w):
            for c in range(3):
                state = (state * 6364136223846793005 + 1442695040888963407) & MASK
                u = (state >> 11) / float(1 << 53)
                v = float(img[y, x, c]) + amplitude * (2.0 * u - 1.0)
                out[y, x, c] = np.float32(min(max(v, 0.0), 1.0))
    return out


def ssim(a, b):
    return structural_similarity(
        a.astype(np.float64),
        b.astype(np.float64),
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        data_range=1.0,
        channel_axis=-1,
    )


def main():
    pairs = {
        "identical 32x24": (smooth(32, 24, 0), smooth(32, 24, 0)),
        "noisy 40x30": (smooth(40, 30, 0), noisy(smooth(40, 30, 0), 7, 0.1)),
        "shifted 37x23": (smooth(37, 23, 0), smooth(37, 23, 2)),
        "noise against noise 16x12": (noisy(smooth(16, 12, 0), 1, 0.3), noisy(smooth(16, 12, 0), 2, 0.3)),
    }
    for name, (a, b) in pairs.items():
        print(f"{name}: {ssim(a, b):.12f}")


if __name__ == "__main__":
    main()
