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

A decoder gives each block's records in importance order (:func:`record_order`),
the order a ``.splatv`` writer gives them and the viewer blends depth ties in;
the encoder cuts blocks by the same key, so a file's records are in that order
as a whole.

Layouts as data: :data:`CHUNK_FIELDS` and :data:`SPLAT_FIELDS` are the block
payload in order; the spec's tables are checked against them.
"""

from __future__ import annotations

import hashlib
import zlib
from dataclasses import dataclass, replace

import numpy as np

from .. import packing
from ..model import far_rows
from ..errors import FormatError
from ..wording import plural
from ..viewer import VISIBLE_RADIUS
from .splatv_layout import COLOR_WORD, WORDS_PER_SPLAT

#: Splats a chunk (one set of position and scale ranges), as a power of two.
CHUNK_LOG2 = 8
CHUNK = 1 << CHUNK_LOG2
#: Splats a block at most (one independently decodable unit, importance order between blocks).
BLOCK = 1 << 16
#: Bias of the stored window exponent: window_index = level * 64 + (e + WINDOW_BIAS) * 4 + rotation index.
WINDOW_BIAS = 13
#: Window exponents kept: W = 2**e, e from WINDOW_MIN (a shorter window takes it) to WINDOW_MAX (a
#: longer one is kept verbatim: a temporal centre far outside [0, 1] seen at every time).
WINDOW_MIN, WINDOW_MAX = -13, 2
#: Highest boost level of a splat (the window_index byte's top two bits): its geometric steps are
#: level * boost_step bits finer.
BOOST_MAX = 3
#: Most bits of a rotation component, boosts included.
ROTATION_BITS_MAX = 16
#: Reserved scale codes: 0 -> half +0 (a linear scale of 0), 1 -> half +inf.
SCALE_ZERO, SCALE_INF, SCALE_FIRST = 0, 1, 2
#: A position farther than this many robust scene extents (the widest interquartile range of an axis)
#: from the median is stored raw: it would widen its chunk's range for its neighbours.
OUTLIER_EXTENTS = 4096.0
#: Payload parts joined into one deflate block at most this many bytes in all (:func:`deflate_groups`).
GROUP_BYTES = 4096
#: Parts before one that a run ending at it may start at (:func:`deflate_groups`).
GROUP_LOOKBACK = 48
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
        A splat's position step is 2**k, k = floor(log2(its least linear scale,
        at most ``flat_octaves`` octaves below its middle one)) + position_shift
        (+ its alpha coarsening; see :func:`size_exponent`): a displacement
        shows in proportion to the splat's thickness along it.
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
    flat_octaves : int
        How far below the middle scale the least one may take the position step down.
    boost_step : int
        A splat's boost level (0 to :data:`BOOST_MAX`, stored with it: the encoder
        gives the splats that add most to the frames the higher levels,
        :func:`boost_levels`) makes its position and motion steps
        ``2**(level * boost_step)`` times finer and gives its rotation, omega and
        temporal centre ``level * boost_step`` more bits. 0: every level means the same.
    color_shift : int
        The encoder's alone, not among the header's numbers: each coded splat's red,
        green and blue bytes are rounded to the nearest multiple of ``2**color_shift``
        (255 at most), which deflate's Huffman codes then store in fewer bits. A decoder
        reads the bytes as they are; the header JSON says ``"color_shift"`` where it is
        not 0 (what ``verify`` judges the colours by).
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
    flat_octaves: int
    boost_step: int = 0
    color_shift: int = 0


#: Quality settings by name, best first. The bench (``bench/bench_splatvq.py``) measures them.
SETTINGS = {
    "default": Setting(position_shift=-3, rotation_bits=7, scale_step=48, trbf_scale_step=192, time_shift=8,
                       omega_shift=6, motion_shift=2, acceleration_shift=1, jerk_shift=2, alpha_levels=4,
                       flat_octaves=2, boost_step=2),
    "small": Setting(position_shift=-2, rotation_bits=6, scale_step=96, trbf_scale_step=255, time_shift=6,
                     omega_shift=5, motion_shift=3, acceleration_shift=1, jerk_shift=2, alpha_levels=4,
                     flat_octaves=2, boost_step=2, color_shift=2),
}
DEFAULT_SETTING = "default"
#: The worst-frame PSNR (dB) each setting promises: what ``convert`` proves a file of it reaches.
FLOORS = {"default": 45.0, "small": 40.0}
#: Precision steps beside a setting (:func:`refined`), coarsest first: 0 is the setting as named,
#: each two steps about halve every quantizer's step.
PRECISIONS = tuple(range(-6, 13))


def precision_name(base: str, step: int) -> str:
    """The header's name of ``base`` at precision ``step``: ``"default"``, ``"default+1"``, ``"small-0.5"``."""
    return f"{base}{step / 2:+g}" if step else base


