"""Pure numpy bit work: float32 bits, half floats, 8-bit unorm.

Two float -> half converters live here:

* :func:`float_to_half` -- the accurate one: IEEE round-to-nearest-even, finite
  values past the half range saturate to +-65504 (counted), NaN stays NaN with its
  payload's top bits, infinities stay infinite.
* :func:`float_to_half_splatvjs` -- a bit-exact model of the ``floatToHalf`` that
  splaTV's in-browser converter runs (truncating, with its quirks; see
  ``specs/splatv.md``).

Everything is vectorised; nothing loops per value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HALF_MAX = 65504.0
HALF_MAX_BITS = 0x7BFF
HALF_INF_BITS = 0x7C00
HALF_SIGN_BIT = 0x8000
HALF_QUIET_BIT = 0x0200

F32_SIGN_BIT = 0x80000000
F32_EXP_MASK = 0x7F800000
F32_MANT_MASK = 0x007FFFFF
#: The top mantissa bit: set in a quiet NaN.
F32_QUIET_BIT = 0x00400000
#: Bits of the canonical quiet NaN.
F32_QUIET_NAN = 0x7FC00000


@dataclass
class HalfCounts:
    """What a float -> half conversion changed beyond plain rounding.

    Attributes
    ----------
    overflow : int
        Finite inputs past the half range (saturated, or turned infinite by the
        splaTV-compatible converter).
    underflow : int
        Nonzero finite inputs that became zero.
    nonfinite : int
        NaN or infinite inputs.
    """

    overflow: int = 0
    underflow: int = 0
    nonfinite: int = 0

    def add(self, other: "HalfCounts") -> None:
        self.overflow += other.overflow
        self.underflow += other.underflow
        self.nonfinite += other.nonfinite


def f32_bits(x: np.ndarray) -> np.ndarray:
    """Bits of float32 values: ``(N,) float32`` -> ``(N,) uint32`` (a view when possible)."""
    return np.ascontiguousarray(x, dtype=np.float32).view(np.uint32)


def _half_table() -> np.ndarray:
    """float32 value of every half bit pattern, built from bits (payloads kept)."""
    h = np.arange(1 << 16, dtype=np.uint32)
    sign = (h >> 15) << 31
    exp = (h >> 10) & 0x1F
    mant = h & 0x3FF
    bits = sign | ((exp + 112) << 23) | (mant << 13)
    bits = np.where(exp == 31, sign | F32_EXP_MASK | (mant << 13), bits)
    out = bits.view(np.float32).copy()
    sub = exp == 0  # zero and subnormals: mant * 2^-24, exact in float32
    magnitude = (mant[sub].astype(np.float64) * 2.0**-24).astype(np.float32)
    out[sub] = np.where(sign[sub] != 0, -magnitude, magnitude)
    out.flags.writeable = False
    return out


#: float32 value of each of the 65,536 half bit patterns.
HALF_TO_FLOAT = _half_table()


def half_to_float(h: np.ndarray) -> np.ndarray:
    """Decode halves exactly: ``(N,) uint16`` -> ``(N,) float32``; NaN payloads kept."""
    return HALF_TO_FLOAT[np.asarray(h, dtype=np.uint16)]


def _nan_to_half(bits: np.ndarray) -> np.ndarray:
    """float32 NaN bits -> half NaN bits keeping sign and the payload's top 10 bits."""
    mant = (bits & F32_MANT_MASK) >> 13
    mant = np.where(mant == 0, HALF_QUIET_BIT, mant)
    return (((bits >> 16) & HALF_SIGN_BIT) | HALF_INF_BITS | mant).astype(np.uint16)


