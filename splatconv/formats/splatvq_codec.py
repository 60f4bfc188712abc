"""The ``.splatvq`` codec core: ``.splatv`` texture records <-> compact blocks (see ``specs/splatvq.md``).

The encoder quantizes the 64-byte records a ``.splatv`` writer packs; the
decoder gives back records, exactly the texture words the viewer's shader reads.
Every decoded value is made from integer codes by a few IEEE double operations
(products with powers of two, one sum, one square root, one division), then
rounded to float32 and, for half slots, to a half by round-to-nearest-even: a
JavaScript worker gets the same bits with ``Math.fround`` and the same half
conversion. Scales and temporal scales are coded in the half-bit domain (a
positive half's bits grow with its logarithm), so they decode with integers only.

Every quantizer is a projection onto a lattice (powers of two, or a fixed step
of half bits) that depends on the splat alone, never on its chunk or block, so
quantizing decoded values again gives them back where the lattice is coarser
than the half a value is stored in (true of both settings; tests check it): a
second conversion changes nothing.

Layouts as data: :data:`CHUNK_FIELDS` and :data:`SPLAT_FIELDS` are the block
payload in order; the spec's tables are checked against them.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from .. import packing
from ..errors import FormatError
from ..viewer import VISIBLE_RADIUS
from .splatv_layout import COLOR_WORD, WORDS_PER_SPLAT

#: Splats a chunk (one set of position and scale ranges), as a power of two.
CHUNK_LOG2 = 8
CHUNK = 1 << CHUNK_LOG2
#: Splats a block at most (one independently decodable unit, importance order between blocks).
BLOCK = 1 << 16
#: Bias of the stored window exponent byte: e = byte - WINDOW_BIAS.
WINDOW_BIAS = 128
#: Window exponents kept: W = 2**e, clipped to this range.
WINDOW_MIN, WINDOW_MAX = -30, 30
#: Reserved scale codes: 0 -> half +0 (a linear scale of 0), 1 -> half +inf.
SCALE_ZERO, SCALE_INF, SCALE_FIRST = 0, 1, 2
#: A position farther than this many robust scene extents (the widest interquartile range of an axis)
#: from the median is stored raw: it would widen its chunk's range for its neighbours.
OUTLIER_EXTENTS = 4096.0
#: Coder byte of the header: raw deflate (RFC 1951; the browser's DecompressionStream('deflate-raw')).
CODER_DEFLATE_RAW = 1
#: Deflate expands at most 1032:1; a block declaring more than this per stored byte is refused.
MAX_RATIO = 1032


@dataclass(frozen=True)
class Setting:
    """The quantizer of one quality setting (stored in the file header, so decoding needs no table).

    Attributes
    ----------
    position_shift : int
        A splat's position step is 2**k, k = floor(log2(its middle linear
        scale)) + position_shift (+ its alpha coarsening; see :func:`size_exponent`):
        a displacement shows in proportion to the splat it moves.
    rotation_bits : int
        Bits of each of the three smallest unit-quaternion components.
    scale_step : int
        Lattice step of scale halves, in half-bit units (1 keeps every half;
        each unit is a factor of about 2**(1/1024) in size).
    trbf_scale_step : int
        The same for the temporal scale.
    time_shift : int
        Temporal centres on the lattice 2**-time_shift.
    omega_shift : int
        omega / |q| * W on the lattice 2**-omega_shift.
    motion_shift : int
        Scaled velocity m_1 * W on the lattice 2**(k + motion_shift), k the
        splat's position step exponent.
    acceleration_shift, jerk_shift : int
        Added to ``motion_shift`` for the degree-2 and degree-3 terms: the
        viewer weighs a splat's time offsets by its temporal opacity, so the
        higher powers of the offset, large only where the splat is faint, take
        a coarser step for the same error in what is drawn.
    alpha_levels : int
        A splat of alpha byte ``a`` takes every geometric step (position,
        motion, omega) ``c = min(alpha_levels, 7 - floor(log2(a)))`` times
        coarser by powers of two (``c >= 0``): what it draws is in proportion
        to its alpha, so the same displacement of a faint splat changes a frame less.
    """

    position_shift: int
    rotation_bits: int
    scale_step: int
    trbf_scale_step: int
    time_shift: int
    omega_shift: int
    motion_shift: int
    acceleration_shift: int
    jerk_shift: int
    alpha_levels: int


#: Quality settings by name, best first. The bench (``bench/bench_splatvq.py``) measures them.
SETTINGS = {
    "default": Setting(position_shift=-6, rotation_bits=8, scale_step=32, trbf_scale_step=32, time_shift=11,
                       omega_shift=6, motion_shift=2, acceleration_shift=1, jerk_shift=1, alpha_levels=2),
    "small": Setting(position_shift=-5, rotation_bits=6, scale_step=64, trbf_scale_step=64, time_shift=10,
                     omega_shift=4, motion_shift=3, acceleration_shift=0, jerk_shift=1, alpha_levels=3),
}
DEFAULT_SETTING = "default"
#: Limits a header's setting is checked against.
SETTING_LIMITS = {"position_shift": (-30, 30), "rotation_bits": (2, 16), "scale_step": (1, 255),
                  "trbf_scale_step": (1, 255), "time_shift": (0, 30), "omega_shift": (0, 30),
                  "motion_shift": (-30, 30), "acceleration_shift": (0, 8), "jerk_shift": (0, 8),
                  "alpha_levels": (0, 7)}

#: The chunk tables of a block payload, in order: name, dtype, values per chunk.
CHUNK_FIELDS = (
    ("position_base", "<f8", 3),    # a lattice point of every step in the chunk, at or below its least position
    ("scale_base", "<u2", 3),       # lowest scale lattice index of each axis
    ("trbf_scale_base", "<u2", 1),  # lowest temporal scale lattice index
)
#: The per-splat fields of a block payload, in order: name, dtype, values per splat.
#: Each value column is stored as byte planes, lowest byte first.
SPLAT_FIELDS = (
    ("position", "<u4", 3),         # (p - base) / 2**k
    ("rotation_index", "u1", 1),    # which component of q is largest (dropped)
    ("rotation", "<u2", 3),         # the other three, in order
    ("omega", "<u2", 4),            # zigzag
    ("scale", "<u2", 3),            # reserved codes, then lattice index - base + 2
    ("color", "u1", 4),             # the RGBA8 word's bytes as they are
    ("trbf_center", "<u4", 1),      # zigzag
    ("trbf_scale", "<u2", 1),       # as scale
    ("window", "u1", 1),            # e + WINDOW_BIAS
    ("motion", "<u4", 9),           # zigzag
)
CHUNK_BYTES = sum(np.dtype(t).itemsize * k for _, t, k in CHUNK_FIELDS)
SPLAT_BYTES = sum(np.dtype(t).itemsize * k for _, t, k in SPLAT_FIELDS)
RAW_BYTES = 4 * WORDS_PER_SPLAT
#: Largest position code: 32 bits.
POSITION_CODE_MAX = (1 << 32) - 1
#: Degree of each motion coefficient (motion_0..8: three velocity, three acceleration, three jerk terms).
MOTION_DEGREE = np.repeat(np.arange(1, 4), 3)

_SQRT1_2 = np.sqrt(0.5)
#: The other three components of a quaternion, by the index of the one dropped.
_OTHERS = np.array([[j for j in range(4) if j != i] for i in range(4)])


def payload_bytes(coded: int, raw: int) -> int:
    """Bytes of a block payload holding ``coded`` quantized and ``raw`` verbatim records."""
    return -(-coded // CHUNK) * CHUNK_BYTES + coded * SPLAT_BYTES + raw * RAW_BYTES


# --------------------------------------------------------------------------
# Small pieces


def _zigzag(v: np.ndarray, dtype) -> np.ndarray:
    v = v.astype(np.int64)
    return ((v << 1) ^ (v >> 63)).astype(dtype)


def _unzigzag(u: np.ndarray) -> np.ndarray:
    u = u.astype(np.int64)
    return (u >> 1) ^ -(u & 1)


def _half(values: np.ndarray) -> np.ndarray:
    """float64 -> float32 (nearest) -> half (nearest even, saturating): the decoder's one rounding rule."""
    with np.errstate(over="ignore", invalid="ignore"):
        return packing.float_to_half(values.astype(np.float32))


