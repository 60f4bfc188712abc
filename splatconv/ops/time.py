"""Time: map a clip's timeline linearly (trim, placing a clip in part of [0, 1]).

A linear time map t' = (t - origin) / duration changes no image: the scene at
t' after the map is the scene at t = origin + t' * duration before it. With
dt = t - c and dt' = t' - c' for the trbf centre c' = (c - origin) / duration,
dt = dt' * duration, so

* the temporal basis exp(-(dt / exp(s))^2) keeps its values with
  exp(s') = exp(s) / |duration|, i.e. s' = s - log|duration| (the scale is stored as a log);
* motion terms m_k dt^k become (m_k duration^k) dt'^k (k = 1, 2, 3);
* rot + omega dt becomes rot + (omega duration) dt'.

Positions, rest rotations, scales, opacity and colour do not change.
"""

from __future__ import annotations

import math

import numpy as np

from .. import viewer
from ..errors import UsageError
from ..model import MOTION, OMEGA, TRBF, Scene
from ..wording import plural
from ._table import blockwise, copy_rows, derive, run_blocks
from .report import OpReport
from .step import Rows, Step


def _check_map(origin: float, duration: float) -> tuple:
    origin, duration = float(origin), float(duration)
    if not (math.isfinite(origin) and math.isfinite(duration) and duration != 0.0):
        raise UsageError(f"a time map needs a finite origin and a finite, non-zero duration "
                         f"(got {origin:g}, {duration:g})")
    return origin, duration


def remap_columns(columns: dict, origin: float, duration: float) -> int:
    """Apply t' = (t - origin) / duration to writeable ``columns`` in place.

    Parameters
    ----------
    columns : dict of str to (N,) float32 ndarray
        Writeable; trbf centre and scale, motion and omega are rewritten.
    origin, duration : float
        Finite; ``duration`` non-zero (negative plays the clip backwards).

    Returns
    -------
    int
        Values that were finite and no longer fit float32 (now infinite).
    """
    origin, duration = _check_map(origin, duration)
    return sum(run_blocks(len(columns["x"]), lambda part: _remap_block(
        {name: columns[name][part] for name in _TIMED}, origin, duration)))


_TIMED = TRBF + MOTION + OMEGA


def _remap_block(block: dict, origin: float, duration: float) -> int:
    """:func:`remap_columns` on one block of rows; returns the values that outgrew float32."""
    log_duration = math.log(abs(duration))
    jobs = [("trbf_center", lambda v: (v - origin) / duration)]
    if log_duration != 0.0:
        # Wider or narrower in time by |duration|: subtract its log (+inf stays +inf: visible always).
        jobs.append(("trbf_scale", lambda v: v - log_duration))
    for k in range(3):
        factor = duration ** (k + 1)
        if factor != 1.0:
            jobs += [(name, lambda v, f=factor: v * f) for name in MOTION[3 * k:3 * k + 3]]
    if duration != 1.0:
        jobs += [(name, lambda v: v * duration) for name in OMEGA]
    return sum(_rewrite(block[name], fn) for name, fn in jobs)


def _rewrite(column: np.ndarray, fn) -> int:
    """Replace float32 ``column`` by ``fn(column in float64)``; count finite values that became infinite.

    NaN and inf go through as they are. Overflow (in the arithmetic or in the
    cast back to float32) raises, and only then is the column redone and counted.
    """
    values = viewer.wide(column)
    try:
        with np.errstate(invalid="ignore", over="raise"):
            column[...] = fn(values)
        return 0
    except FloatingPointError:
        with np.errstate(invalid="ignore", over="ignore"):
            column[...] = fn(values)
        return int((np.isinf(column) & np.isfinite(values)).sum())


def _overflow_note(op: str, overflow: int) -> list:
    if not overflow:
        return []
    return [f"{op}: {overflow:,} finite values grew beyond float32 and are now infinite"]


def remap_time(scene: Scene, origin: float, duration: float) -> tuple[Scene, OpReport]:
    """Map the timeline linearly: what was at time t is at t' = (t - origin) / duration.

    The interval [origin, origin + duration] becomes [0, 1]. Splat for splat,
    the scene drawn at t' afterwards equals the scene drawn at
    origin + t' * duration before (see the module docstring for the terms).

    Parameters
    ----------
    scene : Scene
    origin, duration : float
        Finite; ``duration`` non-zero.

    Returns
    -------
    (Scene, OpReport)
        A new scene (no splat removed).

    Raises
    ------
    UsageError
        When ``origin`` or ``duration`` is not finite, or ``duration`` is 0.

    Examples
    --------
    Place a clip's [0, 1] in [u0, u1] of a longer timeline (segment i of n:
    u0 = i/n, u1 = (i + 1)/n) with :func:`place_in`.
    """
    origin, duration = _check_map(origin, duration)
    columns, overflow = copy_rows(scene.columns, each=lambda block: _remap_block(block, origin, duration))
    report = OpReport("time-map", scene.count, scene.count)
    report.notes.append(f"time-map: t' = (t - {origin:g}) / {duration:g} applied to {plural(scene.count, 'splat')}")
    report.notes += _overflow_note("time-map", overflow)
    report.counts = {"overflow": overflow}
    return derive(scene, columns, report.notes), report