#: Bits (sign cleared) of the float32 values the fast paths convert, besides
#: zero: from 2^-14, the smallest normal half, up to 65504 (accurate: larger
#: values saturate and are counted) or below 32768 (splaTV's converter, whose
#: ``floatToHalf`` is a plain truncation for float32 exponents 113 to 141).
_FAST_LO = 0x38800000
_NEAREST_HI = 0x477FE000
_SPLATVJS_HI = 0x46FFFFFF
#: 2^-112: multiplying by it moves a float32 exponent onto the half's bias
#: (127 - 15 = 112), exactly for results in the half's normal range, and keeps
#: zero zero.
_REBIAS = np.float32(2.0**-112)
#: Rounding bias minus the exponent rebias (127 - 15 = 112), modulo 2^32.
_NEAREST_ADD = (0x0FFF - (112 << 23)) & 0xFFFFFFFF
#: Bits of 2^-25, the largest float32 that rounds to a zero half, less one.
_UNDERFLOW_MAX = 0x33000000
#: Bits of float32 0.5.
_HALF_BITS = 0x3F000000
_NO_INDEX = np.zeros(0, dtype=np.intp)
_NO_INDEX.flags.writeable = False


def float_to_half_into(x: np.ndarray, out: np.ndarray, *, splatvjs: bool = False,
                       scratch: np.ndarray | None = None) -> np.ndarray:
    """Convert the common case in a few integer passes; say where they are wrong.

    ``numpy``'s float16 cast runs about 1.6 ns a value; the passes here cost
    about half of that. The accurate path is exact for every value up to 65504
    in magnitude: normal halves by integer rounding, zero and subnormal halves
    by one float addition that rounds at the half's subnormal step. The
    splaTV-compatible path is exact for zero and wherever floatToHalf is a plain
    truncation (float32 exponents 113 to 141). Every other value -- huge,
    infinite, NaN, nonzero values that become zero (to be counted), and for
    splaTV's converter tiny ones -- is listed for the exact converters, which callers run on that (usually empty) subset. Reductions
    find out whether there are any, so the common case writes no mask.

    Parameters
    ----------
    x : float32 ndarray, any shape, C-contiguous
    out : uint16 ndarray, same shape as ``x``, C-contiguous
        Receives the half bits; listed entries hold garbage.
    splatvjs : bool
        Truncate as :func:`float_to_half_splatvjs` instead of rounding as
        :func:`float_to_half`.
    scratch : uint32 ndarray, optional
        At least ``scratch_size(x.size)`` elements to work in, instead of
        allocating.

    Returns
    -------
    (K,) intp ndarray
        Flat indices (into ``x.reshape(-1)``) where ``out`` must be replaced by
        the exact converter's result, ascending.
    """
    n = x.size
    if scratch is None:
        scratch = np.empty(scratch_size(n), dtype=np.uint32)
    u = x.reshape(-1).view(np.uint32)
    a, t, d = scratch[:n], scratch[n:2 * n], scratch[2 * n:3 * n]
    np.bitwise_and(u, np.uint32(0x7FFFFFFF), out=a)
    if splatvjs:
        hi = _SPLATVJS_HI
        np.subtract(a, np.uint32(1), out=t)  # zero wraps to the top: only tiny nonzero values fall below
        suspect = n and (a.max() > hi or t.min() < _FAST_LO - 1)
        with np.errstate(all="ignore"):  # NaN and huge inputs are listed below
            np.multiply(a.view(np.float32), _REBIAS, out=t.view(np.float32))
        t >>= np.uint32(13)
    else:
        hi = _NEAREST_HI
        # Normal halves: round half to even at bit 13 (add 0xFFF plus the
        # lowest kept bit) and rebias the exponent.
        np.right_shift(a, np.uint32(13), out=t)
        t &= np.uint32(1)
        t += a
        t += np.uint32(_NEAREST_ADD)
        t >>= np.uint32(13)
        # Zero and subnormal halves: adding 0.5 leaves the value's bits on the
        # half's subnormal step (2^-24, the ulp of 0.5) rounded to nearest even.
        with np.errstate(all="ignore"):  # NaN inputs are listed below
            np.add(a.view(np.float32), np.float32(0.5), out=d.view(np.float32))
        d -= np.uint32(_HALF_BITS)
        np.copyto(t, d, where=a < np.uint32(_FAST_LO))
        # Listed too, to be counted: nonzero values that become zero.
        np.subtract(a, np.uint32(1), out=d)
        suspect = n and (a.max() > hi or d.min() < _UNDERFLOW_MAX)
    np.right_shift(u, np.uint32(16), out=a)
    a &= np.uint32(HALF_SIGN_BIT)
    np.bitwise_or(t, a, out=out.reshape(-1), casting="unsafe")
    if not suspect:
        return _NO_INDEX
    np.bitwise_and(u, np.uint32(0x7FFFFFFF), out=a)
    np.subtract(a, np.uint32(1), out=t)
    return np.flatnonzero((a > hi) | (t < (_FAST_LO - 1 if splatvjs else _UNDERFLOW_MAX)))


