"""Write rendered frames: PNG, animated GIF / WebP, or a labelled PNG contact sheet."""

from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw

#: Output kinds by suffix, for a sweep of several frames.
ANIMATED = (".gif", ".webp")
STILL = (".png",)


def _image(frame: np.ndarray):

    return Image.fromarray(np.ascontiguousarray(frame[:, :, :3]), "RGB")


def contact_sheet(frames, times, columns: int | None = None):
    """Frames in a grid, each labelled with its time; returns a PIL image."""

    n = len(frames)
    cols = columns or math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    h, w = frames[0].shape[:2]
    sheet = Image.new("RGB", (cols * w, rows * h))
    draw = ImageDraw.Draw(sheet)
    for i, (frame, t) in enumerate(zip(frames, times)):
        x, y = (i % cols) * w, (i // cols) * h
        sheet.paste(_image(frame), (x, y))
        draw.text((x + 6, y + 4), f"t = {t:.3f}", fill=(255, 255, 255))
    return sheet


def save(frames, times, stream, suffix: str, fps: float = 10.0) -> None:
    """Write frames to an open binary stream in the format ``suffix`` names.

    One frame: a PNG. Several: an animated GIF or WebP (looping, ``fps`` frames a
    second) or, for ``.png``, a contact sheet.
    """
    suffix = suffix.lower()
    if len(frames) == 1 and suffix in STILL:
        _image(frames[0]).save(stream, format="PNG")
    elif suffix in STILL:
        contact_sheet(frames, times).save(stream, format="PNG")
    else:
        images = [_image(f) for f in frames]
        fmt = {".gif": "GIF", ".webp": "WEBP"}[suffix]
        extra = {"lossless": True} if fmt == "WEBP" else {}
        images[0].save(stream, format=fmt, save_all=True, append_images=images[1:],
                       duration=round(1000 / fps), loop=0, **extra)
