"""Segments end to end: several 4D scenes on one timeline, each in its own interval.

Spacetime Gaussians trains a long clip as segments of about 50 frames. Segment i
of K, with n_i frames, is placed on the output's frames F_i .. F_i + n_i - 1 of
N = sum n_i, frame f at time f / (N - 1): its local [0, 1] maps onto
[a_i, b_i] = [F_i, F_i + n_i - 1] / (N - 1), remapped as trim does (centre,
scale, motion term k by d^k, omega by d, d = b_i - a_i).

The viewer hides a splat only by its temporal opacity, cut below 0.02. A splat
whose visible interval (centre +- 1.978 temporal scales) stays clear of the
neighbouring segments' frames is kept as it is. Every other splat ("long-lived":
a background visible through the whole segment has a temporal scale above 1, or
an infinite one) becomes *pieces*: copies of it, each shown through a Gaussian
time window narrow enough to be cut before the neighbouring segment's frames
(after a hand-over of ``leak`` frames), whose composited opacity follows the
splat's over its own segment. The windows of a segment (centres, widths and
weights) are chosen once per segment shape by a small deterministic search that
minimises the composited opacity error over the segment's frames; a splat's
piece is the product of its own temporal Gaussian and a window (a Gaussian
again, so the viewer draws it exactly), with the motion and rotation re-centred
(exact) and a peak opacity 1 - (1 - P mu)^w that composites to the splat's opacity.
How many pieces a long-lived splat gets is set by the splat budget (default at
most twice the segments' splats). See specs/segments.md for the measured limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import viewer
from ..errors import UsageError
from ..model import COLUMNS, MOTION, OMEGA, POSITION, ROTATION, VARIANT_LITE, Scene, lite_rows
from ..progress import SILENT
from ..wording import plural
from .sequence import _shift_poly
from .time import remap_columns

#: Frames per segment when no durations are given (Spacetime Gaussians trains 50).
DEFAULT_FRAMES = 50
#: Output splats at most this many times the segments' splats together.
DEFAULT_BUDGET = 2.0
#: Frames of the neighbouring segment through which a segment's long-lived splats may still fade.
DEFAULT_LEAK = 12
#: Most frames a merge lays out, all segments together (5.5 minutes at 30 frames a second; Spacetime
#: Gaussians clips are about 300): bounds the window search, whose time and memory grow with a segment's frames.
MAX_FRAMES = 10_000
#: Most windows a long-lived splat is split into.
MAX_PIECES = 7
#: Radii are kept this much inside a cut, for the viewer's float32 maths.
_MARGIN = 0.995
#: Pieces whose peak opacity is below half an 8-bit step are left out.
_MIN_PEAK = 0.5 / 255
#: Opacities the window search balances (compositing is not additive near 1).
_ALPHAS = (0.3, 0.7, 0.95, 1.0)
#: Weight of the opacity a frame's leading piece does not carry (see :func:`_layout_cost`).
_SHARE_COST = 0.5
#: Weight of a neighbour's leaked opacity in one's own frames (its content differs a little).
_LEAK_COST = 0.25


@dataclass
class Placement:
    """Where a segment lies on the output timeline."""

    frames: int            # n_i
    first: int             # F_i, its first output frame
    start: float           # a_i
    end: float             # b_i
    cut_before: float      # its splats are hidden at and before this time (-inf: none)
    cut_after: float       # ... at and after this time (+inf: none)

    def local(self, t):
        """Output time -> the segment's own time."""
        return (np.asarray(t, np.float64) - self.start) / (self.end - self.start)


@dataclass
class SegmentOutcome:
    """What :func:`merge_segments` did to one segment."""

    placement: Placement
    count_in: int
    count_out: int
    long_lived: int        # long-lived splats split into pieces (those kept)
    pieces: dict           # pieces (as text) -> long-lived splats cut into that many
    nan_time: int          # dropped: a NaN temporal centre or scale
    never: int             # dropped: an infinite temporal centre
    faint: int             # dropped: long-lived with every piece too faint to draw
    overflow: int          # finite values that became infinite as float32

    @property
    def dropped(self) -> int:
        return self.nan_time + self.never + self.faint

    def as_dict(self) -> dict:
        p = self.placement
        return {"frames": p.frames, "first_frame": p.first, "start": p.start, "end": p.end,
                "splats_in": self.count_in, "splats_out": self.count_out, "long_lived": self.long_lived,
                "pieces_per_long_lived": self.pieces, "dropped": self.dropped}


