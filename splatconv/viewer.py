"""What the splaTV viewer computes from a splat, written once.

Every part of splatconv that needs the viewer's per-splat maths calls this
module: attribute comparison and stats, the float reference renderer, and the
scene operations (transforms, trim, bake, merge, frame sequences). Values are
float64 where bit-exactness is not the point; the ``.splatv`` writer's packing
(which must match the viewer's converter bit for bit) keeps its own float32
arithmetic in :mod:`splatconv.formats.splatv_engine`.

The viewer's vertex shader (``splatconv/render/shaders/splat_main.glsl``), for a
splat at scene time ``t``::

    dt        = t - trbf_center
    topacity  = exp(-(dt / exp(trbf_scale))^2)        hidden when < 0.02
    position  = xyz + motion_0..2 dt + motion_3..5 dt^2 + motion_6..8 dt^3
    rotation  = normalize(rot + omega dt)
    scale     = exp(scale_0..2)
    colour    = clamp(f_dc_0..2, 0, 1)                (stored as bytes)
    opacity   = sigmoid(opacity) * topacity           (alpha stored as a byte)

No I/O, no printing. Column arguments are the :class:`splatconv.model.Scene`
columns dict (``(N,) float32`` arrays named as in :data:`splatconv.model.COLUMNS`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from . import packing
from .model import COLOR, GROUPS, MOTION, OMEGA, POSITION, ROTATION, SCALE

#: Temporal opacity below which the viewer skips a splat.
TEMPORAL_CUTOFF = 0.02
#: |dt| / exp(trbf_scale) at which the temporal opacity falls to the cutoff:
#: a splat is drawn while |t - trbf_center| <= VISIBLE_RADIUS * exp(trbf_scale).
VISIBLE_RADIUS = math.sqrt(-math.log(TEMPORAL_CUTOFF))
#: The viewer's time range.
TIME_RANGE = (0.0, 1.0)

# The texture the viewer draws from (``splatconv/render/shaders/fetch_splatv.glsl``): an
# RGBA32UI texture this many texels wide, each splat 16 uint32 words (4 texels) in a row.
TEXWIDTH = 4096
WORDS_PER_SPLAT = 16
SPLATS_PER_ROW = TEXWIDTH * 4 // WORDS_PER_SPLAT  # 1024: the shader's index & 0x3ff
#: Bytes of one RGBA32UI texel.
TEXEL_BYTES = 16


def texture_height(count: int) -> int:
    """Rows of the texture for ``count`` splats: ceil(count / 1024)."""
    return -(-count // SPLATS_PER_ROW)


def texture_bytes(texheight: int) -> int:
    """Bytes of a texture of ``texheight`` rows."""
    return TEXWIDTH * texheight * TEXEL_BYTES


def wide(values) -> np.ndarray:
    """``values`` as float64, the way every column is widened for the viewer's maths.

    A signalling NaN (trained scenes and hostile files carry them) raises the
    "invalid" flag when float32 is cast to float64: the value becomes a quiet
    NaN, which is all the maths needs, so the flag is no warning to show.
    """
    with np.errstate(invalid="ignore"):
        return np.asarray(values, dtype=np.float64)


def _f64(cols: dict, names) -> np.ndarray:
    """Columns ``names`` stacked as ``(N, k) float64``."""
    return np.stack([wide(cols[n]) for n in names], axis=1)


def sigmoid(x: np.ndarray) -> np.ndarray:
    """1 / (1 + exp(-x)) in float64, without overflow warnings (NaN stays NaN)."""
    x = wide(x)
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(-x))


def logit(p: np.ndarray) -> np.ndarray:
    """Inverse of :func:`sigmoid` in float64: 0 -> -inf, 1 -> inf."""
    p = wide(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log(p) - np.log1p(-p)


def exp(x: np.ndarray) -> np.ndarray:
    """exp in float64 without overflow warnings (large values become inf)."""
    with np.errstate(over="ignore"):
        return np.exp(wide(x))


def scales(cols: dict) -> np.ndarray:
    """Linear scales exp(scale_0..2): ``(N, 3) float64``."""
    return exp(_f64(cols, SCALE))


def opacity(cols: dict) -> np.ndarray:
    """Peak opacity sigmoid(opacity): ``(N,) float64`` in [0, 1] (NaN stays NaN)."""
    return sigmoid(cols["opacity"])


def colors(cols: dict) -> np.ndarray:
    """Colour as the viewer uses it, clamped to [0, 1]: ``(N, 3) float64`` (NaN stays NaN)."""
    return np.clip(_f64(cols, COLOR), 0.0, 1.0)


def trbf_scale(cols: dict) -> np.ndarray:
    """Linear temporal scale exp(trbf_scale): ``(N,) float64``."""
    return exp(cols["trbf_scale"])


def importance(cols: dict) -> np.ndarray:
    """The order key of importance sorting, ``(N,) float64``.

    exp(scale_0) * exp(scale_1) * exp(scale_2) * sigmoid(opacity), each factor
    in double as splaTV's converter computes it.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        size = (exp(cols["scale_0"]) * exp(cols["scale_1"])) * exp(cols["scale_2"])
        return size * opacity(cols)