def refined(setting: Setting, step: int) -> Setting:
    """``setting`` made ``step`` half steps finer (``step`` < 0: coarser).

    Two half steps about halve every quantizer's step: the geometric steps
    (position, motion), the temporal centre's and omega's lattice steps and
    each scale lattice step, and give the rotation a bit more (about 6 dB
    where the error is spread over them all). On real scenes the angular
    quantizers (rotation, omega, scale) buy the most dB for a byte, and the
    geometric ones (position, motion, temporal centre and scale, and the
    encoder's colour step) lose the fewest when coarsened, after two relations
    that cost least of all: the flat splats' position step (``flat_octaves``) and the acceleration's
    (``acceleration_shift``). So, finer, the angular group leads by a half
    step; coarser, the first half step relaxes those two relations, the next
    coarsens the geometric group, the next the angular group, and so on.
    Values are held to :data:`LIMITS`, so the far steps may change fewer of them.
    """
    def held(name, value):
        low, high = LIMITS[name]
        return min(high, max(low, value))

    def lattice(step_units, by):  # a factor of 2 in size is 1024 half-bit units
        return max(1, round(step_units / 2.0 ** by))

    if step >= 0:
        angular, geometric, relaxed = -(-step // 2), step // 2, 0
    else:
        angular, geometric, relaxed = -(-(step + 1) // 2), -(-step // 2), 1
    return replace(
        setting, position_shift=held("position_shift", setting.position_shift - geometric),
        rotation_bits=held("rotation_bits", setting.rotation_bits + angular),
        scale_step=held("scale_step", lattice(setting.scale_step, angular)),
        trbf_scale_step=held("trbf_scale_step", lattice(setting.trbf_scale_step, geometric)),
        time_shift=held("time_shift", setting.time_shift + geometric),
        omega_shift=held("omega_shift", setting.omega_shift + angular),
        motion_shift=held("motion_shift", setting.motion_shift - geometric),
        acceleration_shift=held("acceleration_shift", setting.acceleration_shift + relaxed),
        flat_octaves=held("flat_octaves", setting.flat_octaves - relaxed),
        color_shift=held("color_shift", setting.color_shift - geometric))


#: How a notch moves each quantizer ``convert`` may coarsen beyond its precision step where a
#: scene has precision to spare (its tuning, :func:`coarser`): added to the value, or (a lattice
#: step, in half-bit units) multiplied. In the order it tries them, the cheapest on real scenes
#: first. Each is a header value (or the encoder's colour step): a decoder needs nothing new.
_NOTCH = {"time_shift": -1, "alpha_levels": 1, "color_shift": 1, "trbf_scale_step": 2.0, "flat_octaves": -1,
          "rotation_bits": -1, "omega_shift": -1, "motion_shift": 1, "scale_step": 2.0, "jerk_shift": 1,
          "acceleration_shift": 1, "position_shift": 1}
#: The quantizers a tuning tries, in order.
TUNINGS = tuple(_NOTCH)


def coarser(setting: Setting, name: str) -> Setting | None:
    """``setting`` one notch coarser in the quantizer ``name`` alone (one of :data:`TUNINGS`), or None
    where it is at its limit (:data:`LIMITS`).

    A notch: a lattice step (position, motion, acceleration, jerk, temporal centre,
    omega, colour) twice as coarse, a rotation bit fewer, a scale or temporal scale
    lattice step doubled, one more alpha coarsening level, one octave less of a flat
    splat's finer position step.
    """
    value, notch = getattr(setting, name), _NOTCH[name]
    moved = round(value * notch) if isinstance(notch, float) else value + notch
    low, high = LIMITS[name]
    moved = min(high, max(low, moved))
    return None if moved == value else replace(setting, **{name: moved})


def tuned(setting: Setting, notches) -> Setting:
    """``setting`` coarsened by each of ``notches`` (names of :data:`TUNINGS`, a name once a notch), in order.

    Raises
    ------
    ValueError
        A name that is not a quantizer of :data:`TUNINGS`.
    """
    for name in notches:
        if name not in _NOTCH:
            raise ValueError(f"{name!r} is not a quantizer of a .splatvq setting ({', '.join(TUNINGS)})")
        setting = coarser(setting, name) or setting
    return setting


def tuned_name(name: str, notches) -> str:
    """The header's name of a setting ``name`` tuned by ``notches``: ``"default+2, tuned"``."""
    return f"{name}, tuned" if len(notches) else name


#: Limits a header's setting is checked against.
SETTING_LIMITS = {"position_shift": (-30, 30), "rotation_bits": (2, 16), "scale_step": (1, 255),
                  "trbf_scale_step": (1, 255), "time_shift": (0, 30), "omega_shift": (0, 30),
                  "motion_shift": (-30, 30), "acceleration_shift": (0, 8), "jerk_shift": (0, 8),
                  "alpha_levels": (0, 7), "flat_octaves": (0, 15), "boost_step": (0, 4)}
#: Limits of every number of a :class:`Setting`: the header's, and the encoder's own colour step.
LIMITS = {**SETTING_LIMITS, "color_shift": (0, 7)}

#: The chunk tables of a block payload, in order: name, dtype, values per chunk.
CHUNK_FIELDS = (
    ("position_base", "<f8", 3),    # a lattice point of every step in the chunk, at or below its least position
    ("scale_base", "<u2", 3),       # lowest scale lattice index of each axis
    ("trbf_scale_base", "<u2", 1),  # lowest temporal scale lattice index
)
CHUNK_BYTES = sum(np.dtype(t).itemsize * k for _, t, k in CHUNK_FIELDS)

#: How a per-splat value column is stored. ``byte``: one plane of bytes.
#: ``plain``: ``w`` byte planes, lowest first (``w``, 0 to 4, from the block's width table).
#: ``saturating``: one plane of min(v, 255); then, for the splats whose byte is 255 (in
#: plane order), v - 255 in ``w`` byte planes: most codes take one byte and no plane is
#: mostly zeros (deflate's Huffman codes spend at least a bit a byte).
BYTE, PLAIN, SATURATING = "byte", "plain", "saturating"
#: A saturating plane's escape byte.
SATURATED = 255
#: The per-splat fields of a block payload, in order: name, values per splat, coding.
SPLAT_FIELDS = (
    ("x_step", 1, SATURATING),     # x code as a step from the splat before (see x_steps)
    ("yz", 2, PLAIN),              # y and z codes
    ("window_index", 1, BYTE),     # level * 64 + (e + WINDOW_BIAS) * 4 + the dropped quaternion component
    ("rotation", 3, PLAIN),        # the other three components, in order
    ("scale", 3, SATURATING),      # reserved codes, then lattice index - base + 2
    ("color", 4, BYTE),            # the RGBA8 word's bytes as they are
    ("trbf_center", 1, PLAIN),     # zigzag
    ("trbf_scale", 1, SATURATING),  # as scale
    ("motion", 9, SATURATING),     # zigzag
    ("omega", 4, SATURATING),      # zigzag
)
#: Value columns with a width (plain and saturating), in payload order: one width byte each.
WIDTH_COLUMNS = tuple(f"{name}[{j}]" for name, k, coding in SPLAT_FIELDS if coding != BYTE for j in range(k))
#: Most bytes a value column's width names.
MAX_WIDTH = 4
#: Largest value a column holds: 32 bits (a saturating one: 255 more).
VALUE_MAX = (1 << 32) - 1
#: Fewest and most payload bytes a coded splat takes.
SPLAT_BYTES_MIN = sum(k for _, k, coding in SPLAT_FIELDS if coding != PLAIN)
SPLAT_BYTES_MAX = sum(k * (1 if coding == BYTE else MAX_WIDTH + (coding == SATURATING))
                      for _, k, coding in SPLAT_FIELDS)
RAW_BYTES = 4 * WORDS_PER_SPLAT

#: Classes of a splat's motion: the planes of later motion and omega codes are stored
#: sorted by the class of motion codes decoded before them (stably), each class a deflate
#: block of its own, so that fast and slow splats get Huffman codes of their own.
#: A zigzag code u is of class 0 below 8, 1 below 32, 2 below 128, 3 below 512, else 4.
CLASS_LIMITS = (8, 32, 128, 512)
#: For each classed value column, the motion values whose largest zigzag code gives its class.
CLASSED_BY = {("motion", 1): (0,), ("motion", 2): (0, 1),
              **{("motion", j): (0, 1, 2) for j in range(3, 9)},
              **{("omega", j): (0, 1, 2) for j in range(4)}}

#: Largest position code: 32 bits.
POSITION_CODE_MAX = VALUE_MAX
#: Degree of each motion coefficient (motion_0..8: three velocity, three acceleration, three jerk terms).
MOTION_DEGREE = np.repeat(np.arange(1, 4), 3)

_SQRT1_2 = np.sqrt(0.5)
#: 2**x for every step exponent a decoder meets: |x| is at most the sum of the largest size exponent (16),
#: position shift, alpha coarsening, boost, motion shift, acceleration or jerk shift, omega shift and three windows.
_POW2_BIAS = (16 + BOOST_MAX * SETTING_LIMITS["boost_step"][1] + 3 * max(-WINDOW_MIN, WINDOW_MAX)
              + sum(max(map(abs, SETTING_LIMITS[name]))
                    for name in ("position_shift", "alpha_levels", "motion_shift", "omega_shift"))
              + max(max(map(abs, SETTING_LIMITS[name])) for name in ("acceleration_shift", "jerk_shift")))
_POW2 = np.ldexp(1.0, np.arange(-_POW2_BIAS, _POW2_BIAS + 1))
#: The other three components of a quaternion, by the index of the one dropped.
_OTHERS = np.array([[j for j in range(4) if j != i] for i in range(4)])


def payload_bounds(coded: int, raw: int) -> tuple[int, int]:
    """Fewest and most bytes of a block payload holding ``coded`` quantized and ``raw`` verbatim records."""
    fixed = -(-coded // CHUNK) * CHUNK_BYTES + len(WIDTH_COLUMNS) + raw * RAW_BYTES
    return fixed + coded * SPLAT_BYTES_MIN, fixed + coded * SPLAT_BYTES_MAX


# --------------------------------------------------------------------------
# Small pieces


def _zigzag(v: np.ndarray, dtype) -> np.ndarray:
    v = v.astype(np.int64)
    u = v << 1
    u ^= v >> 63
    return u.astype(dtype, copy=False)


def _unzigzag(u: np.ndarray) -> np.ndarray:
    u = u.astype(np.int64)
    v = u >> 1
    u &= 1
    np.negative(u, out=u)
    v ^= u
    return v


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
    return packing.morton_code((bits ^ flip) >> np.uint32(11))


def alpha_coarsening(alpha: np.ndarray, levels: int) -> np.ndarray:
    """Extra step exponent of each splat from its alpha byte, ``(N,) uint8`` -> ``(N,) int64`` in [0, levels].

    ``min(levels, 7 - floor(log2(a)))``: 0 for alpha 128 and more, one more for
    each halving below (an alpha of 0 counts as 1). Integers only.
    """
    a = np.maximum(alpha.astype(np.int64), 1)
    floor_log2 = np.frexp(a.astype(np.float64))[1] - 1
    return np.clip(7 - floor_log2, 0, levels)


def seen_size(records: np.ndarray, setting: Setting, eyes: np.ndarray) -> np.ndarray:
    """log2 of what each record covers seen face on from the nearest of ``eyes`` (camera positions,
    ``(E, 3)``; none: from anywhere alike), weighed by its opacity: ``(N,) float64``, -inf for a splat of no
    area. Its scales as they decode, its position as stored: the writer's measure of a splat where it has
    no frames to weigh it by."""
    scale = packing.HALF_TO_FLOAT[_scale_decoded(_halves_of(records, SCALE_AT), setting.scale_step)]
    alpha = (records[:, COLOR_WORD] >> np.uint32(24)).astype(np.float64)
    # A signalling NaN half (a .splatv read keeps payloads) warns when widened: it weighs nothing.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ordered = np.sort(scale.astype(np.float64), axis=1)
        out = np.log2(ordered[:, 2] * ordered[:, 1] * alpha)
        if len(eyes):
            pos = records[:, :3].view(np.float32).astype(np.float64)
            near = np.min([((pos - eye) ** 2).sum(axis=1) for eye in eyes], axis=0)
            out -= np.log2(np.maximum(near, 1e-12))
    return np.where(np.isnan(out), -np.inf, out)


#: Boost levels a factor of two in weight is worth (:func:`boost_levels`): for weights from the frames
#: (what a splat adds to them), and for the size seen that the writer falls back on (:func:`seen_size`).
LEVELS_PER_OCTAVE = {"frames": 0.2, "size": 0.5}


def boost_levels(log2_weight: np.ndarray, per_octave: float, centre: float | None = None) -> np.ndarray:
    """Each splat's boost level from the log2 of its weight: ``(N,) uint8``, 0 to :data:`BOOST_MAX`.

    ``round(per_octave * (log2 w - centre))``, at least 0: the splats that weigh
    less than ``centre`` (default: the median of ``log2 w``) take level 0, and a
    splat takes one level more for every ``1 / per_octave`` octaves it weighs
    above it. A weight of 0 (log -inf) or NaN takes level 0, and does not count
    toward the median.
    """
    lw = np.asarray(log2_weight, dtype=np.float64)
    out = np.zeros(len(lw), np.uint8)
    counted = np.isfinite(lw)
    if counted.any():
        mid = np.median(lw[counted]) if centre is None else centre
        out[counted] = np.clip(np.floor(per_octave * (lw[counted] - mid) + 0.5), 0, BOOST_MAX)
    return out


def rotation_max(setting: Setting, boost: np.ndarray) -> np.ndarray:
    """Largest rotation code of each splat, ``2**bits - 1``, its bits ``rotation_bits`` plus its boost, at most 16."""
    return (np.int64(1) << np.minimum(setting.rotation_bits + boost, ROTATION_BITS_MAX)) - 1


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
    no place for them, negative scales, a zero rotation (its omega gives the
    direction on its own), and an axis-aligned flat splat: one component of the
    rotation alone nonzero, omega zero and a zero scale. Seen from a view whose axes
    are the scene's (a generated scene's camera), such a splat's screen covariance is
    exactly diagonal and the viewer's major axis is ``normalize(vec2(0, 0))``: it draws
    nothing. The codes cannot hold the three zeros exactly, and a splat a hair off
    axis is drawn (a generated scene of 20% such splats, 2% of them flat: 43 dB at
    best, six steps finer).
    """
    pos = records[:, :3].view(np.float32).astype(np.float64)
    bad = ~np.isfinite(pos).all(axis=1) | far_rows(pos, OUTLIER_EXTENTS)
    h = records.view(np.uint16)
    for at in ROT_AT + MOTION_AT + OMEGA_AT + (TRBF_CENTER_AT,):
        bad |= (h[:, 2 * at[0] + at[1]] & 0x7FFF) >= packing.HALF_INF_BITS
    for at in SCALE_AT + (TRBF_SCALE_AT,):
        v = h[:, 2 * at[0] + at[1]]
        bad |= (v > packing.HALF_INF_BITS)  # NaN and every negative half
    rot = _halves_of(records, ROT_AT) & 0x7FFF
    bad |= (rot == 0).all(axis=1)
    aligned = np.count_nonzero(rot, axis=1) == 1
    still = ((_halves_of(records, OMEGA_AT) & 0x7FFF) == 0).all(axis=1)
    bad |= aligned & still & (_halves_of(records, SCALE_AT) == 0).any(axis=1)
    return bad


def _rotation_value(code: np.ndarray, rmax) -> np.ndarray:
    """A smallest-three code -> its component value (float64), as the decoder computes it (``rmax`` one a splat,
    or one for all)."""
    rmax = np.asarray(rmax, dtype=np.float64)
    if rmax.ndim:
        rmax = rmax[:, None]
    return (2.0 * code - rmax) / rmax * _SQRT1_2


def _scale_decoded(h: np.ndarray, step: int) -> np.ndarray:
    """Scale half bits as they decode (lattice points; 0 and +inf kept)."""
    special = (h == 0) | (h >= packing.HALF_INF_BITS)
    return np.where(special, h, scale_lattice(h, step) * step).astype(np.uint16)


def size_exponent(scale_halves: np.ndarray, flat_octaves: int) -> np.ndarray:
    """floor(log2) of each splat's thin-axis scale, from decoded scale half bits ``(N, 3) uint16``: ``(N,) int64``.

    The least of the three bit patterns, but at most ``flat_octaves`` octaves
    (1024 half-bit units each) below the middle one: a displacement across a
    flat or needle-shaped splat's thin axis shows in proportion to its
    thickness, while a splat of zero thickness must not take a step of 0.
    Integers only (a half's exponent field): a decoder derives it from the
    scales it decoded. Subnormal and zero scales count as -15, infinite ones as 16."""
    least, middle = np.sort(scale_halves, axis=1)[:, :2].astype(np.int64).T
    h = np.maximum(least, middle - (flat_octaves << 10))
    return np.clip((h >> 10) - 15, -15, 16)


def _decoded_quaternion(code: np.ndarray, index: np.ndarray, rmax: int) -> np.ndarray:
    """Smallest-three codes and the dropped index -> the quaternion's half bits, ``(N, 4) uint16``, as decoded."""
    small3 = _rotation_value(code.astype(np.float64), rmax)
    quat = np.empty((len(code), 4))
    quat[np.arange(len(code)), index] = np.sqrt(np.maximum(
        0.0, 1.0 - ((small3[:, 0] * small3[:, 0] + small3[:, 1] * small3[:, 1]) + small3[:, 2] * small3[:, 2])))
    np.put_along_axis(quat, _OTHERS[index], small3, axis=1)
    return _half(quat)


def _keep_largest(code: np.ndarray, index: np.ndarray, rmax: np.ndarray) -> np.ndarray:
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
        code[bad, j] = np.where(2 * c > (rmax[bad] if np.ndim(rmax) else rmax), c - 1, c + 1)
    return code


def scale_lattice(halves: np.ndarray, step: int) -> np.ndarray:
    """Lattice index of non-negative half bits in [1, 0x7BFF] (int64): the nearest multiple of ``step``, capped."""
    q = (halves.astype(np.int64) + step // 2) // step
    return np.minimum(q, packing.HALF_MAX_BITS // step)


def record_key(records: np.ndarray) -> np.ndarray:
    """The importance key of records as they are: ``(N, 16) uint32`` -> ``(N,) float64``.

    The product of the values of the three scale halves and the alpha byte, in
    that order. Exact in doubles (three 11-bit significands and 8 bits: at most
    41 bits, far from overflow and underflow), so any decoder that multiplies
    the same four values gets the same bits: NaN where a half is NaN or an
    infinity meets a zero, negative or -0 where a (verbatim) half is negative.
    """
    alpha = (records[:, COLOR_WORD] >> np.uint32(24)).astype(np.float64)
    # A signalling NaN half (a .splatv read keeps payloads) warns when widened.
    with np.errstate(invalid="ignore", over="ignore"):
        lin = packing.HALF_TO_FLOAT[_halves_of(records, SCALE_AT)].astype(np.float64)
        return lin[:, 0] * lin[:, 1] * lin[:, 2] * alpha


def order_code(key: np.ndarray) -> np.ndarray:
    """A sort code of importance keys, ``(N,) float64`` -> ``(N,) uint64``: ascending codes, descending keys.

    Non-negative keys first, the largest first (-0 counts as +0), then negative
    ones, the largest first, then NaN: the order of
    :func:`splatconv.viewer.importance_order`. An integer, so that a page sorts
    it with a radix sort of its bits.
    """
    bits = np.where(key == 0, 0.0, key).view(np.uint64)
    code = np.where(bits >> np.uint64(63) != 0, bits, np.uint64(0x7FFF_FFFF_FFFF_FFFF) - bits)
    code[np.isnan(key)] = np.uint64(0xFFFF_FFFF_FFFF_FFFF)
    return code


def record_order(records: np.ndarray) -> np.ndarray:
    """The order a decoder gives a block's records in: ``(N,) intp``, a stable sort by :func:`order_code`.

    Importance order, as a ``.splatv`` writer orders the same records: the
    encoder cuts blocks by the same key (:func:`quantized_key`), so block after
    block, the records of a file are in importance order as a whole; equal keys
    keep their payload order (coded splats, then raw records).
    """
    return np.argsort(order_code(record_key(records)), kind="stable")


def on_lattice(records: np.ndarray, setting: Setting) -> np.ndarray:
    """Records with their scale halves as a coded splat's decode (0, infinities, NaN and negative halves kept).

    A copy, ``(N, 16) uint32``: what the encoder stores as a block's raw records.
    """
    out = np.array(records, dtype="<u4")
    h = out.view(np.uint16)
    for w, i in SCALE_AT:
        h[:, 2 * w + i] = _scale_decoded(h[:, 2 * w + i], setting.scale_step)
    return out


def quantized_key(records: np.ndarray, setting: Setting) -> np.ndarray:
    """The importance key of the records as they decode (:func:`record_key` of :func:`on_lattice`).

    The order between blocks then depends on decoded values only, so that the
    blocks of a decoded file come back the same when it is encoded again, and a
    decoder that orders each block by :func:`record_key` orders the whole file.
    """
    return record_key(on_lattice(records, setting))


def value_class(codes: np.ndarray) -> np.ndarray:
    """The class of each splat's largest zigzag code among ``codes`` ``(N, m)``: ``(N,) uint8``, 0 to
    ``len(CLASS_LIMITS)``: how many of :data:`CLASS_LIMITS` it reaches."""
    return np.searchsorted(np.asarray(CLASS_LIMITS, dtype=np.int64), codes.max(axis=1).astype(np.int64),
                           side="right").astype(np.uint8)


def _width(values: np.ndarray) -> int:
    """Bytes the largest of ``values`` takes (0 when every value is 0)."""
    top = int(values.max()) if len(values) else 0
    return -(-top.bit_length() // 8)


def _byte_planes(values: np.ndarray, width: int):
    """``(n,)`` non-negative integers as ``width`` byte planes, lowest first."""
    v = values.astype("<u4")
    for b in range(width):
        yield ((v >> np.uint32(8 * b)) & np.uint32(0xFF)).astype(np.uint8).tobytes()


def encode_block(records: np.ndarray, setting: Setting, level: int = 9,
                 exact: np.ndarray | None = None, levels: np.ndarray | None = None) -> tuple[bytes, int, int, int, int]:
    """Quantize and compress one block of records (importance order).

    Parameters
    ----------
    records : (M, 16) uint32 ndarray
        M <= :data:`BLOCK`.
    setting : Setting
    level : int
        Deflate level (run-length matching only: the level changes little).
    exact : (M,) bool ndarray, optional
        Records to store verbatim besides those :func:`escapes` names (the
        writer's depth-sort ends; the last value returned counts them).
    levels : (M,) uint8 ndarray, optional
        Each record's boost level (:func:`boost_levels`); default 0.

    Returns
    -------
    stored : bytes
        The block as stored (raw deflate of the payload).
    coded, raw : int
        Records quantized, records kept verbatim (stored after the coded ones; their scales on the lattice).
    payload : int
        Bytes of the payload (what ``stored`` inflates to).
    forced : int
        Records of ``exact`` that would not have been stored verbatim otherwise.
    """
    esc = escapes(records)
    forced = 0
    if exact is not None:
        forced = int(np.count_nonzero(exact & ~esc))
        esc |= exact
    while True:
        kept = np.flatnonzero(~esc)
        # Chunks in Morton order (stable: within a cell, importance order).
        kept = kept[np.argsort(_morton(records[kept, :3].view(np.float32)), kind="stable")]
        tables, fields, kept, too_big = _quantize(records, kept, setting, levels)
        if not too_big.any():
            break
        # Records whose codes do not fit go raw after all, and the block is made again without
        # them (the chunks change, so another pass may find more: each pass takes at least one).
        esc[kept[too_big]] = True
    # Raw records take their scales on the lattice too: their key is then the one the blocks
    # were cut by (quantized_key), so a decoder's order inside each block is the file's order.
    parts = [part for part in payload_parts(tables, fields, on_lattice(records[esc], setting)) if part]
    # Run-length matching only: byte planes hold few long matches; it is some thirty
    # times faster than level 9's search for 1.3% more bytes (bench/README.md).
    # Each group of planes ends a deflate block (Z_BLOCK: no padding, no marker), so each
    # gets Huffman codes of its own (deflate_groups).
    comp = _compressor(level)
    out = []
    for group in deflate_groups(parts, level):
        out.append(comp.compress(b"".join(group)))
        out.append(comp.flush(zlib.Z_BLOCK))
    out.append(comp.flush())
    return b"".join(out), len(kept), int(np.count_nonzero(esc)), sum(map(len, parts)), forced


def deflate_groups(parts: list, level: int = 9) -> list:
    """``parts`` (byte strings) cut into runs of neighbours, each run to end a deflate block.

    A deflate block carries its own Huffman codes: a plane of 65,536 bytes pays
    for them many times over, but a small block's planes, class groups of a few
    splats and the width table do not (a real scene of 477 drawable splats: 127
    parts, about 600 bytes smaller cut so). The cut is the smallest of all cuts into
    runs of at most :data:`GROUP_BYTES` bytes (or of one larger part: every plane of
    a large block is a run of its own), each run deflated as the writer deflates
    it (but for the few bits a flush holds back): a shortest path over the parts,
    each run ending at a part tried from the :data:`GROUP_LOOKBACK` parts before it
    (some 4,000 deflates of at most 4 KB for a block of a few hundred splats, 0.1 to
    0.2 s, far fewer where a proof's candidates share planes, :func:`_deflated_size`;
    a large block's planes take none). An encoder's choice: any cut inflates to the
    same payload.
    """
    n = len(parts)
    best = [0] + [None] * n  # bytes of the best cut of the first j parts
    start = [0] * (n + 1)    # where the last run of that cut starts
    for j in range(1, n + 1):
        held = 0
        for i in range(j - 1, max(-1, j - 1 - GROUP_LOOKBACK), -1):
            held += len(parts[i])
            if i < j - 1 and held > GROUP_BYTES:
                break
            # A part past GROUP_BYTES is a run of its own whatever the cut: its size counts the same in every cut.
            cost = 0 if held > GROUP_BYTES else _deflated_size(b"".join(parts[i:j]), level)
            if best[j] is None or best[i] + cost < best[j]:
                best[j], start[j] = best[i] + cost, i
    groups, j = [], n
    while j > 0:
        groups.append(parts[start[j]:j])
        j = start[j]
    return groups[::-1]


def _deflated_size(data: bytes, level: int) -> int:
    """Bytes ``data`` takes as a deflate block of its own, coded as the writer codes it.

    Remembered by a digest of ``data`` (:data:`_SIZES`): the candidates of a proof
    share most of their planes, and a small block's cut deflates each run again.
    """
    key = (hashlib.blake2b(data, digest_size=16).digest(), level)
    size = _SIZES.get(key)
    if size is None:
        comp = _compressor(level)
        size = len(comp.compress(data)) + len(comp.flush(zlib.Z_BLOCK))
        if len(_SIZES) >= _SIZES_HELD:
            _SIZES.clear()
        _SIZES[key] = size
    return size


#: :func:`_deflated_size`'s memory: digest and level -> bytes; cleared once it holds :data:`_SIZES_HELD`.
_SIZES: dict = {}
_SIZES_HELD = 1 << 16


def _compressor(level: int):
    """The writer's raw deflate: run-length matching only (see :func:`encode_block`)."""
    return zlib.compressobj(level, zlib.DEFLATED, -15, 9, zlib.Z_RLE)


def _quantize(records: np.ndarray, kept: np.ndarray, setting: Setting, levels: np.ndarray | None) -> tuple:
    """The codes of the records ``kept`` names (in Morton order).

    Returns
    -------
    tables, fields : dict
        What :func:`payload_parts` stores.
    kept : (n,) int64 ndarray
        The records in the order they are coded (inside each chunk, by decoded x).
    too_big : (n,) bool ndarray
        Records (in that order) whose codes do not fit their fields.
    """
    n = len(kept)
    starts = np.arange(0, n, CHUNK)
    chunk_of = np.arange(n) // CHUNK

    # Scales, alpha coarsening, boost b (bits finer) and each splat's position step 2**k, k = its size
    # exponent + position_shift + c - b (see size_exponent); positions coded from their chunk's base, a
    # multiple of every step in the chunk.
    scale_h = _halves_of(records[kept, 5:7], ((0, 0), (0, 1), (1, 0)))
    coarse = alpha_coarsening(records[kept, COLOR_WORD] >> np.uint32(24), setting.alpha_levels)
    lv = np.zeros(n, np.int64) if levels is None else np.minimum(levels[kept], BOOST_MAX).astype(np.int64)
    b = lv * setting.boost_step
    k = (size_exponent(_scale_decoded(scale_h, setting.scale_step), setting.flat_octaves) + setting.position_shift
         + coarse - b)
    pos = records[kept, :3].view(np.float32).astype(np.float64)
    if n:
        lo = np.minimum.reduceat(pos, starts, axis=0)
        k_top = np.maximum.reduceat(k, starts)
    else:
        lo, k_top = np.zeros((0, 3)), np.zeros(0, np.int64)
    base = np.ldexp(np.floor(np.ldexp(lo, -k_top[:, None])), k_top[:, None])
    pos_code = np.rint(np.ldexp(pos - base[chunk_of], -k[:, None]))
    del pos
    # Inside each chunk, splats in order of their decoded x (ties in Morton order), x
    # stored as the step from the one before: the order itself carries information
    # (some log2(256!) / 256 = 6.6 bits a splat) that independent codes spend again.
    order = np.lexsort((np.arange(n), np.ldexp(pos_code[:, 0], k), chunk_of))
    kept, k, coarse, pos_code, scale_h = kept[order], k[order], coarse[order], pos_code[order], scale_h[order]
    b, lv = b[order], lv[order]
    del order
    rec = records[kept]
    h = rec.view(np.uint16)

    # Rotation: unit quaternion, largest component positive and dropped; omega / |q| * sign * W
    # (first: the fewest arrays are alive).
    q = packing.HALF_TO_FLOAT[_halves_of(rec, ROT_AT)].astype(np.float64)
    norm = np.sqrt((q * q).sum(axis=1))
    big = np.argmax(np.abs(q), axis=1)
    sign = np.where(q[np.arange(n), big] < 0, -1.0, 1.0) / norm
    rmax = rotation_max(setting, b)
    small3 = np.take_along_axis(q, _OTHERS[big], axis=1) * sign[:, None]
    rot_code = np.clip(np.rint((small3 / _SQRT1_2 + 1.0) * 0.5 * rmax[:, None]), 0, rmax[:, None])
    rot_code = _keep_largest(rot_code, big, rmax).astype(np.uint16)
    del q, small3, norm

    # Temporal centre and scale, quantized first: the window W is that of the decoded values.
    centre_f = packing.HALF_TO_FLOAT[h[:, 30]].astype(np.float64)
    centre_code = np.rint(np.ldexp(centre_f, setting.time_shift + b)).astype(np.int64)
    centre_dec = packing.HALF_TO_FLOAT[_half(np.ldexp(centre_code.astype(np.float64), -(setting.time_shift + b)))]
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
    e[pos_w] = np.clip(_ceil_log2(window[pos_w]), WINDOW_MIN, WINDOW_MAX + 1)
    wide = e > WINDOW_MAX
    e = np.minimum(e, WINDOW_MAX)
    del centre_f, centre_dec, reach, c, t0, t1, window

    # Omega and motion, a column at a time as zigzag codes (uint32: their widest): few temporaries.
    omega_u = np.empty((n, 4), np.uint32)
    fits = np.ones(n, bool)
    for j, (w, i) in enumerate(OMEGA_AT):
        v = np.rint(np.ldexp(packing.HALF_TO_FLOAT[h[:, 2 * w + i]] * sign, e + setting.omega_shift - coarse + b))
        fits &= np.abs(v) < 2.0 ** 31
        omega_u[:, j] = _zigzag(np.where(fits, v, 0), np.uint32)
    motion_u = np.empty((n, 9), np.uint32)
    exps = motion_exponents(setting)
    for j, (w, i) in enumerate(MOTION_AT):
        v = np.rint(np.ldexp(packing.HALF_TO_FLOAT[h[:, 2 * w + i]].astype(np.float64),
                             e * MOTION_DEGREE[j] - k - exps[j]))
        fits &= np.abs(v) < 2.0 ** 31
        motion_u[:, j] = _zigzag(np.where(fits, v, 0), np.uint32)
    del v, sign
    too_big = ~fits | wide | (pos_code > POSITION_CODE_MAX).any(axis=1) | (np.abs(centre_code) >= 1 << 31)
    pos_code = np.where(too_big[:, None], 0, pos_code).astype(np.int64)

    s_special = (scale_h == 0) | (scale_h == packing.HALF_INF_BITS)
    s_lat = scale_lattice(scale_h, setting.scale_step)
    big_lat = np.iinfo(np.int64).max
    s_base = (np.minimum.reduceat(np.where(s_special, big_lat, s_lat), starts, axis=0) if n
              else np.zeros((0, 3), np.int64))
    s_base = np.where(s_base == big_lat, 0, s_base)
    s_code = np.where(scale_h == 0, SCALE_ZERO, np.where(scale_h == packing.HALF_INF_BITS, SCALE_INF,
                                                         s_lat - s_base[chunk_of] + SCALE_FIRST)).astype(np.uint16)
    del s_lat, s_special
    t_base = (np.minimum.reduceat(np.where(t_special, big_lat, t_lat), starts) if n else np.zeros(0, np.int64))
    t_base = np.where(t_base == big_lat, 0, t_base)
    t_code = np.where(tsh == 0, SCALE_ZERO, np.where(tsh == packing.HALF_INF_BITS, SCALE_INF,
                                                     t_lat - t_base[chunk_of] + SCALE_FIRST)).astype(np.uint16)

    tables = {"position_base": base, "scale_base": s_base, "trbf_scale_base": t_base[:, None]}
    fields = {
        "x_step": x_steps(pos_code[:, 0], k)[:, None], "yz": pos_code[:, 1:],
        "window_index": ((lv << 6) + (e + WINDOW_BIAS) * 4 + big).astype(np.uint8)[:, None], "rotation": rot_code,
        "scale": s_code, "color": _colour_bytes(rec[:, COLOR_WORD], setting.color_shift),
        "trbf_center": _zigzag(np.where(too_big, 0, centre_code), np.uint32)[:, None],
        "trbf_scale": t_code[:, None], "motion": motion_u, "omega": omega_u,
    }
    return tables, fields, kept, too_big


def _colour_bytes(words: np.ndarray, shift: int) -> np.ndarray:
    """The RGBA8 words' bytes, ``(n, 4) uint8``, R first, with R, G and B rounded to the nearest multiple of
    ``2**shift`` (255 at most: a projection, so a second encoding keeps them); alpha as it is."""
    out = words.astype("<u4").view(np.uint8).reshape(-1, 4).copy()
    if shift:
        rgb = out[:, :3].astype(np.int32)
        out[:, :3] = np.minimum(((rgb + (1 << (shift - 1))) >> shift) << shift, 255)
    return out


def _class_orders(motion: np.ndarray) -> dict:
    """For each classed column's sources (:data:`CLASSED_BY`): each splat's class, the stable order of splats by it."""
    out = {}
    for by in set(CLASSED_BY.values()):
        classes = value_class(motion[:, list(by)])
        out[by] = np.argsort(classes, kind="stable"), classes
    return out


def _escapes(values: np.ndarray) -> np.ndarray:
    """What a saturating column stores past its plane: v - 255 of the values of 255 and more, in order."""
    return values[values >= SATURATED] - SATURATED


def payload_parts(tables: dict, fields: dict, raw: np.ndarray):
    """A block payload from its codes, as byte strings (planes, class groups, tables), one at a time.

    Parameters
    ----------
    tables : dict
        :data:`CHUNK_FIELDS` by name, ``(chunks, k)`` each.
    fields : dict
        :data:`SPLAT_FIELDS` by name, ``(n, k)`` non-negative integers each (zigzag codes where signed).
    raw : (R, 16) uint32 ndarray
        Records kept verbatim.
    """
    orders = _class_orders(fields["motion"])
    yield b"".join(np.ascontiguousarray(tables[name], dtype=dtype).tobytes() for name, dtype, _ in CHUNK_FIELDS)
    widths = [_width(fields[name][:, j] if coding == PLAIN else _escapes(fields[name][:, j].astype(np.int64)))
              for name, count, coding in SPLAT_FIELDS if coding != BYTE for j in range(count)]
    yield bytes(widths)
    widths = iter(widths)
    for name, count, coding in SPLAT_FIELDS:
        for j in range(count):
            values = fields[name][:, j].astype(np.int64)
            if coding == BYTE:
                yield values.astype(np.uint8).tobytes()
                continue
            width = next(widths)
            if coding == PLAIN:
                yield from _byte_planes(values, width)
                continue
            by = CLASSED_BY.get((name, j))
            if by is not None:
                order, classes = orders[by]
                values = values[order]
            plane = np.minimum(values, SATURATED).astype(np.uint8)
            if by is None:
                yield plane.tobytes()
            else:
                for part in np.split(plane, np.cumsum(np.bincount(classes, minlength=len(CLASS_LIMITS) + 1))[:-1]):
                    yield part.tobytes()
            yield from _byte_planes(_escapes(values), width)
    yield np.ascontiguousarray(raw, dtype="<u4").tobytes()


# --------------------------------------------------------------------------
# Decoding


def inflate(stored: bytes, expected: int, path: str, where: tuple) -> bytes:
    """Raw-inflate a block (or the header), refusing one that gives more or fewer than ``expected`` bytes."""
    d = zlib.decompressobj(-15)
    try:
        out = d.decompress(stored, max(expected, 1))  # a max_length of 0 is no limit at all
        more = d.unconsumed_tail or (not d.eof and d.decompress(b"", 1))
    except zlib.error as e:
        raise FormatError(f"compressed data is corrupt ({e})", path, where) from None
    if more:
        raise FormatError(f"decodes to more than the {expected} bytes declared", path, where)
    if len(out) != expected:
        raise FormatError(f"decodes to {len(out)} bytes, not the {expected} declared", path, where)
    if not d.eof:
        raise FormatError(f"its compressed data stops after the {expected} bytes declared without its end "
                          "marker", path, where)
    if d.unused_data:
        raise FormatError(f"{plural(len(d.unused_data), 'byte')} after the end of its compressed data", path, where)
    return out


class _Reader:
    """Walks a block payload, refusing to read past its end."""

    def __init__(self, payload: bytes, path: str, where: tuple):
        self.buf, self.at, self.path, self.where = memoryview(payload), 0, path, where

    def take(self, dtype, count: int) -> np.ndarray:
        size = np.dtype(dtype).itemsize * count
        if self.at + size > len(self.buf):
            raise FormatError("its payload ends before its last record", self.path, self.where)
        out = np.frombuffer(self.buf, dtype=dtype, count=count, offset=self.at)
        self.at += size
        return out

    def planes(self, count: int, width: int) -> np.ndarray:
        """``width`` byte planes of ``count`` values, lowest first: ``(count,) int64``."""
        v = np.zeros(count, np.int64)
        for b in range(width):
            v |= self.take(np.uint8, count).astype(np.int64) << (8 * b)
        return v


def unpack_payload(payload: bytes, coded: int, raw: int, path: str, where: tuple) -> tuple:
    """A block payload (inflated) -> its codes: the inverse of :func:`payload_parts`.

    Returns
    -------
    tables : dict
        :data:`CHUNK_FIELDS` by name, ``(chunks, k)`` each.
    fields : dict
        :data:`SPLAT_FIELDS` by name, ``(coded, k) int64`` each.
    raw : (raw, 16) uint32 ndarray

    Raises
    ------
    FormatError
        Where a width is past :data:`MAX_WIDTH` or the payload ends before or after its last record.
    """
    r = _Reader(payload, path, where)
    n = coded
    chunks = -(-n // CHUNK)
    tables = {name: r.take(dtype, chunks * k).reshape(chunks, k) for name, dtype, k in CHUNK_FIELDS}
    widths = r.take(np.uint8, len(WIDTH_COLUMNS))
    if (widths > MAX_WIDTH).any():
        raise FormatError(f"a column width of {int(widths.max())} bytes (at most {MAX_WIDTH})", path, where)
    widths = iter(widths.tolist())
    fields, orders = {}, {}
    for name, count, coding in SPLAT_FIELDS:
        values = fields[name] = np.empty((n, count), np.int64)
        for j in range(count):
            if coding == BYTE:
                values[:, j] = r.take(np.uint8, n)
                continue
            width = next(widths)
            if coding == PLAIN:
                values[:, j] = r.planes(n, width)
                continue
            v = r.take(np.uint8, n).astype(np.int64)
            escaped = np.flatnonzero(v == SATURATED)
            v[escaped] += r.planes(len(escaped), width)
            by = CLASSED_BY.get((name, j))
            if by is None:
                values[:, j] = v
                continue
            if by not in orders:  # the motion values it names are decoded by now
                orders[by] = np.argsort(value_class(fields["motion"][:, list(by)]), kind="stable")
            values[orders[by], j] = v
    raw_words = r.take("<u4", raw * WORDS_PER_SPLAT).reshape(raw, WORDS_PER_SPLAT)
    if r.at != len(payload):
        raise FormatError(f"its payload has {plural(len(payload) - r.at, 'byte')} after its last record", path, where)
    return tables, fields, raw_words


def decode_block(payload: bytes, coded: int, raw: int, setting: Setting, path: str, where: tuple) -> np.ndarray:
    """A block payload (inflated) -> its records, ``(coded + raw, 16) uint32``: the texture words.

    In importance order (:func:`record_order`): the order a ``.splatv`` writer gives
    the same records, which the viewer draws depth ties in.
    """
    out = decode_payload(payload, coded, raw, setting, path, where)
    return out[record_order(out)]


def decode_payload(payload: bytes, coded: int, raw: int, setting: Setting, path: str, where: tuple) -> np.ndarray:
    """A block payload (inflated) -> its records in payload order (coded splats, then raw records).

    :func:`decode_block` gives them in a decoder's order; this is what it orders.
    """
    table, fields, raw_words = unpack_payload(payload, coded, raw, path, where)
    n = coded
    chunk_of = np.arange(n) // CHUNK
    out = np.zeros((n + raw, WORDS_PER_SPLAT), dtype="<u4")
    out[n:] = raw_words
    if not n:
        return out
    base = table["position_base"]
    if not np.isfinite(base).all():
        raise FormatError("a chunk's position base is not finite", path, where)
    scale = _scale_halves(fields["scale"], table["scale_base"][chunk_of], setting.scale_step, path, where)
    colour = np.ascontiguousarray(fields["color"].astype(np.uint8)).view("<u4")[:, 0]
    coarse = alpha_coarsening(colour >> np.uint32(24), setting.alpha_levels)
    head = fields["window_index"][:, 0]
    boost = (head >> 6).astype(np.int64) * setting.boost_step  # its level times the step: bits finer
    k = size_exponent(scale, setting.flat_octaves) + setting.position_shift + coarse - boost
    # x_codes refuses an x code past POSITION_CODE_MAX; y and z are at most 4 bytes wide.
    code = np.concatenate([x_codes(fields["x_step"][:, 0], k, path, where)[:, None], fields["yz"]], axis=1)
    with np.errstate(over="ignore", invalid="ignore"):
        pos = base[chunk_of] + np.ldexp(code.astype(np.float64), k[:, None])
        out[:n, :3] = pos.astype(np.float32).view(np.uint32)
    e, index = ((head >> 2) & 15).astype(np.int64) - WINDOW_BIAS, head & 3
    # Rotation.
    rmax = rotation_max(setting, boost)
    past = (fields["rotation"] > rmax[:, None]).any(axis=1)
    if past.any():  # the first such splat's largest code
        raise FormatError(f"a rotation code is past {int(rmax[np.argmax(past)])}", path, where)
    quat_halves = _decoded_quaternion(fields["rotation"], index, rmax)
    tscale = _scale_halves(fields["trbf_scale"], table["trbf_scale_base"][chunk_of], setting.trbf_scale_step,
                           path, where)[:, 0]
    centre = np.ldexp(_unzigzag(fields["trbf_center"][:, 0]).astype(np.float64), -(setting.time_shift + boost))
    half = out[:n].view(np.uint16)
    for j, (w, i) in enumerate(ROT_AT):
        half[:, 2 * w + i] = quat_halves[:, j]
    for j, (w, i) in enumerate(SCALE_AT):
        half[:, 2 * w + i] = scale[:, j]
    # Omega and motion a column at a time: code * 2**x, the power from a table (exact: |x| is small).
    step = _POW2[_POW2_BIAS - (e + setting.omega_shift - coarse + boost)]
    for j, (w, i) in enumerate(OMEGA_AT):
        half[:, 2 * w + i] = _half(_unzigzag(fields["omega"][:, j]) * step)
    exps = motion_exponents(setting)
    for j, (w, i) in enumerate(MOTION_AT):
        if j % 3 == 0:
            step = _POW2[_POW2_BIAS + k + exps[j] - e * MOTION_DEGREE[j]]
        half[:, 2 * w + i] = _half(_unzigzag(fields["motion"][:, j]) * step)
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
