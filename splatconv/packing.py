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


def float_to_half(x: np.ndarray, counts: HalfCounts | None = None) -> np.ndarray:
    """Accurate float32 -> half: round to nearest even, saturate, keep NaN.

    Parameters
    ----------
    x : (N,) float32 ndarray
    counts : HalfCounts, optional
        Incremented with the number of saturated, flushed-to-zero and
        non-finite inputs.

    Returns
    -------
    (N,) uint16 ndarray
        Half bit patterns.
    """
    x = np.asarray(x, dtype=np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        out = x.astype(np.float16).view(np.uint16)
    finite = np.isfinite(x)
    over = finite & (np.abs(x) > HALF_MAX)
    nan = np.isnan(x)
    if over.any():
        out[over] = HALF_MAX_BITS | (f32_bits(x[over]) >> 16 & HALF_SIGN_BIT).astype(np.uint16)
    if nan.any():
        out[nan] = _nan_to_half(f32_bits(x[nan]))
    if counts is not None:
        counts.overflow += int(np.count_nonzero(over))
        counts.nonfinite += int(x.size - np.count_nonzero(finite))
        counts.underflow += int(np.count_nonzero((out & 0x7FFF == 0) & (x != 0) & finite))
    return out


def float_to_half_splatvjs(x: np.ndarray, counts: HalfCounts | None = None) -> np.ndarray:
    """splaTV's ``floatToHalf``, bit for bit.

    It truncates the mantissa; any input with a float32 exponent of 15 or more
    (|x| >= 32768), infinity and NaN become infinity with the input's sign bit;
    float32 subnormals give ``mantissa >> 13``; below 2^-14 the 24-bit mantissa is
    shifted right by ``113 - exponent`` *modulo 32*, as JavaScript's ``>>`` does,
    so some tiny values turn into garbage instead of zero.

    Parameters
    ----------
    x : (N,) float32 ndarray
    counts : HalfCounts, optional
        ``overflow`` counts finite inputs made infinite; ``underflow`` nonzero
        inputs made zero.

    Returns
    -------
    (N,) uint16 ndarray
    """
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
    if counts is not None:
        finite = exp != 0xFF
        counts.overflow += int(np.count_nonzero(finite & (exp >= 142)))
        counts.nonfinite += int(np.count_nonzero(~finite))
        counts.underflow += int(np.count_nonzero((out & 0x7FFF == 0) & (f & 0x7FFFFFFF != 0)))
    return out


def pack_half2(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Two ``(N,) uint16`` arrays -> ``(N,) uint32``, ``low`` in bits 0-15 (packHalf2x16)."""
    return low.astype(np.uint32) | (high.astype(np.uint32) << 16)


def unpack_half2(words: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(N,) uint32`` -> (low, high) ``(N,) uint16`` halves."""
    words = np.asarray(words, dtype=np.uint32)
    return (words & 0xFFFF).astype(np.uint16), (words >> 16).astype(np.uint16)


def unorm8_nearest(v: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Scaled values (already x255, float64) -> uint8, clamped then rounded to nearest even.

    Returns
    -------
    bytes : (N,) uint8 ndarray
    clamped : int
        Values outside [0, 255] (NaN excluded).
    nan : int
        NaN values (written as 0).
    """
    v = np.asarray(v, dtype=np.float64)
    nan = np.isnan(v)
    clamped = int(np.count_nonzero((v < 0) | (v > 255)))
    out = np.rint(np.clip(np.where(nan, 0.0, v), 0.0, 255.0)).astype(np.uint8)
    return out, clamped, int(np.count_nonzero(nan))


def unorm8_truncate(v: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Scaled values (x255, float64) -> uint8 the way splaTV's JS stores them.

    ``Math.max(0, Math.min(255, v))`` then a Uint8Array store: truncation toward
    zero; NaN gives 0. Returns the bytes and the clamped and NaN counts, as
    :func:`unorm8_nearest` does.
    """
    v = np.asarray(v, dtype=np.float64)
    nan = np.isnan(v)
    clamped = int(np.count_nonzero((v < 0) | (v > 255)))
    out = np.trunc(np.clip(np.where(nan, 0.0, v), 0.0, 255.0)).astype(np.uint8)
    return out, clamped, int(np.count_nonzero(nan))


def pack_rgba8(r, g, b, a) -> np.ndarray:
    """Four ``(N,) uint8`` -> ``(N,) uint32`` with R in the low byte."""
    return (r.astype(np.uint32) | (g.astype(np.uint32) << 8)
            | (b.astype(np.uint32) << 16) | (a.astype(np.uint32) << 24))


def unpack_rgba8(words: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(N,) uint32`` -> R, G, B, A ``(N,) uint8`` (R is the low byte)."""
    words = np.asarray(words, dtype=np.uint32)
    return tuple(((words >> s) & 0xFF).astype(np.uint8) for s in (0, 8, 16, 24))
