"""Camera maths exactly as the splaTV viewer does it (column-major 4x4 lists).

Matrices here are flat lists of 16 Python floats in column-major order, the form
the viewer keeps in its URL hash and hands to ``uniformMatrix4fv``. Arithmetic is
done in double precision in the viewer's operation order so that the depth sort
sees the same numbers.
"""

from __future__ import annotations

from ..errors import UsageError
from ..jsonutil import decode as decode_json
from ..jsonutil import is_finite_number

ZNEAR = 0.2
ZFAR = 200.0
#: Default largest preview width.
MAX_DEFAULT_WIDTH = 1280
#: Largest image side drawn: GL implementations guarantee 16,384 (llvmpipe's and
#: most GPUs' limit); a larger framebuffer is "not complete".
MAX_IMAGE_SIDE = 16384


def projection_matrix(fx: float, fy: float, width: float, height: float) -> list:
    """The viewer's perspective projection (y flipped, depth in [0, 1])."""
    return [
        (2 * fx) / width, 0.0, 0.0, 0.0,
        0.0, -(2 * fy) / height, 0.0, 0.0,
        0.0, 0.0, ZFAR / (ZFAR - ZNEAR), 1.0,
        0.0, 0.0, -(ZFAR * ZNEAR) / (ZFAR - ZNEAR), 0.0,
    ]


def view_matrix(camera: dict) -> list:
    """World -> camera matrix of a ``cameras.json`` camera, as the viewer builds it."""
    r = [float(v) for row in camera["rotation"] for v in row]
    t = [float(v) for v in camera["position"]]
    return [
        r[0], r[1], r[2], 0.0,
        r[3], r[4], r[5], 0.0,
        r[6], r[7], r[8], 0.0,
        -t[0] * r[0] - t[1] * r[3] - t[2] * r[6],
        -t[0] * r[1] - t[1] * r[4] - t[2] * r[7],
        -t[0] * r[2] - t[1] * r[5] - t[2] * r[8],
        1.0,
    ]


def multiply(a: list, b: list) -> list:
    """``a @ b`` for column-major flat matrices, summed in the viewer's order."""
    out = []
    for col in range(4):
        for row in range(4):
            out.append(b[4 * col] * a[row] + b[4 * col + 1] * a[4 + row]
                       + b[4 * col + 2] * a[8 + row] + b[4 * col + 3] * a[12 + row])
    return out


def parse_view(text: str) -> list:
    """A ``--view`` value: a JSON list of 16 finite numbers (column-major).

    Raises
    ------
    UsageError
    """
    try:
        values = decode_json(text)
    except ValueError as e:
        raise UsageError(f"--view: invalid JSON: {getattr(e, 'msg', e)}") from None
    if not (isinstance(values, list) and len(values) == 16 and all(map(is_finite_number, values))):
        raise UsageError("--view: expected a JSON list of 16 finite numbers (a column-major view matrix)")
    return [float(v) for v in values]


def parse_size(text: str) -> tuple:
    """``WxH`` -> (W, H), both positive integers no larger than :data:`MAX_IMAGE_SIDE`."""
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.isdigit() and len(p) < 12 for p in parts):
        raise UsageError(f"--size: expected WIDTHxHEIGHT, got {text!r}")
    w, h = int(parts[0]), int(parts[1])
    if not (0 < w <= MAX_IMAGE_SIDE and 0 < h <= MAX_IMAGE_SIDE):
        raise UsageError(f"--size: {w}x{h} is outside 1..{MAX_IMAGE_SIDE}")
    return w, h


def fit(camera: dict, size: tuple | None = None, max_width: int = MAX_DEFAULT_WIDTH) -> tuple:
    """Image size and focal lengths that draw ``camera``'s view at ``size``.

    Parameters
    ----------
    camera : dict
        A ``cameras.json`` camera (``width``, ``height``, ``fx``, ``fy``).
    size : (int, int), optional
        (width, height); default the camera's, scaled down to at most
        ``max_width`` wide and :data:`MAX_IMAGE_SIDE` high.

    Returns
    -------
    (width, height, fx, fy) : (int, int, float, float)
        Width and height are at most :data:`MAX_IMAGE_SIDE`.
    """
    w, h = int(camera["width"]), int(camera["height"])
    if size is None:
        # A camera taller than the largest framebuffer is scaled down to fit too
        # (fx, fy along), rather than failing in the GL driver.
        scale = min(1.0, max_width / w, MAX_IMAGE_SIDE / h)
        width = min(MAX_IMAGE_SIDE, max(1, round(w * scale)))
        height = min(MAX_IMAGE_SIDE, max(1, round(h * scale)))
    else:
        # verify and diff compare what the camera saw, at whatever size: fx and fy scale
        # with the image rather than cropping its centre; with another aspect ratio the
        # smaller ratio keeps the camera's whole view in frame. (render keeps the
        # camera's fx, fy at an explicit size, as the viewer does in a window of that
        # size: see frames.resolve_view.)
        (width, height), scale = size, min(size[0] / w, size[1] / h)
    return width, height, float(camera["fx"]) * scale, float(camera["fy"]) * scale
