"""Cameras moved about a scene: orbited about its centre, stepped towards it, and paths between cameras.

A camera here is a ``cameras.json`` camera (a dict: ``rotation``, the 3x3
camera-to-world matrix whose columns are the camera's axes, ``position``,
``width``, ``height``, ``fx``, ``fy``); each function returns a new one.
``render --orbit`` and ``--path`` draw along :func:`orbit_path` and
:func:`camera_path`; a compressed file's proof (:mod:`splatconv.render.proof`)
draws the views :func:`orbited` and :func:`stepped` place near each camera.
"""

from __future__ import annotations

import math

import numpy as np

from .. import viewer
from ..cameras import framing_box
from ..model import Scene


def drawn_box(scene: Scene, drawn: np.ndarray | None = None) -> tuple:
    """The 2nd..98th percentile box of the splats the viewer can draw: ``(lo, hi)``, each ``(3,) float64``.

    Zeros for a scene with nothing drawable (see :func:`splatconv.cameras.framing_box`).
    ``drawn``: ``~viewer.undrawable(scene.columns)`` where the caller has it.
    """
    if drawn is None:
        drawn = ~viewer.undrawable(scene.columns) if scene.count else np.zeros(0, bool)
    if not drawn.any():
        return np.zeros(3), np.zeros(3)
    lo, hi = framing_box(*(np.asarray(scene.columns[a])[drawn] for a in "xyz"))
    return np.asarray(lo, np.float64), np.asarray(hi, np.float64)


def scene_centre(scene: Scene) -> np.ndarray:
    """The middle of :func:`drawn_box`: what an orbit turns about, ``(3,) float64``."""
    lo, hi = drawn_box(scene)
    return (lo + hi) / 2


def orbited(camera: dict, centre: np.ndarray, degrees: float) -> dict:
    """``camera`` turned by ``degrees`` about its own up axis through ``centre``."""
    rotation = np.asarray(camera["rotation"], np.float64)  # camera-to-world: columns are its axes
    up = rotation[:, 1] / max(np.linalg.norm(rotation[:, 1]), 1e-12)
    a = math.radians(degrees)
    k = np.array([[0, -up[2], up[1]], [up[2], 0, -up[0]], [-up[1], up[0], 0]])
    turn = np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * (k @ k)
    position = centre + turn @ (np.asarray(camera["position"], np.float64) - centre)
    return dict(camera, rotation=(turn @ rotation).tolist(), position=position.tolist())


def stepped(camera: dict, centre: np.ndarray, share: float) -> dict:
    """``camera`` moved ``share`` of the way towards ``centre``, looking as before."""
    position = np.asarray(camera["position"], np.float64)
    return dict(camera, position=(position + share * (centre - position)).tolist())


def _quaternion(m: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (its nearest rotation when not quite orthonormal)."""
    # The eigenvector of the largest eigenvalue of Bar-Itzhack's symmetric 4x4 matrix: no branch
    # on the trace, and a matrix a little off orthonormal (cameras.json rounding) still gives a rotation.
    (a, b, c), (d, e, f), (g, h, i) = m
    k = np.array([[a - e - i, d + b, g + c, h - f],
                  [d + b, e - a - i, h + f, c - g],
                  [g + c, h + f, i - a - e, d - b],
                  [h - f, c - g, d - b, a + e + i]]) / 3
    _values, vectors = np.linalg.eigh(k)
    x, y, z, w = vectors[:, -1]
    return np.array([w, x, y, z])


def _matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _slerp(qa: np.ndarray, qb: np.ndarray, share: float) -> np.ndarray:
    dot = float(qa @ qb)
    if dot < 0:  # q and -q are one rotation: take the shorter way round
        qb, dot = -qb, -dot
    if dot > 0.9995:  # nearly one rotation: the straight line is as good and never divides by ~0
        q = qa + share * (qb - qa)
        return q / np.linalg.norm(q)
    angle = math.acos(dot)
    return (math.sin((1 - share) * angle) * qa + math.sin(share * angle) * qb) / math.sin(angle)


def between(a: dict, b: dict, share: float) -> dict:
    """The camera ``share`` (0..1) of the way from ``a`` to ``b``.

    The position moves in a straight line, the rotation turns at a steady rate
    (slerp, the shorter way round), and the focal lengths change linearly from
    ``a``'s to ``b``'s as ``b`` draws in ``a``'s frame (scaled by the smaller of
    the width and height ratios, so ``b``'s whole view shows). The frame is
    ``a``'s size throughout. ``share`` 0 gives ``a``'s view, 1 ``b``'s.
    """
    scale = min(int(a["width"]) / int(b["width"]), int(a["height"]) / int(b["height"]))
    if share <= 0:
        return dict(a)
    if share >= 1:  # the end exactly as the camera is
        return dict(a, rotation=b["rotation"], position=b["position"], fx=float(b["fx"]) * scale,
                    fy=float(b["fy"]) * scale)
    rotation = _matrix(_slerp(_quaternion(np.asarray(a["rotation"], np.float64)),
                              _quaternion(np.asarray(b["rotation"], np.float64)), share))
    pa, pb = np.asarray(a["position"], np.float64), np.asarray(b["position"], np.float64)
    fx = (1 - share) * float(a["fx"]) + share * float(b["fx"]) * scale
    fy = (1 - share) * float(a["fy"]) + share * float(b["fy"]) * scale
    return dict(a, rotation=rotation.tolist(), position=(pa + share * (pb - pa)).tolist(), fx=fx, fy=fy)


def shares(count: int) -> list:
    """``count`` evenly spaced steps over [0, 1], ends included (one step: 0)."""
    return [0.0] if count == 1 else [k / (count - 1) for k in range(count)]


def orbit_path(camera: dict, centre: np.ndarray, degrees: float, count: int) -> list:
    """``count`` cameras turning ``camera`` by 0 to ``degrees`` about ``centre`` (see :func:`orbited`)."""
    return [orbited(camera, centre, degrees * s) if s else dict(camera) for s in shares(count)]


def camera_path(a: dict, b: dict, count: int) -> list:
    """``count`` cameras from ``a`` to ``b`` (see :func:`between`)."""
    return [between(a, b, s) for s in shares(count)]
