"""Pruning: rank splats by what they add to given frames, and leave out the least.

:func:`contributions` estimates, for every splat, how much it adds to the
frames drawn from some views at some times, as the viewer draws them
(``splatconv/render/shaders/splat_main.glsl`` and ``splat.frag``): at each time
and view its blend weight, summed over the pixels of the frame, is

    alpha * temporal opacity * near fade * footprint * share inside * transmittance

where the footprint is the integral of the splat's 2D Gaussian as the shader
draws it (axes clamped to 1,024 pixels, cut at 2 on the quad), the share inside
is the part of its footprint's box inside the frame, and the transmittance is
what the splats in front of it let through: estimated on a grid of cells, each
splat spread over the cells its footprint's box covers, its opacity over a cell
its weight at the cell's point nearest its centre (times the share of the cell
it covers, when smaller). The viewer blends front to back, so a splat hidden
behind opaque ones adds little however large it is.

:func:`leave_out` removes splats (the least contributing first, from
:func:`ranked`) and says how many; the scene's ``meta["pruned"]`` counts the
splats pruned so far, for a format that records it.

No I/O, no renderer: views are given as matrices, the way the viewer holds them.
"""

from __future__ import annotations

import math

import numpy as np

from .. import viewer
from ..model import COLUMNS, Scene
from ..wording import plural
from .report import OpReport

#: The shader draws a splat's quad over |p| <= 2 with weight exp(-|p|^2): its integral over the
#: quad, times |major| |minor| / 4 pixels (the quad's p is half an axis in pixels).
_QUAD_INTEGRAL = math.pi * (1.0 - math.exp(-4.0)) / 4.0
#: The shader's largest axis in pixels.
_MAX_AXIS = 1024.0
#: Side of an occlusion cell in pixels; doubled until the cells a frame's splats cover fit
#: :data:`_CELL_BUDGET` entries a splat (big splats cover many cells).
_CELL = 8
_CELL_BUDGET = 8
#: Splats whose cell entries are made at once (:func:`_transmittance`).
_CHUNK_SPLATS = 1 << 16
#: Splats placed in the frames at once (:func:`contributions`): a larger scene's are worked out a chunk
#: at a time, their footprints alone kept (in float32).
_FRAME_SPLATS = 1 << 16
#: Opacity over a cell at most: keeps log(1 - a) finite.
_MOST_OPACITY = 0.999


#: Order of a symmetric 3x3 matrix's entries as columns: (0,0), (1,1), (2,2), (0,1), (0,2), (1,2).
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def _at_time(sub: dict, t: float, lo: float, hi: float):
    """What every view at time ``t`` shares, for the drawable splats ``sub`` (columns): centres
    ``(n, 3)``, the 3D covariance the shader builds, Vrk = 4 (S R)^T (S R), as ``(n, 6)`` (:data:`_PAIRS`),
    and the opacity ``(n,)`` at its best between ``lo`` and ``hi`` (a splat seen only between two
    times still counts)."""
    position = viewer.position_at(sub, t).astype(np.float32)
    w, x, y, z = viewer.rotation_at(sub, t).T
    # The shader's R (a column-major mat3 there): r[i][j] is row i, column j.
    r = [[1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)],
         [2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)],
         [2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)]]
    s2 = viewer.scales(sub) ** 2
    with np.errstate(over="ignore", invalid="ignore"):
        vrk = np.stack([4 * (s2[:, 0] * r[0][i] * r[0][j] + s2[:, 1] * r[1][i] * r[1][j]
                             + s2[:, 2] * r[2][i] * r[2][j]) for i, j in _PAIRS], axis=1).astype(np.float32)
        centre = viewer.wide(sub["trbf_center"])
        gap = np.maximum(np.maximum(lo - centre, centre - hi), 0.0)
        temporal = viewer.apply_cut(viewer.temporal_basis(gap, viewer.trbf_scale(sub)))
    return position, vrk, viewer.opacity(sub) * temporal