@dataclass
class SegmentReport:
    """What :func:`merge_segments` did: a :class:`SegmentOutcome` per segment merged."""

    placements: list
    segments: list
    leak: int
    budget: float
    notes: list = field(default_factory=list)

    @property
    def counts_in(self) -> list:
        return [s.count_in for s in self.segments]

    @property
    def counts_out(self) -> list:
        return [s.count_out for s in self.segments]

    @property
    def long_lived(self) -> list:
        return [s.long_lived for s in self.segments]

    @property
    def count_in(self) -> int:
        return sum(self.counts_in)

    @property
    def count_out(self) -> int:
        return sum(self.counts_out)

    def frame_times(self) -> list:
        """(output frame, output time, segment, local time) for every frame of every segment."""
        total = sum(p.frames for p in self.placements)
        out = []
        for i, p in enumerate(self.placements):
            for j in range(p.frames):
                f = p.first + j
                out.append((f, f / (total - 1), i, j / (p.frames - 1)))
        return out

    def as_dict(self) -> dict:
        return {
            "segments": [s.as_dict() for s in self.segments],
            "splats_in": self.count_in, "splats_out": self.count_out,
            "ratio": round(self.count_out / self.count_in, 4) if self.count_in else None,
            "leak_frames": self.leak, "budget": self.budget, "notes": list(self.notes),
        }


def check_budget(budget: float) -> float:
    """The splat budget, checked: a finite number, at least 1 (an infinite one is no bound).

    Raises
    ------
    UsageError
    """
    if not (1.0 <= budget < math.inf):
        raise UsageError(f"--budget must be a finite number of at least 1, got {budget:g}")
    return budget


def check_durations(durations) -> list:
    """Segment frame counts as ints, checked: at least 2 each, at most :data:`MAX_FRAMES` together.

    Raises
    ------
    UsageError
    """
    n = [int(d) for d in durations]
    if any(d < 2 for d in n):
        raise UsageError("--durations: every segment needs at least 2 frames")
    if sum(n) > MAX_FRAMES:
        raise UsageError(f"--durations: {sum(n):,} frames in all; a merge lays out at most {MAX_FRAMES:,}")
    return n


def check_segment_count(count: int) -> None:
    """Refuse ``count`` segments of :data:`DEFAULT_FRAMES` frames (no ``--durations``) past :data:`MAX_FRAMES`.

    Raises
    ------
    UsageError
    """
    if count * DEFAULT_FRAMES > MAX_FRAMES:
        raise UsageError(f"{count:,} segments of {DEFAULT_FRAMES} frames are {count * DEFAULT_FRAMES:,} frames in "
                         f"all; a merge lays out at most {MAX_FRAMES:,}")


def placements(durations, leak: int = DEFAULT_LEAK) -> list:
    """Each segment's interval and cuts on the output's [0, 1].

    Parameters
    ----------
    durations : list of int
        Frames of each segment (>= 2 each).
    leak : int
        Frames of a neighbour a segment's pieces may still show in (0: cut before its first).
    """
    n = check_durations(durations)
    if len(n) < 2:
        raise UsageError("--segments needs at least two segments")
    total = sum(n)
    step = 1.0 / (total - 1)
    out, first = [], 0
    for i, d in enumerate(n):
        a, b = first * step, (first + d - 1) * step
        before = a - (leak + 1) * step if i > 0 else -math.inf
        after = b + (leak + 1) * step if i < len(n) - 1 else math.inf
        out.append(Placement(d, first, a, b, before, after))
        first += d
    return out


def place(columns: dict, start: float, end: float) -> dict:
    """Map a scene's own [0, 1] onto [start, end] of a longer timeline: float64 columns.

    t' = start + t (end - start), by trim's time map
    (:func:`splatconv.ops.time.remap_columns`): centres move, temporal scales and
    the motion and angular-velocity terms rescale so that the scene at t' draws as
    it did at t.
    """
    d = end - start
    out = {name: np.array(viewer.wide(columns[name])) for name in COLUMNS}
    remap_columns(out, -start / d, 1.0 / d)
    return out


# --------------------------------------------------------------------------
# Windows: the pieces' time windows of one segment shape, found by a small search.


