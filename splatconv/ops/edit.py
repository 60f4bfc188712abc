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

The filters' masks are computed in one pass over blocks of rows (a block stays
in cache while every mask reads it), combined, and the survivors copied once,
each block transformed as it is copied. A trim adds a pass: its time map has to
come before the crop's mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import viewer
from ..model import Scene
from . import filters
from . import time as time_ops
from ._table import compact, copy_rows, derive, run_blocks
from .report import OpReport
from .transform import Transform, _block_transformer, transform_cameras, transform_columns, transform_report

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
            object.__setattr__(self, "min_opacity", filters._check_minimum(self.min_opacity))
        if self.max_splats is not None:
            object.__setattr__(self, "max_splats", filters._check_count(self.max_splats))

    @property
    def empty(self) -> bool:
        """Whether the plan changes nothing."""
        return (not self.drop_undrawable and not self.drop_nonfinite and self.trim is None and self.crop is None
                and self.min_opacity is None and self.max_splats is None
                and (self.transform is None or self.transform.is_identity))


def _masks(columns: dict, wanted: dict) -> dict:
    """Masks (or keys) of several filters in one pass over blocks of rows.

    ``wanted`` maps a name to ``(fn, dtype)``; ``fn(part, block)`` gives the values of
    rows ``part`` (a slice), ``block`` their columns.
    """
    n = len(columns["x"])
    out = {name: np.empty(n, dtype=dtype) for name, (_fn, dtype) in wanted.items()}
    base = {name: columns[name].view(np.ndarray) for name in columns}

    def job(part):
        block = {name: base[name][part] for name in base}
        for name, (fn, _dtype) in wanted.items():
            out[name][part] = fn(part, block)

    run_blocks(n, job)
    return out


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
    reports = []
    columns = scene.columns
    alive = None  # rows of `columns` still kept; None: all
    owned = False  # whether `columns` is a copy made here (may be changed in place)

    def keep(mask, report):
        nonlocal alive
        reports.append(report)
        alive = mask if alive is None else alive & mask

    # Pass 1 (before the time map): drop-undrawable, drop-nonfinite and the trim's
    # visibility; without a trim, the masks of pass 2 too.
    first = {}
    if plan.drop_undrawable:
        first["undrawable"] = (lambda part, block: viewer.undrawable_kinds(block), np.int8)
    if plan.drop_nonfinite:
        first["nonfinite"] = (filters.nonfinite_tester(columns), bool)
    if plan.trim is not None:
        t0, t1 = plan.trim
        first["trim"] = (lambda part, block: time_ops.visible_in_mask(block, t0, t1), bool)
    second = {}
    if plan.crop is not None:
        lo, hi = plan.crop
        inside = filters.crop_tester(lo, hi)
        second["crop"] = (lambda part, block: inside(block), bool)
    if plan.min_opacity is not None:
        opaque = filters.opacity_tester(plan.min_opacity)
        second["opacity"] = (lambda part, block: opaque(block), bool)
    if plan.max_splats is not None:
        second["importance"] = (lambda part, block: filters.importance_key(block), np.float64)
    if plan.trim is None:
        first.update(second)
    masks = _masks(columns, first) if first else {}
    if plan.drop_undrawable:
        kinds = masks["undrawable"]
        keep(kinds == viewer.DRAWABLE, filters.undrawable_report(kinds, alive))
    if plan.drop_nonfinite:
        keep(masks["nonfinite"], filters.nonfinite_report(columns, masks["nonfinite"], alive))
    if plan.trim is not None:
        mask = masks["trim"]
        count_in = len(mask) if alive is None else int(alive.sum())
        dropped = ~mask if alive is None else alive & ~mask
        nan_time = time_ops._nan_time(columns, np.flatnonzero(dropped))
        alive = mask if alive is None else alive & mask
        columns, overflow = copy_rows(columns, np.flatnonzero(alive),
                                      each=lambda block: time_ops._remap_block(block, t0, t1 - t0))
        alive, owned = None, True
        reports.append(time_ops.trim_report(count_in, len(columns["x"]), nan_time, t0, t1, overflow))

        # Pass 2, after the time map: crop, min-opacity and the importance key of max-splats.
        masks = _masks(columns, second) if second else {}
    if plan.crop is not None:
        keep(masks["crop"], filters.crop_report(masks["crop"], lo, hi, alive))
    if plan.min_opacity is not None:
        keep(masks["opacity"], filters.opacity_report(masks["opacity"], plan.min_opacity, alive))
    if plan.max_splats is not None:
        rows = None if alive is None else np.flatnonzero(alive)
        count_in = len(columns["x"]) if rows is None else len(rows)
        chosen = filters.most_important(columns, plan.max_splats, rows, key=masks["importance"])
        reports.append(filters.max_splats_report(count_in, len(chosen), plan.max_splats))
        if len(chosen) < len(columns["x"]):
            alive = np.zeros(len(columns["x"]), dtype=bool)
            alive[chosen] = True

    # The copy of the survivors, transformed block by block as it is made.
    cameras = scene.cameras
    transform = plan.transform if plan.transform is not None and not plan.transform.is_identity else None
    removed = alive is not None and not alive.all()
    if transform is not None and owned and not removed:
        grown = transform_columns(columns, transform)
        cameras = transform_cameras(cameras, transform)
        reports.append(transform_report(len(columns["x"]), len(cameras or []), transform, grown))
    elif transform is not None or removed:
        index = np.flatnonzero(alive) if removed else None
        each = _block_transformer(transform) if transform is not None else None
        columns, grown = (compact if owned and removed else copy_rows)(columns, index, each=each)
        if transform is not None:
            cameras = transform_cameras(cameras, transform)
            reports.append(transform_report(len(columns["x"]), len(cameras or []), transform, grown))
    notes = [line for report in reports for line in report.notes]
    return derive(scene, columns, notes, cameras=cameras), reports


__all__ = ["ORDER", "EditPlan", "apply_edits", "OpReport"]
