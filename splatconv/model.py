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


@dataclass
class Scene:
    """A set of splats plus what a viewer needs to show them.

    Attributes
    ----------
    columns : dict of str to ndarray
        One ``(N,) float32`` array per name in :data:`COLUMNS`. Arrays may be
        read-only views (memory-mapped input, broadcast constants); treat them as
        immutable.
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
        lengths = {len(self.columns[name]) for name in COLUMNS}
        if len(lengths) != 1:
            raise ValueError(f"scene columns differ in length: {sorted(lengths)}")

    @property
    def count(self) -> int:
        """Number of splats N."""
        return len(self.columns["x"])

    def column(self, name: str) -> np.ndarray:
        """Return column ``name`` as an ``(N,) float32`` array."""
        return self.columns[name]

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
        return {name: np.asarray(self.columns[name])[index] for name in COLUMNS}


def constant_column(value, count: int) -> np.ndarray:
    """A read-only ``(count,) float32`` column holding ``value``, using no memory."""
    return np.broadcast_to(np.float32(value), (count,))
