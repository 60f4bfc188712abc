"""Clean-up filters: drop splats the viewer never draws, broken splats, faint splats, splats outside a
box, all but the N most important.

Each filter has a ``*_mask`` function (which rows it keeps, computed without
copying anything) and a scene function returning ``(Scene, OpReport)``. The
edit pipeline (:mod:`splatconv.ops.edit`) combines the masks and copies the
survivors once.
"""

from __future__ import annotations

import numpy as np

from .. import viewer
from ..errors import UsageError
from ..model import COLUMNS, MOTION, POSITION, SCALE, Scene, row_fields
from ..wording import kinds_text, plural
from ._table import blockwise, derive, gather, keep_rows, run_blocks
from .report import OpReport
from .step import Rows, Step

#: What removes a splat in :func:`drop_nonfinite`: a value the viewer gives no meaning
#: (:data:`splatconv.viewer.MEANINGFUL_INFINITIES`, per group).
NONFINITE_RULES = viewer.MEANINGFUL_INFINITIES
#: Groups whose every value must be finite for a splat to be kept.
FINITE_GROUPS = {g: names for g, (names, kept) in NONFINITE_RULES.items() if not kept}
#: Groups where only NaN removes a splat: both infinities mean something to the viewer.
NAN_GROUPS = {g: names for g, (names, kept) in NONFINITE_RULES.items() if len(kept) == 2}

# --------------------------------------------------------------------------
# drop-undrawable

def undrawable_kinds(columns: dict) -> np.ndarray:
    """:func:`splatconv.viewer.undrawable_kinds` of every row, a block at a time: ``(N,) int8``."""
    return blockwise(viewer.undrawable_kinds, columns, COLUMNS, dtype=np.int8)


def undrawable_report(kinds: np.ndarray, alive: np.ndarray | None = None) -> OpReport:
    """The report of :func:`drop_undrawable` for ``kinds`` (``(N,) int8``, :func:`undrawable_kinds`) over the
    rows ``alive`` (all when None); ``counts``: splats removed of each kind."""
    live = kinds if alive is None else kinds[alive]
    count_in = len(live)
    by_kind = np.bincount(live.astype(np.intp) + 1, minlength=len(viewer.UNDRAWABLE_KINDS) + 1)[1:]
    report = OpReport("drop-undrawable", count_in, count_in - int(by_kind.sum()))
    report.counts = {kind: int(c) for kind, c in zip(viewer.UNDRAWABLE_KINDS, by_kind)}
    if report.removed:
        report.notes.append(f"drop-undrawable: removed {report.removed:,} of {plural(count_in, 'splat')} the viewer "
                            f"can never draw ({kinds_text(report.counts)})")
    else:
        report.notes.append(f"drop-undrawable: removed 0 of {plural(count_in, 'splat')}: the viewer can draw "
                            f"every one")
    return report


def drop_undrawable(scene: Scene) -> tuple[Scene, OpReport]:
    """Remove the splats the viewer can never draw at any time in [0, 1].

    What is undrawable is :func:`splatconv.viewer.undrawable_kinds`: a zero
    rotation with zero omega, a NaN position or motion term, an alpha byte of 0,
    or a temporal opacity below the cut over all of [0, 1]. None of them adds
    anything to any pixel at any time, so every splat that is drawn is drawn the
    same without them (the viewer's depth sort spreads its 65,536 depth buckets
    over every record, drawn or not, so the order it gives splats of nearly equal
    depth, and which farthest splat it leaves out, can change, as removing any
    splat can change them).

    Returns
    -------
    (Scene, OpReport)
        The scene without those splats (the same columns when none is removed),
        and ``counts``: splats removed of each kind (:data:`splatconv.viewer.UNDRAWABLE_KINDS`).
    """
    kinds = undrawable_kinds(scene.columns)
    report = undrawable_report(kinds)
    return derive(scene, keep_rows(scene, kinds == viewer.DRAWABLE), report.notes), report


# --------------------------------------------------------------------------
# drop-nonfinite


def nonfinite_mask(columns: dict) -> np.ndarray:
    """Rows :func:`drop_nonfinite` keeps: ``(N,) bool`` (see :data:`NONFINITE_RULES`).

    A row is dropped when any position, rotation, motion, omega or trbf centre
    value is NaN or infinite, when a scale is NaN or +inf (-inf, a flat splat, is
    kept), when its trbf scale is NaN or -inf, or when its opacity or a colour
    value is NaN.
    """
    out = np.empty(len(columns["x"]), dtype=bool)
    test = nonfinite_tester(columns)

    def job(part):
        out[part] = test(part, {name: columns[name][part] for name in _CHECKED})

    run_blocks(len(out), job)
    return out


