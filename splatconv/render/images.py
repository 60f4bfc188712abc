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


def sheet_grid(count: int) -> tuple:
    """(columns, rows) of a contact sheet of ``count`` frames: as square as it gets."""
    cols = math.ceil(math.sqrt(count))
    return cols, math.ceil(count / cols)


def save(frames, times, stream, suffix: str, fps: float = 10.0) -> tuple:
    """Write frames to an open binary stream in the format ``suffix`` names.

    One frame: a PNG. Several: an animated GIF or WebP (looping, ``fps`` frames a
    second) or, for ``.png``, a contact sheet: the frames in a grid
    (:func:`sheet_grid`), each labelled with its time, pasted as they come so
    that no frame is kept.

    Parameters
    ----------
    frames : iterable of (H, W, 3+) uint8 ndarray
        One per time, all the same size.
    times : sequence of float

    Returns
    -------
    (int, int)
        Width and height of the image written (of the sheet, for a sheet).
    """
    suffix = suffix.lower()
    frames = iter(frames)
    if len(times) == 1 and suffix in STILL:
        image = _image(next(frames))
        image.save(stream, format="PNG")
        return image.size
    if suffix in STILL:
        cols, rows = sheet_grid(len(times))
        sheet = draw = None
        for i, (frame, t) in enumerate(zip(frames, times)):
            h, w = frame.shape[:2]
            if sheet is None:
                sheet = Image.new("RGB", (cols * w, rows * h))
                draw = ImageDraw.Draw(sheet)
            x, y = (i % cols) * w, (i // cols) * h
            sheet.paste(_image(frame), (x, y))
            draw.text((x + 6, y + 4), f"t = {t:.3f}", fill=(255, 255, 255))
        sheet.save(stream, format="PNG")
        return sheet.size
    # PIL's GIF and WebP writers take every frame at once.
    pictures = [_image(f) for f in frames]
    fmt = {".gif": "GIF", ".webp": "WEBP"}[suffix]
    extra = {"lossless": True} if fmt == "WEBP" else {}
    pictures[0].save(stream, format=fmt, save_all=True, append_images=pictures[1:],
                     duration=round(1000 / fps), loop=0, **extra)
    return pictures[0].size
