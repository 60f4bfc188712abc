"""Frame sequences -> one 4D scene.

A sequence is N static frames at times t_0 < ... < t_{N-1}. Two cases:

* **Same splats** (row i of every frame is the same splat): each splat's life
  is fitted with the Spacetime Gaussians lite model, which is what the viewer
  draws: a cubic position in dt = t - c around the temporal centre c, a linear
  rotation normalize(rot + omega dt), a temporal Gaussian opacity
  P exp(-((t - c) / s)^2) and constant scales and colour. Everything is fitted
  by least squares over frames, vectorised over splats: the normal-equation sums
  are accumulated one frame at a time, then solved in one batched call, so a
  frame is never held beside another. A sequence sampled from a lite scene is
  fitted back to round-off.
* **Different splats per frame**: frame k's splats are shown around t_k only,
  cut by the viewer's 0.02 temporal cutoff before the neighbouring frames' times.

Splats whose motion one cubic cannot follow within ``max_error`` are split into
pieces: copies with their own cubic, each shown through a Gaussian time window;
neighbouring windows overlap so that their composited opacity stays close to the
splat's (see :func:`_piece_peak`). No I/O here: frames come from a callable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import viewer
from ..errors import UsageError
from ..model import COLOR, COLUMNS, MOTION, OMEGA, POSITION, ROTATION, SCALE, STATIC_TRBF_SCALE, VARIANT_LITE, Scene
from ..progress import SILENT
from ..wording import plural

#: Identity modes of ``--same-splats``.
SAME_SPLATS_MODES = ("auto", "yes", "no")
#: Default ``max_error`` as a share of the first frame's extent (1st-99th percentile box diagonal).
DEFAULT_MAX_ERROR_SHARE = 1e-3
#: Most halvings of the clip tried for a splat that one cubic cannot follow (2^4 = 16 pieces + 2).
MAX_SPLIT_LEVEL = 4
#: Window value at a piece's core edges: overlapping windows whose composite stays near-constant
#: (measured in specs/segments.md and tests/test_sequence.py: below 0.07 opacity off for alpha 0.99).
PIECE_EDGE = 0.75
#: Frames where a piece's window is at least this count towards its fit error.
_PIECE_ERROR_WINDOW = 0.3
#: Pieces whose peak opacity is below half an 8-bit step are not written.
_MIN_PIECE_PEAK = 0.5 / 255
#: Largest log temporal scale written: exp(scale) = 1024 keeps opacity above 0.999999 over [0, 1].
_WIDE = float(STATIC_TRBF_SCALE)
#: Tikhonov weight on higher polynomial terms: lets a splat seen in fewer than 4 frames get the
#: lowest-degree curve through them instead of a singular solve.
_RIDGE = 1e-9
#: A colour change (0..1) beyond which a splat is unlikely to be one splat in every frame; when most
#: splats change this much, a note suggests --same-splats no.
_RECOLOURED = 0.1
#: Fitted terms whose effect over the clip is below this share of the splat's scale are noise (zeroed):
#: half a float32 step, the resolution of the frames' own values.
_ROUNDOFF = 2.0 ** -24


@dataclass
class SequenceReport:
    """What :func:`fit_sequence` did.

    ``*_error`` entries are distributions over input splats (p50, p90, p99, max)
    of each splat's worst frame: position in scene units, rotation in degrees,
    opacity in [0, 1] (the fitted viewer opacity against the frame's).
    """

    frames: int
    times: list
    same_splats: bool
    splats_per_frame: list
    splats_out: int
    max_error: float | None = None
    split_splats: int = 0
    pieces_added: int = 0
    dropped: int = 0
    position_error: dict = field(default_factory=dict)
    rotation_error_deg: dict = field(default_factory=dict)
    opacity_error: dict = field(default_factory=dict)
    scale_variation: float = 0.0
    color_variation: float = 0.0
    notes: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {
            "frames": self.frames, "times": [round(t, 9) for t in self.times], "same_splats": self.same_splats,
            "splats_per_frame": self.splats_per_frame if not self.same_splats else self.splats_per_frame[:1],
            "splats_out": self.splats_out, "max_error": self.max_error, "split_splats": self.split_splats,
            "pieces_added": self.pieces_added, "dropped": self.dropped,
            "position_error": self.position_error, "rotation_error_deg": self.rotation_error_deg,
            "opacity_error": self.opacity_error, "scale_variation": self.scale_variation,
            "color_variation": self.color_variation, "notes": list(self.notes),
        }


def default_times(count: int) -> np.ndarray:
    """Frame k of N at k / (N - 1): ``(N,) float64`` (a single frame at 0.5)."""
    if count == 1:
        return np.array([0.5])
    return np.arange(count, dtype=np.float64) / (count - 1)


def check_times(times, count: int, stored=np.float32) -> np.ndarray:
    """Frame times as ``(N,) float64``, refusing a wrong count, values outside [0, 1] or non-increasing ones.

    The viewer plays [0, 1], so a frame outside it would never be shown; and the
    output stores temporal centres as ``stored`` (a numpy float type: float32 in
    a PLY, float16 in the viewer's texture), so times, given or the default
    k / (N - 1), must still increase strictly once rounded to it (else two
    frames would share one time).

    Raises
    ------
    UsageError
    """
    if times is None:
        t = default_times(count)
    else:
        t = np.asarray(times, dtype=np.float64) + 0.0  # -0 is 0
        if t.ndim != 1 or len(t) != count:
            raise UsageError(f"--frame-times gives {plural(t.size, 'time')} for {plural(count, 'frame')}")
        if not np.isfinite(t).all():
            raise UsageError("--frame-times must be finite numbers")
        outside = t[(t < 0) | (t > 1)]
        if len(outside):
            raise UsageError(f"--frame-times: {outside[0]:g} is not in the viewer's time range [0, 1]")
        if count > 1 and not (np.diff(t) > 0).all():
            raise UsageError("--frame-times must increase strictly")
    same = np.flatnonzero(np.diff(t.astype(stored)) <= 0)
    if len(same):
        k = int(same[0])
        where = "--frame-times: " if times is not None else f"{plural(count, 'frame')} at k / (N - 1): "
        raise UsageError(f"{where}{float(t[k])!r} and {float(t[k + 1])!r} are one time once stored as "
                         f"{np.dtype(stored).name}, the output's precision for times")
    return t


def fit_sequence(read_frame, count: int, *, times=None, same_splats: str = "auto", max_error: float | None = None,
                 counts=None, time_type=np.float32, progress=SILENT):
    """Make one 4D scene from ``count`` frames.

    Parameters
    ----------
    read_frame : callable
        ``read_frame(k) -> Scene``; called again for every pass over the frames
        (same splats: two passes, plus two per split level), one frame at a time.
    count : int
        Frames N >= 1.
    times : (N,) array-like, optional
        Frame times (default :func:`default_times`).
    same_splats : {"auto", "yes", "no"}
        Whether row i of every frame is one splat; auto: when every frame has the same count.
    max_error : float, optional
        Largest position error (scene units) before a splat is split into pieces;
        default :data:`DEFAULT_MAX_ERROR_SHARE` of the first frame's extent.
    counts : list of (int or None), optional
        Splats per frame, where the caller knows them without reading; a frame
        whose count is missing (None, or no list) is read once more to count it.
    time_type : numpy float type
        How the output stores temporal centres (:func:`check_times`).

    Returns
    -------
    (Scene, SequenceReport)

    Raises
    ------
    UsageError
        Bad times, ``same_splats="yes"`` with differing counts, or no frames.
    """
    if same_splats not in SAME_SPLATS_MODES:
        raise UsageError(f"unknown --same-splats {same_splats!r} (expected one of {', '.join(SAME_SPLATS_MODES)})")
    if count < 1:
        raise UsageError("no frames")
    t = check_times(times, count, time_type)
    if max_error is not None and not (math.isfinite(max_error) and max_error > 0):
        raise UsageError("--max-error must be a positive number")
    counts = [None] * count if counts is None else list(counts)
    if len(counts) != count:
        raise ValueError(f"counts holds {len(counts)} entries for {count} frames")
    unknown = [k for k, c in enumerate(counts) if c is None]
    if unknown:
        with progress.stage("counting splats", len(unknown), "frame") as advance:
            for k in unknown:
                counts[k] = read_frame(k).count
                advance()
    counts = [int(c) for c in counts]
    same = len(set(counts)) == 1 if same_splats == "auto" else same_splats == "yes"
    if same and len(set(counts)) != 1:
        raise UsageError(f"--same-splats yes, but the frames hold different counts ({min(counts):,} to "
                         f"{plural(max(counts), 'splat')})")
    report = SequenceReport(frames=count, times=[float(x) for x in t], same_splats=same,
                            splats_per_frame=counts, splats_out=0)
    if same:
        scene = _fit_same(read_frame, t, counts[0], max_error, report, progress)
    else:
        scene = _stack_frames(read_frame, t, counts, report, progress)
    report.splats_out = scene.count
    return scene, report


# --------------------------------------------------------------------------
# Different splats per frame.


def frame_windows(times: np.ndarray) -> np.ndarray:
    """Log temporal scales that show frame k at t_k and cut it before t_{k-1} and t_{k+1}: ``(N,) float64``.

    The viewer hides a splat beyond VISIBLE_RADIUS * exp(scale) of its centre;
    the scale puts that reach 0.1% inside the nearer neighbouring frame time.
    A single frame gets the wide (always visible) scale.
    """
    if len(times) == 1:
        return np.array([_WIDE])
    gaps = np.diff(times)
    nearest = np.minimum(np.concatenate([[np.inf], gaps]), np.concatenate([gaps, [np.inf]]))
    return np.minimum(np.log(nearest / (viewer.VISIBLE_RADIUS * 1.001)), _WIDE)


def _stack_frames(read_frame, t, counts, report, progress) -> Scene:
    total = sum(counts)
    scales = frame_windows(t)
    out = {name: np.empty(total, np.float32) for name in COLUMNS}
    moving = 0
    at = 0
    with progress.stage("stacking frames", len(t), "frame") as advance:
        for k in range(len(t)):
            frame = read_frame(k)
            n = frame.count
            if n != counts[k]:
                raise UsageError(f"frame {k} changed while being read ({counts[k]:,} then {plural(n, 'splat')})")
            c = frame.columns
            moving += _has_motion(c)
            for name in POSITION + COLOR + ("opacity",) + SCALE + ROTATION:
                out[name][at:at + n] = c[name]
            for name in MOTION + OMEGA:
                out[name][at:at + n] = 0.0
            out["trbf_center"][at:at + n] = t[k]
            out["trbf_scale"][at:at + n] = scales[k]
            at += n
            advance()
    if moving:
        report.notes.append(f"{plural(moving, 'frame')} carry motion or a temporal window; each frame is taken at its "
                            "rest state (motion, omega and the temporal window replaced)")
    return Scene(columns=out, variant=VARIANT_LITE, meta={"frames": len(t)})


def _has_motion(cols) -> bool:
    for name in MOTION + OMEGA:
        a = np.asarray(cols[name])
        if a.size and np.any(a != 0):
            return True
    return False


# --------------------------------------------------------------------------
# Same splats: least-squares fits, accumulated frame by frame.


def _frame_state(cols: dict):
    """What a frame says of each splat: position, unit quaternion, opacity, log scales, colour, seen."""
    pos = np.stack([viewer.wide(cols[n]) for n in POSITION], axis=1)
    rot = np.stack([viewer.wide(cols[n]) for n in ROTATION], axis=1)
    alpha = viewer.opacity(cols)
    with np.errstate(invalid="ignore", over="ignore"):
        norm = np.sqrt((rot * rot).sum(axis=1))
        seen = np.isfinite(pos).all(axis=1) & np.isfinite(norm) & (norm > 0) & np.isfinite(alpha) & (alpha > 0)
        q = np.where(seen[:, None], rot / np.where(seen, norm, 1.0)[:, None], 0.0)
    pos = np.where(seen[:, None], pos, 0.0)
    alpha = np.where(seen, alpha, 0.0)
    logscale = np.stack([viewer.wide(cols[n]) for n in SCALE], axis=1)
    color = np.stack([viewer.wide(cols[n]) for n in COLOR], axis=1)
    return pos, q, alpha, logscale, color, seen


def _rows_state(frame: Scene, rows: np.ndarray):
    """:func:`_frame_state` of rows ``rows`` of a frame only (the piece passes follow few splats)."""
    return _frame_state(frame.take(rows))


def _powers(u, degree: int = 3) -> np.ndarray:
    """``u ** [0..degree]`` along a new last axis."""
    u = np.asarray(u, np.float64)
    return u[..., None] ** np.arange(degree + 1)


def _shift_poly(coef: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Re-expand sum_j a_j x^j around x = d: coefficients of (x - d)^i.

    ``coef`` is ``(N, J, 3)``, ``d`` ``(N,)``; exact algebra (binomial theorem).
    """
    J = coef.shape[1]
    out = np.zeros_like(coef)
    for i in range(J):
        for j in range(i, J):
            out[:, i] += math.comb(j, i) * coef[:, j] * (d ** (j - i))[:, None]
    return out


@dataclass
class _Sums:
    """Normal-equation sums of every splat, in the normalised time u = (t - mid) / half."""

    n: int

    def __post_init__(self):
        n = self.n
        self.seen = np.zeros(n)                  # frames seen
        self.first = np.full(n, -1)              # first and last frame seen
        self.last = np.full(n, -1)
        self.G = np.zeros((n, 4, 4))             # sum w x x^T, x = u^[0..3]
        self.b = np.zeros((n, 4, 3))             # sum w x p^T
        self.R = np.zeros((3, n, 4, 4))          # sum w u^j (I - q q^T), j = 0..2
        self.om = np.zeros((n, 5))               # sum a^2 u^j, j = 0..4 (log-opacity fit weights)
        self.oy = np.zeros((n, 3))               # sum a^2 u^j ln a
        self.asum = np.zeros(n)                  # sum of opacities where seen
        self.scale = np.zeros((n, 3))
        self.color = np.zeros((n, 3))
        self.finite = np.zeros((n, 6), np.int32)       # frames with a finite scale / colour value
        self.fallback = np.full((n, 6), np.nan, np.float32)  # a seen frame's value, for none finite
        self.lo = np.full((n, 6), np.inf)
        self.hi = np.full((n, 6), -np.inf)

    def add(self, k: int, u: float, state) -> None:
        pos, q, alpha, logscale, color, seen = state
        w = seen.astype(np.float64)
        self.first[seen & (self.first < 0)] = k
        self.last[seen] = k
        x = _powers(u)
        self.seen += w
        self.G += w[:, None, None] * np.outer(x, x)
        self.b += (w[:, None] * pos)[:, None, :] * x[None, :, None]
        p = -q[:, :, None] * q[:, None, :]
        p[:, range(4), range(4)] += 1.0
        p *= w[:, None, None]
        for j in range(3):
            self.R[j] += p * u ** j
        with np.errstate(divide="ignore"):
            la = np.where(seen, np.log(np.where(seen, alpha, 1.0)), 0.0)
        a2 = alpha * alpha
        self.om += a2[:, None] * _powers(u, 4)
        self.oy += (a2 * la)[:, None] * _powers(u, 2)
        self.asum += alpha
        sc = np.concatenate([logscale, color], axis=1)
        ok = seen[:, None] & np.isfinite(sc)
        self.scale += np.where(ok[:, :3], logscale, 0.0)
        self.color += np.where(ok[:, 3:], color, 0.0)
        self.finite += ok
        self.fallback[seen] = sc[seen]
        np.minimum(self.lo, np.where(ok, sc, np.inf), out=self.lo)
        np.maximum(self.hi, np.where(ok, sc, -np.inf), out=self.hi)


def _solve_cubic(G: np.ndarray, b: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """Batched ridge-regularised solve of ``G a = b``: ``(M, 4, 3)``."""
    ridge = _RIDGE * np.maximum(seen, 1.0)
    A = G + ridge[:, None, None] * np.diag([0.0, 1.0, 1.0, 1.0])[None]
    A[:, 0, 0] += (seen == 0) * 1.0  # unseen: a = 0 rather than a singular matrix
    return np.linalg.solve(A, b)


def _fit_rotation(R: np.ndarray, seen: np.ndarray):
    """(r, w) with normalize(r + w u) closest to the frames' quaternions: two ``(N, 4)``.

    The smallest eigenvector of sum_k A_k^T (I - q_k q_k^T) A_k with A_k = [I, u_k I]:
    the residual of each frame's quaternion against the line, free of each
    frame's scale and sign (q and -q are one rotation), so unit or unnormalised,
    sign-flipped frames fit the same. A tiny weight on w prefers a constant
    rotation where the frames cannot tell (one rotation in every frame).
    """
    n = R.shape[1]
    M = np.zeros((n, 8, 8))
    M[:, :4, :4], M[:, :4, 4:], M[:, 4:, :4], M[:, 4:, 4:] = R[0], R[1], R[1], R[2]
    scale = np.maximum(np.trace(R[0], axis1=1, axis2=2), 1.0)
    M[:, range(4, 8), range(4, 8)] += (_RIDGE * 1e-3 * scale)[:, None]
    _, vecs = np.linalg.eigh(M)
    v = vecs[:, :, 0]
    r, w = v[:, :4], v[:, 4:]
    r = np.where((seen > 0)[:, None], r, np.array([1.0, 0, 0, 0]))
    w = np.where((seen > 0)[:, None], w, 0.0)
    return r, w


def _fit_opacity(sums: _Sums, u: np.ndarray):
    """Temporal Gaussian per splat: peak P, centre u_c and scale s_u (u units), or wide where flat.

    Weighted least squares of ln(alpha) by a quadratic in u, weights alpha^2 (so
    faint frames, whose logarithm is noisy, count little); exact for samples of a
    Gaussian. A centre outside the frames' range extended by half the span on
    each side is clamped there and the peak and width refitted with it fixed,
    so the motion terms stay small. A flat or dipping profile becomes a constant.
    """
    m, y = sums.om, sums.oy
    A = np.stack([m[:, 0:3], m[:, 1:4], m[:, 2:5]], axis=1)
    A = A + (_RIDGE * np.maximum(m[:, 0], 1e-300))[:, None, None] * np.diag([0.0, 1.0, 1.0])[None]
    A[:, 0, 0] += (m[:, 0] == 0) * 1.0
    a = np.linalg.solve(A, y[:, :, None])[:, :, 0]
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    curved = a2 < -1e-9
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        uc = np.where(curved, -a1 / (2 * a2), 0.0)
    limit = 2.0
    clamp = curved & (np.abs(uc) > limit)
    uc = np.where(clamp, np.clip(uc, -limit, limit), uc)
    # With the centre fixed: ln a = lnP - k (u - uc)^2, z = (u - uc)^2 = u^2 - 2 uc u + uc^2.
    s0, s1, s2, s3, s4 = (m[:, j] for j in range(5))
    z1 = s2 - 2 * uc * s1 + uc * uc * s0
    z2 = s4 - 4 * uc * s3 + (4 * uc * uc + 2 * uc * uc) * s2 - 4 * uc ** 3 * s1 + uc ** 4 * s0
    y0, y1, y2 = y[:, 0], y[:, 1], y[:, 2]
    zy = y2 - 2 * uc * y1 + uc * uc * y0
    det = s0 * z2 - z1 * z1
    with np.errstate(divide="ignore", invalid="ignore"):
        k_fixed = np.where(det > 0, (z1 * y0 - s0 * zy) / np.where(det > 0, det, 1.0), 0.0)
        lnp_fixed = np.where(s0 > 0, (y0 + k_fixed * z1) / np.where(s0 > 0, s0, 1.0), 0.0)
        k = np.where(clamp, k_fixed, -a2)
        lnp = np.where(clamp, lnp_fixed, a0 - a1 * a1 / (4 * a2))
    gaussian = curved & (k > 1e-9)
    mean = sums.asum / np.maximum(sums.seen, 1.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        peak = np.where(gaussian, np.exp(np.minimum(lnp, 0.0)), mean)
        s_u = np.where(gaussian, 1.0 / np.sqrt(np.where(gaussian, k, 1.0)), np.inf)
    uc = np.where(gaussian, uc, 0.0)
    # Seen in one or two frames: a quadratic is not determined; show the splat around
    # where it was seen and cut it before the frames where it was not (as a frame of a
    # sequence of different splats is).
    few = (sums.seen > 0) & (sums.seen <= 2)
    if few.any():
        uc_f = m[few, 1] / m[few, 0]
        before = np.where(sums.first[few] > 0, u[np.maximum(sums.first[few] - 1, 0)], -np.inf)
        after = np.where(sums.last[few] < len(u) - 1, u[np.minimum(sums.last[few] + 1, len(u) - 1)], np.inf)
        gap = np.minimum(uc_f - before, after - uc_f)
        s_f = gap / (viewer.VISIBLE_RADIUS * 1.001)
        k_f = np.where(np.isfinite(s_f), 1.0 / np.where(np.isfinite(s_f), s_f, 1.0) ** 2, 0.0)
        z1 = m[few, 2] - 2 * uc_f * m[few, 1] + uc_f * uc_f * m[few, 0]
        lnp_f = (y[few, 0] + k_f * z1) / m[few, 0]
        # Two frames: a Gaussian through both opacities, cut before the unseen neighbours:
        # one free parameter (the centre); take the widest that passes the cuts and P <= 1.
        two = sums.seen[few] == 2
        if two.any():
            u1, u2 = u[sums.first[few][two]], u[sums.last[few][two]]
            mm, yy = m[few][two], y[few][two]
            w1 = (mm[:, 1] - mm[:, 0] * u2) / (u1 - u2)       # alpha_1^2 and alpha_2^2 from the moments
            w2 = mm[:, 0] - w1
            l1 = (yy[:, 1] - yy[:, 0] * u2) / (u1 - u2) / w1   # ln alpha_1, ln alpha_2
            l2 = (yy[:, 0] - w1 * l1) / w2
            lo = np.where(np.isfinite(before[two]), before[two], u1 - 2 * (u2 - u1))
            hi = np.where(np.isfinite(after[two]), after[two], u2 + 2 * (u2 - u1))
            c = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, 257)[None, :]
            with np.errstate(divide="ignore", invalid="ignore"):
                kk = (l1 - l2)[:, None] / ((u2 - u1)[:, None] * (u2 + u1)[:, None] - 2 * c * (u2 - u1)[:, None])
                lnp = l1[:, None] + kk * (u1[:, None] - c) ** 2
                r2 = viewer.VISIBLE_RADIUS ** 2 * 1.002
                ok = (kk > 0) & (lnp <= 1e-9) & ~(kk * (before[two][:, None] - c) ** 2 < r2) \
                    & ~(kk * (after[two][:, None] - c) ** 2 < r2)
            best = np.argmin(np.where(ok, kk, np.inf), axis=1)
            found = ok[np.arange(len(best)), best]
            rows = np.flatnonzero(two)[found]
            pick = (np.flatnonzero(found), best[found])
            uc_f[rows] = c[pick]
            s_f[rows] = 1.0 / np.sqrt(kk[pick])
            lnp_f[rows] = lnp[pick]
        peak[few] = np.exp(np.minimum(lnp_f, 0.0))
        uc[few], s_u[few] = uc_f, s_f
    return peak, uc, s_u


def _fit_same(read_frame, t, n, max_error, report, progress) -> Scene:
    mid = 0.5 * (t[0] + t[-1])
    half = 0.5 * (t[-1] - t[0]) or 1.0
    u = (t - mid) / half
    sums = _Sums(n)
    moving = 0
    extent = None
    with progress.stage("fitting frames", len(t), "frame") as advance:
        for k in range(len(t)):
            frame = _checked(read_frame, k, n)
            moving += _has_motion(frame.columns)
            state = _frame_state(frame.columns)
            if extent is None:
                extent = _extent(state[0][state[5]])
            sums.add(k, u[k], state)
            advance()
    if moving:
        report.notes.append(f"{plural(moving, 'frame')} carry motion or a temporal window; each frame is taken at its "
                            "rest state")
    if max_error is None:
        max_error = DEFAULT_MAX_ERROR_SHARE * extent if extent > 0 else 1e-6
    report.max_error = float(max_error)

    peak, uc, s_u = _fit_opacity(sums, u)
    centre = mid + uc * half
    with np.errstate(over="ignore"):
        trbf_scale = np.minimum(np.log(s_u * half), _WIDE)
    a = _solve_cubic(sums.G, sums.b, sums.seen)                       # around u = 0
    a = a / (half ** np.arange(4))[None, :, None]                      # per (t - mid)^j
    motion = _shift_poly(a, centre - mid)                              # per (t - centre)^j
    r, w = _fit_rotation(sums.R, sums.seen)
    w = w / half
    r = r + w * (centre - mid)[:, None]
    norm = np.sqrt((r * r).sum(axis=1))
    norm = np.where(norm > 1e-12, norm, 1.0)
    r, w = r / norm[:, None], w / norm[:, None]
    _snap_roundoff(motion, r, w, t, centre, extent)
    # Mean of the frames' finite values; a value finite in no frame stays as the frames had it.
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(sums.finite > 0, np.concatenate([sums.scale, sums.color], axis=1) / sums.finite,
                        sums.fallback)
    cols = {
        "x": motion[:, 0, 0], "y": motion[:, 0, 1], "z": motion[:, 0, 2],
        "trbf_center": centre, "trbf_scale": trbf_scale, "opacity": viewer.logit(np.clip(peak, 1e-7, 1 - 1e-7)),
    }
    for j in range(3):
        for i in range(3):
            cols[MOTION[3 * j + i]] = motion[:, j + 1, i]
        cols[SCALE[j]] = mean[:, j]
        cols[COLOR[j]] = mean[:, 3 + j]
    for i in range(4):
        cols[ROTATION[i]], cols[OMEGA[i]] = r[:, i], w[:, i]
    spread = np.where(np.isfinite(sums.hi - sums.lo), sums.hi - sums.lo, 0.0) if n else np.zeros((0, 6))
    report.scale_variation = float(spread[:, :3].max()) if n else 0.0
    report.color_variation = float(spread[:, 3:].max()) if n else 0.0
    if report.scale_variation > 1e-6 or report.color_variation > 1e-6:
        report.notes.append(f"scales and colours differ between frames (up to {report.scale_variation:.3g} in log "
                            f"scale, {report.color_variation:.3g} in colour); each splat keeps its mean")
    recoloured = int((spread[:, 3:].max(axis=1) > _RECOLOURED).sum()) if n else 0
    if recoloured > n // 2:
        report.notes.append(f"{plural(recoloured, 'splat')} of {n:,} change colour by more than {_RECOLOURED:g} "
                            "between frames: if row i is not the same splat in every frame (.splat files, for "
                            "one, are sorted by importance), use --same-splats no")

    errors = _errors(read_frame, t, n, cols, progress)
    keep = sums.seen > 0
    report.dropped = int(n - keep.sum())
    if report.dropped:
        report.notes.append(f"{plural(report.dropped, 'splat')} invisible in every frame dropped")
    bad = keep & (errors[0] > max_error)
    pos_err = errors[0].copy()
    pieces = None
    if bad.any():
        pieces, pos_err[bad], added = _split(read_frame, t, np.flatnonzero(bad), cols, max_error, progress)
        keep &= ~bad
        report.split_splats = int(bad.sum())
        report.pieces_added = added
        report.notes.append(f"{plural(report.split_splats, 'splat')} whose motion one cubic cannot follow within "
                            f"{max_error:.3g} were split into pieces: {added:+,} splats")
        unmet = int((pos_err[bad] > max_error).sum())
        if unmet:
            report.notes.append(f"{unmet:,} of them still exceed {max_error:.3g} after {2 ** MAX_SPLIT_LEVEL} "
                                "pieces (see the error distribution)")
    report.position_error = _distribution(pos_err[sums.seen > 0])
    report.rotation_error_deg = _distribution(errors[1][sums.seen > 0])
    report.opacity_error = _distribution(errors[2][sums.seen > 0])
    out = {name: viewer.wide(cols[name])[keep] for name in COLUMNS}
    if pieces is not None:
        out = {name: np.concatenate([out[name], pieces[name]]) for name in COLUMNS}
    out = _stored(out, report.notes)
    return Scene(columns=out, variant=VARIANT_LITE, meta={"frames": len(t)})


def _stored(cols: dict, notes: list) -> dict:
    """The fitted columns (float64) as float32, noting values past float32's range, which become infinite.

    Frames with coordinates near float32's largest (3.4e38) give fitted terms
    beyond it: they are written as the infinities they round to, and said.
    """
    out, past = {}, {}
    for name, v in cols.items():
        with np.errstate(over="ignore"):
            out[name] = v.astype(np.float32)
        n = int((np.isinf(out[name]) & np.isfinite(v)).sum())
        if n:
            past[name] = n
    if past:
        notes.append(f"{plural(sum(past.values()), 'fitted value')} past float32's range (3.4e38) stored as "
                     f"infinite ({', '.join(f'{name} {n:,}' for name, n in past.items())}): frames with "
                     "coordinates that large")
    return out


def _snap_roundoff(motion: np.ndarray, r: np.ndarray, w: np.ndarray, t: np.ndarray, centre: np.ndarray,
                   extent: float) -> None:
    """Zero, in place, fitted terms below the frames' float32 resolution.

    A motion term moving a splat less than :data:`_ROUNDOFF` of its distance from
    the origin or of the scene's extent over the clip, a unit-quaternion component
    below it and an angular velocity turning less than it over the clip (only its
    part across the rotation turns: the part along it is the fit's free direction). Where a
    splat does not move or turn, the fit of its float32 positions and rotations
    leaves such terms (round-off and the frames' rounding, 1e-13 to 5e-8 on the
    sample), which no viewer can show and writers would report as lost values.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        reach = np.maximum(np.abs(t[0] - centre), np.abs(t[-1] - centre))
        ref = np.maximum(np.sqrt((motion[:, 0] ** 2).sum(axis=1)), extent) * _ROUNDOFF
        for j in range(1, motion.shape[1]):
            motion[:, j][np.abs(motion[:, j]) * (reach ** j)[:, None] < ref[:, None]] = 0.0
        r[np.abs(r) < _ROUNDOFF] = 0.0
        # normalize(r + w dt) does not turn while w is parallel to r (the rotation fit's free
        # direction, so a still splat gets some): only the perpendicular part counts.
        across = w - (w * r).sum(axis=1)[:, None] * r
        w[np.sqrt((across * across).sum(axis=1)) * reach < _ROUNDOFF] = 0.0
        w[np.abs(w) * reach[:, None] < _ROUNDOFF] = 0.0


def _checked(read_frame, k: int, n: int) -> Scene:
    frame = read_frame(k)
    if frame.count != n:
        raise UsageError(f"frame {k} holds {plural(frame.count, 'splat')}, the first {n:,}: not the same splats "
                         "(use --same-splats no)")
    return frame


def _extent(p: np.ndarray) -> float:
    if len(p) == 0:
        return 0.0
    lo, hi = np.percentile(p, [1, 99], axis=0)
    return float(np.sqrt(((hi - lo) ** 2).sum()))


def _distribution(v: np.ndarray) -> dict:
    if len(v) == 0:
        return {"p50": 0.0, "p90": 0.0, "p99": 0.0, "max": 0.0}
    p = np.percentile(v, [50, 90, 99, 100])
    return {k: float(x) for k, x in zip(("p50", "p90", "p99", "max"), p)}


def _errors(read_frame, t, n, cols, progress):
    """Each splat's worst frame: position distance, rotation angle (degrees), opacity difference."""
    pos_err, rot_err, op_err = np.zeros(n), np.zeros(n), np.zeros(n)
    peak = viewer.opacity(cols)
    with progress.stage("measuring the fit", len(t), "frame") as advance:
        for k in range(len(t)):
            pos, q, alpha, _, _, seen = _frame_state(_checked(read_frame, k, n).columns)
            fit = viewer.position_at(cols, t[k])
            d = np.sqrt(((fit - pos) ** 2).sum(axis=1))
            np.maximum(pos_err, np.where(seen, d, 0.0), out=pos_err)
            qf = viewer.rotation_at(cols, t[k])
            dot = np.minimum(np.abs((qf * q).sum(axis=1)), 1.0)
            np.maximum(rot_err, np.where(seen, np.degrees(2 * np.arccos(dot)), 0.0), out=rot_err)
            a = peak * viewer.temporal_opacity(cols, t[k])
            np.maximum(op_err, np.abs(a - alpha), out=op_err)
            advance()
    return pos_err, rot_err, op_err


# --------------------------------------------------------------------------
# Pieces: a splat that one cubic cannot follow becomes overlapping time-windowed copies.


def _window_scale(width: float) -> float:
    """Linear scale of a piece window whose value is PIECE_EDGE at +-width/2."""
    return 0.5 * width / math.sqrt(-math.log(PIECE_EDGE))


def _piece_peak(alpha: np.ndarray) -> np.ndarray:
    """Peak opacity of each piece so a regular row of overlapping windows composites to ``alpha``.

    Composited, co-located copies give 1 - prod_j (1 - P g_j(t)); the table
    holds its mean over one window period for each P, and is inverted by
    interpolation (it rises with P).
    """
    P = np.linspace(0.0, 1.0, 1025)
    phase = np.linspace(-0.5, 0.5, 33)
    j = np.arange(-6, 7)
    d = (phase[:, None] - j[None, :])  # distance to piece centres, in piece widths
    g = viewer.apply_cut(viewer.temporal_basis(d, 0.5 / math.sqrt(-math.log(PIECE_EDGE))))
    comp = 1.0 - np.prod(1.0 - P[:, None, None] * g[None], axis=2)
    mean = comp.mean(axis=1)
    return np.interp(np.clip(alpha, 0.0, mean[-1]), mean, P)


def _split(read_frame, t, rows, cols, max_error, progress):
    """Pieces for splats ``rows``: the smallest number of halvings (1..MAX_SPLIT_LEVEL) meeting ``max_error``."""
    todo = rows
    err_out = np.full(len(rows), np.inf)
    chosen = {}
    for level in range(1, MAX_SPLIT_LEVEL + 1):
        if len(todo) == 0:
            break
        pieces, err = _fit_pieces(read_frame, t, todo, cols, level, progress)
        done = (err <= max_error) | (level == MAX_SPLIT_LEVEL)
        at = np.searchsorted(rows, todo)
        err_out[at[done]] = err[done]
        chosen[level] = {k: v[np.repeat(done, len(v) // max(len(todo), 1))] for k, v in pieces.items()}
        todo = todo[~done]
    out = {name: np.concatenate([chosen[lv][name] for lv in chosen]) for name in COLUMNS}
    peak_ok = viewer.opacity(out) >= _MIN_PIECE_PEAK
    out = {name: v[peak_ok] for name, v in out.items()}
    return out, err_out, int(len(out["x"]) - len(rows))


def _fit_pieces(read_frame, t, rows, cols, level, progress):
    """Cubics of splats ``rows`` on 2^level pieces plus one beyond each end; pieces and each splat's error."""
    m = len(rows)
    parts = 2 ** level
    width = (t[-1] - t[0]) / parts
    centres = t[0] + (np.arange(-1, parts + 1) + 0.5) * width         # (J,)
    J = len(centres)
    sw = _window_scale(width)
    reach = viewer.VISIBLE_RADIUS * sw
    u = (t[:, None] - centres[None, :]) / width                        # frame time around each piece
    g = viewer.temporal_basis(t[:, None] - centres[None, :], sw)
    g[np.abs(t[:, None] - centres[None, :]) > reach] = 0.0
    G = np.zeros((m, J, 4, 4))
    b = np.zeros((m, J, 4, 3))
    cnt = np.zeros((m, J))
    sub = {name: np.asarray(cols[name])[rows] for name in COLUMNS}
    n = len(np.asarray(cols["x"]))
    with progress.stage(f"fitting pieces ({parts})", len(t), "frame") as advance:
        for k in range(len(t)):
            pos, _, _, _, _, seen = _rows_state(_checked(read_frame, k, n), rows)
            live = np.flatnonzero(g[k] > 0)
            w = seen.astype(np.float64)[:, None] * g[k, live][None, :]         # (m, L)
            x = _powers(u[k, live])                                             # (L, 4)
            G[:, live] += w[:, :, None, None] * (x[:, :, None] * x[:, None, :])[None]
            b[:, live] += w[:, :, None, None] * x[None, :, :, None] * pos[:, None, None, :]
            cnt[:, live] += w
            advance()
    a = _solve_cubic(G.reshape(m * J, 4, 4), b.reshape(m * J, 4, 3), cnt.reshape(-1))
    a = a / (width ** np.arange(4))[None, :, None]
    # Each piece: the whole-clip fit's rotation, scale and colour, the piece's cubic,
    # a window centred on the piece with a peak that composites to the splat's opacity there.
    cj = np.tile(centres, m)
    src = np.repeat(np.arange(m), J)
    alpha = _opacity_at(sub, src, cj)
    out = {name: viewer.wide(sub[name][src]) for name in SCALE + COLOR}
    dt = cj - viewer.wide(sub["trbf_center"])[src]
    for i in range(4):
        out[ROTATION[i]] = sub[ROTATION[i]][src] + sub[OMEGA[i]][src] * dt
        out[OMEGA[i]] = viewer.wide(sub[OMEGA[i]][src])
    for i, name in enumerate(POSITION):
        out[name] = a[:, 0, i]
    for j in range(3):
        for i in range(3):
            out[MOTION[3 * j + i]] = a[:, j + 1, i]
    out["trbf_center"] = cj
    out["trbf_scale"] = np.full(m * J, math.log(sw))
    out["opacity"] = viewer.logit(np.clip(_piece_peak(alpha), 1e-7, 1 - 1e-7))
    err = _piece_errors(read_frame, t, rows, n, out, g, J, progress)
    return out, err


def _opacity_at(sub, src, times) -> np.ndarray:
    """The whole-clip fit's viewer opacity of splat ``src`` at ``times`` (no cut): ``(M,) float64``."""
    centre = viewer.wide(sub["trbf_center"])[src]
    with np.errstate(over="ignore", invalid="ignore"):
        s = viewer.trbf_scale(sub)[src]
        g = viewer.temporal_basis(times - centre, s)
    return viewer.opacity(sub)[src] * g


def _piece_errors(read_frame, t, rows, n, pieces, g, J, progress):
    m = len(rows)
    err = np.zeros(m)
    with progress.stage("measuring pieces", len(t), "frame") as advance:
        for k in range(len(t)):
            pos, _, _, _, _, seen = _rows_state(_checked(read_frame, k, n), rows)
            fit = viewer.position_at(pieces, t[k]).reshape(m, J, 3)
            d = np.sqrt(((fit - pos[:, None, :]) ** 2).sum(axis=2))
            counts = (g[k] >= _PIECE_ERROR_WINDOW)[None, :] & seen[:, None]
            np.maximum(err, np.where(counts, d, 0.0).max(axis=1), out=err)
            advance()
    return err