_RULES = [(name, kept) for names, kept in NONFINITE_RULES.values() for name in names]
#: Columns where any infinity removes a splat; where only NaN does; and, for the
#: columns that keep one infinity, the other one, which removes it.
_FINITE = [name for name, kept in _RULES if not kept]
_NAN_ONLY = [name for name, kept in _RULES if kept]
_BAD_INFINITY = {name: -kept[0] for name, kept in _RULES if len(kept) == 1}
_CHECKED = tuple(_FINITE + _NAN_ONLY)


def nonfinite_tester(columns: dict):
    """``test(part, block)``: :func:`nonfinite_mask` of the rows ``part`` of ``columns`` (``block`` their views)."""
    found = row_fields([columns[name] for name in _CHECKED])
    if found is None:
        return lambda part, block: _nonfinite_block(block)
    # Fields of one row table: test a block's rows whole, a few calls instead of ~90.
    matrix, fields = found
    finite, nan_only = fields[:len(_FINITE)], fields[len(_FINITE):]

    def test(part, block):
        rows = matrix[part]
        bad = ~np.isfinite(rows)[:, finite].all(axis=1)
        bad |= np.isnan(rows[:, nan_only]).any(axis=1)
        for name, infinity in _BAD_INFINITY.items():
            bad |= block[name] == infinity
        return ~bad

    return test


def _nonfinite_block(block: dict) -> np.ndarray:
    """:func:`nonfinite_mask` of one block of separate columns."""
    acc = np.zeros(len(block["x"]), dtype=np.float32)
    part = np.empty_like(acc)
    with np.errstate(invalid="ignore"):
        # v * 0 is 0 for finite v and NaN for NaN or +-inf: their sum is NaN exactly
        # when some value is non-finite.
        for name in _FINITE:
            np.multiply(block[name], np.float32(0), out=part)
            acc += part
        for name in _NAN_ONLY:
            np.multiply(block[name], np.float32(0), out=part)
            # +-inf * 0 is NaN too: count only the NaN inputs.
            np.copyto(part, 0, where=~np.isnan(block[name]))
            acc += part
    # The infinity a column does not keep (a scale of +inf; a trbf scale of -inf, a
    # zero-width temporal basis, never visible: 0/0 at its centre).
    for name, infinity in _BAD_INFINITY.items():
        acc[block[name] == infinity] = np.nan
    return acc == acc


def _nonfinite_counts(columns: dict, rows: np.ndarray) -> dict:
    """Of rows ``rows``, how many have a disqualifying value in each group (a row may count in several)."""
    counts = {}
    with np.errstate(invalid="ignore"):  # signalling NaNs compared
        for group, (names, kept) in NONFINITE_RULES.items():
            bad = np.zeros(len(rows), dtype=bool)
            for name in names:
                v = np.asarray(columns[name])[rows]
                bad |= np.isnan(v) | (np.isinf(v) & ~np.isin(v, kept))
            if bad.any():
                counts[group] = int(bad.sum())
    return counts


def nonfinite_report(columns: dict, keep: np.ndarray, alive: np.ndarray | None = None) -> OpReport:
    """The report of :func:`drop_nonfinite` for mask ``keep`` over the rows ``alive`` (all when None)."""
    count_in = len(keep) if alive is None else int(alive.sum())
    dropped = ~keep if alive is None else alive & ~keep
    rows = np.flatnonzero(dropped)
    report = OpReport("drop-nonfinite", count_in, count_in - len(rows))
    if len(rows):
        report.counts = _nonfinite_counts(columns, rows)
        groups = ", ".join(f"{g} {c:,}" for g, c in report.counts.items())
        report.notes.append(f"drop-nonfinite: removed {len(rows):,} of {plural(count_in, 'splat')} with a NaN or infinite "
                            f"value ({groups}; a splat may count in several)")
    else:
        report.notes.append(f"drop-nonfinite: removed 0 of {plural(count_in, 'splat')}: none has a NaN or an infinity "
                            f"that removes it")
    return report


