"""What every format module shares: the report a write returns.

A format module (see :mod:`splatconv.formats`) declares ``NAME``, ``SUFFIXES``,
``CAN_READ``, ``CAN_WRITE``, ``COMPAT_MODES``, ``DEFAULT_SORT``, ``HOLDS_EMPTY``,
``DYNAMIC``, ``STORES_TEXTURE`` and ``PLAYS_SEGMENTS`` and
provides ``read(path, **options) -> Scene``,
``write(scene, stream, *, compat=None, sort=None, **options) -> WriteReport``,
``info_fields(scene) -> dict`` and, when ``CAN_READ``, ``splat_count(path) -> int or None``
(the splats ``read`` would give, found from the header or the file size without
reading them; None when only reading tells) and ``most_splats(path) -> int`` (at
most the splats ``read`` would give, found the same way: it bounds the memory a
read takes before it starts).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import UnsupportedError
from ..model import MOTION, OMEGA
from ..viewer import TIME_RANGE, temporal_opacity
from ..wording import plural


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

    def byte_notes(self) -> list:
        """Notes for the values clamped to a byte and the NaNs written as 0."""
        notes = [f"{key}: {plural(count, 'value')} outside [0, 1] clamped" for key, count in self.clamped.items() if count]
        return notes + [f"{key}: {plural(count, 'NaN value')} written as 0"
                        for key, count in self.nan_bytes.items() if count]


#: Smallest temporal opacity over the viewer's clip at which a static format
#: may drop a splat's temporal basis: the alpha byte moves by at most half a
#: step (sigmoid(opacity) * 255 * (1 - this) <= 0.5), so the viewer shows the
#: same picture at every time.
STATIC_MIN_TEMPORAL = 1.0 - 0.5 / 255.0


def time_varying(columns: dict) -> np.ndarray:
    """Which splats the viewer shows differently at different times in [0, 1]: ``(N,) bool``.

    A splat is time-varying when any motion or omega coefficient is non-zero
    (NaN included), or when its temporal opacity falls below
    :data:`STATIC_MIN_TEMPORAL` somewhere in [0, 1] (also when it is NaN, or
    hidden by the viewer's cut). The temporal opacity peaks at the splat's
    centre, so its least value over [0, 1] is at one of the ends.
    """
    moving = np.zeros(len(columns["x"]), dtype=bool)
    for name in MOTION + OMEGA:
        moving |= np.asarray(columns[name]) != 0  # NaN != 0 too
    for t in TIME_RANGE:
        moving |= ~(temporal_opacity(columns, t, cut=False) >= STATIC_MIN_TEMPORAL)
    return moving


def refuse_time_varying(columns: dict, what: str) -> None:
    """Raise :class:`UnsupportedError` when a static format ``what`` cannot hold the scene's motion or fading.

    Writing such a scene as static would show, at every time, splats that
    move, turn or fade in the clip, each frozen at its own rest time: a picture
    the scene never shows. Baking a moment is the way to a static file.
    """
    varying = int(np.count_nonzero(time_varying(columns)))
    if varying:
        n = len(columns["x"])
        raise UnsupportedError(
            f"{varying:,} of {plural(n, 'splat')} move, turn or fade over time and {what} is static; bake one moment "
            "with `splatconv bake INPUT OUTPUT --time T`")
