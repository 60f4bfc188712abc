"""Bake a moment: the scene as the viewer shows it at one time, as a static scene.

At time ``t`` the viewer draws each splat (see :mod:`splatconv.viewer`) at
``position_at(t)``, turned by ``rotation_at(t)``, with opacity
``sigmoid(opacity) * temporal_opacity(t)``. The baked splat holds exactly those values:

* position and rotation at ``t`` (the rotation normalised, as the viewer uses it);
* opacity logit(sigmoid(opacity) * temporal opacity), computed in log space so
  that neither a very opaque nor a very faint splat loses precision;
* scale and colour as they are;
* no motion, no omega, and the model's static temporal basis
  (:data:`splatconv.model.STATIC_TRBF_CENTER`, :data:`~splatconv.model.STATIC_TRBF_SCALE`:
  temporal opacity above 0.999999 at every time in [0, 1]), so the baked
  scene shows the same picture at every time, at full baked opacity.

Only splats the viewer draws at ``t`` are baked (:func:`splatconv.viewer.not_drawn_kinds_at`:
zero rotation, a NaN position, alpha zero, hidden in time below the temporal cut;
a note names them as :func:`splatconv.wording.kinds_text` does everywhere): so no zero or NaN quaternion is ever written, and a scene with or
without splats the viewer never draws bakes to the same rows. Infinities the
viewer gives a meaning to are written as finite values every reader decodes to
the same thing (:data:`FLAT_LOG_SCALE` for a flat splat's log scale, and see
:func:`finite_stand_ins`), so that readers which drop non-finite rows keep them.
Everything else is kept as the viewer would draw it, infinite positions included
(``drop_nonfinite`` removes those).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .. import model, viewer
from ..errors import UsageError
from ..model import Scene
from ..wording import kinds_text, plural
from . import filters
from .report import OpReport


#: Most frames ``bake --frames`` writes: far past any flipbook (an hour at 25 frames a second is
#: 90,000), and a folder's worth (frame names, one file each, are made before anything is read).
MAX_FRAMES = 100_000


def check_frame_count(count: int) -> None:
    """Refuse a frame count outside 2 to :data:`MAX_FRAMES`.

    Raises
    ------
    UsageError
        For fewer than two frames (one frame has no k / (N - 1)) or more than :data:`MAX_FRAMES`.
    """
    if count < 2:
        raise UsageError(f"--frames {count}: at least 2 frames (frame k is at time k/(N-1))")
    if count > MAX_FRAMES:
        raise UsageError(f"--frames {count}: at most {MAX_FRAMES:,} frames")


def frame_times(count: int) -> np.ndarray:
    """Times of ``count`` frames spread over the viewer's clip: ``(count,) float64``, k / (count - 1).

    The first frame is at 0 and the last at 1, the times the frame-sequence
    input reads a folder of frames at.

    Raises
    ------
    UsageError
        For a count :func:`check_frame_count` refuses.
    """
    check_frame_count(count)
    return np.arange(count, dtype=np.float64) / (count - 1)


#: The log scale a flat splat (linear scale exactly 0, log scale -inf) is baked
#: with: exp(-120) = 7.7e-53 is 0 in float32 and in every narrower format (a
#: ``.splat``'s float32 linear scales, the viewer's half floats), so every reader
#: draws the splat as flat as the viewer does; -inf would be as exact, but readers
#: that drop rows with a non-finite value (splat-transform's NaN filter) lose it.
FLAT_LOG_SCALE = -120.0
#: Rows baked at a time (see :func:`bake`).
_BLOCK = 1 << 13
#: Columns of a drawn splat that a bake reads beside the viewer's values at its time.
_KEPT_AS_THEY_ARE = model.OPACITY + model.SCALE + model.COLOR
#: The opacity logit an opacity of +inf is baked with: sigmoid(40) is 1 in float64
#: and float32, as sigmoid(inf) is.
OPAQUE_LOGIT = 40.0


@dataclass
class BakeReport(OpReport):
    """What baking did: an :class:`~splatconv.ops.report.OpReport` (``op`` ``"bake"``) and the time.

    ``counts``: splats left out because the viewer does not draw them at ``time``,
    by kind (:data:`splatconv.viewer.UNDRAWABLE_KINDS`); ``faded``, kept splats whose opacity
    the temporal opacity lowered; ``flat``, ``opaque`` and ``color``, splats whose
    infinities :func:`finite_stand_ins` wrote as finite values; ``nonfinite``,
    splats ``drop_nonfinite`` removed from the baked scene.
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