def drop_nonfinite(scene: Scene) -> tuple[Scene, OpReport]:
    """Remove splats the viewer cannot draw sensibly because of a NaN or infinity.

    Removed: a NaN or infinite position, rotation, motion, omega or trbf centre
    value (the splat is nowhere, everywhere or shapeless); a NaN or +inf scale
    (a log scale of +inf is an infinitely large splat); a NaN or -inf
    trbf scale (NaN: the temporal opacity is NaN, which the viewer's 0.02 cut
    does not hide and which blends as garbage; -inf: zero temporal width, never
    visible); a NaN opacity (written as alpha 0: never visible, dead weight); a
    NaN colour (written as byte 0: the splat draws as a dark blot, an artefact of
    a diverged training step, not a colour). Kept: a log scale of -inf (a linear
    scale of exactly 0: a flat splat, which the viewer draws), a trbf scale of
    +inf ("visible at every time"), an opacity or colour of +-inf (the viewer's
    sigmoid and clamp give them 0 or 1). See :data:`NONFINITE_RULES`.

    Parameters
    ----------
    scene : Scene

    Returns
    -------
    (Scene, OpReport)
        The scene without those splats (the same columns when none is removed),
        and counts per attribute group.
    """
    keep = nonfinite_mask(scene.columns)
    report = nonfinite_report(scene.columns, keep)
    return derive(scene, keep_rows(scene, keep), report.notes), report


# --------------------------------------------------------------------------
# min-opacity


def opacity_mask(columns: dict, minimum: float) -> np.ndarray:
    """Rows :func:`min_opacity` keeps: peak opacity sigmoid(opacity) >= ``minimum``; ``(N,) bool``.

    A NaN opacity is below every minimum (the writer stores it as alpha 0).
    """
    return blockwise(opacity_tester(minimum), columns, ("opacity",))


def opacity_tester(minimum: float):
    """``test(block)``: :func:`opacity_mask` of one block of columns."""
    least = opacity_threshold(minimum)
    return lambda block: block["opacity"] >= least


def opacity_threshold(minimum: float) -> np.float32:
    """The least float32 opacity x with sigmoid(x) >= ``minimum`` (-inf when all do; NaN, which no
    comparison passes, when none does).

    The viewer's float64 sigmoid (:func:`splatconv.viewer.opacity`) never
    decreases, so ``opacity >= threshold`` keeps exactly the rows whose peak
    opacity reaches ``minimum`` (a NaN neither): one float32 comparison a row
    instead of a sigmoid. Found by bisection over the float32 values, ordered as
    integers, with the viewer's own function.
    """
    minimum = float(minimum)

    def value(key: int) -> np.float32:  # the float32 at position `key` of the ordered values
        bits = key if key >= 0 else 0x80000000 | -key
        return np.array([bits], dtype=np.uint32).view(np.float32)[0]

    def reaches(key: int) -> bool:
        return bool(viewer.opacity({"opacity": np.array([value(key)])})[0] >= minimum)

    lo, hi = -0x7F800000, 0x7F800000  # -inf, +inf
    if reaches(lo):
        return value(lo)
    if not reaches(hi):
        return np.float32(np.nan)
    while hi - lo > 1:  # reaches(hi) and not reaches(lo)
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if reaches(mid) else (mid, hi)
    return value(hi)


def check_minimum(minimum: float) -> float:
    """``minimum`` as a float in [0, 1]; :class:`~splatconv.errors.UsageError` when it is not."""
    minimum = float(minimum)
    if not 0.0 <= minimum <= 1.0:
        raise UsageError(f"--min-opacity: {minimum:g} is outside [0, 1]")
    return minimum


def opacity_report(keep: np.ndarray, minimum: float, alive: np.ndarray | None = None) -> OpReport:
    """The report of :func:`min_opacity` for mask ``keep`` over the rows ``alive`` (all when None)."""
    count_in = len(keep) if alive is None else int(alive.sum())
    removed = int((~keep).sum() if alive is None else (alive & ~keep).sum())
    report = OpReport("min-opacity", count_in, count_in - removed)
    report.notes.append(f"min-opacity: removed {removed:,} of {plural(count_in, 'splat')} with peak opacity below "
                        f"{minimum:g}")
    return report


def min_opacity(scene: Scene, minimum: float) -> tuple[Scene, OpReport]:
    """Remove splats whose peak opacity sigmoid(opacity) is below ``minimum``.

    The peak is the stored opacity through the viewer's sigmoid, which the splat
    reaches at its trbf centre; the temporal fade only lowers it.

    Parameters
    ----------
    scene : Scene
    minimum : float
        In [0, 1].

    Raises
    ------
    UsageError
        When ``minimum`` is outside [0, 1].
    """
    minimum = check_minimum(minimum)
    keep = opacity_mask(scene.columns, minimum)
    report = opacity_report(keep, minimum)
    return derive(scene, keep_rows(scene, keep), report.notes), report


