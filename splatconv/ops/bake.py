"""Bake a moment: the scene as the viewer shows it at one time, as a static scene.

At time ``t`` the viewer draws each splat (see :mod:`splatconv.viewer`) at
``position_at(t)``, turned by ``rotation_at(t)``, with opacity
``sigmoid(opacity) * temporal_opacity(t)``, and skips it when the temporal
opacity is below the 0.02 cut. The baked splat holds exactly those values:

* position and rotation at ``t`` (the rotation normalised, as the viewer uses it);
* opacity logit(sigmoid(opacity) * temporal opacity), computed in log space so
  that neither a very opaque nor a very faint splat loses precision;
* scale and colour as they are;
* no motion, no omega, and the model's static temporal basis
  (:data:`splatconv.model.STATIC_TRBF_CENTER`, :data:`~splatconv.model.STATIC_TRBF_SCALE`:
  temporal opacity above 0.999999 at every time in [0, 1]), so the baked
  scene shows the same picture at every time, at full baked opacity.

Splats under the cut at ``t`` are removed, and so are splats whose temporal
opacity is NaN (a NaN trbf centre or scale: the viewer's drawing of them is
undefined). Everything else is kept as the viewer would draw it, NaN
positions included (``--drop-nonfinite`` removes those).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .. import model, viewer
from ..errors import UsageError
from ..model import Scene
from ..wording import plural
from .report import OpReport


def frame_times(count: int) -> np.ndarray:
    """Times of ``count`` frames spread over the viewer's clip: ``(count,) float64``, k / (count - 1).

    The first frame is at 0 and the last at 1, the times the frame-sequence
    input reads a folder of frames at.

    Raises
    ------
    UsageError
        For fewer than two frames (one frame has no k / (N - 1)).
    """
    if count < 2:
        raise UsageError(f"--frames {count}: at least 2 frames (frame k is at time k/(N-1))")
    return np.arange(count, dtype=np.float64) / (count - 1)


@dataclass
class BakeReport(OpReport):
    """What baking did: an :class:`~splatconv.ops.report.OpReport` (``op`` ``"bake"``) and the time.

    ``counts``: ``hidden``, splats under the viewer's 0.02 cut at ``time``;
    ``undefined``, splats with a NaN temporal opacity (both removed);
    ``faded``, kept splats whose opacity the temporal opacity lowered.
    """

    time: float = 0.0


def baked_opacity(opacity: np.ndarray, temporal: np.ndarray) -> np.ndarray:
    """logit(sigmoid(opacity) * temporal), computed in log space: ``(N,) float64``.

    log(sigmoid(x)) = -log(1 + exp(-x)) and logit(p) = log p - log(1 - p) with
    log(1 - p) = log(-expm1(log p)): no rounding to 0 or 1 on the way, so an
    opacity of 30 or -30 keeps its value where ``temporal`` is 1. A temporal
    opacity of exactly 1 keeps the opacity as it is. NaN stays NaN.

    Parameters
    ----------
    opacity : (N,) float ndarray
        Logits.
    temporal : (N,) float64 ndarray
        Temporal opacities in (0, 1].
    """
    x = viewer.wide(opacity)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        log_p = -np.logaddexp(0.0, -x) + np.log(temporal)
        out = log_p - np.log(-np.expm1(log_p))
    return np.where(temporal == 1.0, x, out)


def bake(scene: Scene, time: float) -> tuple[Scene, BakeReport]:
    """The scene as the viewer shows it at ``time``, as a static scene.

    Parameters
    ----------
    scene : Scene
    time : float
        Scene time; the viewer plays [0, 1] (other finite times are allowed).

    Returns
    -------
    (Scene, BakeReport)
        The baked scene (variant :data:`splatconv.model.VARIANT_3DGS`, the
        input's cameras) and what was removed. The input is not changed.

    Raises
    ------
    UsageError
        For a time that is not a finite number.
    """
    t = float(time)
    if not np.isfinite(t):
        raise UsageError(f"--time {time}: not a finite number")
    cols = scene.columns
    n = scene.count
    temporal = viewer.temporal_opacity(cols, t, cut=False)
    undefined = np.isnan(temporal)
    hidden = temporal < viewer.TEMPORAL_CUTOFF
    keep = np.flatnonzero(~(hidden | undefined))
    part = _rows_of(cols, keep if len(keep) < n else None)
    m = len(keep)
    _rows, out = model.lite_rows(m)
    position = viewer.position_at(part, t)
    rotation = viewer.rotation_at(part, t)
    kept_temporal = temporal[keep]
    with np.errstate(over="ignore", invalid="ignore"):
        for i, name in enumerate(model.POSITION):
            out[name][:] = position[:, i]
        for i, name in enumerate(model.ROTATION):
            out[name][:] = rotation[:, i]
        out["opacity"][:] = baked_opacity(part["opacity"], kept_temporal)
    for name in model.SCALE + model.COLOR:
        out[name][:] = part[name]
    for name in model.MOTION + model.OMEGA:
        out[name][:] = 0.0
    out["trbf_center"][:] = model.STATIC_TRBF_CENTER
    out["trbf_scale"][:] = model.STATIC_TRBF_SCALE
    counts = {"hidden": int(np.count_nonzero(hidden)), "undefined": int(np.count_nonzero(undefined)),
              "faded": int(np.count_nonzero(kept_temporal < 1.0))}
    notes = [f"baked at t={t:g}: {m:,} of {plural(n, 'splat')} visible"]
    if counts["hidden"]:
        notes.append(f"{plural(counts['hidden'], 'splat')} hidden at t={t:g} (temporal opacity below "
                     f"{viewer.TEMPORAL_CUTOFF}) removed")
    if counts["undefined"]:
        notes.append(f"{plural(counts['undefined'], 'splat')} with a NaN trbf centre or scale (no defined opacity at "
                     "any time) removed")
    baked = Scene(columns=out, cameras=scene.cameras, variant=model.VARIANT_3DGS, meta={"baked_time": t})
    return baked, BakeReport("bake", n, m, notes, counts, time=t)


def _rows_of(cols: dict, index) -> dict:
    """Rows ``index`` (all when None) of every column; from a row table by one gather of whole rows."""
    if index is None:
        return cols
    found = model.row_fields([np.asarray(cols[name]) for name in model.COLUMNS])
    if found is None:
        return {name: np.asarray(cols[name])[index] for name in model.COLUMNS}
    matrix, fields = found
    rows = matrix[index]  # one pass over memory instead of one strided pass a column
    return {name: rows[:, f] for name, f in zip(model.COLUMNS, fields)}


def bake_frames(scene: Scene, count: int):
    """Bake ``count`` moments, frame k at time k / (count - 1) (:func:`frame_times`).

    Returns a generator, so that a caller writing the frames holds one at a time.

    Returns
    -------
    iterator of (float, Scene, BakeReport)
        The time, the baked scene and its report, frame by frame.

    Raises
    ------
    UsageError
        For fewer than two frames (at once, not on the first frame).
    """
    times = frame_times(count)
    return ((float(t), *bake(scene, float(t))) for t in times)


def frame_names(count: int, suffix: str) -> list:
    """``frame_0000`` + ``suffix`` ... one name a frame, numbered from 0 with at least 4 digits."""
    width = max(4, len(str(count - 1)))
    return [f"frame_{k:0{width}d}{suffix}" for k in range(count)]


def other_frames(files, names, suffix: str) -> list:
    """Names among ``files`` that look like frames (``frame_`` digits ``suffix``) but are not ``names``, sorted."""
    pattern = re.compile(r"frame_\d+" + re.escape(suffix) + r"\Z")
    ours = set(names)
    return sorted(f for f in files if pattern.match(f) and f not in ours)