def _rotated(vrk: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Symmetric matrices ``(n, 6)`` (:data:`_PAIRS`) turned by ``w`` (3x3): W Vrk W^T, as ``(n, 6)``."""
    k = np.zeros((6, 6))
    for out, (a, b) in enumerate(_PAIRS):
        for col, (i, j) in enumerate(_PAIRS):
            k[col, out] = w[a, i] * w[b, j] + (w[a, j] * w[b, i] if i != j else 0.0)
    return vrk @ k.astype(np.float32)


def _frame(position, vrk, alpha, view, projection, width: int, height: int):
    """Each splat's blend weight over one frame ignoring occlusion, and where it lies: the rows drawn
    ``(m,)``, their weight and depth ``(m,)``, and their footprint in pixels: its box (x0, x1, y0, y1),
    centre and the inverse of its spread (see the end)."""
    vm = np.asarray(view, np.float64).reshape(4, 4).T  # column-major -> rows
    pm = np.asarray(projection, np.float64).reshape(4, 4).T
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        cam = position @ vm[:3, :3].T.astype(np.float32) + vm[:3, 3].astype(np.float32)
        clip = cam @ pm[:, :3].T.astype(np.float32) + pm[:, 3].astype(np.float32)  # projection * (cam, 1)
        pw = clip[:, 3]
        limit = 1.2 * pw
        # The shader's culling (a splat behind the camera fails it too).
        rows = np.flatnonzero((clip[:, 2] >= -limit) & (np.abs(clip[:, 0]) <= limit)
                              & (np.abs(clip[:, 1]) <= limit) & (pw > 0) & (alpha > 0))
        cam, clip, pw = cam[rows], clip[rows], pw[rows]
        fade = np.clip(clip[:, 2] / pw + 1.0, 0.0, 1.0)
        fx, fy = pm[0, 0] * width / 2, -pm[1, 1] * height / 2
        # cov2d = J^T (W Vrk W^T) J with the shader's J columns u = fx/z (1, 0, -x/z) and
        # v = -fy/z (0, 1, -y/z) in camera space.
        c00, c11, c22, c01, c02, c12 = _rotated(vrk[rows], vm[:3, :3]).T
        z = cam[:, 2]
        px, py = cam[:, 0] / z, cam[:, 1] / z
        a = (fx / z) ** 2 * (c00 - 2 * px * c02 + px * px * c22)
        c = (fy / z) ** 2 * (c11 - 2 * py * c12 + py * py * c22)
        b = -(fx * fy / (z * z)) * (c01 - py * c02 - px * c12 + px * py * c22)
        mid, radius = (a + c) / 2, np.hypot((a - c) / 2, b)
        major = np.minimum(np.sqrt(2 * (mid + radius)), _MAX_AXIS)
        minor = np.minimum(np.sqrt(2 * (mid - radius)), _MAX_AXIS)
        area = _QUAD_INTEGRAL * major * minor
        # The footprint's box: two standard deviations (its pixels' spread is the covariance / 4).
        half_x = np.minimum(np.sqrt(np.maximum(a, 0)), _MAX_AXIS)
        half_y = np.minimum(np.sqrt(np.maximum(c, 0)), _MAX_AXIS)
        sx = (clip[:, 0] / pw + 1) * (width / 2)
        sy = (1 - clip[:, 1] / pw) * (height / 2)
        x0, x1 = np.maximum(sx - half_x, 0), np.minimum(sx + half_x, width)
        y0, y1 = np.maximum(sy - half_y, 0), np.minimum(sy + half_y, height)
        inside = (np.clip((x1 - x0) / np.maximum(2 * half_x, 1e-6), 0, 1)
                  * np.clip((y1 - y0) / np.maximum(2 * half_y, 1e-6), 0, 1))
        weight = alpha[rows] * fade * area * inside
        weight[~(mid - radius >= 0) | ~(x1 > x0) | ~(y1 > y0) | ~np.isfinite(weight)] = 0.0
        det = a * c - b * b
        shown = weight > 0
        # The footprint: box, centre and 2 cov2d^-1 (its weight at offset d is exp(-d^T (2 cov2d^-1) d)).
        foot = tuple(v[shown] for v in (x0, x1, y0, y1, sx, sy, 2 * c / det, -2 * b / det, 2 * a / det))
    return rows[shown], weight[shown], z[shown], foot


def _transmittance(weight, depth, box, alpha, width: int, height: int) -> np.ndarray:
    """What the splats in front of each one let through, ``(n,)``: on a grid of cells, front to back.

    The splats are taken :data:`_CHUNK_SPLATS` at a time, front to back, each
    chunk's (splat, cell) entries made and summed on their own, the light lost
    in each cell so far carried from chunk to chunk: a frame of a million splats
    needs a chunk's entries, not all of them at once.
    """
    out = np.ones(len(weight))
    if len(weight) == 0:
        return out
    front = np.argsort(depth, kind="stable")
    x0, x1, y0, y1, sx, sy, qa, qb, qc = (v[front] for v in box)
    cell = _CELL
    while True:
        cx0, cy0 = (x0 // cell).astype(np.int64), (y0 // cell).astype(np.int64)
        nx = np.maximum(np.ceil(x1 / cell).astype(np.int64) - cx0, 1)
        ny = np.maximum(np.ceil(y1 / cell).astype(np.int64) - cy0, 1)
        count = nx * ny
        columns = -(-width // cell)
        if (count.sum() <= _CELL_BUDGET * len(front) + 4096 and columns * -(-height // cell) < 1 << 16) \
                or cell >= max(width, height):
            break
        cell *= 2
    # A splat's opacity over a cell: its weight at the cell's point nearest its centre, times the
    # share of the cell it covers when smaller than one.
    a = alpha[front]
    small = a * np.minimum(1.0, weight[front] / np.maximum(a, 1e-12) / (cell * cell))
    lost = np.zeros(columns * -(-height // cell))  # log of what each cell lets through, splats so far
    through = np.empty(len(front))
    for lo in range(0, len(front), _CHUNK_SPLATS):
        hi = min(lo + _CHUNK_SPLATS, len(front))
        c = count[lo:hi]
        # One entry a (splat, cell it covers), front to back: the k-th cell of a splat's box is
        # (k % nx, k // nx) from its corner.
        owner = np.repeat(np.arange(lo, hi), c)
        k = np.arange(len(owner)) - np.repeat(np.cumsum(c) - c, c)
        nxo = nx[owner]
        kx, ky = cx0[owner] + k % nxo, cy0[owner] + k // nxo
        del k, nxo
        cells = (ky * columns + kx).astype(np.uint16)  # fewer than 2**16 cells: a radix sort
        px = np.clip(sx[owner], kx * cell, (kx + 1) * cell) - sx[owner]
        py = np.clip(sy[owner], ky * cell, (ky + 1) * cell) - sy[owner]
        del kx, ky
        with np.errstate(over="ignore", invalid="ignore"):
            falloff = np.exp(-(qa[owner] * px * px + 2 * qb[owner] * px * py + qc[owner] * py * py))
        del px, py
        cover = np.minimum(np.nan_to_num(small[owner] * falloff), _MOST_OPACITY)
        del falloff
        order = np.argsort(cells, kind="stable")  # by cell, front to back within one
        owner, cells, cover = owner[order], cells[order], cover[order]
        del order
        loss = np.log1p(-cover)
        del cover
        total = np.cumsum(loss)
        first = np.ones(len(loss), bool)
        first[1:] = cells[1:] != cells[:-1]
        start = np.maximum.accumulate(np.where(first, np.arange(len(loss)), 0))
        # What is in front: the same cell's earlier entries in this chunk, and the chunks before.
        before = total - loss - (total[start] - loss[start]) + lost[cells]
        through[lo:hi] = np.bincount(owner - lo, weights=np.exp(before), minlength=hi - lo) / c
        lost += np.bincount(cells, weights=loss, minlength=len(lost))
    out[front] = through
    return out


def contributions(cols: dict, views, times, drawable: np.ndarray | None = None) -> np.ndarray:
    """What each splat adds to the frames drawn from ``views`` at ``times``: ``(N,) float64``, >= 0.

    The sum over frames of the splat's blend weight over the frame's pixels (see
    the module docstring), its opacity at each time the best within half the gap
    to the next time (or to the ends of [0, 1]): a splat seen only between two
    times counts. 0 for a splat no frame draws (hidden in time, behind every
    camera, out of every frame, or undrawable).

    Parameters
    ----------
    cols : dict
        The scene's columns.
    views : sequence of (view, projection, width, height)
        Column-major world-to-camera and projection matrices (16 floats each), as
        the viewer holds them, and the frame's size in pixels.
    times : sequence of float
        In [0, 1].
    drawable : (N,) bool ndarray, optional
        ``~viewer.undrawable(cols)``, where the caller has it.
    """
    score = np.zeros(len(cols["x"]))
    rows = np.flatnonzero(~viewer.undrawable(cols) if drawable is None else drawable)
    times = sorted(float(t) for t in times)
    edges = [viewer.TIME_RANGE[0]] + [(a + b) / 2 for a, b in zip(times[:-1], times[1:])] + [viewer.TIME_RANGE[1]]
    for t, lo, hi in zip(times, edges[:-1], edges[1:]):
        frames = _footprints(cols, rows, t, lo, hi, views)
        while frames:  # each frame's footprints let go of once it is summed
            drawn, weight, depth, box, alpha, width, height = frames.pop(0)
            score[rows[drawn]] += weight * _transmittance(weight, depth, box, alpha, width, height)
            del drawn, weight, depth, box, alpha
    return score


def _footprints(cols: dict, rows: np.ndarray, t: float, lo: float, hi: float, views) -> list:
    """:func:`_frame` of the splats ``rows`` at time ``t`` from each of ``views``: for each view, the splats
    drawn (indices into ``rows``), their weight, depth, footprint and opacity, and the frame's size.

    Worked out :data:`_FRAME_SPLATS` splats at a time; where that takes more than one chunk, what is kept
    is kept in float32 (a million splats' footprints for every view)."""
    narrow = len(rows) > _FRAME_SPLATS
    kept = (lambda v: v.astype(np.float32)) if narrow else (lambda v: v)
    parts = [[] for _ in views]
    for start in range(0, len(rows), _FRAME_SPLATS):
        sub = {name: np.asarray(cols[name])[rows[start:start + _FRAME_SPLATS]] for name in COLUMNS}
        position, vrk, alpha = _at_time(sub, t, lo, hi)
        del sub
        for part, (view, projection, width, height) in zip(parts, views):
            drawn, weight, depth, box = _frame(position, vrk, alpha, view, projection, width, height)
            part.append(((drawn + start).astype(np.int32 if narrow else np.intp), kept(weight), kept(depth),
                         tuple(kept(v) for v in box), kept(alpha[drawn])))
        del position, vrk, alpha
    frames = []
    for part, (_view, _projection, width, height) in zip(parts, views):
        drawn, weight, depth, boxes, alpha = zip(*part)
        part.clear()
        frames.append((np.concatenate(drawn), np.concatenate(weight), np.concatenate(depth),
                       tuple(np.concatenate(v) for v in zip(*boxes)), np.concatenate(alpha), width, height))
    return frames


def ranked(cols: dict, score: np.ndarray, drawable: np.ndarray | None = None) -> np.ndarray:
    """Drawable rows (:func:`splatconv.viewer.undrawable`), least ``score`` first: ``(M,) intp``.

    Equal scores go less important first (:func:`splatconv.viewer.importance`),
    then by row. ``drawable``: ``~viewer.undrawable(cols)``, where the caller has it.
    """
    rows = np.flatnonzero(~viewer.undrawable(cols) if drawable is None else drawable)
    with np.errstate(invalid="ignore"):
        key = np.nan_to_num(viewer.importance({k: cols[k][rows] for k in COLUMNS}), nan=0.0)
    return rows[np.lexsort((rows, key, score[rows]))]


def leave_out(scene: Scene, rows: np.ndarray, *, of: int) -> tuple:
    """``scene`` without ``rows``: ``(Scene, OpReport)``.

    Parameters
    ----------
    rows : (K,) intp ndarray
        Distinct row numbers to leave out (e.g. the first K of :func:`ranked`).
    of : int
        The splats they were chosen from (the drawable ones), for the note.

    The new scene's ``meta["pruned"]`` is the scene's (0 if none) plus K.
    """
    keep = np.ones(scene.count, bool)
    keep[rows] = False
    columns = {name: np.asarray(scene.columns[name])[keep] for name in COLUMNS}
    meta = dict(scene.meta, pruned=int(scene.meta.get("pruned", 0)) + len(rows))
    out = Scene(columns, cameras=scene.cameras, variant=scene.variant, meta=meta, notes=list(scene.notes))
    report = OpReport("prune", scene.count, int(keep.sum()), counts={"pruned": len(rows), "of": of})
    report.notes.append(f"pruned {plural(len(rows), 'splat')} of {of:,} drawable, those that add least to "
                        "the proof's frames")
    return out, report