# --------------------------------------------------------------------------
# crop


def peak_time(columns: dict, window=viewer.TIME_RANGE) -> np.ndarray:
    """When each splat is most opaque within ``window``: trbf centre clamped to it, ``(N,) float64``.

    The temporal opacity peaks at the trbf centre and falls away on both sides,
    so within a time range its largest value is at the centre clamped to the
    range. NaN where the centre is NaN.
    """
    centre = viewer.wide(columns["trbf_center"])
    return np.clip(centre, window[0], window[1])


def crop_mask(columns: dict, lo, hi, window=viewer.TIME_RANGE) -> np.ndarray:
    """Rows :func:`crop` keeps: centre at the time of peak opacity inside the box ``lo``..``hi``; ``(N,) bool``.

    Bounds are inclusive; a NaN centre is never inside. Where the time of peak
    opacity is the trbf centre itself (dt = 0) the centre is the rest position
    xyz: the motion terms are m dt^k = 0 there (a NaN motion value is not looked
    at; ``drop_nonfinite`` is for those).
    """
    return blockwise(crop_tester(lo, hi, window), columns, POSITION + MOTION + ("trbf_center",))


def crop_tester(lo, hi, window=viewer.TIME_RANGE):
    """``test(block)``: :func:`crop_mask` of one block of columns."""
    lo = [np.float64(v) for v in lo]  # compared in float64 with the float64 centres
    hi = [np.float64(v) for v in hi]
    # The float32 values are compared with float32 bounds that decide alike (no widening).
    lo32, hi32 = zip(*(_float32_bounds(a, b) for a, b in zip(lo, hi)))
    start, end = _float32_bounds(*window)

    def inside(block):
        ok = (block["x"] >= lo32[0]) & (block["x"] <= hi32[0])
        for i, name in enumerate(POSITION[1:], 1):
            ok &= block[name] >= lo32[i]
            ok &= block[name] <= hi32[i]
        # Motion terms vanish where the peak is the trbf centre itself (dt = 0, the usual
        # case): the motion is evaluated only for the splats whose centre lies outside
        # the window (or is NaN).
        centre = block["trbf_center"]
        moving = np.flatnonzero(~((centre >= start) & (centre <= end)))
        if len(moving):
            part = {name: block[name][moving] for name in POSITION + MOTION + ("trbf_center",)}
            at = viewer.position_at(part, peak_time(part, window))
            ok[moving] = ((at >= lo) & (at <= hi)).all(axis=1)
        return ok

    return inside


#: The crop value (:func:`crop_values`) of a splat outside the box.
OUTSIDE = -2


def crop_values(columns: dict, lo, hi, window=viewer.TIME_RANGE) -> np.ndarray:
    """What :func:`crop` finds of each row: ``(N,) int8``, :data:`OUTSIDE` for a row outside the box
    (:func:`crop_mask`), else its :func:`splatconv.viewer.undrawable_kinds` code (-1: drawable), so that
    the report can say how many splats the box keeps that the viewer can never draw."""
    return blockwise(crop_value_tester(lo, hi, window), columns, COLUMNS, dtype=np.int8)


def crop_value_tester(lo, hi, window=viewer.TIME_RANGE):
    """``test(block)``: :func:`crop_values` of one block of columns."""
    inside = crop_tester(lo, hi, window)
    return lambda block: np.where(inside(block), viewer.undrawable_kinds(block), np.int8(OUTSIDE)).astype(np.int8)


def _float32_bounds(lo: float, hi: float) -> tuple:
    """float32 bounds that decide as ``lo``, ``hi`` do: for every float32 v (and NaN),
    ``lo <= v`` exactly when ``lo32 <= v``, and ``v <= hi`` exactly when ``v <= hi32``.

    ``lo32`` is the least float32 >= ``lo``, ``hi32`` the greatest <= ``hi`` (an
    infinity where there is none).
    """
    with np.errstate(over="ignore"):
        lo32, hi32 = np.float32(lo), np.float32(hi)
    if float(lo32) < lo:
        lo32 = np.nextafter(lo32, np.float32(np.inf))
    if float(hi32) > hi:
        hi32 = np.nextafter(hi32, np.float32(-np.inf))
    return lo32, hi32


