"""Cameras in the 3DGS / Spacetime Gaussians ``cameras.json`` form.

A camera is a dict ``{"id", "img_name", "width", "height", "position",
"rotation", "fy", "fx"}``: ``position`` is the camera centre in world
coordinates, ``rotation`` the 3x3 camera-to-world rotation (rows of a nested
list; columns are the camera's x-right, y-down, z-forward axes, OpenCV style).
The splaTV viewer starts at ``cameras[0]``, so a written file never has an empty
list.
"""

from __future__ import annotations

import os

import numpy as np

from .errors import FormatError
from .files.inputs import open_input
from .jsonutil import is_finite_number, loads_strict

CAMERA_KEYS = ("id", "img_name", "width", "height", "position", "rotation", "fy", "fx")

#: Size and focal length of the camera made up for scenes that come without one.
DEFAULT_WIDTH = 1280
DEFAULT_HEIGHT = 720
DEFAULT_FOCAL = 1000.0
#: Largest ``width`` / ``height`` of a camera: past any image anyone draws, and
#: small enough that sizes scaled from it stay exact in a double.
MAX_CAMERA_PIXELS = (1 << 31) - 1
#: Largest cameras file read: a camera is about 300 bytes of JSON.
MAX_CAMERAS_BYTES = 64 << 20

_is_number = is_finite_number


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
            if not (isinstance(v, int) and not isinstance(v, bool) and 0 < v <= MAX_CAMERA_PIXELS):
                raise FormatError(f"'{key}' must be a positive integer up to {MAX_CAMERA_PIXELS}, "
                                  f"got {_shown(v)}", source, where)
        for key in ("fx", "fy"):
            if not (_is_number(cam[key]) and cam[key] > 0):
                raise FormatError(f"'{key}' must be a positive finite number, got {_shown(cam[key])}", source, where)
        pos = cam["position"]
        if not (isinstance(pos, list) and len(pos) == 3 and all(map(_is_number, pos))):
            raise FormatError("'position' must be a list of 3 finite numbers", source, where)
        rot = cam["rotation"]
        if not (isinstance(rot, list) and len(rot) == 3 and all(
                isinstance(r, list) and len(r) == 3 and all(map(_is_number, r)) for r in rot)):
            raise FormatError("'rotation' must be a 3x3 list of finite numbers", source, where)
    return cameras


def _shown(value) -> str:
    """``repr`` of a JSON value for a message, cut short (a hostile file can hold megabytes)."""
    text = repr(value) if not isinstance(value, int) or abs(value) < 1 << 64 else "a number past 2**64"
    return text if len(text) <= 40 else text[:37] + "..."


def load_cameras(path: str | os.PathLike) -> list:
    """Read and validate a ``cameras.json`` file (a regular file of at most :data:`MAX_CAMERAS_BYTES`).

    Raises
    ------
    FormatError
        When the file is missing, not a regular file, too large, not strict
        JSON, or a camera is malformed.
    """
    path = os.fspath(path)
    try:
        with open_input(path, what="cameras") as f:
            raw = f.read(MAX_CAMERAS_BYTES + 1)
    except OSError as e:
        raise FormatError(f"cannot read cameras: {e.strerror}", path) from None
    if len(raw) > MAX_CAMERAS_BYTES:
        raise FormatError(f"cameras file is larger than the {MAX_CAMERAS_BYTES} bytes allowed", path)
    cameras = loads_strict(raw, path, "invalid JSON")
    validate_cameras(cameras, path)
    if not cameras:
        raise FormatError("holds no cameras; the viewer needs at least one", path)
    return cameras


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
    return camera_for_box(*framing_box(x, y, z))


#: Points the framing box looks at, at most: evenly strided over the scene.
FRAMING_SAMPLES = 1 << 16


def framing_box(x: np.ndarray, y: np.ndarray, z: np.ndarray):
    """2nd and 98th percentiles of each coordinate over the points with all three finite.

    Of a large scene, every k-th point is taken (k the smallest step that
    leaves at most :data:`FRAMING_SAMPLES`): percentiles of 65,536 evenly strided
    points frame a scene as well as those of all of them, at a fraction of the
    cost. The values are those of ``np.percentile(pts, [2, 98], axis=0)`` (its
    default linear method) on the float64 points taken, computed without the
    ``(N, 3)`` float64 copy: float32 columns are sorted as they are (widening to
    float64 keeps their order), one column at a time.

    Parameters
    ----------
    x, y, z : (N,) ndarray
        Splat centres, float32 (other dtypes are widened to float64).

    Returns
    -------
    lo, hi : (3,) float64 ndarray
    """
    cols = [np.asarray(c) for c in (x, y, z)]
    step = max(1, -(-len(cols[0]) // FRAMING_SAMPLES))
    dtype = np.float32 if all(c.dtype == np.float32 for c in cols) else np.float64
    with np.errstate(invalid="ignore"):  # signalling NaNs warn when widened
        cols = [np.array(c[::step], dtype=dtype) for c in cols]  # copies, sorted below
    finite = np.isfinite(cols[0]) & np.isfinite(cols[1]) & np.isfinite(cols[2])
    if not finite.all():
        cols = [c[finite] for c in cols]
    if len(cols[0]) == 0:
        return np.zeros(3), np.zeros(3)
    lo, hi = np.array([_percentiles_2_98(c) for c in cols]).T
    return lo, hi


#: The quantiles np.percentile(..., [2, 98]) uses, computed as it computes them.
_QUANTILES = np.true_divide(np.array([2, 98]), 100)


def _percentiles_2_98(values: np.ndarray) -> np.ndarray:
    """``np.percentile(values, [2, 98])`` (linear method, no NaN) by sorting ``values`` in place.

    A full sort is cheaper than ``np.partition`` at four positions here (numpy
    sorts float32 with SIMD).
    """
    values.sort()
    prev, nxt, t = _linear_positions(len(values))
    return _lerp(values[prev].astype(np.float64), values[nxt].astype(np.float64), t)


def _linear_positions(n: int):
    """Sorted positions and weights of np.percentile's linear method for ``n`` values.

    Returns
    -------
    prev, nxt : (2,) intp ndarray
        Positions of the values to interpolate between (-1: the last one).
    t : (2,) float64 ndarray
    """
    virtual = (n - 1) * _QUANTILES
    prev = np.floor(virtual)
    nxt = prev + 1
    above = virtual >= n - 1
    prev[above] = -1
    nxt[above] = -1
    prev = prev.astype(np.intp)
    nxt = nxt.astype(np.intp)
    return prev, nxt, virtual - prev


def _lerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """numpy's own ``_lerp`` for percentiles, step by step, so the float64 results are the same bits."""
    diff = b - a
    result = a + diff * t
    np.subtract(b, diff * (1 - t), out=result, where=t >= 0.5)
    return result


def camera_for_box(lo: np.ndarray, hi: np.ndarray) -> dict:
    """The framing camera for a box ``lo``..``hi`` (``(3,) float64``); see :func:`framing_camera`."""
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
