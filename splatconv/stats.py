"""Reports as data: what a scene file holds (``info``). Never prints."""

from __future__ import annotations

import math

import numpy as np

from .formats import splatv
from .model import COLUMNS, Scene

#: Temporal opacity below which the viewer skips a splat.
TEMPORAL_CUTOFF = 0.02
#: |dt| / exp(trbf_scale) at which exp(-(dt/s)^2) falls to the cutoff.
_VISIBLE_RADIUS = math.sqrt(-math.log(TEMPORAL_CUTOFF))


def _finite_range(values: np.ndarray):
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    return [float(v.min()), float(v.max())]


def describe(scene: Scene, path: str, fmt: str) -> dict:
    """Facts about a scene file, as JSON-able data.

    Parameters
    ----------
    scene : Scene
    path : str
    fmt : str
        Format name (``"ply"`` or ``"splatv"``).

    Returns
    -------
    dict
        Keys: path, format, variant, count, file_bytes, texture, cameras,
        time_range, visible_time_range, bounds, nonfinite, and format-specific
        extras (ply: ply_format, color, ignored_properties, extra_elements;
        splatv: chunks), notes.
    """
    cols = scene.columns
    n = scene.count
    meta = scene.meta
    texheight = splatv.texture_height(n)
    texture = {
        "width": splatv.TEXWIDTH,
        "height": meta.get("texheight", texheight),
        "declared_bytes": meta.get("declared_bytes", splatv.TEXWIDTH * texheight * 16),
        "actual_bytes": meta.get("actual_bytes", None),
    }
    bounds = None
    pos = np.stack([np.asarray(cols[c], dtype=np.float64) for c in ("x", "y", "z")], axis=1)
    pos = pos[np.isfinite(pos).all(axis=1)]
    if len(pos):
        bounds = {"min": pos.min(axis=0).tolist(), "max": pos.max(axis=0).tolist()}
    centre = np.asarray(cols["trbf_center"], dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        reach = np.exp(np.asarray(cols["trbf_scale"], dtype=np.float64)) * _VISIBLE_RADIUS
        lo, hi = _finite_range(centre - reach), _finite_range(centre + reach)
    info = {
        "path": path,
        "format": fmt,
        "variant": scene.variant,
        "count": n,
        "file_bytes": meta.get("file_bytes"),
        "texture": texture,
        "cameras": [{"id": c.get("id"), "img_name": c.get("img_name"), "width": c.get("width"),
                     "height": c.get("height")} for c in (scene.cameras or [])],
        "time_range": _finite_range(centre),
        "visible_time_range": [lo[0], hi[1]] if lo and hi else None,
        "bounds": bounds,
        "nonfinite": {name: int(np.count_nonzero(~np.isfinite(cols[name]))) for name in COLUMNS},
    }
    if fmt == "ply":
        info.update({
            "ply_format": meta.get("format"),
            "color": meta.get("color"),
            "ignored_properties": meta.get("ignored_properties", []),
            "extra_elements": meta.get("extra_elements", []),
        })
    else:
        info["chunks"] = meta.get("chunks", [])
    info["notes"] = list(scene.notes)
    return info