def bake(scene: Scene, time: float, *, drop_nonfinite: bool = False) -> tuple[Scene, BakeReport]:
    """The scene as the viewer shows it at ``time``, as a static scene.

    Parameters
    ----------
    scene : Scene
    time : float
        Scene time; the viewer plays [0, 1] (other finite times are allowed).
    drop_nonfinite : bool
        Also remove baked splats with a NaN or infinite value left in what is
        written (:func:`splatconv.ops.filters.drop_nonfinite` on the baked scene:
        positions, scales, colours; rotations and opacities are finite by then).

    Returns
    -------
    (Scene, BakeReport)
        The baked scene (variant :data:`splatconv.model.VARIANT_3DGS`, the
        input's cameras), only of splats the viewer draws at ``time``, and what
        was left out. The input is not changed.

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
    # A block of rows at a time: the viewer's float64 values of a block stay in cache, and only the
    # columns a static scene keeps are filled (the time columns are the static constants). The drawn
    # rows of each block go after those of the blocks before: the columns are made as long as the
    # scene, and only the drawn count of them is ever touched and kept.
    kinds = np.empty(n, dtype=np.int8)
    kept_names = model.POSITION + model.ROTATION + model.OPACITY + model.SCALE + model.COLOR
    full = {name: np.empty(n, dtype=np.float32) for name in kept_names}
    counts = {"faded": 0, "flat": 0, "opaque": 0, "color": 0}
    turning = 0
    m = 0
    for start in range(0, n, _BLOCK):
        rows = slice(start, min(start + _BLOCK, n))
        part = {name: np.asarray(cols[name])[rows] for name in model.COLUMNS}
        code, position, rotation, temporal = viewer.state_at(part, t)
        kinds[rows] = code
        drawn = code == viewer.DRAWABLE
        if scene.sh_degree:
            turning += sum(int(np.count_nonzero((part[name] != 0) & drawn)) for name in model.OMEGA)
        keep = np.flatnonzero(drawn)
        if len(keep) < len(code):  # the viewer's values at t, computed once for every row, of the rows kept
            part = {name: part[name][keep] for name in _KEPT_AS_THEY_ARE}
            position, rotation, temporal = position[keep], rotation[keep], temporal[keep]
        done = m + len(keep)
        out = {name: full[name][m:done] for name in kept_names}
        rotation = viewer.unit_quaternions(rotation)
        with np.errstate(over="ignore", invalid="ignore"):
            for i, name in enumerate(model.POSITION):
                out[name][:] = position[:, i]
            for i, name in enumerate(model.ROTATION):
                out[name][:] = rotation[:, i]
            out["opacity"][:] = baked_opacity(part["opacity"], temporal)
        for name in model.SCALE + model.COLOR:
            out[name][:] = part[name]
        counts["faded"] += int(np.count_nonzero(temporal < 1.0))
        for key, count in finite_stand_ins(out).items():
            counts[key] += count
        m = done
    out = {name: full[name][:m] for name in kept_names}
    out.update(model.static_columns(m))
    out = {name: out[name] for name in model.COLUMNS}
    counts = {**viewer.kind_counts(kinds), **counts}
    notes = [f"baked at t={t:g}: {m:,} of {plural(n, 'splat')} drawn"]
    if m < n:
        left_out = kinds_text({k: counts[k] for k in viewer.UNDRAWABLE_KINDS})
        notes.append(f"left out {n - m:,} splats the viewer does not draw at t={t:g} ({left_out}): "
                     "the viewer draws none of them then, so no pixel is lost")
    notes.extend(_stand_in_notes(counts))
    if scene.sh_degree:
        # A splat's SH bands hold in its rest frame's directions as long as it does not turn: kept then.
        if turning:
            notes.extend(model.sh_dropped_note(scene.sh_degree, "a bake of splats that turn over time"))
        else:
            out = model.with_sh(out, cols, np.flatnonzero(kinds == viewer.DRAWABLE) if m < n else None)
    baked = Scene(columns=out, cameras=scene.cameras, variant=model.VARIANT_3DGS, meta={"baked_time": t})
    if drop_nonfinite:
        baked, dropped = filters.drop_nonfinite(baked)
        counts["nonfinite"] = dropped.removed
        notes.extend(dropped.notes)
    return baked, BakeReport("bake", n, baked.count, notes, counts, time=t)


def finite_stand_ins(cols: dict) -> dict:
    """Write the infinities the viewer gives a meaning to as finite values, in place; how many splats each.

    ``flat``: a log scale of -inf (linear scale 0, a flat splat the viewer
    draws) becomes :data:`FLAT_LOG_SCALE`; ``opaque``: an opacity of +inf
    (sigmoid 1) becomes :data:`OPAQUE_LOGIT`; ``color``: a colour of -inf or +inf
    becomes 0 or 1, as the viewer clamps it. Each decodes to the same value in
    float32, so the splat draws the same; a non-finite row is dropped by some
    readers. Other infinities (an infinite position or scale) are left as they are.

    Parameters
    ----------
    cols : dict of (N,) float32 ndarray
        Baked columns, changed in place.
    """
    counts = {}
    for key, names, test, value in (("flat", model.SCALE, lambda v: v == -np.inf, FLAT_LOG_SCALE),
                                    ("opaque", ("opacity",), lambda v: v == np.inf, OPAQUE_LOGIT),
                                    ("color", model.COLOR, np.isinf, None)):
        hit = np.zeros(len(cols["x"]), dtype=bool)
        for name in names:
            v = cols[name]
            rows = test(v)
            hit |= rows
            v[rows] = value if value is not None else np.clip(v[rows], 0.0, 1.0)
        counts[key] = int(np.count_nonzero(hit))
    return counts


def _stand_in_notes(counts: dict) -> list:
    notes = []
    if counts["flat"]:
        notes.append(f"{plural(counts['flat'], 'flat splat')} (a linear scale of exactly 0) given log scale "
                     f"{FLAT_LOG_SCALE:g}, not -inf: its exp is still 0 in float32 (a .splat stores that 0), so "
                     "every reader draws them flat, and readers that drop non-finite rows keep them")
    if counts["opaque"]:
        notes.append(f"{plural(counts['opaque'], 'splat')} with opacity +inf written with opacity {OPAQUE_LOGIT:g} "
                     "(sigmoid 1 either way), which readers that drop non-finite rows keep")
    if counts["color"]:
        notes.append(f"{plural(counts['color'], 'splat')} with an infinite colour value written as 0 or 1, as the "
                     "viewer clamps it")
    return notes


def bake_frames(scene: Scene, count: int, *, drop_nonfinite: bool = False):
    """Bake ``count`` moments, frame k at time k / (count - 1) (:func:`frame_times`), each as :func:`bake` does.

    Returns a generator, so that a caller writing the frames holds one at a time.

    Returns
    -------
    iterator of (float, Scene, BakeReport)
        The time, the baked scene and its report, frame by frame.

    Raises
    ------
    UsageError
        For a count :func:`check_frame_count` refuses (at once, not on the first frame).
    """
    times = frame_times(count)
    return ((float(t), *bake(scene, float(t), drop_nonfinite=drop_nonfinite)) for t in times)


def frame_names(count: int, suffix: str) -> list:
    """``frame_0000`` + ``suffix`` ... one name a frame, numbered from 0 with at least 4 digits.

    Raises
    ------
    UsageError
        For a count :func:`check_frame_count` refuses, before a name is made.
    """
    check_frame_count(count)
    width = max(4, len(str(count - 1)))
    return [f"frame_{k:0{width}d}{suffix}" for k in range(count)]


def other_frames(files, names, suffix: str) -> list:
    """Names among ``files`` that look like frames (``frame_`` digits ``suffix``) but are not ``names``, sorted."""
    pattern = re.compile(r"frame_\d+" + re.escape(suffix) + r"\Z")
    ours = set(names)
    return sorted(f for f in files if pattern.match(f) and f not in ours)
