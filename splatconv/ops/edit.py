"""The edits ``convert`` applies, in one fixed order, in as few passes over the splats as possible.

Order (:data:`ORDER`): drop-undrawable, drop-nonfinite, trim, crop, min-opacity,
max-splats, transform. drop-undrawable comes first because what the viewer can
never draw is a fact about the source scene over its whole [0, 1], before any
edit changes it: each undrawable splat is counted under its own kind before
drop-nonfinite sees it (a NaN position is both), and max-splats then ranks only
splats that can be drawn (an undrawable splat may well be among the largest).
Filters come first so that each later step sees only what survives; trim comes
before crop so the crop's "time of peak opacity" is taken within the trimmed
clip; max-splats comes last of the filters because it ranks what the others
leave; the transform comes last so that the crop box is in the input's
coordinates (those ``info`` prints).

Each filter is a :class:`~splatconv.ops.step.Step` (made by :data:`_FILTERS`).
Their values are computed in one pass over blocks of rows (a block stays in
cache while every filter reads it), each filter then keeps its rows, and the
survivors are copied once, each block transformed as it is copied. A trim adds
a pass: its time map has to come before the crop's mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import Scene, sh_degree
from . import filters
from . import time as time_ops
from ._table import compact, copy_rows, derive, run_blocks
from .report import OpReport
from .step import Rows
from .transform import (Transform, block_transformer, rotate_sh, transform_cameras, transform_columns,
                        transform_report)

#: The order the edits apply in, named as their options.
ORDER = ("drop-undrawable", "drop-nonfinite", "trim", "crop", "min-opacity", "max-splats", "transform")


@dataclass(frozen=True)
class EditPlan:
    """Which edits to apply (None or False: not that one).

    Attributes
    ----------
    drop_undrawable : bool
    drop_nonfinite : bool
    trim : (float, float) or None
        (T0, T1), 0 <= T0 < T1 <= 1.
    crop : ((3,) tuple, (3,) tuple) or None
        Box corners (lo, hi).
    min_opacity : float or None
    max_splats : int or None
    transform : Transform or None
    """

    drop_undrawable: bool = False
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
            object.__setattr__(self, "min_opacity", filters.check_minimum(self.min_opacity))
        if self.max_splats is not None:
            object.__setattr__(self, "max_splats", filters.check_count(self.max_splats))

    @property
    def empty(self) -> bool:
        """Whether the plan changes nothing."""
        return (not self.drop_undrawable and not self.drop_nonfinite and self.trim is None and self.crop is None
                and self.min_opacity is None and self.max_splats is None
                and (self.transform is None or self.transform.is_identity))


#: The filters of a plan, in :data:`ORDER`: the :class:`EditPlan` field that asks for each, and
#: how its value (validated) makes the step.
_FILTERS = (
    ("drop_undrawable", lambda _: filters.DropUndrawable()),
    ("drop_nonfinite", lambda _: filters.DropNonfinite()),
    ("trim", lambda interval: time_ops.Trim(*interval)),
    ("crop", lambda box: filters.Crop(*box)),
    ("min_opacity", filters.MinOpacity),
    ("max_splats", filters.MaxSplats),
)


def _steps(plan: EditPlan) -> list:
    """The filter steps ``plan`` asks for, in order (None or False: not asked; 0 is a value)."""
    values = [(getattr(plan, field), make) for field, make in _FILTERS]
    return [make(value) for value, make in values if value is not None and value is not False]


def _values(columns: dict, steps: list) -> dict:
    """Each step's values (:meth:`~splatconv.ops.step.Step.tester`) of every row, in one pass over
    blocks of rows: step name -> ``(N,) step.dtype``."""
    n = len(columns["x"])
    tests = {step.name: step.tester(columns) for step in steps}
    out = {step.name: np.empty(n, dtype=step.dtype) for step in steps}
    base = {name: columns[name].view(np.ndarray) for name in columns}

    def job(part):
        block = {name: base[name][part] for name in base}
        for name, test in tests.items():
            out[name][part] = test(part, block)

    run_blocks(n, job)
    return out


def _copy_survivors(rows: Rows, transform: Transform | None, cameras, reports: list) -> tuple:
    """The columns and cameras of the rows kept, transformed by ``transform`` (None: none), copied
    once (block by block, transformed as copied); the transform's report goes to ``reports``."""
    columns = rows.columns
    removed = rows.alive is not None and not rows.alive.all()
    if transform is not None:
        cameras = transform_cameras(cameras, transform)  # first: a camera it cannot move is refused at once
    if transform is not None and rows.owned and not removed:
        grown = transform_columns(columns, transform)
    elif transform is not None or removed:
        index = np.flatnonzero(rows.alive) if removed else None
        each = block_transformer(transform) if transform is not None else None
        columns, grown = (compact if rows.owned and removed else copy_rows)(columns, index, each=each)
        if transform is not None:
            rotate_sh(columns, transform)
    if transform is not None:
        reports.append(transform_report(len(columns["x"]), len(cameras or []), transform, grown,
                                        sh_degree(columns) > 0))
    return columns, cameras


def apply_edits(scene: Scene, plan: EditPlan) -> tuple[Scene, list]:
    """Apply ``plan`` to ``scene`` in the order of :data:`ORDER`.

    The result equals applying :func:`~splatconv.ops.filters.drop_undrawable`,
    :func:`~splatconv.ops.filters.drop_nonfinite`,
    :func:`~splatconv.ops.time.trim`, :func:`~splatconv.ops.filters.crop`,
    :func:`~splatconv.ops.filters.min_opacity`,
    :func:`~splatconv.ops.filters.max_splats` and
    :func:`~splatconv.ops.transform.apply_transform` one after another, with
    the same reports, but reads and copies the splats once (twice with a trim).

    Returns
    -------
    (Scene, list of OpReport)
        The edited scene (its ``notes``: the input's, then every report's) and a
        report per edit applied, in order.
    """
    rows, reports, steps = Rows(scene.columns), [], _steps(plan)
    while steps:
        # One pass reads the rows for the steps up to the first that re-times them: those
        # after it read its copy, in the next pass.
        cut = next((i + 1 for i, step in enumerate(steps) if step.retimes), len(steps))
        now, steps = steps[:cut], steps[cut:]
        values = _values(rows.columns, now)
        for step in now:
            reports.append(step.apply(rows, values[step.name]))
    transform = plan.transform if plan.transform is not None and not plan.transform.is_identity else None
    columns, cameras = _copy_survivors(rows, transform, scene.cameras, reports)
    notes = [line for report in reports for line in report.notes]
    return derive(scene, columns, notes, cameras=cameras), reports


__all__ = ["ORDER", "EditPlan", "apply_edits", "OpReport"]
