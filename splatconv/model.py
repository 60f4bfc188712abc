"""The data at the centre: one columnar table of splat attributes.

Every reader produces a :class:`Scene` and every writer consumes one. Columns are
named after the Spacetime Gaussians *lite* PLY properties and hold the values the
way that model stores them (log scales, logit opacity, RGB colour, log temporal
scale), so a lite PLY maps onto a scene without any arithmetic. No I/O here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Attribute columns of a scene, in the order of the lite PLY layout (normals
#: excluded: they are always zero and the viewer ignores them).
POSITION = ("x", "y", "z")
TRBF = ("trbf_center", "trbf_scale")
MOTION = tuple(f"motion_{i}" for i in range(9))
COLOR = ("f_dc_0", "f_dc_1", "f_dc_2")
OPACITY = ("opacity",)
SCALE = ("scale_0", "scale_1", "scale_2")
ROTATION = ("rot_0", "rot_1", "rot_2", "rot_3")
OMEGA = ("omega_0", "omega_1", "omega_2", "omega_3")

COLUMNS = POSITION + TRBF + MOTION + COLOR + OPACITY + SCALE + ROTATION + OMEGA

#: Optional view-dependent colour: the spherical-harmonic coefficients of degrees 1 to 3 beside the
#: degree-0 colour, named and ordered as a 3DGS PLY stores them: channel-major, ``f_rest_{c * K + k}``
#: for channel c (r, g, b) and coefficient k of the K a channel holds at the scene's degree.
SH_REST = tuple(f"f_rest_{i}" for i in range(45))
#: Coefficients a channel holds beyond degree 0, by SH degree.
SH_COEFFS = {0: 0, 1: 3, 2: 8, 3: 15}

#: Normals: in the lite PLY row, always zero, not part of the model.
NORMALS = ("nx", "ny", "nz")
#: Fields of a Spacetime Gaussians lite PLY row, in file order.
LITE_ROW = POSITION + TRBF + NORMALS + MOTION + COLOR + OPACITY + SCALE + ROTATION + OMEGA

#: Attribute groups, as reports name them.
GROUPS = {
    "position": POSITION,
    "rotation": ROTATION,
    "scale": SCALE,
    "color": COLOR,
    "opacity": OPACITY,
    "motion": MOTION,
    "omega": OMEGA,
    "trbf": TRBF,
}

#: Variant names, as ``info`` prints them.
VARIANT_LITE = "Spacetime Gaussians lite"
VARIANT_3DGS = "plain 3DGS"
VARIANT_FULL = "Spacetime Gaussians full"

#: Temporal radial basis given to static (3DGS) splats: centred on the middle of
#: the [0, 1] time range and so wide (exp(scale) = 1024) that the temporal
#: opacity exp(-(dt/1024)^2) stays above 0.999999 for every dt in [-1, 1].
STATIC_TRBF_CENTER = np.float32(0.5)
STATIC_TRBF_SCALE = np.float32(np.log(1024.0))


def sh_names(degree: int) -> tuple:
    """The ``f_rest_*`` columns of a scene of SH ``degree`` (0 to 3): 0, 9, 24 or 45 names."""
    return SH_REST[:3 * SH_COEFFS[degree]]


def sh_degree(columns: dict) -> int:
    """The SH degree (0 to 3) whose ``f_rest_*`` columns ``columns`` holds.

    Raises
    ------
    ValueError
        When the ``f_rest_*`` columns present are not exactly those of one degree.
    """
    present = [name for name in columns if name.startswith("f_rest_")]
    for degree in SH_COEFFS:
        if len(present) == 3 * SH_COEFFS[degree] and set(present) == set(sh_names(degree)):
            return degree
    raise ValueError(f"scene holds {len(present)} f_rest columns: not those of one SH degree (9, 24 or 45)")


def attribute_names(columns: dict) -> tuple:
    """Every column a scene's ``columns`` holds, in order: :data:`COLUMNS`, then its SH bands."""
    return COLUMNS + sh_names(sh_degree(columns))


def with_sh(columns: dict, source: dict, index=None) -> dict:
    """``columns`` with the SH bands of ``source`` (rows ``index`` of them; all when None) added."""
    names = sh_names(sh_degree(source))
    if names:
        columns = dict(columns)
        for name in names:
            col = np.asarray(source[name])
            columns[name] = col.copy() if index is None else col[index]
    return columns


def drop_sh(columns: dict) -> dict:
    """``columns`` without SH bands (the same dict when it holds none)."""
    if not sh_degree(columns):
        return columns
    return {name: columns[name] for name in columns if not name.startswith("f_rest_")}


def sh_dropped_note(degree: int, what: str) -> list:
    """The note that a write into ``what`` dropped SH bands of ``degree`` (none for degree 0)."""
    if not degree:
        return []
    bands = "1" if degree == 1 else f"1\u2013{degree}"
    return [f"dropped SH degree {bands} bands: {what} holds colour only"]


