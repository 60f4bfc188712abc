"""Cameras in the 3DGS / Spacetime Gaussians ``cameras.json`` form.

A camera is a dict ``{"id", "img_name", "width", "height", "position",
"rotation", "fy", "fx"}``: ``position`` is the camera centre in world
coordinates, ``rotation`` the 3x3 camera-to-world rotation (rows of a nested
list; columns are the camera's x-right, y-down, z-forward axes, OpenCV style).
The splaTV viewer starts at ``cameras[0]``, so a written file never has an empty
list.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from .errors import FormatError

CAMERA_KEYS = ("id", "img_name", "width", "height", "position", "rotation", "fy", "fx")

#: Size and focal length of the camera made up for scenes that come without one.
DEFAULT_WIDTH = 1280
DEFAULT_HEIGHT = 720
DEFAULT_FOCAL = 1000.0


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def validate_cameras(cameras, source: str) -> list:
    """Check a decoded cameras list and return it unchanged.

    Parameters
    ----------
    cameras : object
        Decoded JSON.
    source : str
        Where it came from, for error messages.

    Raises
    ------
    FormatError
        Naming the camera index and key that is wrong.
    """
    if not isinstance(cameras, list):
        raise FormatError("expected a JSON list of cameras", source)
    for i, cam in enumerate(cameras):
        where = (f"camera {i}",)
        if not isinstance(cam, dict):
            raise FormatError("expected an object", source, where)
        missing = [k for k in CAMERA_KEYS if k not in cam]
        if missing:
            raise FormatError(f"missing {', '.join(missing)}", source, where)
        for key in ("width", "height"):
            v = cam[key]
            if not (isinstance(v, int) and not isinstance(v, bool) and v > 0):
                raise FormatError(f"'{key}' must be a positive integer, got {v!r}", source, where)
        for key in ("fx", "fy"):
            if not (_is_number(cam[key]) and cam[key] > 0):
                raise FormatError(f"'{key}' must be a positive number, got {cam[key]!r}", source, where)
        pos = cam["position"]
        if not (isinstance(pos, list) and len(pos) == 3 and all(map(_is_number, pos))):
            raise FormatError("'position' must be a list of 3 finite numbers", source, where)
        rot = cam["rotation"]
        if not (isinstance(rot, list) and len(rot) == 3 and all(
                isinstance(r, list) and len(r) == 3 and all(map(_is_number, r)) for r in rot)):
            raise FormatError("'rotation' must be a 3x3 list of finite numbers", source, where)
    return cameras


def load_cameras(path: str | os.PathLike) -> list:
    """Read and validate a ``cameras.json`` file.

    Raises
    ------
    FormatError
        When the file is missing, is not strict JSON, or a camera is malformed.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            text = f.read().decode("utf-8")
    except OSError as e:
        raise FormatError(f"cannot read cameras: {e.strerror}", path) from None
    except UnicodeDecodeError as e:
        raise FormatError(f"not UTF-8 text (byte {e.start})", path) from None
    try:
        cameras = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as e:
        raise FormatError(f"invalid JSON: {e.msg} (line {e.lineno}, column {e.colno})", path) from None
    except ValueError as e:
        raise FormatError(f"invalid JSON: {e}", path) from None
    validate_cameras(cameras, path)
    if not cameras:
        raise FormatError("holds no cameras; the viewer needs at least one", path)
    return cameras


def _reject_constant(name: str):
    raise ValueError(f"{name} is not allowed in strict JSON")


def framing_camera(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> dict:
    """Make one camera that frames a point set, looking along +z.

    The camera sits on the -z side of the bulk of the points (2nd to 98th
    percentile of the finite ones, so stray splats do not shrink the view) with
    the world axes as its axes, far enough back that the box fills about 80% of a
    1280x720 image.

    Parameters
    ----------
    x, y, z : (N,) float32 ndarray
        Splat centres.

    Returns
    -------
    dict
        A camera in ``cameras.json`` form.
    """
    with np.errstate(invalid="ignore"):  # signalling NaNs warn when widened
        pts = np.stack([np.asarray(c, dtype=np.float64) for c in (x, y, z)], axis=1)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if len(pts) == 0:
        lo = hi = np.zeros(3)
    else:
        lo, hi = np.percentile(pts, [2, 98], axis=0)
    centre = (lo + hi) / 2
    half_w, half_h, half_d = np.maximum((hi - lo) / 2, 1e-3)
    # Distance at which the half-extent spans 40% of the image in each direction.
    dist = max(half_w * DEFAULT_FOCAL / (0.4 * DEFAULT_WIDTH),
               half_h * DEFAULT_FOCAL / (0.4 * DEFAULT_HEIGHT)) + half_d
    position = [float(centre[0]), float(centre[1]), float(centre[2] - dist)]
    return {
        "id": 0,
        "img_name": "splatconv_default",
        "width": DEFAULT_WIDTH,
        "height": DEFAULT_HEIGHT,
        "position": [round(v, 6) for v in position],
        "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        "fy": DEFAULT_FOCAL,
        "fx": DEFAULT_FOCAL,
    }