def check_box(lo, hi) -> tuple:
    """Validate a crop box: two finite (3,) corners with lo <= hi; returns them as tuples of float."""
    lo = tuple(float(v) for v in lo)
    hi = tuple(float(v) for v in hi)
    if len(lo) != 3 or len(hi) != 3 or not all(np.isfinite(lo + hi)):
        raise UsageError("--crop: expected six finite numbers X0,Y0,Z0,X1,Y1,Z1")
    for axis, a, b in zip("xyz", lo, hi):
        if a > b:
            raise UsageError(f"--crop: the box is empty along {axis} ({a:g} > {b:g})")
    return lo, hi


def crop_report(values: np.ndarray, lo, hi, alive: np.ndarray | None = None) -> OpReport:
    """The report of :func:`crop` for ``values`` (:func:`crop_values`) over the rows ``alive`` (all when None).

    ``counts``: the splats kept in the box that the viewer can never draw, by kind
    (:data:`splatconv.viewer.UNDRAWABLE_KINDS`); a second note names them when there are any
    (``--drop-undrawable``, which comes first, leaves none).
    """
    keep = values != OUTSIDE
    count_in = len(keep) if alive is None else int(alive.sum())
    kept = keep if alive is None else alive & keep
    removed = count_in - int(kept.sum())
    report = OpReport("crop", count_in, count_in - removed)
    box = f"({', '.join(f'{v:g}' for v in lo)}) .. ({', '.join(f'{v:g}' for v in hi)})"
    report.notes.append(f"crop: removed {removed:,} of {plural(count_in, 'splat')} whose centre at peak opacity lies "
                        f"outside {box}")
    report.counts = viewer.kind_counts(values[kept])
    undrawable = sum(report.counts.values())
    if undrawable:
        report.notes.append(f"crop: {undrawable:,} of the {plural(report.count_out, 'splat')} kept in the box the "
                            f"viewer can never draw ({kinds_text(report.counts)})")
    return report


def crop(scene: Scene, lo, hi) -> tuple[Scene, OpReport]:
    """Keep splats whose centre, at their time of peak opacity, lies in an axis-aligned box.

    The time of peak opacity is the trbf centre clamped to the viewer's [0, 1]
    (:func:`peak_time`): the moment the splat is most visible in the clip. The
    centre there includes the motion (:func:`splatconv.viewer.position_at`).

    Parameters
    ----------
    scene : Scene
    lo, hi : sequence of 3 float
        Box corners; bounds inclusive.

    Raises
    ------
    UsageError
        When a bound is not finite or ``lo`` exceeds ``hi`` on an axis.
    """
    lo, hi = check_box(lo, hi)
    values = crop_values(scene.columns, lo, hi)
    report = crop_report(values, lo, hi)
    return derive(scene, keep_rows(scene, values != OUTSIDE), report.notes), report


# --------------------------------------------------------------------------
# max-splats


def importance_key(columns: dict) -> np.ndarray:
    """The writer's importance key of every row, ``(N,) float64`` (:func:`splatconv.viewer.importance`)."""
    return blockwise(viewer.importance, columns, ("opacity",) + SCALE, dtype=np.float64)


def most_important(columns: dict, count: int, rows: np.ndarray | None = None, key: np.ndarray | None = None):
    """The ``count`` most important of ``rows`` (all when None), in ascending row order: ``(M,) intp``.

    Importance as the writer sorts by it (:func:`splatconv.viewer.importance`,
    ties in row order, NaN last; :func:`splatconv.viewer.importance_order`).
    ``key`` is :func:`importance_key` of ``columns`` when already computed.
    """
    key = importance_key(columns) if key is None else key
    if rows is None:
        rows = np.arange(len(key))
    else:
        key = key[rows]
    if count >= len(rows):
        return rows
    chosen = viewer.importance_order(key)[:count]
    chosen.sort()
    return rows[chosen]


def check_count(count: int) -> int:
    """``count`` as a whole number >= 0; :class:`~splatconv.errors.UsageError` when it is not."""
    if isinstance(count, bool) or int(count) != count or count < 0:
        raise UsageError(f"--max-splats: expected a count >= 0, got {count!r}")
    return int(count)