def place_in(scene: Scene, start: float, end: float) -> tuple[Scene, OpReport]:
    """Map the clip's [0, 1] onto [start, end]: t' = start + t (end - start).

    For putting a clip in part of a longer timeline (a segment among several).
    The same as ``remap_time(scene, -start / (end - start), 1 / (end - start))``.
    """
    start, end = float(start), float(end)
    if not (math.isfinite(start) and math.isfinite(end) and end != start):
        raise UsageError(f"cannot place a clip in [{start:g}, {end:g}]")
    span = end - start
    return remap_time(scene, -start / span, 1.0 / span)


def check_interval(t0: float, t1: float) -> tuple:
    """Validate a trim interval: 0 <= t0 < t1 <= 1; returns it as floats."""
    t0, t1 = float(t0), float(t1)
    lo, hi = viewer.TIME_RANGE
    if not (lo <= t0 < t1 <= hi):
        raise UsageError(f"--trim: expected {lo:g} <= T0 < T1 <= {hi:g}, got {t0:g},{t1:g}")
    return t0, t1


def visible_in_mask(columns: dict, t0: float, t1: float) -> np.ndarray:
    """Rows visible (temporal opacity >= the viewer's 0.02) at some time in [t0, t1]: ``(N,) bool``.

    A NaN trbf centre or scale is visible nowhere (the splat has no time).
    """
    def visible(block):
        first, last = viewer.visible_interval(block)
        return (last >= t0) & (first <= t1)

    return blockwise(visible, columns, TRBF)


def trim_report(count_in: int, kept: int, nan_time: int, t0: float, t1: float, overflow: int) -> OpReport:
    """The report of :func:`trim`."""
    report = OpReport("trim", count_in, kept)
    removed = count_in - kept
    why = f" ({nan_time:,} of them with a NaN trbf centre or scale)" if nan_time else ""
    report.notes.append(f"trim: removed {removed:,} of {plural(count_in, 'splat')} not visible in [{t0:g}, {t1:g}]{why}; "
                        f"that interval now spans the clip's [0, 1] (times t' = (t - {t0:g}) / {t1 - t0:g}, "
                        f"motion and angular velocity rescaled to match)")
    report.notes += _overflow_note("trim", overflow)
    report.counts = {"removed": removed, "nan_time": nan_time, "overflow": overflow}
    return report


def _nan_time(columns: dict, rows: np.ndarray) -> int:
    c = np.asarray(columns["trbf_center"])[rows]
    s = np.asarray(columns["trbf_scale"])[rows]
    return int((np.isnan(c) | np.isnan(s)).sum())


def trim(scene: Scene, t0: float, t1: float) -> tuple[Scene, OpReport]:
    """Keep what is visible somewhere in [t0, t1] and map that interval onto [0, 1].

    A splat is kept when its temporal opacity reaches the viewer's cut (0.02)
    at some time in [t0, t1]; then t' = (t - t0) / (t1 - t0) (:func:`remap_columns`),
    so the trimmed scene drawn at t' equals the original drawn at
    t0 + t' (t1 - t0).

    Parameters
    ----------
    scene : Scene
    t0, t1 : float
        0 <= t0 < t1 <= 1.

    Raises
    ------
    UsageError
        When the interval is not inside [0, 1] or is empty.
    """
    t0, t1 = check_interval(t0, t1)
    keep = visible_in_mask(scene.columns, t0, t1)
    dropped = np.flatnonzero(~keep)
    columns, overflow = copy_rows(scene.columns, np.flatnonzero(keep),
                                  each=lambda block: _remap_block(block, t0, t1 - t0))
    report = trim_report(scene.count, scene.count - len(dropped), _nan_time(scene.columns, dropped), t0, t1,
                         overflow)
    return derive(scene, columns, report.notes), report


class Trim(Step):
    """:func:`trim` to [``t0``, ``t1``] as a step of a plan: it keeps the splats visible in the
    interval and copies them with the interval's time map (the steps after it read the copy)."""

    name = "trim"
    retimes = True

    def __init__(self, t0: float, t1: float):
        self.t0, self.t1 = check_interval(t0, t1)

    def tester(self, columns: dict):
        return lambda part, block: visible_in_mask(block, self.t0, self.t1)

    def apply(self, rows: Rows, keep: np.ndarray) -> OpReport:
        t0, t1 = self.t0, self.t1
        count_in = rows.count
        dropped = ~keep if rows.alive is None else rows.alive & ~keep
        nan_time = _nan_time(rows.columns, np.flatnonzero(dropped))
        rows.keep(keep)
        columns, overflow = copy_rows(rows.columns, np.flatnonzero(rows.alive),
                                      each=lambda block: _remap_block(block, t0, t1 - t0))
        rows.columns, rows.alive, rows.owned = columns, None, True
        return trim_report(count_in, len(columns["x"]), nan_time, t0, t1, overflow)


__all__ = ["remap_columns", "remap_time", "place_in", "check_interval", "visible_in_mask", "trim", "Trim"]