def scratch_size(n: int) -> int:
    """uint32 elements of working space :func:`float_to_half_into` needs for ``n`` values."""
    return 3 * n


def float_to_half(x: np.ndarray, counts: HalfCounts | None = None) -> np.ndarray:
    """Accurate float32 -> half: round to nearest even, saturate, keep NaN.

    Parameters
    ----------
    x : float32 ndarray, any shape
        Other float dtypes are rounded to float32 first.
    counts : HalfCounts, optional
        Incremented with the number of saturated, flushed-to-zero and
        non-finite inputs.

    Returns
    -------
    uint16 ndarray, shape of ``x``
        Half bit patterns.
    """
    return _convert(x, counts, False)


def float_to_half_splatvjs(x: np.ndarray, counts: HalfCounts | None = None) -> np.ndarray:
    """splaTV's ``floatToHalf``, bit for bit.

    It truncates the mantissa; any input with a float32 exponent of 15 or more
    (|x| >= 32768), infinity and NaN become infinity with the input's sign bit;
    float32 subnormals give ``mantissa >> 13``; below 2^-14 the 24-bit mantissa is
    shifted right by ``113 - exponent`` *modulo 32*, as JavaScript's ``>>`` does,
    so some tiny values turn into garbage instead of zero.

    Parameters
    ----------
    x : float32 ndarray, any shape
    counts : HalfCounts, optional
        ``overflow`` counts finite inputs made infinite; ``underflow`` nonzero
        inputs made zero.

    Returns
    -------
    uint16 ndarray, shape of ``x``
    """
    return _convert(x, counts, True)


def _convert(x, counts: HalfCounts | None, splatvjs: bool) -> np.ndarray:
    """Fast path for the bulk, exact converter for the flagged rest."""
    with np.errstate(over="ignore", invalid="ignore"):  # float64 input past float32's range
        x = np.asarray(x, dtype=np.float32)
    if not x.flags.c_contiguous:
        x = x.copy()
    out = np.empty(x.shape, dtype=np.uint16)
    idx = float_to_half_into(x, out, splatvjs=splatvjs)
    if len(idx):
        # Values in the fast range add nothing to the counts, so counting the
        # listed subset alone gives the totals.
        half, overflow, underflow, nonfinite = float_to_half_exact(x.reshape(-1)[idx], splatvjs=splatvjs)
        out.reshape(-1)[idx] = half
        if counts is not None:
            counts.overflow += int(np.count_nonzero(overflow))
            counts.underflow += int(np.count_nonzero(underflow))
            counts.nonfinite += int(np.count_nonzero(nonfinite))
    return out