def _radius_scale(x, n, leak, left, right):
    """Largest window scale (frame units) at centres ``x`` that is cut before the cuts."""
    lo = -(leak + 1) if left else -np.inf
    hi = n - 1 + (leak + 1) if right else np.inf
    return _MARGIN * np.minimum(x - lo, hi - x) / viewer.VISIBLE_RADIUS


def _window_values(x, s, t):
    g = viewer.temporal_basis(t[:, None] - x[None, :], s[None, :])
    g[~(g >= viewer.TEMPORAL_CUTOFF)] = 0.0
    return g


def _peaks(alpha, w):
    """Piece peak opacities 1 - (1 - alpha)^w (alpha 1: 1 where w > 0)."""
    alpha = np.asarray(alpha, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(alpha >= 1.0, (w > 0) * 1.0, -np.expm1(w * np.log1p(-np.minimum(alpha, 1.0))))


def _layout_costs(x, n, leak, left, right):
    """Cost of each candidate layout ``x`` ``(B, m)`` (frame units); with their scales and weights.

    Weights: a ridge least-squares partition of one over the frames, negatives
    clipped (the search only ranks candidates; the kept layout's peaks are then
    solved properly by :func:`_peak_table`).
    """
    s = _radius_scale(x, n, leak, left, right)                           # (B, m)
    t = np.arange(n, dtype=np.float64)
    g = _values(x, s, t)                                                 # (B, n, m)
    gtg = np.einsum("bnj,bnk->bjk", g, g) + 1e-6 * np.eye(x.shape[1])[None]
    w = np.clip(np.linalg.solve(gtg, g.sum(axis=1)[..., None])[..., 0], 0.0, None)   # (B, m)
    # The neighbours' pieces, laid out alike (mirrored), still show in the leak
    # frames: they fill in some of the fade, and cost a little as content.
    mirrors = ([2 * n - 1 - x] if right else []) + ([-1 - x] if left else [])
    gn = [_values(m, s, t) for m in mirrors]
    cost = np.zeros(len(x))
    for alpha in _ALPHAS:
        p = _peaks(alpha, w)[:, None, :]                                 # (B, 1, m)
        own = 1.0 - np.prod(1.0 - p * g, axis=2)                        # (B, n)
        other = np.zeros_like(own)
        for gm in gn:
            other = 1.0 - (1.0 - other) * np.prod(1.0 - p * gm, axis=2)
        both = 1.0 - (1.0 - own) * (1.0 - other)
        # Copies of a splat that share a moment blend with other splats' copies between
        # them (depth order interleaves them): prefer one piece carrying each frame.
        lead = (p * g).max(axis=2)
        cost += (np.mean((both - alpha) ** 2, axis=1) + _LEAK_COST * np.mean(other ** 2, axis=1)
                 + _SHARE_COST * np.mean((own - lead) ** 2, axis=1))
    return cost / len(_ALPHAS), s, w


def _values(x, s, t):
    """Window values ``(B, n, m)`` of layouts ``x``, ``s`` ``(B, m)`` at times ``t`` ``(n,)``, cut as the viewer."""
    g = viewer.temporal_basis(t[None, :, None] - x[:, None, :], s[:, None, :])
    g[~(g >= viewer.TEMPORAL_CUTOFF)] = 0.0
    return g


_LAYOUTS: dict = {}


def windows(n: int, pieces: int, leak: int, left: bool, right: bool):
    """Window centres, scales (frame units, frame 0 .. n-1) and weights for one segment shape.

    A deterministic random search (fixed seed), cached per shape.

    Returns
    -------
    (x, s, table, cost) : ``(m,) float64`` centres and scales, the peak table
        (:func:`_peak_table`) and the search's mean square composited error.
    """
    key = (n, pieces, leak, left, right)
    if key in _LAYOUTS:
        return _LAYOUTS[key]
    rng = np.random.default_rng(20260 + 7 * pieces + n)
    lo = -(leak + 1) + 0.01 if left else -2.0 * n
    hi = n - 1 + (leak + 1) - 0.01 if right else 3.0 * n
    batch = 64
    best = None
    for rnd in range(12):
        if best is None or rnd < 4:
            x = np.sort(rng.uniform(lo, hi, (batch, pieces)), axis=1)
        else:
            spread = (hi - lo) * (0.05 if rnd < 8 else 0.01)
            x = np.sort(np.clip(best[1][None, :] + rng.normal(0.0, spread, (batch, pieces)), lo, hi), axis=1)
        cost, s, w = _layout_costs(x, n, leak, left, right)
        i = int(np.argmin(cost))
        if best is None or cost[i] < best[0]:
            best = (float(cost[i]), x[i], s[i], w[i])
    cost, x, s, w = best
    keep = w > 0
    x, s, w = x[keep], s[keep], w[keep]
    table = _peak_table(x, s, w, n, left, right)
    _LAYOUTS[key] = (x, s, table, cost)
    return _LAYOUTS[key]


#: Opacities at which the peak table is solved (denser towards 1, where compositing bends most).
PEAK_GRID = 1.0 - np.linspace(1.0, 0.0, 25) ** 2


def _peak_table(x, s, w, n, left, right) -> np.ndarray:
    """Peaks of each window for each opacity of :data:`PEAK_GRID`: ``(len(PEAK_GRID), m)``.

    Projected Gauss-Newton on the composited opacity at the segment's frames,
    1 - prod_j (1 - P_j g_j(t)) = alpha, the mirrored neighbours' leak included
    at its current value; started from the log-additive guess 1 - (1 - alpha)^w.
    """
    t = np.arange(n, dtype=np.float64)
    g = _window_values(x, s, t)
    mirror = ([2 * n - 1 - x] if right else []) + ([-1 - x] if left else [])
    gn = [_window_values(mx, s, t) for mx in mirror]
    table = np.zeros((len(PEAK_GRID), len(x)))
    for a, alpha in enumerate(PEAK_GRID):
        p = np.clip(_peaks(alpha, w), 0.0, 1.0)
        for _ in range(25):
            keep = 1.0 - p[None, :] * g                        # (n, m)
            own = np.prod(keep, axis=1)
            other = np.ones(n)
            for gm in gn:
                other = other * np.prod(1.0 - p[None, :] * gm, axis=1)
            r = 1.0 - own * other - alpha
            with np.errstate(divide="ignore", invalid="ignore"):
                J = np.where(keep > 1e-12, g * (own * other)[:, None] / keep, 0.0)
            step = np.linalg.lstsq(J.T @ J + 1e-9 * np.eye(len(x)), J.T @ r, rcond=None)[0]
            p = np.clip(p - step, 0.0, 1.0)
        table[a] = p
    return table


def _lookup_peaks(table: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Peaks ``(M, m)`` for opacities ``alpha`` ``(M, m)`` (each piece by its own column)."""
    out = np.empty_like(alpha)
    a = np.clip(np.nan_to_num(alpha, nan=0.0), 0.0, 1.0)
    for j in range(table.shape[1]):
        out[:, j] = np.interp(a[:, j], PEAK_GRID, table[:, j])
    return out


# --------------------------------------------------------------------------
# Merging.


def _long_lived(cols: dict, p: Placement) -> tuple:
    """Rows to split (visible at or beyond a cut), rows with no time (NaN centre or scale), and rows never shown.

    A splat whose temporal centre is infinite has temporal opacity 0 (or NaN,
    cut) at every finite time: the viewer never shows it.
    """
    lo, hi = viewer.visible_interval(cols)
    nan_time = np.isnan(lo) | np.isnan(hi)
    never = ~nan_time & np.isinf(np.asarray(cols["trbf_center"]))
    with np.errstate(invalid="ignore"):
        split = ~nan_time & ~never & ((lo <= p.cut_before) | (hi >= p.cut_after))
    return split, nan_time, never


def _windowed(cols: dict, rows: np.ndarray, p: Placement, m: int, leak: int, first_last) -> tuple:
    """Each splat of ``rows`` times each window of the ``m``-window layout: centres, scales, peaks, which to keep.

    Returns ``(c_new, s_new, pk, ok)``, each ``(M, J)``: ``ok`` marks the pieces
    drawn (inside the cuts, finite, and at least half an 8-bit step at peak).
    """
    left, right = first_last
    x, s, table, _ = windows(p.frames, m, leak, left, right)
    step = (p.end - p.start) / (p.frames - 1)
    wc = p.start + x * step                                   # window centres, output time
    ws = s * step                                             # window scales
    c = cols["trbf_center"][rows]
    sc = viewer.exp(cols["trbf_scale"][rows])
    peak = viewer.opacity(cols)[rows]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        inv = 1.0 / sc[:, None] ** 2 + 1.0 / ws[None, :] ** 2          # (M, J)
        s_new = 1.0 / np.sqrt(inv)
        c_new = np.where(np.isinf(sc)[:, None], wc[None, :],
                         (c[:, None] / sc[:, None] ** 2 + wc[None, :] / ws[None, :] ** 2) / inv)
        mu = np.where(np.isinf(sc)[:, None], 1.0, np.exp(-(c[:, None] - wc[None, :]) ** 2
                                                         / (sc[:, None] ** 2 + ws[None, :] ** 2)))
    # The product lies inside the window, so inside the cuts; keep a float margin anyway.
    reach = np.minimum(c_new - p.cut_before, p.cut_after - c_new) * _MARGIN / viewer.VISIBLE_RADIUS
    s_new = np.minimum(s_new, reach)
    pk = _lookup_peaks(table, peak[:, None] * mu)
    ok = (reach > 0) & (pk >= _MIN_PEAK) & np.isfinite(c_new) & (s_new > 0)
    return c_new, s_new, pk, ok


def _pieces(cols: dict, rows: np.ndarray, p: Placement, m: int, leak: int, first_last) -> tuple:
    """Pieces of splats ``rows`` (placed, float64 columns) for segment ``p`` with the ``m``-window layout.

    Returns
    -------
    (dict, ndarray)
        The pieces' float64 columns, and how many pieces each row got ``(M,) int64``
        (the layout may keep fewer windows than ``m``; pieces too faint to draw are left out).
    """
    c_new, s_new, pk, ok = _windowed(cols, rows, p, m, leak, first_last)
    src, j = np.nonzero(ok)
    rows_src = rows[src]
    cn, sn = c_new[src, j], s_new[src, j]
    out = {}
    shift = cn - cols["trbf_center"][rows_src]
    coef = np.stack([np.stack([cols[n][rows_src] for n in POSITION], axis=1)]
                    + [np.stack([cols[MOTION[3 * k + i]][rows_src] for i in range(3)], axis=1) for k in range(3)],
                    axis=1)                                              # (P, 4, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        moved = _shift_poly(coef, shift)
    for i, name in enumerate(POSITION):
        out[name] = moved[:, 0, i]
    for k in range(3):
        for i in range(3):
            out[MOTION[3 * k + i]] = moved[:, k + 1, i]
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(4):
            out[ROTATION[i]] = cols[ROTATION[i]][rows_src] + cols[OMEGA[i]][rows_src] * shift
            out[OMEGA[i]] = cols[OMEGA[i]][rows_src]
    for name in COLUMNS:
        if name not in out:
            out[name] = cols[name][rows_src]
    out["trbf_center"] = cn
    out["trbf_scale"] = np.log(sn)
    out["opacity"] = viewer.logit(np.clip(pk[src, j], 1e-7, 1 - 1e-7))
    return out, ok.sum(axis=1)


def _best_layout(n: int, m: int, leak: int, sides) -> int:
    """The number of windows k <= m whose layout composites best (a search may find m worse than fewer)."""
    return min(range(1, m + 1), key=lambda k: (windows(n, k, leak, *sides)[3], k))


def layout_options(n: int, leak: int, sides) -> list:
    """The layouts a long-lived splat may get, as ``(m, pieces, cost)``: each a piece more buys less.

    ``m`` is the windows asked of :func:`windows`, ``pieces`` the windows its
    layout keeps (the search may keep fewer than ``m``: for a 50-frame middle
    segment, 3 to 6 asked keep 3 and 7 keep 4), ``cost`` its composited error. Pieces rise
    and cost falls strictly, and the cost is convex in the pieces (the lower
    hull), so that allotting in order of gain per piece never skips a step.
    """
    best = {}
    for m in range(1, MAX_PIECES + 1):
        x, _s, _table, cost = windows(n, m, leak, *sides)
        if len(x) and (len(x) not in best or cost < best[len(x)][1]):
            best[len(x)] = (m, cost)
    hull = []
    for size in sorted(best):
        m, cost = best[size]
        if hull and cost >= hull[-1][2]:
            continue
        while len(hull) >= 2 and ((hull[-1][2] - cost) * (hull[-1][1] - hull[-2][1])
                                  >= (hull[-2][2] - hull[-1][2]) * (size - hull[-1][1])):
            hull.pop()
        hull.append((m, size, cost))
    return hull


def impact(cols: dict, rows: np.ndarray) -> np.ndarray:
    """How much a splat can matter in an image: peak opacity x its two largest axes' area: ``(M,) float64``."""
    s = np.sort(viewer.scales(cols)[rows], axis=1)
    with np.errstate(over="ignore", invalid="ignore"):
        v = viewer.opacity(cols)[rows] * s[:, 2] * s[:, 1]
    return np.where(np.isfinite(v), v, 0.0)


def allocate(weights: np.ndarray, extra: int, options: list, sizes: np.ndarray | None = None) -> np.ndarray:
    """Which of ``options`` (:func:`layout_options`) each long-lived splat gets: indices ``(M,) int64``.

    Every splat starts at ``options[0]``; ``extra`` pieces beyond that are
    spent greedily where weight x (cost drop per piece) is largest, each step
    costing the pieces it adds, until the next step in that order no longer
    fits. ``sizes`` ``(M, len(options))`` are the pieces each splat would be
    drawn with at each option (default the options' own: a splat's pieces too
    faint to draw are left out, so it may get fewer); counting those, not the
    windows asked, leaves no budget unspent. Ties and order are deterministic
    (stable sort).
    """
    n = len(weights)
    level = np.zeros(n, dtype=np.int64)
    if n == 0 or len(options) < 2:
        return level
    costs = np.array([o[2] for o in options])
    if sizes is None:
        sizes = np.broadcast_to(np.array([o[1] for o in options], np.int64), (n, len(options)))
    steps = np.diff(sizes, axis=1)                                       # (M, L - 1); <= 0: no piece more
    with np.errstate(invalid="ignore"):
        per_piece = np.where(steps > 0, weights[:, None] * (costs[:-1] - costs[1:])[None, :] / np.maximum(steps, 1),
                             np.inf)
    # A splat's steps come in order: none is worth more than the one before it.
    gains = np.minimum.accumulate(per_piece, axis=1).ravel()
    order = np.argsort(-gains, kind="stable")
    order = order[gains[order] > 0]
    spend = np.cumsum(steps.ravel()[order])
    over = np.flatnonzero(spend > extra)
    order = order[:over[0]] if len(over) else order
    np.add.at(level, order // steps.shape[1], 1)
    return level


def merge_segments(scenes: list, durations=None, *, leak: int = DEFAULT_LEAK, budget: float = DEFAULT_BUDGET,
                   pieces: int | None = None, progress=SILENT):
    """Lay scenes end to end on one timeline (see the module docstring).

    Parameters
    ----------
    scenes : list of Scene
        Two or more segments, each over its own [0, 1].
    durations : list of int, optional
        Frames of each segment (default :data:`DEFAULT_FRAMES` each): segment i
        takes that share of the output and its frames stay at frame times.
    leak : int
        Frames of a neighbour a long-lived splat may still fade through.
    budget : float
        Output splats at most ``budget`` times the inputs' (sets pieces per long-lived splat).
    pieces : int, optional
        Pieces per long-lived splat, overriding the budget.

    Returns
    -------
    (Scene, SegmentReport)
        Cameras: the first segment's that has any.
    """
    if durations is None:
        durations = [DEFAULT_FRAMES] * len(scenes)
    if len(durations) != len(scenes):
        raise UsageError(f"--durations gives {plural(len(durations), 'value')} for {plural(len(scenes), 'segment')}")
    check_budget(budget)
    places = placements(durations, leak)
    report, parts = SegmentReport(places, [], leak, budget), []
    with progress.stage("placing segments", len(scenes), "segment") as advance:
        for i, (scene, p) in enumerate(zip(scenes, places)):
            sides = (i > 0, i < len(scenes) - 1)
            part, outcome = _merge_one(scene, p, sides, leak=leak, budget=budget, pieces=pieces)
            parts.append(part)
            report.segments.append(outcome)
            advance()
    out = _end_to_end(parts, report.count_out)
    report.notes += _notes(report.segments, durations)
    cameras = next((s.cameras for s in scenes if s.cameras), None)
    return Scene(columns=out, cameras=cameras, variant=VARIANT_LITE, meta={}), report


def _merge_one(scene: Scene, p: Placement, sides: tuple, *, leak: int, budget: float, pieces: int | None) -> tuple:
    """One segment of :func:`merge_segments` placed at ``p``, its long-lived splats cut into pieces:
    (its float32 columns, its :class:`SegmentOutcome`). ``sides``: whether it has a segment before,
    after it."""
    cols = place(scene.columns, p.start, p.end)
    split, nan_time, never = _long_lived(cols, p)
    keep = ~split & ~nan_time & ~never
    n_long = int(split.sum())
    faint = 0
    kept = {name: v[keep] for name, v in cols.items()}
    m = np.zeros(0, np.int64)
    if n_long:
        rows = np.flatnonzero(split)
        if pieces is not None:
            m = np.full(n_long, _best_layout(p.frames, pieces, leak, sides), np.int64)
        else:
            options = layout_options(p.frames, leak, sides)
            sizes = np.stack([_windowed(cols, rows, p, o[0], leak, sides)[3].sum(axis=1) for o in options],
                             axis=1)
            # Past what every splat's costliest layout takes, more budget buys
            # nothing: capped there, an infinite or 1e308 budget is an integer.
            base = int(keep.sum()) + int(sizes[:, 0].sum())
            most = base + int(np.maximum(np.diff(sizes, axis=1), 0).sum())
            extra = int(math.floor(min(budget * scene.count, most))) - base
            m = np.array([o[0] for o in options], np.int64)[allocate(impact(cols, rows), extra, options, sizes)]
        made = np.zeros(n_long, np.int64)
        extra_cols = []
        for k in np.unique(m):
            piece_cols, made[m == k] = _pieces(cols, rows[m == k], p, int(k), leak, sides)
            extra_cols.append(piece_cols)
        kept = {name: np.concatenate([kept[name]] + [e[name] for e in extra_cols]) for name in COLUMNS}
        # A splat with no piece bright enough to draw is removed, and counted as such.
        faint = int((made == 0).sum())
        n_long -= faint
        m = made[made > 0]
    with np.errstate(over="ignore", invalid="ignore"):
        part = {name: kept[name].astype(np.float32) for name in COLUMNS}
    overflow = sum(int((np.isinf(part[name]) & np.isfinite(kept[name])).sum()) for name in COLUMNS)
    cut_into = {str(int(k)): int((m == k).sum()) for k in np.unique(m)}
    return part, SegmentOutcome(p, scene.count, len(part["x"]), n_long, cut_into, int(nan_time.sum()),
                                int(never.sum()), faint, overflow)


def _end_to_end(parts: list, total: int) -> dict:
    """The segments' columns one after another in one lite row table; ``parts`` is emptied as it goes."""
    _rows, out = lite_rows(total)
    at = 0
    while parts:
        part = parts.pop(0)  # each part freed once copied: the output is held once, not twice
        k = len(part["x"])
        for name in COLUMNS:
            out[name][at:at + k] = part[name]
        at += k
    return out


def _notes(segments: list, durations) -> list:
    """What a merge of ``segments`` (:class:`SegmentOutcome`) dropped or lost, then what it did."""
    notes = []
    nan_time, never, faint = (sum(getattr(s, kind) for s in segments) for kind in ("nan_time", "never", "faint"))
    overflow = sum(s.overflow for s in segments)
    if nan_time:
        notes.append(f"{plural(nan_time, 'splat')} with a NaN temporal centre or scale dropped "
                     "(they have no place in time)")
    if never:
        notes.append(f"{plural(never, 'splat')} with an infinite temporal centre dropped "
                     "(the viewer never shows them)")
    if faint:
        notes.append(f"{plural(faint, 'long-lived splat')} dropped: every piece of each was "
                     "fainter than half an 8-bit step in its segment's frames")
    if overflow:
        notes.append(f"{overflow:,} finite values grew beyond float32 and are now infinite")
    count_in, count_out = sum(s.count_in for s in segments), sum(s.count_out for s in segments)
    notes.append(
        f"segments: {len(segments)} on one timeline ({', '.join(str(d) for d in durations)} frames); "
        f"{plural(sum(s.long_lived for s in segments), 'long-lived splat')} split into time-windowed pieces; "
        f"{count_in:,} -> {plural(count_out, 'splat')}"
        + (f" ({count_out / count_in:.2f}x)" if count_in else ""))
    return notes
