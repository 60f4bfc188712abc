"""The edits ``convert`` applies, in one fixed order, copying the splats at most twice.

Order (:data:`ORDER`): drop-nonfinite, trim, crop, min-opacity, max-splats,
transform. Filters come first so that each later step sees only what survives;
trim comes before crop so the crop's "time of peak opacity" is taken within the
trimmed clip; max-splats comes last of the filters because it ranks what the
others leave; the transform comes last so that the crop box is in the input's
coordinates (those ``info`` prints). The masks of the filters are computed on
the input and combined; the survivors are copied once (twice with trim, whose
time map needs them first) and transformed in that copy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import Scene
from . import filters
from . import time as time_ops
from ._table import derive, gather
from .report import OpReport
from .transform import Transform, transform_cameras, transform_columns, transform_report

#: The order the edits apply in, named as their options.
ORDER = ("drop-nonfinite", "trim", "crop", "min-opacity", "max-splats", "transform")


@dataclass(frozen=True)
class EditPlan:
    """Which edits to apply (None or False: not that one).

    Attributes
    ----------
    drop_nonfinite : bool
    trim : (float, float) or None
        (T0, T1), 0 <= T0 < T1 <= 1.
    crop : ((3,) tuple, (3,) tuple) or None
        Box corners (lo, hi).
    min_opacity : float or None
    max_splats : int or None
    transform : Transform or None
    """

    drop_nonfinite: bool = False
    trim: tuple | None = None
    crop: tuple | None = None
    min_opacity: float | None = None
    max_splats: int | None = None
    transform: Transform | None = None

    def __post_init__(self):
        # Validate up front, before any (possibly long) read.
        if self.trim is not None:
            object.__setattr__(self, "trim", time_ops.check_interval(*self.trim))
        if self.crop is not None:
            object.__setattr__(self, "crop", filters.check_box(*self.crop))
        if self.min_opacity is not None:
            object.__setattr__(self, "min_opacity", filters._check_minimum(self.min_opacity))
        if self.max_splats is not None:
            object.__setattr__(self, "max_splats", filters._check_count(self.max_splats))

    @property
    def empty(self) -> bool:
        """Whether the plan changes nothing."""
        return (not self.drop_nonfinite and self.trim is None and self.crop is None and self.min_opacity is None
                and self.max_splats is None and (self.transform is None or self.transform.is_identity))


def apply_edits(scene: Scene, plan: EditPlan) -> tuple[Scene, list]:
    """Apply ``plan`` to ``scene`` in the order of :data:`ORDER`.

    The result equals applying :func:`~splatconv.ops.filters.drop_nonfinite`,
    :func:`~splatconv.ops.time.trim`, :func:`~splatconv.ops.filters.crop`,
    :func:`~splatconv.ops.filters.min_opacity`,
    :func:`~splatconv.ops.filters.max_splats` and
    :func:`~splatconv.ops.transform.apply_transform` one after another, with
    the same reports, but copies the splats once (twice with a trim).

    Returns
    -------
    (Scene, list of OpReport)
        The edited scene (its ``notes``: the input's, then every report's) and a
        report per edit applied, in order.
    """
    reports = []
    columns, owned = scene.columns, False
    alive = None  # rows of `columns` still kept; None: all

    def keep(mask, report_of):
        nonlocal alive
        reports.append(report_of(mask, alive))
        alive = mask if alive is None else alive & mask

    def compact():
        nonlocal columns, owned, alive
        if alive is not None and not alive.all():
            columns, owned = gather(columns, np.flatnonzero(alive)), True
        alive = None

    def own():
        nonlocal columns, owned
        compact()
        if not owned:
            columns, owned = gather(columns), True

    if plan.drop_nonfinite:
        keep(filters.nonfinite_mask(columns), lambda m, a: filters.nonfinite_report(columns, m, a))
    if plan.trim is not None:
        t0, t1 = plan.trim
        count_in = len(columns["x"]) if alive is None else int(alive.sum())
        mask = time_ops.visible_in_mask(columns, t0, t1)
        dropped = ~mask if alive is None else alive & ~mask
        nan_time = time_ops._nan_time(columns, np.flatnonzero(dropped))
        alive = mask if alive is None else alive & mask
        own()
        overflow = time_ops.remap_columns(columns, t0, t1 - t0)
        reports.append(time_ops.trim_report(count_in, len(columns["x"]), nan_time, t0, t1, overflow))
    if plan.crop is not None:
        lo, hi = plan.crop
        keep(filters.crop_mask(columns, lo, hi), lambda m, a: filters.crop_report(m, lo, hi, a))
    if plan.min_opacity is not None:
        a_min = plan.min_opacity
        keep(filters.opacity_mask(columns, a_min), lambda m, a: filters.opacity_report(m, a_min, a))
    if plan.max_splats is not None:
        rows = None if alive is None else np.flatnonzero(alive)
        count_in = len(columns["x"]) if rows is None else len(rows)
        chosen = filters.most_important(columns, plan.max_splats, rows)
        reports.append(filters.max_splats_report(count_in, len(chosen), plan.max_splats))
        if len(chosen) < len(columns["x"]):
            alive = np.zeros(len(columns["x"]), dtype=bool)
            alive[chosen] = True
    cameras = scene.cameras
    if plan.transform is not None and not plan.transform.is_identity:
        own()
        grown = transform_columns(columns, plan.transform)
        cameras = transform_cameras(cameras, plan.transform)
        reports.append(transform_report(len(columns["x"]), len(cameras or []), plan.transform, grown))
    compact()
    notes = [line for report in reports for line in report.notes]
    return derive(scene, columns, notes, cameras=cameras), reports


__all__ = ["ORDER", "EditPlan", "apply_edits", "OpReport"]