def float_to_half_exact(x: np.ndarray, *, splatvjs: bool = False):
    """The exact converters on any values, with what each value went through.

    The reference behind :func:`float_to_half` and :func:`float_to_half_splatvjs`
    (which run it on what :func:`float_to_half_into` flags); the masks let a caller
    count per attribute over a mixed subset.

    Parameters
    ----------
    x : (N,) float32 ndarray
    splatvjs : bool
        splaTV's truncating ``floatToHalf`` instead of round to nearest even.

    Returns
    -------
    half : (N,) uint16 ndarray
    overflow, underflow, nonfinite : (N,) bool ndarray
        Finite values past the half range (saturated, or made infinite by
        splaTV's converter); nonzero values made zero; NaN and infinities.
    """
    x = np.asarray(x, dtype=np.float32)
    if splatvjs:
        return _splatvjs_exact(x)
    return _nearest_exact(x)


def _nearest_exact(x: np.ndarray):
    with np.errstate(over="ignore", invalid="ignore"):
        out = x.astype(np.float16).view(np.uint16)
    finite = np.isfinite(x)
    over = finite & (np.abs(x) > HALF_MAX)
    nan = np.isnan(x)
    if over.any():
        out[over] = HALF_MAX_BITS | (f32_bits(x[over]) >> 16 & HALF_SIGN_BIT).astype(np.uint16)
    if nan.any():
        out[nan] = _nan_to_half(f32_bits(x[nan]))
    under = (out & 0x7FFF == 0) & (x != 0) & finite
    return out, over, under, ~finite


def _splatvjs_exact(x: np.ndarray):
    f = f32_bits(x)
    sign = (f >> 31) << 15
    exp = (f >> 23) & 0xFF
    frac = f & F32_MANT_MASK
    small = (exp != 0) & (exp < 113)
    shift = (113 - exp.astype(np.int64)) % 32
    frac_small = (frac | 0x00800000) >> np.where(small, shift, 0).astype(np.uint32)
    # The JS checks bit 24 after the shift; a 24-bit mantissa never has it, so the
    # branch that would round up to the smallest normal never fires.
    frac = np.where(small, frac_small, frac)
    new_exp = np.where(exp < 113, 0, np.where(exp < 142, exp - 112, 31)).astype(np.uint32)
    frac = np.where(exp >= 142, 0, frac)
    out = (sign | (new_exp << 10) | (frac >> 13)).astype(np.uint16)
    finite = exp != 0xFF
    over = finite & (exp >= 142)
    under = (out & 0x7FFF == 0) & (f & 0x7FFFFFFF != 0)
    return out, over, under, ~finite


def unpack_half2(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(N,) uint32`` -> (low, high) ``(N,) uint16`` halves.

    The halves are read-only strided views of ``words`` (when it already is a
    native uint32 array): a uint16 view splits words without shifting or copying.
    """
    words = np.asarray(words, dtype=np.uint32)
    halves = words[..., None].view(np.uint16)
    halves.flags.writeable = False
    low = 0 if np.little_endian else 1
    return halves[..., low], halves[..., 1 - low]


def unpack_rgba8(words: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(N,) uint32`` -> R, G, B, A ``(N,) uint8`` (R is the low byte).

    Read-only strided views of ``words`` (when it already is a native uint32
    array), as :func:`unpack_half2` gives.
    """
    words = np.asarray(words, dtype=np.uint32)
    channels = words[..., None].view(np.uint8)
    channels.flags.writeable = False
    order = (0, 1, 2, 3) if np.little_endian else (3, 2, 1, 0)
    return tuple(channels[..., i] for i in order)


def morton_code(cells: np.ndarray) -> np.ndarray:
    """The Morton (Z-order) code of ``(N, 3)`` integer cells, 21 bits an axis: ``(N,) uint64``.

    Bit i of the x, y and z cells goes to bit 3i, 3i + 1 and 3i + 2; bits above
    the 21st are dropped.
    """
    cells = np.asarray(cells, dtype=np.uint64)
    code = np.zeros(len(cells), np.uint64)
    for axis in range(3):
        v = cells[:, axis] & np.uint64(0x1FFFFF)
        for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                            (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
            v = (v | (v << np.uint64(shift))) & np.uint64(mask)
        code |= v << np.uint64(axis)
    return code