#: The view matrix splaTV's ``hybrid.js`` opens every file at (column-major, world to camera).
SPLATV_VIEW = (0.99, 0.01, -0.14, 0.0, 0.02, 0.99, 0.12, 0.0, 0.14, -0.12, 0.98, 0.0, -0.09, -0.26, 0.2, 1.0)
#: Its built-in camera's focal lengths, in pixels of a window of :data:`SPLATV_WINDOW`.
SPLATV_FOCAL = (1159.5880733038064, 1164.6601287484507)
SPLATV_WINDOW = (1280, 720)
#: How far from a camera's own direction :func:`depth_directions` looks (a user's first drag).
DEPTH_CONE_DEGREES = 6.0


def depth_directions(cameras: list) -> np.ndarray:
    """The directions the viewer sorts splats along from ``cameras`` and its opening view: ``(K, 3) float64``.

    The viewer's depth key is row 2 of projection x view, whose first three
    values are a positive multiple of the camera's z axis (the third column of a
    ``cameras.json`` rotation; the third row of :data:`SPLATV_VIEW`). Each
    direction comes with four tilted :data:`DEPTH_CONE_DEGREES` away from it.
    """
    axes = [np.asarray(c["rotation"], np.float64)[:, 2] for c in cameras or ()]
    axes.append(np.array([SPLATV_VIEW[2], SPLATV_VIEW[6], SPLATV_VIEW[10]]))
    a = math.radians(DEPTH_CONE_DEGREES)
    out = []
    for axis in axes:
        norm = np.linalg.norm(axis)
        if not np.isfinite(norm) or norm == 0:
            continue
        axis = axis / norm
        side = np.cross(axis, [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        up = np.cross(axis, side)
        out.append(axis)
        out.extend(math.cos(a) * axis + math.sin(a) * w for w in (side, -side, up, -up))
    return np.asarray(out, np.float64).reshape(-1, 3)


#: The viewer's depth key of a splat at depth d along a camera's z axis: ``d * DEPTH_KEY_SCALE | 0``
#: (its projection's ``zfar / (zfar - znear)`` times 4096).
DEPTH_KEY_SCALE = 4096 * 200.0 / (200.0 - 0.2)
#: Splats nearest and farthest along each direction that :func:`depth_extremes` names, besides ties.
DEPTH_ENDS = 2


def js_int32(x) -> np.ndarray:
    """JavaScript's ``x | 0``: truncate, wrap modulo 2^32 into int32; NaN and infinities give 0. ``int64``."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        inside = np.abs(x) < 2.0**31  # truncation alone; not NaN, the infinities or what wraps
    if inside.all():
        return x.astype(np.int64)
    out = np.where(inside, x, 0.0).astype(np.int64)
    outside = ~inside
    rest = x[outside]  # few on a real scene: its NaN positions
    t = np.fmod(np.trunc(np.where(np.isfinite(rest), rest, 0.0)), 2.0**32)
    t = np.where(t < 0, t + 2.0**32, t)
    out[outside] = np.where(t >= 2.0**31, t - 2.0**32, t).astype(np.int64)
    return out


def depth_extremes(x: np.ndarray, y: np.ndarray, z: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The splats nearest and farthest along each direction: ``(N,) bool`` for positions ``(N,)`` each.

    The viewer scales its depth keys by their range and never draws the
    farthest splat when the scaled key reaches the top, drawing its first record
    in its place (:func:`splatconv.render.sort.viewer_order`): which splat that
    is, and whether the rounding drops it, follow from the two ends' exact
    positions, drawable or not (the viewer sorts every record). Named are the
    :data:`DEPTH_ENDS` splats of the lowest and of the highest keys
    (``d * DEPTH_KEY_SCALE | 0``, so a non-finite or far position lands where
    the viewer's key puts it) and every splat that ties with an end.
    """
    n = len(x)
    out = np.zeros(n, bool)
    if not n:
        return out
    ends = min(DEPTH_ENDS, n - 1)
    with np.errstate(invalid="ignore", over="ignore"):  # a signalling NaN warns when widened
        x, y, z = (np.asarray(v, np.float64) for v in (x, y, z))
        for d in np.asarray(directions, np.float64) * DEPTH_KEY_SCALE:
            key = js_int32(x * d[0] + y * d[1] + z * d[2])
            out |= (key == key.min()) | (key == key.max())
            if ends:
                out[np.argpartition(key, ends)[:ends]] = True
                out[np.argpartition(key, n - 1 - ends)[n - ends:]] = True
    return out


def temporal_basis(dt, scale) -> np.ndarray:
    """The viewer's temporal radial basis exp(-(dt / scale)^2), broadcast: float64.

    ``scale`` is linear (exp(trbf_scale)). Time tools evaluate it over grids of
    times and splats; :func:`temporal_opacity` is it at one time for a scene.
    No cut is applied; an infinite scale gives 1, NaN stays NaN.
    """
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        u = np.asarray(dt, dtype=np.float64) / np.asarray(scale, dtype=np.float64)
        return np.exp(-(u * u))


def apply_cut(values: np.ndarray) -> np.ndarray:
    """Temporal opacities as the viewer uses them: values below :data:`TEMPORAL_CUTOFF` become 0 (in place).

    NaN compares false with the cutoff, so it is kept, as the shader keeps it.
    """
    values[values < TEMPORAL_CUTOFF] = 0.0
    return values


def temporal_opacity(cols: dict, t: float, *, cut: bool = True) -> np.ndarray:
    """Temporal opacity exp(-(dt / exp(trbf_scale))^2) at time ``t``: ``(N,) float64``.

    With ``cut`` (default) values below :data:`TEMPORAL_CUTOFF` are 0, as the
    viewer hides those splats. An infinite temporal scale gives 1 at every time.
    A NaN result (NaN centre or scale, or a zero scale at dt = 0) compares false
    with the cutoff, so the viewer does not hide it: it stays NaN here.
    """
    value = temporal_basis(float(t) - wide(cols["trbf_center"]), trbf_scale(cols))
    if cut:
        value[value < TEMPORAL_CUTOFF] = 0.0
    return value


def visible(cols: dict, t: float) -> np.ndarray:
    """Whether the viewer draws each splat at time ``t`` (temporal cut only): ``(N,) bool``."""
    return ~(temporal_opacity(cols, t, cut=False) < TEMPORAL_CUTOFF)


def visible_interval(cols: dict) -> tuple[np.ndarray, np.ndarray]:
    """Times between which each splat passes the temporal cut: two ``(N,) float64``.

    ``trbf_center -+ VISIBLE_RADIUS * exp(trbf_scale)``; an infinite scale gives
    (-inf, inf). NaN where the centre or scale is NaN.
    """
    centre = wide(cols["trbf_center"])
    with np.errstate(over="ignore", invalid="ignore"):
        reach = trbf_scale(cols) * VISIBLE_RADIUS
        return centre - reach, centre + reach


def motion(cols: dict) -> np.ndarray:
    """Motion coefficients ``(N, 3, 3) float64``: ``[:, k]`` multiplies dt^(k+1)."""
    return _f64(cols, MOTION).reshape(-1, 3, 3)


def positions(cols: dict) -> np.ndarray:
    """Rest positions (at dt = 0): ``(N, 3) float64``."""
    return _f64(cols, POSITION)


def position_at(cols: dict, t) -> np.ndarray:
    """Centre at time ``t`` (a float, or ``(N,)`` times, one a splat): ``(N, 3) float64``.

    xyz + m0 dt + m1 dt^2 + m2 dt^3 with dt = t - trbf_center, the terms summed in
    the viewer's order.
    """
    dt = wide(t) - wide(cols["trbf_center"])
    out = np.empty((len(cols["x"]), 3), dtype=np.float64)
    # An axis at a time on whole columns (faster than on (N, 3) slices); the same operations in the
    # same order, so the same values.
    with np.errstate(over="ignore", invalid="ignore"):
        for a, name in enumerate(POSITION):
            m0, m1, m2 = (wide(cols[MOTION[3 * k + a]]) for k in range(3))
            out[:, a] = wide(cols[name]) + (m0 * dt + m1 * dt * dt + m2 * dt * dt * dt)
    return out


def rotation_at(cols: dict, t: float, *, normalize: bool = True) -> np.ndarray:
    """Rotation quaternion (w, x, y, z) at time ``t``: ``(N, 4) float64``.

    rot + omega dt, normalised as the viewer does (a zero quaternion gives NaN,
    as it does in the shader).
    """
    dt = float(t) - wide(cols["trbf_center"])
    q = np.empty((len(dt), 4), dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        for i, (rot, omega) in enumerate(zip(ROTATION, OMEGA)):
            q[:, i] = wide(cols[rot]) + wide(cols[omega]) * dt
    return unit_quaternions(q) if normalize else q


def unit_quaternions(q: np.ndarray) -> np.ndarray:
    """Quaternion rows ``(N, 4)`` normalised as the shader does, in float64 (a zero row gives NaN)."""
    q = wide(q)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return q / np.sqrt((q * q).sum(axis=1, keepdims=True))


def group_values(cols: dict, group: str) -> np.ndarray:
    """A group's columns as the viewer uses them: ``(N, k) float64``.

    Scales and the temporal scale linear (exp), colour clamped to [0, 1],
    opacity through the sigmoid; everything else as stored.
    """
    if group == "scale":
        return scales(cols)
    if group == "color":
        return colors(cols)
    if group == "opacity":
        return opacity(cols)[:, None]
    v = _f64(cols, GROUPS[group])
    if group == "trbf":
        v[:, 1] = exp(v[:, 1])
    return v


def float_record(cols: dict) -> dict:
    """Every value the shader reads of a splat, unquantized: name -> ``(N,) float64``.

    Keys are the shader's inputs as :data:`splatconv.render.layout.FLOAT_TEXELS`
    names them: positions, trbf centre, rotation, linear scales, linear trbf
    scale, clamped colour, sigmoid opacity, motion and omega.
    """
    s = scales(cols)
    c = colors(cols)
    out = {name: wide(cols[name]) for name in POSITION + ROTATION + MOTION + OMEGA}
    out["trbf_center"] = wide(cols["trbf_center"])
    out["trbf_scale"] = trbf_scale(cols)
    for i in range(3):
        out[f"scale_{i}"] = s[:, i]
        out[f"f_dc_{i}"] = c[:, i]
    out["opacity"] = opacity(cols)
    return out


# --------------------------------------------------------------------------
# Values without meaning: NaN, and the infinities the viewer gives no meaning.

#: Per attribute group: its columns, and the infinities the viewer gives a meaning.
#: NaN never has one, nor has an infinity not listed. Position, rotation, motion,
#: omega or trbf centre: any infinity puts the splat nowhere or everywhere, or gives
#: it no orientation. A log scale of -inf is a linear scale of exactly 0: a flat
#: splat, which the viewer draws (+inf: an infinitely large one). A temporal scale
#: of +inf is "visible at every time". An opacity of -inf/+inf is sigmoid 0/1; a
#: colour of -inf/+inf is clamped to 0/1. ``drop-nonfinite`` removes a splat with a
#: value without meaning, and ``info`` counts those values.
MEANINGFUL_INFINITIES = {
    "position": (POSITION, ()),
    "rotation": (ROTATION, ()),
    "scale": (SCALE, (-np.inf,)),
    "motion": (MOTION, ()),
    "omega": (OMEGA, ()),
    "trbf centre": (("trbf_center",), ()),
    "trbf scale": (("trbf_scale",), (np.inf,)),
    "opacity": (("opacity",), (-np.inf, np.inf)),
    "color": (COLOR, (-np.inf, np.inf)),
}
_KEPT_INFINITIES = {name: kept for names, kept in MEANINGFUL_INFINITIES.values() for name in names}


def without_meaning(values: np.ndarray, name: str) -> np.ndarray:
    """Values of column ``name`` the viewer gives no meaning: NaN, or an infinity not in
    :data:`MEANINGFUL_INFINITIES` for it: ``(N,) bool``."""
    values = np.asarray(values)
    bad = ~np.isfinite(values)
    for kept in _KEPT_INFINITIES[name]:
        bad &= values != kept
    return bad


# --------------------------------------------------------------------------
# Undrawable splats: what the viewer can never draw at any time in [0, 1].

#: Kinds of undrawable splat, in the order a splat is classed (a splat of several
#: kinds counts under the first), so the counts of the kinds add up to the total.
#:
#: ``zero_rotation``: rotation (0, 0, 0, 0) and omega (0, 0, 0, 0): the shader's
#: ``rot /= sqrt(dot(rot, rot))`` is 0/0 at every time (a rotation that passes
#: through zero at one instant only is drawn at every other).
#: ``nan_position``: a NaN position or motion term: the centre is NaN at every time.
#: ``alpha_zero``: the alpha byte is 0 (sigmoid(opacity) * 255 rounds to 0, or the
#: opacity is NaN, which writers store as 0): the splat adds nothing to any pixel.
#: ``hidden_in_time``: the temporal opacity is below the 0.02 cut at every t in
#: [0, 1], whether the time values are kept as float32 or stored as the viewer's
#: half floats (the centre and the linear scale exp(trbf_scale), either rounding),
#: with a margin for the GPU's float32 exp and pow.
UNDRAWABLE_KINDS = ("zero_rotation", "nan_position", "alpha_zero", "hidden_in_time")
#: Code of a drawable splat in :func:`undrawable_kinds`.
DRAWABLE = -1
#: Columns :func:`undrawable_kinds` reads.
_UNDRAWABLE_READS = ROTATION + OMEGA + POSITION + MOTION + ("opacity", "trbf_center", "trbf_scale")
#: Rows :func:`undrawable_counts` classes at a time.
_COUNT_BLOCK = 1 << 14
#: Relative margin below the cut a splat's best temporal opacity must keep to be
#: undrawable in time: the shader's float32 ``exp`` and ``pow`` are not exact.
_CUT_MARGIN = 1e-3


def _all_zero(cols: dict, names) -> np.ndarray:
    """Rows whose columns ``names`` are all exactly zero (either sign)."""
    out = np.ones(len(cols[names[0]]), dtype=bool)
    for n in names:
        out &= np.asarray(cols[n]) == 0
    return out


def _any_nan(cols: dict, names) -> np.ndarray:
    out = np.zeros(len(cols[names[0]]), dtype=bool)
    for n in names:
        out |= np.isnan(np.asarray(cols[n]))
    return out


def alpha_zero(cols: dict) -> np.ndarray:
    """Rows whose alpha byte is 0 however a writer rounds: ``(N,) bool``.

    sigmoid(opacity) * 255 rounds to 0 (it then also truncates to 0), or the
    opacity is NaN (stored as byte 0). The byte never decreases as the opacity
    grows, so this is one float32 comparison a row with :func:`_alpha_zero_max`.
    """
    x = np.asarray(cols["opacity"], dtype=np.float32)
    return np.isnan(x) | (x <= _alpha_zero_max())


def _alpha_zero_byte(x: np.float32) -> bool:
    """Whether the float32 opacity ``x`` gives alpha byte 0, by the viewer's own float64 sigmoid."""
    return bool(np.rint(opacity({"opacity": np.array([x], dtype=np.float32)})[0] * 255.0) == 0)


@functools.lru_cache(maxsize=None)
def _alpha_zero_max() -> np.float32:
    """The largest float32 opacity whose alpha byte is 0: bisection over the float32 values ordered
    as integers (the byte is monotone in the opacity), with :func:`_alpha_zero_byte`."""

    def value(key: int) -> np.float32:  # the float32 at position `key` of the ordered values
        bits = key if key >= 0 else 0x80000000 | -key
        return np.array([bits], dtype=np.uint32).view(np.float32)[0]

    lo, hi = -0x7F800000, 0x7F800000  # -inf gives byte 0, +inf byte 255
    while hi - lo > 1:  # byte 0 at lo, not at hi
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if _alpha_zero_byte(value(mid)) else (lo, mid)
    return value(lo)


def _best_temporal(centre: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Largest temporal basis over t in [0, 1] (reached at the centre clamped to it), float64."""
    dt = np.clip(centre, *TIME_RANGE) - centre
    return temporal_basis(dt, scale)


def hidden_in_time(cols: dict) -> np.ndarray:
    """Rows below the temporal cut at every t in [0, 1]: ``(N,) bool``.

    Checked on the values as read, and on what a ``.splatv`` stores of them: the
    half of the centre and the half of the linear scale exp(trbf_scale) that the
    viewer reads (either rounding), each below ``TEMPORAL_CUTOFF * (1 - 1e-3)``.
    For values read from a ``.splatv`` those halves are the values again, so the
    test is of what the file holds. The log scale is never stored, so it is never
    rounded: a half of it is a temporal scale no file holds (it once made a splat
    whose stored peak is 0.019849 drawable).
    A NaN centre or scale is never hidden: NaN passes the shader's
    ``topacity < 0.02`` test. Nor is a centre in [0, 1] (its halves stay there):
    at t = centre the basis is 1, or NaN for a zero scale.
    """
    below = TEMPORAL_CUTOFF * (1.0 - _CUT_MARGIN)
    centre = np.asarray(cols["trbf_center"], dtype=np.float32)
    hidden = np.zeros(len(centre), dtype=bool)
    rows = np.flatnonzero((centre < 0) | (centre > 1))  # NaN neither
    if not len(rows):
        return hidden
    centre = centre[rows]
    scale = exp(np.asarray(cols["trbf_scale"], dtype=np.float32)[rows])
    keep = _best_temporal(wide(centre), scale) < below
    with np.errstate(over="ignore"):
        scale32 = scale.astype(np.float32)  # both writers store exp(trbf_scale) through a float32
    for splatvjs in (False, True):
        c = packing.half_to_float(packing.float_to_half_exact(centre, splatvjs=splatvjs)[0])
        s = packing.half_to_float(packing.float_to_half_exact(scale32, splatvjs=splatvjs)[0])
        keep &= _best_temporal(wide(c), wide(s)) < below
    hidden[rows[keep]] = True
    return hidden


def undrawable_kinds(cols: dict) -> np.ndarray:
    """Why the viewer can never draw each splat: ``(N,) int8``.

    The index in :data:`UNDRAWABLE_KINDS` of the first kind that applies, or
    :data:`DRAWABLE` (-1). Removing every splat that is not drawable leaves each
    frame the viewer draws, at every time in [0, 1], unchanged.
    """
    n = len(cols["x"])
    code = np.full(n, DRAWABLE, dtype=np.int8)
    tests = (lambda: _all_zero(cols, ROTATION + OMEGA), lambda: _any_nan(cols, POSITION + MOTION),
             lambda: alpha_zero(cols), lambda: hidden_in_time(cols))
    for kind, test in enumerate(tests):
        code[(code == DRAWABLE) & test()] = kind
    return code


def undrawable(cols: dict) -> np.ndarray:
    """Rows the viewer can never draw at any time in [0, 1]: ``(N,) bool`` (see :data:`UNDRAWABLE_KINDS`)."""
    return undrawable_kinds(cols) != DRAWABLE


def undrawable_counts(cols: dict) -> dict:
    """Undrawable splats by kind: ``{kind: int}`` in :data:`UNDRAWABLE_KINDS` order, each splat under one kind.

    A block of rows at a time: columns that are views of one row table (a PLY read
    in place) are then read from cache, not from memory once per column.
    """
    n = len(cols["x"])
    code = np.empty(n, dtype=np.int8)
    for start in range(0, n, _COUNT_BLOCK):
        rows = slice(start, start + _COUNT_BLOCK)
        code[rows] = undrawable_kinds({name: cols[name][rows] for name in _UNDRAWABLE_READS})
    return kind_counts(code)


def kind_counts(code: np.ndarray) -> dict:
    """Codes ``(N,) int8`` of :func:`undrawable_kinds` or :func:`not_drawn_kinds_at` as ``{kind: int}``, every kind."""
    counts = np.bincount(code.astype(np.intp) + 1, minlength=len(UNDRAWABLE_KINDS) + 1)
    return {kind: int(counts[i + 1]) for i, kind in enumerate(UNDRAWABLE_KINDS)}


# --------------------------------------------------------------------------
# Drawn at one time: the same kinds, at one t instead of over all of [0, 1].

#: Smallest normal float32: the shader's float32 ``dot(rot, rot)`` below it is 0 or
#: subnormal (which GPUs may flush to 0), and ``rot / sqrt(dot(rot, rot))`` has no direction.
_F32_TINY = float(np.finfo(np.float32).tiny)


def rotation_has_no_direction(q: np.ndarray) -> np.ndarray:
    """Rows of quaternions ``(N, 4)`` the shader cannot normalise: ``(N,) bool``.

    Zero, NaN or infinite, or so short that the shader's float32 ``dot(rot, rot)``
    is 0 or subnormal: ``rot /= sqrt(dot(rot, rot))`` then gives NaN or infinity
    (or, flushed, 0/0), not a rotation. Every other row normalises to a finite unit
    quaternion, whose largest component is at least 0.5 in size.
    """
    q = wide(q)
    with np.errstate(over="ignore", invalid="ignore"):
        length2 = (q * q).sum(axis=1)
    return ~(length2 >= _F32_TINY) | ~np.isfinite(length2)


def not_drawn_kinds_at(cols: dict, t: float) -> np.ndarray:
    """Why the viewer does not draw each splat at time ``t``: ``(N,) int8``.

    The index in :data:`UNDRAWABLE_KINDS` of the first kind that applies at ``t``,
    or :data:`DRAWABLE` (-1):

    ``zero_rotation``: the rotation at ``t``, rot + omega dt, has no direction
    (:func:`rotation_has_no_direction`: zero, NaN or infinite).
    ``nan_position``: the position at ``t`` (:func:`position_at`) is NaN.
    ``alpha_zero``: the alpha byte is 0 (:func:`alpha_zero`), or the splat passes
    the temporal cut at ``t`` but sigmoid(opacity) * temporal opacity * 255 rounds
    to 0, or the temporal opacity is NaN (a NaN trbf centre or scale): blended
    into 8-bit pixels, an alpha below half a step changes none of them.
    ``hidden_in_time``: the temporal opacity at ``t`` is below the 0.02 cut.

    Every undrawable splat (:func:`undrawable_kinds`) is not drawn at any ``t`` in
    [0, 1]. The maths is float64; at the one instant where a spinning rotation
    passes through zero, the shader's float32 sum may not be exactly zero.
    """
    return state_at(cols, t)[0]


def state_at(cols: dict, t: float) -> tuple:
    """:func:`not_drawn_kinds_at` and what it computes on the way, for a caller that needs them too.

    Returns
    -------
    code : (N,) int8
        As :func:`not_drawn_kinds_at`.
    position : (N, 3) float64
        :func:`position_at` ``t``.
    rotation : (N, 4) float64
        rot + omega dt, not normalised (:func:`rotation_at` with ``normalize=False``).
    temporal : (N,) float64
        :func:`temporal_opacity` at ``t``, not cut.
    """
    n = len(cols["x"])
    code = np.full(n, DRAWABLE, dtype=np.int8)
    temporal = temporal_opacity(cols, t, cut=False)
    rotation = rotation_at(cols, t, normalize=False)
    position = position_at(cols, t)
    hidden = temporal < TEMPORAL_CUTOFF
    faint = ~hidden & ~(np.rint(opacity(cols) * temporal * 255.0) > 0)  # NaN included
    tests = (lambda: rotation_has_no_direction(rotation), lambda: np.isnan(position).any(axis=1),
             lambda: alpha_zero(cols) | faint, lambda: hidden)
    for kind, test in enumerate(tests):
        code[(code == DRAWABLE) & test()] = kind
    return code, position, rotation, temporal


def drawn_at(cols: dict, t: float) -> np.ndarray:
    """Rows the viewer draws at time ``t``: ``(N,) bool`` (see :func:`not_drawn_kinds_at`)."""
    return not_drawn_kinds_at(cols, t) == DRAWABLE


def not_drawn_counts_at(cols: dict, t: float) -> dict:
    """Splats not drawn at ``t`` by kind: ``{kind: int}`` in :data:`UNDRAWABLE_KINDS` order."""
    return kind_counts(not_drawn_kinds_at(cols, t))


# --------------------------------------------------------------------------
# Importance order: the record order of splatv (and of --max-splats).


def importance_order(key: np.ndarray) -> np.ndarray:
    """Row order by descending ``key``, equal keys in input order, NaN last.

    The same permutation as ``np.argsort(-key, kind="stable")`` (NaN keys all
    compare equal, as do +0 and -0), from one SIMD value sort instead of a merge
    sort: each key is mapped to an unsigned integer that sorts the same way, and
    the row number goes in the low bits, so the packed values are distinct and
    any sort of them is stable. A float32 key fits whole beside the row number.
    A float64 key gives its lowest bits to the row number; runs of rows whose
    kept bits tie but whose full keys differ are then re-sorted by the full key,
    so the result is exact either way.

    Parameters
    ----------
    key : (N,) float32 or float64 ndarray

    Returns
    -------
    (N,) intp ndarray
    """
    key = np.asarray(key)
    if key.dtype not in (np.float32, np.float64):
        key = key.astype(np.float64)
    return importance_order_into(key, np.empty(len(key), dtype=np.uint64), lambda rows: key[rows])


#: Elements per step of whole-array passes that would otherwise need N-sized
#: temporaries; small enough that the temporaries come from the heap, not mmap.
_CHUNK = 1 << 13
#: Exponent and sign bits of a float64: the row number may take the rest.
_FLOAT64_KEPT_BITS = 1 + 11 + 1


def importance_order_into(key: np.ndarray, packed: np.ndarray, key_of) -> np.ndarray:
    """:func:`importance_order` computed in ``packed``, ``(N,) uint64``, which may be ``key``'s own memory.

    ``key_of(rows)`` gives the full keys of some rows again, for kept-bit ties
    (``key`` may be overwritten by then). The order returned is a view of ``packed``.
    """
    n = len(key)
    wide = key.dtype == np.float64
    row_bits = max(1, (n - 1).bit_length())
    limit = 64 - _FLOAT64_KEPT_BITS if wide else 32
    if row_bits > limit or np.dtype(np.intp).itemsize != 8:  # pragma: no cover
        with np.errstate(invalid="ignore"):
            return np.argsort(-key, kind="stable")
    low = np.uint64((1 << row_bits) - 1)
    # A chunk at a time, without N-sized temporaries: on some machines touching
    # fresh memory costs about as much as the sort.
    for start in range(0, n, _CHUNK):
        part = _descending_bits(key[start:start + _CHUNK]).astype(np.uint64)
        if wide:
            part &= ~low
        else:
            part <<= np.uint64(row_bits)
        part |= np.arange(start, start + len(part), dtype=np.uint64)
        packed[start:start + _CHUNK] = part
    packed.sort()
    ties = _kept_bit_ties(packed, low) if wide else ()
    packed &= low
    order = packed.view(np.intp)
    if len(ties):
        _resort_ties(order, ties, key_of)
    return order


def _descending_bits(key: np.ndarray) -> np.ndarray:
    """Unsigned integers that ascend as ``key`` descends: -0 as +0, NaN the largest (last)."""
    itype, utype = (np.int64, np.uint64) if key.dtype == np.float64 else (np.int32, np.uint32)
    with np.errstate(invalid="ignore"):
        bits = (key + key.dtype.type(0.0)).view(itype)  # -0 + 0 is +0
    # Non-negative keys: flip all but the sign bit (larger key, smaller pattern);
    # negative keys keep their bits (sign set: after all others, larger magnitude later).
    flip = np.right_shift(bits, itype(8 * key.dtype.itemsize - 1))  # all ones for negatives
    np.invert(flip, out=flip)
    flip &= itype(np.iinfo(itype).max)
    bits ^= flip
    out = bits.view(utype)
    nan = np.isnan(key)
    if nan.any():
        out[nan] = np.iinfo(utype).max
    return out


def _kept_bit_ties(packed: np.ndarray, low: np.uint64) -> np.ndarray:
    """Positions i of sorted ``packed`` whose bits above ``low`` equal those at i + 1."""
    ties = []
    for start in range(0, len(packed) - 1, _CHUNK):
        a = packed[start:start + _CHUNK + 1]
        ties.append(np.flatnonzero((a[1:] ^ a[:-1]) <= low) + start)
    return np.concatenate(ties) if ties else np.zeros(0, np.intp)


def _resort_ties(order: np.ndarray, ties: np.ndarray, key_of) -> None:
    """Order runs of kept-bit ties by the full key, then row, where full keys differ."""
    # Compared a chunk at a time: a scene of equal keys ties everywhere, and its full keys, twice over
    # and in float64 temporaries, would cost more than the scene.
    wrong = np.concatenate([
        _descending_bits(key_of(order[part])) != _descending_bits(key_of(order[part + 1]))
        for part in (ties[start:start + _CHUNK] for start in range(0, len(ties), _CHUNK))])
    if not wrong.any():
        return  # whole-key ties only: already in row order
    # Runs of consecutive tie positions; each spans positions first .. last + 1.
    new_run = np.concatenate([[True], ties[1:] != ties[:-1] + 1])
    run = np.cumsum(new_run) - 1
    firsts = ties[new_run]
    lasts = np.append(ties[np.flatnonzero(new_run)[1:] - 1], ties[-1]) + 1
    bad = np.unique(run[wrong])
    lengths = lasts[bad] - firsts[bad] + 1
    at = np.repeat(firsts[bad] - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
    # Runs are contiguous and already in kept-bit order, so sorting their union by
    # (full key, row) puts every member back inside its own run.
    rows = order[at]
    order[at] = rows[np.lexsort((rows, _descending_bits(key_of(rows))))]


def sort_ends(cols: dict, cameras: list, kinds: np.ndarray | None = None) -> np.ndarray:
    """The splats the viewer's depth sort turns on, seen from ``cameras`` or its opening view: ``(N,) bool``.

    The viewer sorts every record, drawable or not, by a key scaled by the
    keys' range; it never draws the farthest when the scaled key reaches the top,
    and draws its first record in its place. So the frames drop and repeat what
    a ``.splatv``'s do only if a file keeps, exactly: the splats at the ends of
    the depth range (:func:`depth_extremes` along :func:`depth_directions`; of
    undrawable ones, one at each position: only their keys count) and the first
    record in importance order. A writer that leaves out undrawable splats keeps
    these; :func:`splatconv.compare.pair` finds them the same way.

    ``kinds`` : :func:`undrawable_kinds` of ``cols`` when the caller has them.
    """
    n = len(cols["x"])
    out = np.zeros(n, bool)
    if not n:
        return out
    drawable = (undrawable_kinds(cols) if kinds is None else kinds) == DRAWABLE
    out[:] = depth_extremes(cols["x"], cols["y"], cols["z"], depth_directions(cameras))
    rows = np.flatnonzero(out & ~drawable)
    xyz = np.stack([np.asarray(cols[a], np.float32)[rows] for a in "xyz"], axis=1)
    place = xyz.view(np.uint32).copy()
    place[~np.isfinite(xyz).all(axis=1)] = 0x7FC00000  # a non-finite position's key is 0: one place
    out[rows] = False
    out[rows[np.unique(place, axis=0, return_index=True)[1]]] = True
    out[importance_order(importance(cols))[0]] = True
    return out