def max_splats_report(count_in: int, count_out: int, limit: int) -> OpReport:
    """The report of :func:`max_splats`."""
    report = OpReport("max-splats", count_in, count_out)
    if count_out < count_in:
        report.notes.append(f"max-splats: kept the {count_out:,} most important of {plural(count_in, 'splat')}, "
                            f"removed {count_in - count_out:,}")
    else:
        report.notes.append(f"max-splats: {plural(count_in, 'splat')} are within {limit:,}, none removed")
    return report


def max_splats(scene: Scene, count: int) -> tuple[Scene, OpReport]:
    """Keep the ``count`` most important splats, in their input order.

    Importance is the key the writer sorts by: exp(scale_0) exp(scale_1)
    exp(scale_2) sigmoid(opacity); equal keys keep the earlier row, NaN keys go last.

    Parameters
    ----------
    scene : Scene
    count : int
        At least 0.
    """
    count = check_count(count)
    rows = most_important(scene.columns, count)
    report = max_splats_report(scene.count, len(rows), count)
    columns = scene.columns if len(rows) == scene.count else gather(scene.columns, rows)
    return derive(scene, columns, report.notes), report


# --------------------------------------------------------------------------
# The filters as steps of a plan (splatconv.ops.edit.apply_edits)


class DropUndrawable(Step):
    """:func:`drop_undrawable` as a step; its values are the kinds (``int8``, -1: drawable)."""

    name = "drop-undrawable"
    dtype = np.int8

    def tester(self, columns: dict):
        return lambda part, block: viewer.undrawable_kinds(block)

    def apply(self, rows: Rows, kinds: np.ndarray) -> OpReport:
        report = undrawable_report(kinds, rows.alive)
        rows.keep(kinds == viewer.DRAWABLE)
        return report


class DropNonfinite(Step):
    """:func:`drop_nonfinite` as a step."""

    name = "drop-nonfinite"

    def tester(self, columns: dict):
        return nonfinite_tester(columns)

    def apply(self, rows: Rows, keep: np.ndarray) -> OpReport:
        report = nonfinite_report(rows.columns, keep, rows.alive)
        rows.keep(keep)
        return report


class Crop(Step):
    """:func:`crop` to the box (``lo``, ``hi``) as a step (the box checked by :func:`check_box`); its
    values are :func:`crop_values` (``int8``)."""

    name = "crop"
    dtype = np.int8

    def __init__(self, lo, hi):
        self.lo, self.hi = check_box(lo, hi)

    def tester(self, columns: dict):
        values = crop_value_tester(self.lo, self.hi)
        return lambda part, block: values(block)

    def apply(self, rows: Rows, values: np.ndarray) -> OpReport:
        report = crop_report(values, self.lo, self.hi, rows.alive)
        rows.keep(values != OUTSIDE)
        return report


class MinOpacity(Step):
    """:func:`min_opacity` as a step."""

    name = "min-opacity"

    def __init__(self, minimum: float):
        self.minimum = check_minimum(minimum)

    def tester(self, columns: dict):
        opaque = opacity_tester(self.minimum)
        return lambda part, block: opaque(block)

    def apply(self, rows: Rows, keep: np.ndarray) -> OpReport:
        report = opacity_report(keep, self.minimum, rows.alive)
        rows.keep(keep)
        return report


class MaxSplats(Step):
    """:func:`max_splats` as a step; its values are the importance key (``float64``)."""

    name = "max-splats"
    dtype = np.float64

    def __init__(self, count: int):
        self.count = check_count(count)

    def tester(self, columns: dict):
        return lambda part, block: importance_key(block)

    def apply(self, rows: Rows, key: np.ndarray) -> OpReport:
        n = len(rows.columns["x"])
        alive = None if rows.alive is None else np.flatnonzero(rows.alive)
        chosen = most_important(rows.columns, self.count, alive, key=key)
        report = max_splats_report(rows.count, len(chosen), self.count)
        if len(chosen) < n:
            mask = np.zeros(n, dtype=bool)
            mask[chosen] = True  # a subset of the rows kept so far
            rows.keep(mask)
        return report


__all__ = ["NONFINITE_RULES", "FINITE_GROUPS", "NAN_GROUPS", "undrawable_kinds", "drop_undrawable",
           "nonfinite_mask", "drop_nonfinite", "opacity_mask", "min_opacity",
           "peak_time", "crop_mask", "crop_values", "OUTSIDE", "check_box", "crop", "importance_key", "most_important",
           "max_splats", "check_minimum", "check_count", "DropUndrawable", "DropNonfinite", "Crop", "MinOpacity",
           "MaxSplats"]
