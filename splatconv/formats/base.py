"""What every format module shares: the report a write returns.

A format module (see :mod:`splatconv.formats`) declares ``NAME``, ``SUFFIXES``,
``CAN_READ``, ``CAN_WRITE``, ``COMPAT_MODES``, ``DEFAULT_SORT``, ``HOLDS_EMPTY``
and ``DYNAMIC`` and provides ``read(path, **options) -> Scene``,
``write(scene, stream, *, compat=None, sort=None, **options) -> WriteReport`` and
``info_fields(scene) -> dict``.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class WriteReport:
    """What a write did, for the user.

    Attributes
    ----------
    count : int
        Splats written.
    notes : list of str
        Every lossy step, as sentences.
    texheight : int
        Texture rows (texture formats; 0 otherwise).
    half : dict
        Attribute -> :class:`splatconv.packing.HalfCounts` (half-float formats).
    clamped, nan_bytes : dict
        ``"color"``/``"alpha"`` -> values clamped to a byte / NaN written as 0.
    """

    count: int = 0
    notes: list = field(default_factory=list)
    texheight: int = 0
    half: dict = field(default_factory=dict)
    clamped: dict = field(default_factory=dict)
    nan_bytes: dict = field(default_factory=dict)