@dataclass
class Scene:
    """A set of splats plus what a viewer needs to show them.

    Attributes
    ----------
    columns : dict of str to ndarray
        One ``(N,) float32`` array per name in :data:`COLUMNS`. Arrays may be
        read-only views (memory-mapped input, broadcast constants); treat them as
        immutable. Besides them, optionally the SH bands of one degree
        (:func:`sh_names`), as long.
    cameras : list of dict or None
        Cameras in the 3DGS ``cameras.json`` form, or None when the source had none.
    variant : str
        What the source was (one of the ``VARIANT_*`` names or ``"splatv"``).
    meta : dict
        Format-specific facts about the source for ``info`` (sizes, ignored
        properties, chunk list, ...). Plain JSON-able values.
    notes : list of str
        Lossy or noteworthy steps taken while reading, to be shown to the user.
    """

    columns: dict
    cameras: list | None = None
    variant: str = VARIANT_LITE
    meta: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    def __post_init__(self):
        missing = [name for name in COLUMNS if name not in self.columns]
        if missing:
            raise ValueError(f"scene lacks columns {missing}")
        lengths = {len(self.columns[name]) for name in attribute_names(self.columns)}
        if len(lengths) != 1:
            raise ValueError(f"scene columns differ in length: {sorted(lengths)}")

    @property
    def sh_degree(self) -> int:
        """Degree (0 to 3) of the SH bands the scene holds (0: colour only)."""
        return sh_degree(self.columns)

    @property
    def count(self) -> int:
        """Number of splats N."""
        return len(self.columns["x"])

    def take(self, index: np.ndarray) -> dict:
        """Gather rows ``index`` of every column.

        Parameters
        ----------
        index : (M,) integer ndarray
            Row numbers.

        Returns
        -------
        dict of str to (M,) float32 ndarray
        """
        return {name: np.asarray(self.columns[name])[index] for name in attribute_names(self.columns)}


def constant_column(value, count: int) -> np.ndarray:
    """A read-only ``(count,) float32`` column holding ``value``, using no memory."""
    return np.broadcast_to(np.float32(value), (count,))


def static_columns(count: int) -> dict:
    """The time columns of ``count`` splats that neither move nor fade (a static 3DGS scene).

    The temporal basis :data:`STATIC_TRBF_CENTER`, :data:`STATIC_TRBF_SCALE`
    and zero motion and omega: the values the PLY and ``.splat`` readers give a
    scene without time, and bake gives what it freezes.

    Returns
    -------
    dict of str to (count,) float32 ndarray
        ``trbf_center``, ``trbf_scale``, ``motion_*`` and ``omega_*``: read-only
        constant columns (:func:`constant_column`), using no memory.
    """
    cols = {"trbf_center": constant_column(STATIC_TRBF_CENTER, count),
            "trbf_scale": constant_column(STATIC_TRBF_SCALE, count)}
    cols.update((name, constant_column(0.0, count)) for name in MOTION + OMEGA)
    return cols


def lite_rows(count: int) -> tuple[np.ndarray, dict]:
    """A table in the lite PLY row layout, and the model columns as views of it.

    Filling the columns fills the rows, so a lite PLY writer can write the
    table as it is.

    Parameters
    ----------
    count : int
        Rows N.

    Returns
    -------
    rows : (N, 32) float32 ndarray
        Fields in :data:`LITE_ROW` order; the normals are zero, the rest
        uninitialised.
    columns : dict of str to (N,) float32 ndarray
        Writeable strided views of ``rows``, one per name in :data:`COLUMNS`.
    """
    rows = np.empty((count, len(LITE_ROW)), dtype=np.float32)
    columns = {}
    for i, name in enumerate(LITE_ROW):
        if name in NORMALS:
            rows[:, i] = 0.0
        else:
            columns[name] = rows[:, i]
    return rows, {name: columns[name] for name in COLUMNS}


def _buffer_root(a: np.ndarray):
    """The object that owns ``a``'s memory (the end of its chain of bases)."""
    while isinstance(a.base, np.ndarray):
        a = a.base
    return a if a.base is None else a.base


def row_fields(columns: list):
    """Whether columns are fields of one row-major buffer, and where.

    True of columns read from a memory-mapped binary PLY, or made by
    :func:`lite_rows`: a block of rows can then be copied whole, or split into
    columns by a few transposed copies, instead of one strided pass per column.

    Parameters
    ----------
    columns : list of ndarray

    Returns
    -------
    (matrix, fields) or None
        ``matrix`` is an ``(N, W) float32`` read-only view from the first to the
        last of the fields in each row (so it stays inside the buffer) and
        ``matrix[:, fields[i]]`` is ``columns[i]``. None unless all columns are
        native float32 values at 4-byte-aligned offsets of one row stride, in
        one buffer.
    """
    first = columns[0]
    n = len(first)
    stride = first.strides[0] if first.ndim == 1 else 0
    if n == 0 or stride <= 0 or stride % 4:
        return None
    root = _buffer_root(first)
    for c in columns:
        if (c.ndim != 1 or len(c) != n or c.dtype != np.dtype("=f4") or c.strides[0] != stride
                or _buffer_root(c) is not root):
            return None
    address = [c.__array_interface__["data"][0] for c in columns]
    base = min(address)
    offsets = [a - base for a in address]
    if any(o % 4 or o >= stride for o in offsets):
        return None
    fields = [o // 4 for o in offsets]
    matrix = np.lib.stride_tricks.as_strided(columns[address.index(base)], shape=(n, max(fields) + 1),
                                             strides=(stride, 4), writeable=False)
    return matrix, fields


def far_rows(xyz: np.ndarray, extents: float) -> np.ndarray:
    """Positions far from the rest: ``(N, 3)`` float64 -> ``(N,) bool``.

    A row is far when an axis of it lies more than ``extents`` robust scene
    extents (the widest interquartile range of an axis over the finite rows, at
    least 1e-6) from the finite rows' median. NaN rows are not far; infinite ones are.
    """
    far = np.zeros(len(xyz), bool)
    finite = xyz[np.isfinite(xyz).all(axis=1)]
    if len(finite):
        lo, mid, hi = np.percentile(finite, (25, 50, 75), axis=0)
        extent = max(float(np.max(hi - lo)), 1e-6)
        with np.errstate(invalid="ignore"):
            far = (np.abs(xyz - mid) > extents * extent).any(axis=1)
    return far
