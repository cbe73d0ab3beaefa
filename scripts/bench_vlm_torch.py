#!/usr/bin/env python3
"""PyTorch baseline for the Rust dense CLIP feature extraction.

Builds a random (seeded) transformers CLIPVisionModelWithProjection with
CLIP ViT-B/16's shape (width 768, 12 layers, 12 heads, MLP 3072, image 224,
patch 16, projection 512, quick-GELU), float32, eval, on the CPU, and times
the sliding-window dense extraction of a random uint8 RGB frame: resize the
short side to --short-side (patch-rounded, bilinear, antialiased),
normalise, cut 224 x 224 windows (stride 112), run the modified last block
(--dense) on all windows of the frame in one batch, average the per-window
unit vectors per patch cell and re-normalise. One warm-up frame, then
--frames timed frames.

The dense and sliding code is tests/clip_vision_reference.py's.

Prints one line of JSON to stdout:
  {"impl": "pytorch", "torch", "transformers", "threads", "width",
   "height", "short_side", "windows", "grid": [gh, gw],
   "seconds_per_frame", "frames_per_s", "per_frame": [...]}
Anything else goes to stderr.

    python3 scripts/bench_vlm_torch.py --width 640 --height 360 \\
        --short-side 336 --frames 3 --dense naclip [--threads N]
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
    hf_tower,
    resize_normalise,
    sliding_dense,
    windows,
)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--short-side", type=int, default=336)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--dense", choices=VARIANTS, default="naclip")
    ap.add_argument("--threads", type=int, default=None)
    args = ap.parse_args()

    import transformers
    from transformers import CLIPVisionConfig, CLIPVisionModelWithProjection
    from transformers.utils import logging

    logging.disable_progress_bar()
    threads = args.threads or os.cpu_count()
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    config = CLIPVisionConfig(
        hidden_size=768,
        intermediate_size=3072,
        projection_dim=512,
        num_hidden_layers=12,
        num_attention_heads=12,
        image_size=224,
        patch_size=16,
        hidden_act="quick_gelu",
        layer_norm_eps=1e-5,
    )
    model = CLIPVisionModelWithProjection(config).to(torch.float32).eval()
    tower = hf_tower(model)
    g = torch.Generator().manual_seed(1)
    frame = torch.randint(0, 256, (args.height, args.width, 3), dtype=torch.uint8, generator=g)

    def one_frame():
        pixels = resize_normalise(frame, args.short_side, tower.patch)
        return pixels, sliding_dense(tower, args.dense, pixels)

    per_frame = []
    with torch.inference_mode():
        t0 = time.perf_counter()
        pixels, feats = one_frame()
        print(f"warm-up frame: {time.perf_counter() - t0:.3f} s", file=sys.stderr)
        for i in range(args.frames):
            t0 = time.perf_counter()
            one_frame()
            per_frame.append(time.perf_counter() - t0)
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
                "windows": len(windows(h, w, tower.image_size, tower.patch)),
                "grid": [int(feats.shape[0]), int(feats.shape[1])],
                "seconds_per_frame": mean,
                "frames_per_s": 1.0 / mean,
                "per_frame": per_frame,
            }
        )
    )


if __name__ == "__main__":
    main()
