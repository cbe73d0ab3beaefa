"""The capture's photograph of a rendered view, for the scripts that
compare renders with photographs (render-strip.py, heldout-psnr.py)."""
import sys
from pathlib import Path

from PIL import Image


def photograph(images: Path, view: str) -> Image.Image:
    """IMAGES/VIEW.jpg (or .JPG, .png, .jpeg) as RGB; exits naming the
    folder and the view when there is none."""
    for ext in (".jpg", ".JPG", ".png", ".jpeg"):
        p = images / f"{view}{ext}"
        if p.is_file():
            return Image.open(p).convert("RGB")
    sys.exit(f"{images}: no photograph named {view}.jpg or {view}.png")
