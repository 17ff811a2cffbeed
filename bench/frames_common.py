"""Frames written by `voxwall render` for the benchmarks that compare pictures: read as RGBA and
compared by PSNR over the four 8-bit channels (as the tests' psnr over an Image)."""
import sys

import numpy as np

try:
    from PIL import Image  # python3-pil
except ImportError:  # pragma: no cover
    Image = None


def load_rgba(path, who):
    """The frame at `path` as a float64 array of RGBA; stops `who` when PIL is missing."""
    if Image is None:
        print(f"{who}: python3-pil is needed to read the frames", file=sys.stderr)
        sys.exit(1)
    return np.asarray(Image.open(path).convert("RGBA"), dtype=np.float64)


def psnr8(a, b):
    """PSNR in dB over 8-bit channels; 99 for identical pictures."""
    mse = np.mean((a - b) ** 2)
    return 99.0 if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)
