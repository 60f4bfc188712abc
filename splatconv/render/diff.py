"""Image comparison: PSNR, error statistics and heatmaps (numpy; Pillow for files)."""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import FormatError, UnsupportedError

#: Most pixels an image file may have to be read (8,192 x 8,192): checked from its
#: header before decoding, so a small file claiming a huge image costs nothing.
#: Below Pillow's own decompression-bomb warning (about 89M pixels).
MAX_IMAGE_PIXELS = 8192 * 8192

#: Default pixel tolerance (per channel, out of 255) for the "pixels off" share.
TOLERANCE = 8


@dataclass
class ImageDiff:
    """How far image B is from image A (RGB, 8 bit)."""

    psnr: float  # dB; math.inf when identical
    max_abs_error: int
    mean_abs_error: float
    share_off: float  # share of pixels with a channel off by more than the tolerance
    tolerance: int

    @property
    def identical(self) -> bool:
        """The RGB channels are equal (PSNR is infinite)."""
        return math.isinf(self.psnr)

    def as_dict(self) -> dict:
        """JSON form: ``psnr`` is null for identical images (``identical`` says so), as JSON has no infinity."""
        return {"psnr": None if self.identical else round(self.psnr, 3), "identical": self.identical,
                "max_abs_error": self.max_abs_error, "mean_abs_error": round(self.mean_abs_error, 4),
                "share_off": round(self.share_off, 6), "tolerance": self.tolerance}


def compare(a: np.ndarray, b: np.ndarray, tolerance: int = TOLERANCE) -> ImageDiff:
    """Compare two ``(H, W, 3+) uint8`` images on their RGB channels."""
    if a.shape[:2] != b.shape[:2]:
        raise UnsupportedError(f"images differ in size: {a.shape[1]}x{a.shape[0]} and {b.shape[1]}x{b.shape[0]}")
    d = np.abs(a[..., :3].astype(np.int16) - b[..., :3].astype(np.int16))
    return ImageDiff(psnr(a, b), int(d.max()), float(d.mean()), float((d.max(axis=-1) > tolerance).mean()), tolerance)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR of two ``(H, W, 3+) uint8`` images of one size on their RGB channels (dB; ``math.inf`` when equal).

    The squared errors summed as integers (exact): RGBA frames, as a proof draws them,
    in one pass over their contiguous bytes, the alpha's squares set to 0."""
    if a.shape == b.shape and a.ndim == 3 and a.shape[-1] == 4 and a.flags.c_contiguous and b.flags.c_contiguous:
        sq = np.subtract(a, b, dtype=np.int16)
        np.abs(sq, out=sq)
        sq = sq.view(np.uint16)  # |d| <= 255: its square fits 16 bits
        np.multiply(sq, sq, out=sq)
        sq[..., 3] = 0
        total = int(sq.reshape(-1).sum(dtype=np.uint64))
    else:
        d = a[..., :3].astype(np.int64) - b[..., :3].astype(np.int64)
        total = int((d * d).sum())
    mse = total / (a.shape[0] * a.shape[1] * 3)
    return math.inf if mse == 0 else 10 * math.log10(255.0**2 / mse)


def heatmap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel largest channel error as a black-red-yellow-white ramp, ``(H, W, 3) uint8``.

    The ramp is scaled so that an error of 32/255 or more is white: small
    quantization errors stay visible next to real damage.
    """
    d = np.abs(a[..., :3].astype(np.int16) - b[..., :3].astype(np.int16)).max(axis=-1)
    x = np.clip(d / 32.0, 0.0, 1.0) * 3.0
    rgb = np.stack([np.clip(x, 0, 1), np.clip(x - 1, 0, 1), np.clip(x - 2, 0, 1)], axis=-1)
    return (rgb * 255).round().astype(np.uint8)


def side_by_side(*images: np.ndarray) -> np.ndarray:
    """Images next to each other with a 4-pixel grey gap, ``(H, W', 3) uint8``."""
    h = max(i.shape[0] for i in images)
    gap = np.full((h, 4, 3), 64, np.uint8)
    parts = []
    for k, img in enumerate(images):
        pad = np.zeros((h, img.shape[1], 3), np.uint8)
        pad[:img.shape[0]] = img[..., :3]
        parts.extend([gap, pad] if k else [pad])
    return np.concatenate(parts, axis=1)


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def is_image(path) -> bool:
    """Whether ``path`` names an image file (by suffix) rather than a scene file."""
    return os.fspath(path).lower().endswith(IMAGE_SUFFIXES)


def load_image(path) -> np.ndarray:
    """An image file as ``(H, W, 3) uint8`` RGB (alpha dropped, palette expanded)."""
    from PIL import Image, UnidentifiedImageError  # Pillow for files only: convert's proof compares arrays

    path = os.fspath(path)
    too_big = f"more than the {MAX_IMAGE_PIXELS:,} pixels an image may have"
    try:
        with warnings.catch_warnings():
            # Our own limit, lower than Pillow's, is checked below; its warning would
            # only reach stderr, and its error (past twice its limit) is ours to word.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(path)
        with im:
            width, height = im.size
            if width * height > MAX_IMAGE_PIXELS:
                raise FormatError(f"image is {width}x{height} ({width * height:,} pixels), {too_big}", path)
            return np.asarray(im.convert("RGB"))
    except Image.DecompressionBombError:
        raise FormatError(f"image has {too_big}", path) from None
    except FileNotFoundError:
        raise FormatError("cannot open: No such file or directory", path) from None
    except (UnidentifiedImageError, OSError) as e:
        raise FormatError(f"not a readable image ({e})", path) from None


def save_png(img: np.ndarray, stream) -> None:
    """Write ``(H, W, 3+) uint8`` RGB to an open binary stream as PNG (use an atomic writer)."""

    from PIL import Image

    Image.fromarray(np.ascontiguousarray(img[..., :3]), "RGB").save(stream, format="PNG")