def _halves_of(records: np.ndarray, names_at) -> np.ndarray:
    """Half bits of record slots: ``(N, k) uint16`` from (word, 0 low / 1 high) pairs."""
    h = records.view(np.uint16)
    return np.stack([h[:, 2 * w + i] for w, i in names_at], axis=1)


#: (word, half) of each attribute group in a record (see specs/splatv.md).
ROT_AT = ((3, 0), (3, 1), (4, 0), (4, 1))
SCALE_AT = ((5, 0), (5, 1), (6, 0))
MOTION_AT = ((8, 0), (8, 1), (9, 0), (9, 1), (10, 0), (10, 1), (11, 0), (11, 1), (12, 0))
OMEGA_AT = ((13, 0), (13, 1), (14, 0), (14, 1))
TRBF_CENTER_AT, TRBF_SCALE_AT = (15, 0), (15, 1)


def _morton(positions: np.ndarray) -> np.ndarray:
    """A Morton key of float32 positions, ``(N, 3) float32`` -> ``(N,) uint64``, from each float's top 21 bits.

    The bits of a float in an order-preserving form are a log-spaced grid that
    needs no scene bounds: fine near the scene's middle, coarse far out, and the
    same whichever splats a scene holds.
    """
    bits = np.ascontiguousarray(positions, dtype=np.float32).view(np.uint32)
    flip = np.where(bits >> 31 != 0, np.uint32(0xFFFFFFFF), np.uint32(0x80000000))
    keys = ((bits ^ flip) >> np.uint32(11)).astype(np.uint64)
    out = np.zeros(len(positions), dtype=np.uint64)
    for axis in range(3):
        v = keys[:, axis]
        v = (v | (v << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
        v = (v | (v << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
        v = (v | (v << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
        v = (v | (v << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
        v = (v | (v << np.uint64(2))) & np.uint64(0x1249249249249249)
        out |= v << np.uint64(axis)
    return out


def alpha_coarsening(alpha: np.ndarray, levels: int) -> np.ndarray:
    """Extra step exponent of each splat from its alpha byte, ``(N,) uint8`` -> ``(N,) int64`` in [0, levels].

    ``min(levels, 7 - floor(log2(a)))``: 0 for alpha 128 and more, one more for
    each halving below (an alpha of 0 counts as 1). Integers only.
    """
    a = np.maximum(alpha.astype(np.int64), 1)
    floor_log2 = np.frexp(a.astype(np.float64))[1] - 1
    return np.clip(7 - floor_log2, 0, levels)


def motion_exponents(setting: Setting) -> np.ndarray:
    """Lattice exponent offset of each motion term (motion_0..8) over k: ``(9,) int64``."""
    extra = np.array([0, setting.acceleration_shift, setting.jerk_shift], dtype=np.int64)
    return setting.motion_shift + np.repeat(extra, 3)


def _predicted_x(previous: np.ndarray, k_previous: np.ndarray, k: np.ndarray) -> np.ndarray:
    """floor(previous * 2**(k_previous - k)) in float64 (exact: a power-of-two scaling and a floor)."""
    return np.floor(np.ldexp(previous.astype(np.float64), k_previous - k))


def x_steps(code: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Position x codes in chunks sorted by decoded x -> their steps: ``(N,) int64`` each, steps >= 0.

    The first splat of a chunk keeps its code; each other stores its code less
    floor(previous code * 2**(previous k - its k)): the previous splat's x on
    its own, possibly coarser or finer, lattice.
    """
    steps = code.copy()
    rest = np.arange(len(code)) % CHUNK != 0
    i = np.flatnonzero(rest)
    steps[i] = code[i] - _predicted_x(code[i - 1], k[i - 1], k[i]).astype(np.int64)
    return steps


def x_codes(steps: np.ndarray, k: np.ndarray, path: str, where: tuple) -> np.ndarray:
    """The inverse of :func:`x_steps`, one chunk column at a time: ``(N,) int64``.

    Raises
    ------
    FormatError
        Where a code would pass :data:`POSITION_CODE_MAX` (a damaged block).
    """
    n = len(steps)
    chunks = -(-n // CHUNK)
    pad = chunks * CHUNK - n
    d = np.concatenate([steps, np.zeros(pad, np.int64)]).reshape(chunks, CHUNK)
    # Padding takes a huge k, so that it predicts 0 from anything before it.
    kk = np.concatenate([k, np.full(pad, 1 << 20, np.int64)]).reshape(chunks, CHUNK)
    c = np.empty_like(d)
    c[:, 0] = d[:, 0]
    for j in range(1, CHUNK):
        pred = _predicted_x(c[:, j - 1], kk[:, j - 1], kk[:, j])
        if (pred > POSITION_CODE_MAX).any():
            raise FormatError("a position code is past 2**32 - 1", path, where)
        c[:, j] = d[:, j] + pred.astype(np.int64)
    c = c.reshape(-1)[:n]
    if (c > POSITION_CODE_MAX).any():
        raise FormatError("a position code is past 2**32 - 1", path, where)
    return c


def _ceil_log2(x: np.ndarray) -> np.ndarray:
    """ceil(log2(x)) of positive finite float64 values, exactly: int64."""
    m, e = np.frexp(x)
    return (e - (m == 0.5)).astype(np.int64)


# --------------------------------------------------------------------------
# Encoding


def escapes(records: np.ndarray) -> np.ndarray:
    """Records stored verbatim: ``(N,) bool`` for ``(N, 16) uint32`` records.

    Non-finite positions and far outliers (more than :data:`OUTLIER_EXTENTS`
    interquartile extents from the median), NaN or infinite halves where the codes have
    no place for them, negative scales, and a zero rotation (its omega gives the
    direction on its own).
    """
    pos = records[:, :3].view(np.float32).astype(np.float64)
    bad = ~np.isfinite(pos).all(axis=1)
    finite = pos[~bad]
    if len(finite):
        lo, mid, hi = np.percentile(finite, (25, 50, 75), axis=0)
        extent = max(float(np.max(hi - lo)), 1e-6)
        with np.errstate(invalid="ignore"):
            bad |= (np.abs(pos - mid) > OUTLIER_EXTENTS * extent).any(axis=1)
    h = records.view(np.uint16)
    for at in ROT_AT + MOTION_AT + OMEGA_AT + (TRBF_CENTER_AT,):
        bad |= (h[:, 2 * at[0] + at[1]] & 0x7FFF) >= packing.HALF_INF_BITS
    for at in SCALE_AT + (TRBF_SCALE_AT,):
        v = h[:, 2 * at[0] + at[1]]
        bad |= (v > packing.HALF_INF_BITS)  # NaN and every negative half
    rot = _halves_of(records, ROT_AT)
    bad |= ((rot & 0x7FFF) == 0).all(axis=1)
    return bad


def _rotation_value(code: np.ndarray, rmax: int) -> np.ndarray:
    """A smallest-three code -> its component value (float64), as the decoder computes it."""
    return (2.0 * code - rmax) / rmax * _SQRT1_2


def _scale_decoded(h: np.ndarray, step: int) -> np.ndarray:
    """Scale half bits as they decode (lattice points; 0 and +inf kept)."""
    special = (h == 0) | (h >= packing.HALF_INF_BITS)
    return np.where(special, h, scale_lattice(h, step) * step).astype(np.uint16)


def size_exponent(scale_halves: np.ndarray) -> np.ndarray:
    """floor(log2) of each splat's middle linear scale, from decoded scale half bits ``(N, 3) uint16``: ``(N,) int64``.

    The middle of the three, not the least: a flat splat (one scale near or at
    0, common in trained scenes) is drawn as a disc, and a step in proportion to
    its thickness would spend bits on a precision no frame shows but edge-on.
    Integers only (a half's exponent field): a decoder derives it from the
    scales it decoded. Subnormal and zero scales count as -15, infinite ones as 16.
    """
    middle = np.sort(scale_halves, axis=1)[:, 1].astype(np.int64)
    return np.clip((middle >> 10) - 15, -15, 16)


def _decoded_quaternion(code: np.ndarray, index: np.ndarray, rmax: int) -> np.ndarray:
    """Smallest-three codes and the dropped index -> the quaternion's half bits, ``(N, 4) uint16``, as decoded."""
    small3 = _rotation_value(code.astype(np.float64), rmax)
    quat = np.empty((len(code), 4))
    quat[np.arange(len(code)), index] = np.sqrt(np.maximum(
        0.0, 1.0 - ((small3[:, 0] * small3[:, 0] + small3[:, 1] * small3[:, 1]) + small3[:, 2] * small3[:, 2])))
    np.put_along_axis(quat, _OTHERS[index], small3, axis=1)
    return _half(quat)


def _keep_largest(code: np.ndarray, index: np.ndarray, rmax: int) -> np.ndarray:
    """Codes nudged toward zero where a kept component would decode larger than the dropped one.

    A second conversion drops the largest decoded component (the first of equals):
    it must be the one dropped the first time, or the codes would differ.
    """
    code = code.copy()
    for _ in range(8):
        mag = _decoded_quaternion(code, index, rmax) & 0x7FFF  # a half's magnitude orders as its bits do
        bad = np.flatnonzero(np.argmax(mag, axis=1) != index)
        if not len(bad):
            break
        small = np.take_along_axis(mag[bad], _OTHERS[index[bad]], axis=1)
        j = np.argmax(small, axis=1)
        c = code[bad, j]
        code[bad, j] = np.where(2 * c > rmax, c - 1, c + 1)
    return code


def scale_lattice(halves: np.ndarray, step: int) -> np.ndarray:
    """Lattice index of non-negative half bits in [1, 0x7BFF] (int64): the nearest multiple of ``step``, capped."""
    q = (halves.astype(np.int64) + step // 2) // step
    return np.minimum(q, packing.HALF_MAX_BITS // step)


def quantized_key(records: np.ndarray, setting: Setting) -> np.ndarray:
    """The importance key of the quantized records: product of the decoded linear scales and the alpha byte.

    The order between blocks then depends on quantized values only, so that the
    blocks of a decoded file come back the same when it is encoded again.
    """
    alpha = (records[:, COLOR_WORD] >> np.uint32(24)).astype(np.float64)
    # A signalling NaN half (a .splatv read keeps payloads) warns when widened: its splat is kept verbatim anyway.
    with np.errstate(invalid="ignore", over="ignore"):
        lin = packing.HALF_TO_FLOAT[_scale_decoded(_halves_of(records, SCALE_AT), setting.scale_step)]
        lin = lin.astype(np.float64)
        return lin[:, 0] * lin[:, 1] * lin[:, 2] * alpha


def _planes(values: np.ndarray, dtype) -> list:
    """``(n, k)`` values as byte planes, component by component, lowest byte first: a list of ``n``-byte planes."""
    a = np.ascontiguousarray(np.asarray(values).astype(dtype).T)  # (k, n)
    width = a.dtype.itemsize
    planes = np.ascontiguousarray(a.view(np.uint8).reshape(a.shape[0], -1, width).transpose(0, 2, 1))
    return [p.tobytes() for p in planes.reshape(a.shape[0] * width, a.shape[1])]


def encode_block(records: np.ndarray, setting: Setting, level: int = 9, forced: np.ndarray | None = None
                 ) -> tuple[bytes, int, int]:
    """Quantize and compress one block of records (importance order).

    Parameters
    ----------
    records : (M, 16) uint32 ndarray
        M <= :data:`BLOCK`.

    Returns
    -------
    stored : bytes
        The block as stored (raw deflate of the payload).
    coded, raw : int
        Records quantized, records kept verbatim (decoded after the coded ones).
    """
    esc = escapes(records)
    if forced is not None:
        esc |= forced
    raw_records = records[esc]
    kept = np.flatnonzero(~esc)
    # Chunks in Morton order (stable: within a cell, importance order).
    kept = kept[np.argsort(_morton(records[kept, :3].view(np.float32)), kind="stable")]
    rec = records[kept]
    n = len(rec)
    h = rec.view(np.uint16)
    # Temporal centre and scale, quantized first: the window W is that of the decoded values.
    centre = h[:, 30].copy()
    centre_f = packing.HALF_TO_FLOAT[centre].astype(np.float64)
    centre_code = np.rint(np.ldexp(centre_f, setting.time_shift)).astype(np.int64)
    centre_dec = packing.HALF_TO_FLOAT[_half(np.ldexp(centre_code.astype(np.float64), -setting.time_shift))]
    tsh = h[:, 31]
    t_special = (tsh == 0) | (tsh == packing.HALF_INF_BITS)
    t_lat = scale_lattice(tsh, setting.trbf_scale_step)
    tsh_dec = np.where(t_special, tsh, t_lat * setting.trbf_scale_step).astype(np.uint16)
    reach = packing.HALF_TO_FLOAT[tsh_dec].astype(np.float64) * VISIBLE_RADIUS
    c = centre_dec.astype(np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        t0 = np.clip(c - reach, 0.0, 1.0)
        t1 = np.clip(c + reach, 0.0, 1.0)
        window = np.maximum(np.abs(t0 - c), np.abs(t1 - c))
    e = np.full(n, WINDOW_MIN, dtype=np.int64)
    pos_w = window > 0
    e[pos_w] = np.clip(_ceil_log2(window[pos_w]), WINDOW_MIN, WINDOW_MAX)

    # Rotation: unit quaternion, largest component positive and dropped; omega / |q| * sign * W.
    q = packing.HALF_TO_FLOAT[_halves_of(rec, ROT_AT)].astype(np.float64)
    norm = np.sqrt((q * q).sum(axis=1))
    big = np.argmax(np.abs(q), axis=1)
    sign = np.where(q[np.arange(n), big] < 0, -1.0, 1.0)
    unit = q * (sign / norm)[:, None]
    rmax = (1 << setting.rotation_bits) - 1
    others = _OTHERS[big]
    small3 = np.take_along_axis(unit, others, axis=1)
    rot_code = np.clip(np.rint((small3 / _SQRT1_2 + 1.0) * 0.5 * rmax), 0, rmax)
    rot_code = _keep_largest(rot_code, big, rmax)
    omega = packing.HALF_TO_FLOAT[_halves_of(rec, OMEGA_AT)].astype(np.float64)
    coarse = alpha_coarsening(rec[:, COLOR_WORD] >> np.uint32(24), setting.alpha_levels)
    omega_shift = (e + setting.omega_shift - coarse)[:, None]
    omega_code = np.rint(np.ldexp(omega * (sign / norm)[:, None], omega_shift))

    # Positions: each splat on the lattice 2**k, k = its size exponent + position_shift
    # (see size_exponent), coded from its chunk's base, a multiple of every step in the chunk.
    scale_h = _halves_of(rec, SCALE_AT)
    k = size_exponent(_scale_decoded(scale_h, setting.scale_step)) + setting.position_shift + coarse
    starts = np.arange(0, n, CHUNK)
    chunk_of = np.arange(n) // CHUNK
    pos = rec[:, :3].view(np.float32).astype(np.float64)
    if n:
        lo = np.minimum.reduceat(pos, starts, axis=0)
        k_top = np.maximum.reduceat(k, starts)
    else:
        lo, k_top = np.zeros((0, 3)), np.zeros(0, np.int64)
    base = np.ldexp(np.floor(np.ldexp(lo, -k_top[:, None])), k_top[:, None])
    pos_code = np.rint(np.ldexp(pos - base[chunk_of], -k[:, None]))

    motion = packing.HALF_TO_FLOAT[_halves_of(rec, MOTION_AT)].astype(np.float64)
    motion_shift = e[:, None] * MOTION_DEGREE[None, :] - k[:, None] - motion_exponents(setting)[None, :]
    motion_code = np.rint(np.ldexp(motion, motion_shift))

    # Records whose codes do not fit go raw after all: the block is made again with them forced raw.
    too_big = ((pos_code > POSITION_CODE_MAX).any(axis=1) | (np.abs(omega_code) >= 1 << 15).any(axis=1)
               | (np.abs(motion_code) >= 2.0 ** 31).any(axis=1) | (np.abs(centre_code) >= 1 << 31))
    if too_big.any():
        esc[kept[too_big]] = True
        return encode_block(records, setting, level, esc)

    s_special = (scale_h == 0) | (scale_h == packing.HALF_INF_BITS)
    s_lat = scale_lattice(scale_h, setting.scale_step)
    big_lat = np.iinfo(np.int64).max
    s_base = (np.minimum.reduceat(np.where(s_special, big_lat, s_lat), starts, axis=0) if n
              else np.zeros((0, 3), np.int64))
    s_base = np.where(s_base == big_lat, 0, s_base)
    s_code = np.where(scale_h == 0, SCALE_ZERO,
                      np.where(scale_h == packing.HALF_INF_BITS, SCALE_INF, s_lat - s_base[chunk_of] + SCALE_FIRST))
    t_base = (np.minimum.reduceat(np.where(t_special, big_lat, t_lat), starts) if n else np.zeros(0, np.int64))
    t_base = np.where(t_base == big_lat, 0, t_base)
    t_code = np.where(tsh == 0, SCALE_ZERO,
                      np.where(tsh == packing.HALF_INF_BITS, SCALE_INF, t_lat - t_base[chunk_of] + SCALE_FIRST))

    colour = rec[:, COLOR_WORD:COLOR_WORD + 1].copy().view(np.uint8)
    # Inside each chunk, splats in order of their decoded x (ties in Morton order), x
    # stored as the step from the one before: the order itself carries information
    # (some log2(256!) / 256 = 6.6 bits a splat) that independent codes spend again.
    pos_code = pos_code.astype(np.int64)
    order = np.lexsort((np.arange(n), np.ldexp(pos_code[:, 0].astype(np.float64), k), chunk_of))
    big, rot_code, omega_code, s_code = big[order], rot_code[order], omega_code[order], s_code[order]
    colour, centre_code, t_code, e = colour[order], centre_code[order], t_code[order], e[order]
    motion_code, pos_code, k = motion_code[order], pos_code[order], k[order]
    pos_code[:, 0] = x_steps(pos_code[:, 0], k)
    parts = [
        np.ascontiguousarray(base, dtype="<f8").tobytes()
        + np.ascontiguousarray(s_base, dtype="<u2").tobytes()
        + np.ascontiguousarray(t_base, dtype="<u2").tobytes(),
        *_planes(pos_code, "<u4"),
        *_planes(big[:, None], "u1"),
        *_planes(rot_code, "<u2"),
        *_planes(_zigzag(omega_code, np.uint16), "<u2"),
        *_planes(s_code, "<u2"),
        *_planes(colour, "u1"),
        *_planes(_zigzag(centre_code, np.uint32)[:, None], "<u4"),
        *_planes(t_code[:, None], "<u2"),
        *_planes((e + WINDOW_BIAS)[:, None], "u1"),
        *_planes(_zigzag(motion_code, np.uint32), "<u4"),
        np.ascontiguousarray(raw_records, dtype="<u4").tobytes(),
    ]
    # Run-length matching only: byte planes hold few long matches; it is some thirty
    # times faster than level 9's search for 1.3% more bytes (bench/README.md).
    # Each plane ends a deflate block (Z_BLOCK: no padding, no marker), so each gets
    # Huffman codes of its own: a plane's byte statistics differ from its neighbours'.
    comp = zlib.compressobj(level, zlib.DEFLATED, -15, 9, zlib.Z_RLE)
    out = []
    for part in parts:
        out.append(comp.compress(part))
        out.append(comp.flush(zlib.Z_BLOCK))
    out.append(comp.flush())
    return b"".join(out), n, len(raw_records)


# --------------------------------------------------------------------------
# Decoding


def inflate(stored: bytes, expected: int, path: str, where: tuple) -> bytes:
    """Raw-inflate a block, refusing one that gives more or fewer than ``expected`` bytes."""
    d = zlib.decompressobj(-15)
    try:
        out = d.decompress(stored, expected)
        more = d.unconsumed_tail or (not d.eof and d.decompress(b"", 1))
    except zlib.error as e:
        raise FormatError(f"compressed data is corrupt ({e})", path, where) from None
    if more:
        raise FormatError(f"decodes to more than the {expected} bytes declared", path, where)
    if len(out) != expected or not d.eof:
        raise FormatError(f"decodes to {len(out)} bytes, not the {expected} declared", path, where)
    if d.unused_data:
        raise FormatError(f"{len(d.unused_data)} bytes after the end of its compressed data", path, where)
    return out


def _take(buf: memoryview, at: int, dtype, count: int):
    size = np.dtype(dtype).itemsize * count
    return np.frombuffer(buf, dtype=dtype, count=count, offset=at), at + size


def _unplane(buf, at: int, dtype, n: int, k: int):
    dt = np.dtype(dtype)
    raw, at = _take(buf, at, np.uint8, n * k * dt.itemsize)
    # (k, width, n) planes -> (n, k) values
    vals = np.ascontiguousarray(raw.reshape(k, dt.itemsize, n).transpose(2, 0, 1)).view(dt).reshape(n, k)
    return vals, at


def decode_block(payload: bytes, coded: int, raw: int, setting: Setting, path: str, where: tuple) -> np.ndarray:
    """A block payload (inflated) -> its records, ``(coded + raw, 16) uint32``: the texture words."""
    buf = memoryview(payload)
    chunks = -(-coded // CHUNK)
    table = {}
    at = 0
    for name, dtype, k in CHUNK_FIELDS:
        v, at = _take(buf, at, dtype, chunks * k)
        table[name] = v.reshape(chunks, k)
    fields = {}
    for name, dtype, k in SPLAT_FIELDS:
        fields[name], at = _unplane(buf, at, dtype, coded, k)
    raw_words, at = _take(buf, at, "<u4", raw * WORDS_PER_SPLAT)
    n = coded
    chunk_of = np.arange(n) // CHUNK
    out = np.zeros((n + raw, WORDS_PER_SPLAT), dtype="<u4")
    out[n:] = raw_words.reshape(raw, WORDS_PER_SPLAT)
    if not n:
        return out
    base = table["position_base"]
    if not np.isfinite(base).all():
        raise FormatError("a chunk's position base is not finite", path, where)
    scale = _scale_halves(fields["scale"], table["scale_base"][chunk_of], setting.scale_step, path, where)
    colour = np.ascontiguousarray(fields["color"]).view("<u4")[:, 0]
    coarse = alpha_coarsening(colour >> np.uint32(24), setting.alpha_levels)
    k = size_exponent(scale) + setting.position_shift + coarse
    code = fields["position"].astype(np.int64)
    code[:, 0] = x_codes(code[:, 0], k, path, where)
    with np.errstate(over="ignore", invalid="ignore"):
        pos = base[chunk_of] + np.ldexp(code.astype(np.float64), k[:, None])
        out[:n, :3] = pos.astype(np.float32).view(np.uint32)
    e = fields["window"][:, 0].astype(np.int64) - WINDOW_BIAS
    # Rotation.
    index = fields["rotation_index"][:, 0]
    if (index > 3).any():
        raise FormatError("a rotation index is past 3", path, where)
    rmax = (1 << setting.rotation_bits) - 1
    if (fields["rotation"] > rmax).any():
        raise FormatError(f"a rotation code is past {rmax}", path, where)
    quat_halves = _decoded_quaternion(fields["rotation"], index, rmax)
    tscale = _scale_halves(fields["trbf_scale"], table["trbf_scale_base"][chunk_of], setting.trbf_scale_step,
                           path, where)[:, 0]
    centre = np.ldexp(_unzigzag(fields["trbf_center"][:, 0]).astype(np.float64), -setting.time_shift)
    with np.errstate(over="ignore"):  # a damaged window byte may scale a code past the double range: inf
        omega = np.ldexp(_unzigzag(fields["omega"]).astype(np.float64), -(e + setting.omega_shift - coarse)[:, None])
        motion = np.ldexp(_unzigzag(fields["motion"]).astype(np.float64),
                          k[:, None] + motion_exponents(setting)[None, :] - e[:, None] * MOTION_DEGREE[None, :])
    half = out[:n].view(np.uint16)
    for j, (w, i) in enumerate(ROT_AT):
        half[:, 2 * w + i] = quat_halves[:, j]
    for j, (w, i) in enumerate(OMEGA_AT):
        half[:, 2 * w + i] = _half(omega[:, j])
    for j, (w, i) in enumerate(SCALE_AT):
        half[:, 2 * w + i] = scale[:, j]
    for j, (w, i) in enumerate(MOTION_AT):
        half[:, 2 * w + i] = _half(motion[:, j])
    half[:, 2 * TRBF_CENTER_AT[0] + TRBF_CENTER_AT[1]] = _half(centre)
    half[:, 2 * TRBF_SCALE_AT[0] + TRBF_SCALE_AT[1]] = tscale
    out[:n, COLOR_WORD] = colour
    return out


def _scale_halves(code: np.ndarray, base: np.ndarray, step: int, path: str, where: tuple) -> np.ndarray:
    """Scale codes -> half bits (integers only)."""
    code = code.astype(np.int64)
    h = (base.astype(np.int64) + code - SCALE_FIRST) * step
    h = np.where(code == SCALE_ZERO, 0, np.where(code == SCALE_INF, packing.HALF_INF_BITS, h))
    if (h > packing.HALF_INF_BITS).any():
        raise FormatError("a scale code decodes past the half range", path, where)
    return h.astype(np.uint16)
