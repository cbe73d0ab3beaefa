#!/usr/bin/env python3
"""PyTorch baseline for the Rust dense CLIP feature extraction.

Builds a random (seeded) transformers CLIPVisionModelWithProjection with
CLIP ViT-B/16's shape (width 768, 12 layers, 12 heads, MLP 3072, image 224,
patch 16, projection 512, quick-GELU), float32, eval, on the CPU, and times
the sliding-window dense extraction of a random uint8 RGB frame: resize the
short side to --short-side (patch-rounded, bilinear, antialiased),
normalise, cut 224 x 224 windows (stride 112), run the modified last block
(--dense) on the windows of the frame in batches of --batch (default: all in
one batch), average the per-window unit vectors per patch cell and
re-normalise. One warm-up frame, then --frames timed frames.

The dense and sliding code is tests/clip_vision_reference.py's.

Prints one line of JSON to stdout:
  {"impl": "pytorch", "torch", "transformers", "threads", "width",
   "height", "short_side", "batch", "windows", "grid": [gh, gw],
   "seconds_per_frame", "frames_per_s", "cpu_seconds_per_frame" (process
   CPU time, all threads), "per_frame": [...]}
Anything else goes to stderr.

    python3 scripts/bench_vlm_torch.py --width 640 --height 360 \\
        --short-side 336 --frames 3 --dense naclip [--batch B] [--threads N]
"""

import argparse
import json
import os
import sys
import time

import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))

from clip_vision_reference import (  # noqa: E402
    VARIANTS,
    VIT_B16,
    dense_features,
    hf_tower,
    resize_normalise,
    sliding_dense,
    windows,
)


def sliding_dense_batched(tower, variant, pixels, batch):
    """sliding_dense with the windows run `batch` at a time (the Rust
    extractor's --batch); batch 0 or >= the window count is sliding_dense."""
    c, p = tower.image_size, tower.patch
    _, _, h, w = pixels.shape
    origins = windows(h, w, c, p)
    if batch <= 0 or batch >= len(origins):
        return sliding_dense(tower, variant, pixels)
    feats = torch.cat(
        [
            dense_features(
                tower,
                variant,
                torch.cat([pixels[:, :, y : y + c, x : x + c] for y, x in origins[s : s + batch]]),
            )
            for s in range(0, len(origins), batch)
        ]
    )
    gh, gw, g = h // p, w // p, c // p
    acc = torch.zeros(gh, gw, feats.shape[-1], dtype=feats.dtype)
    count = torch.zeros(gh, gw, 1, dtype=feats.dtype)
    for (y, x), f in zip(origins, feats):
        acc[y // p : y // p + g, x // p : x // p + g] += f
        count[y // p : y // p + g, x // p : x // p + g] += 1
    acc = acc / count
    return acc / acc.norm(dim=-1, keepdim=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--short-side", type=int, default=336)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--dense", choices=VARIANTS, default="naclip")
    ap.add_argument("--batch", type=int, default=0, help="windows per forward pass (0: all)")
    ap.add_argument("--threads", type=int, default=None)
    args = ap.parse_args()

    import transformers
    from transformers import CLIPVisionConfig, CLIPVisionModelWithProjection
    from transformers.utils import logging

    logging.disable_progress_bar()
    threads = args.threads or os.cpu_count()
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    config = CLIPVisionConfig(**VIT_B16)
    model = CLIPVisionModelWithProjection(config).to(torch.float32).eval()
    tower = hf_tower(model)
    g = torch.Generator().manual_seed(1)
    frame = torch.randint(0, 256, (args.height, args.width, 3), dtype=torch.uint8, generator=g)

    def one_frame():
        pixels = resize_normalise(frame, args.short_side, tower.patch)
        return pixels, sliding_dense_batched(tower, args.dense, pixels, args.batch)

    per_frame = []
    cpu = 0.0
    with torch.inference_mode():
        t0 = time.perf_counter()
        pixels, feats = one_frame()
        print(f"warm-up frame: {time.perf_counter() - t0:.3f} s", file=sys.stderr)
        for i in range(args.frames):
            t0, c0 = time.perf_counter(), time.process_time()
            one_frame()
            per_frame.append(time.perf_counter() - t0)
            cpu += time.process_time() - c0
            print(f"frame {i}: {per_frame[-1]:.3f} s", file=sys.stderr)
    _, _, h, w = pixels.shape
    mean = sum(per_frame) / len(per_frame)
    print(
        json.dumps(
            {
                "impl": "pytorch",
                "torch": torch.__version__,
                "transformers": transformers.__version__,
                "threads": threads,
                "width": args.width,
                "height": args.height,
                "short_side": args.short_side,
                "batch": args.batch,
                "windows": len(windows(h, w, tower.image_size, tower.patch)),
                "grid": [int(feats.shape[0]), int(feats.shape[1])],
                "seconds_per_frame": mean,
                "frames_per_s": 1.0 / mean,
                "cpu_seconds_per_frame": cpu / len(per_frame),
                "per_frame": per_frame,
            }
        )
    )


if __name__ == "__main__":
    main()
