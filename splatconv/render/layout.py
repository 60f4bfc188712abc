"""The float reference texture: which value of a splat each texel component holds.

The float reference path feeds the viewer's shader maths unquantized attributes:
an RGBA32F texture, :data:`FLOAT_TEXELS_PER_SPLAT` texels a splat, in the values
the shader reads (:func:`splatconv.viewer.float_record`: linear scales, linear
temporal scale, clamped colour, sigmoid opacity), each rounded once to float32.
:data:`FLOAT_TEXELS` is the one statement of the layout; ``specs/render.md``
writes it down and ``shaders/fetch_float.glsl`` reads it (tests check both).
numpy only: importing this module never imports moderngl.
"""

from __future__ import annotations

import numpy as np

from .. import viewer
from ..viewer import SPLATS_PER_ROW, TEXWIDTH, texture_height

#: Texel k of a splat -> the names of its (x, y, z, w) components, as
#: :func:`splatconv.viewer.float_record` names the values; None: unused (zero).
FLOAT_TEXELS = (
    ("x", "y", "z", "trbf_center"),
    ("rot_0", "rot_1", "rot_2", "rot_3"),
    ("scale_0", "scale_1", "scale_2", "trbf_scale"),
    ("f_dc_0", "f_dc_1", "f_dc_2", "opacity"),
    ("motion_0", "motion_1", "motion_2", "motion_3"),
    ("motion_4", "motion_5", "motion_6", "motion_7"),
    ("motion_8", "omega_0", "omega_1", "omega_2"),
    ("omega_3", None, None, None),
)
FLOAT_TEXELS_PER_SPLAT = len(FLOAT_TEXELS)
#: float32 values a splat's row holds.
FLOAT_WORDS = 4 * FLOAT_TEXELS_PER_SPLAT
#: Splats per texture row (the shader's ``i & 0x1ff``, ``i >> 9``).
FLOAT_SPLATS_PER_ROW = TEXWIDTH // FLOAT_TEXELS_PER_SPLAT
#: Column of each named value in a splat's row.
FLOAT_COLUMN = {name: 4 * k + c for k, names in enumerate(FLOAT_TEXELS) for c, name in enumerate(names) if name}

#: Rows converted per step: bounds the float64 temporaries of float_record.
_CHUNK = 1 << 16


def texture_records(count: int) -> int:
    """Records the viewer draws for a scene of ``count`` splats: whole ``.splatv`` texture rows."""
    return texture_height(count) * SPLATS_PER_ROW


def float_attributes(scene, order: np.ndarray | None = None, records: int | None = None) -> np.ndarray:
    """Scene -> float reference rows, ``(max(N, records), FLOAT_WORDS) float32``.

    Parameters
    ----------
    scene : splatconv.model.Scene
    order : (M,) int ndarray, optional
        Row ``i`` holds splat ``order[i]`` (default: scene order); M rows, maybe
        fewer than the scene's (the splats a converted file kept).
    records : int, optional
        Pad with zero rows to this many: the zero padding of the ``.splatv``
        texture, which the viewer sorts and draws too (so both paths see the same
        depth range and draw order).

    Returns
    -------
    (R, FLOAT_WORDS) float32 ndarray
        Each row laid out as :data:`FLOAT_TEXELS`, values from
        :func:`splatconv.viewer.float_record` (float64) rounded once to float32.
    """
    n = scene.count if order is None else len(order)
    out = np.zeros((max(n, records or 0), FLOAT_WORDS), dtype=np.float32)
    for start in range(0, n, _CHUNK):
        rows = slice(start, min(start + _CHUNK, n))
        pick = rows if order is None else np.asarray(order[rows])
        values = viewer.float_record({name: column[pick] for name, column in scene.columns.items()})
        with np.errstate(over="ignore"):  # float64 past float32's range becomes inf, as on upload
            for name, column in FLOAT_COLUMN.items():
                out[rows, column] = values[name]
    return out
