"""Half-float and unorm8 packers: exhaustive, vector and property-based checks."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from splatconv import packing
from tests import reference

ALL_HALVES = np.arange(1 << 16, dtype=np.uint16)


def ref_splatvjs(x: float) -> int:
    """splaTV's floatToHalf, one value at a time, from the algorithm's description."""
    f = struct.unpack("<I", struct.pack("<f", x))[0]
    sign, exp, frac = (f >> 31) & 1, (f >> 23) & 0xFF, f & 0x7FFFFF
    if exp == 0:
        new_exp = 0
    elif exp < 113:
        new_exp = 0
        frac = (frac | 0x800000) >> ((113 - exp) % 32)  # JS >> takes the count mod 32
    elif exp < 142:
        new_exp = exp - 112
    else:
        new_exp, frac = 31, 0
    return (sign << 15) | (new_exp << 10) | (frac >> 13)


def ref_nearest(x: float) -> int:
    """IEEE round-to-nearest-even through the C library (struct 'e'), saturating."""
    if math.isnan(x):
        raise ValueError
    try:
        return struct.unpack("<H", struct.pack("<e", x))[0]
    except OverflowError:
        return 0xFBFF if x < 0 else 0x7BFF


SPLATVJS_VECTORS = [
    (1e-15, 0x0048), (3e-15, 0x00D8), (1e-14, 0x02D0), (2e-14, 0x05A1), (5e-8, 0x0000),
    (6e-5, 0x03EE), (65504.0, 0x7C00), (65520.0, 0x7C00), (float("nan"), 0x7C00), (-0.0, 0x8000),
    (1e-40, 0x0008), (0.1, 0x2E66), (1.00146484375, 0x3C01),
]


@pytest.mark.parametrize("value,expected", SPLATVJS_VECTORS)
def test_splatvjs_vectors(value, expected):
    got = packing.float_to_half_splatvjs(np.array([value], np.float32))[0]
    assert got == expected, f"{value!r}: got 0x{got:04x}, want 0x{expected:04x}"


def test_nearest_rounds_where_splatvjs_truncates():
    x = np.array([1.00146484375], np.float32)
    assert packing.float_to_half(x)[0] == 0x3C02


def test_half_table_decodes_every_pattern_like_numpy():
    ref = ALL_HALVES.view(np.float16).astype(np.float32)
    got = packing.half_to_float(ALL_HALVES)
    finite = ~np.isnan(ref)
    assert np.array_equal(got[finite], ref[finite])
    assert np.array_equal(np.isnan(got), np.isnan(ref))


def test_nearest_roundtrips_all_65536_patterns_bit_exactly():
    # NaN payloads included: a half NaN read and written again keeps its bits.
    back = packing.float_to_half(packing.half_to_float(ALL_HALVES))
    assert np.array_equal(back, ALL_HALVES)


def test_splatvjs_on_all_65536_patterns():
    values = packing.half_to_float(ALL_HALVES)
    got = packing.float_to_half_splatvjs(values)
    want = np.array([ref_splatvjs(float(v)) for v in values], np.uint16)
    assert np.array_equal(got, want)
    # Exactly representable halves survive truncation unless |x| >= 32768 or NaN.
    keep = ~np.isnan(values) & (np.abs(values) < 32768)
    assert np.array_equal(got[keep], ALL_HALVES[keep])


def test_nearest_midpoints_round_to_even():
    # Every midpoint between adjacent positive finite halves, as float64 (exact).
    lo = packing.half_to_float(np.arange(0, 0x7BFF, dtype=np.uint16)).astype(np.float64)
    hi = packing.half_to_float(np.arange(1, 0x7C00, dtype=np.uint16)).astype(np.float64)
    mid = (lo + hi) / 2
    got = packing.float_to_half(mid)
    even = np.where(np.arange(0, 0x7BFF) % 2 == 0, np.arange(0, 0x7BFF), np.arange(1, 0x7C00))
    assert np.array_equal(got, even.astype(np.uint16))


def test_nearest_saturates_and_counts():
    counts = packing.HalfCounts()
    x = np.array([65504, 65505, 70000, -1e30, np.inf, -np.inf, np.nan, 1e-9, 0.0], np.float32)
    got = packing.float_to_half(x, counts)
    assert [hex(v) for v in got] == ["0x7bff", "0x7bff", "0x7bff", "0xfbff", "0x7c00", "0xfc00",
                                     "0x7e00", "0x0", "0x0"]
    assert (counts.overflow, counts.nonfinite, counts.underflow) == (3, 3, 1)


def test_splatvjs_counts_overflow_and_underflow():
    counts = packing.HalfCounts()
    packing.float_to_half_splatvjs(np.array([40000, 65504, 5e-8, np.nan, 1.0], np.float32), counts)
    assert (counts.overflow, counts.underflow, counts.nonfinite) == (2, 1, 1)


# Lists of floats, one packer call each: about twice the values of 2,000 one-float examples, in a quarter of the
# time (hypothesis's cost is per example, not per value).
@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(width=32, allow_nan=False), min_size=1, max_size=40))
def test_nearest_matches_ieee_reference(xs):
    got = packing.float_to_half(np.array(xs, np.float32))
    assert [(x, g, ref_nearest(x)) for x, g in zip(xs, got.tolist()) if g != ref_nearest(x)] == []


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(width=32), min_size=1, max_size=40))
def test_splatvjs_matches_reference(xs):
    got = packing.float_to_half_splatvjs(np.array(xs, np.float32))
    assert [(x, g, ref_splatvjs(x)) for x, g in zip(xs, got.tolist()) if g != ref_splatvjs(x)] == []


@settings(max_examples=500, deadline=None)
@given(st.floats(width=32, min_value=-65504, max_value=65504, allow_nan=False))
def test_nearest_error_is_at_most_half_an_ulp(x):
    h = packing.float_to_half(np.array([x], np.float32))
    back = float(packing.half_to_float(h)[0])
    ulp = max(2.0 ** (math.floor(math.log2(abs(x))) - 10), 2.0**-24) if x else 2.0**-24
    assert abs(back - x) <= ulp / 2


@given(st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=50),
       st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=50))
def test_pack_half2_roundtrip(a, b):
    n = min(len(a), len(b))
    lo, hi = np.array(a[:n], np.uint16), np.array(b[:n], np.uint16)
    words = reference.pack_half2(lo, hi)
    assert np.array_equal(words & 0xFFFF, lo) and np.array_equal(words >> 16, hi)
    back_lo, back_hi = packing.unpack_half2(words)
    assert np.array_equal(back_lo, lo) and np.array_equal(back_hi, hi)


def test_unorm8_nearest_and_truncate():
    # Clamped counts only values whose byte the clamp changes: -0.4 rounds (and truncates) to 0,
    # -0.6 rounds to -1 (clamped) but truncates to 0; 255.4 and 255.6 truncate to 255.
    v = np.array([-3, 0, 0.49, 0.5, 1.5, 254.5, 254.99, 255, 300, np.nan, -0.4, -0.6, 255.4, 255.6])
    near, clamped, nan = reference.unorm8_nearest(v)
    assert near.tolist() == [0, 0, 0, 0, 2, 254, 255, 255, 255, 0, 0, 0, 255, 255]
    assert (clamped, nan) == (4, 1)
    trunc, clamped, nan = reference.unorm8_truncate(v)
    assert trunc.tolist() == [0, 0, 0, 0, 1, 254, 254, 255, 255, 0, 0, 0, 255, 255]
    assert (clamped, nan) == (2, 1)


def test_rgba8_red_in_low_byte():
    word = reference.pack_rgba8(*(np.array([v], np.uint8) for v in (1, 2, 3, 4)))
    assert word[0] == 0x04030201
    assert [c[0] for c in packing.unpack_rgba8(word)] == [1, 2, 3, 4]


def _special_bit_patterns() -> np.ndarray:
    """float32 bit patterns around every boundary the fast paths test, plus random ones."""
    edges = [0, 1, 0x00800000, 0x33000000, 0x33800000, 0x387FE000, 0x38800000, 0x477FE000, 0x477FF000,
             0x47000000, 0x7F7FFFFF, 0x7F800000, 0x7F800001, 0x7FC00000, 0x7FFFFFFF]
    around = np.array(edges, np.int64)[:, None] + np.arange(-300, 301)
    around = around[(around >= 0) & (around < 1 << 31)].astype(np.uint32)
    rng = np.random.default_rng(0)
    rand = rng.integers(0, 1 << 32, 1 << 18, dtype=np.uint64).astype(np.uint32)
    normal = rng.normal(0, 1, 1 << 16).astype(np.float32).view(np.uint32)
    bits = np.concatenate([around, rand, normal])
    return np.concatenate([bits, bits | np.uint32(0x80000000)])


@pytest.mark.parametrize("splatvjs", [False, True])
def test_fast_paths_match_the_exact_converters(splatvjs):
    # The integer fast path handles the common range and flags the rest; together
    # they must equal the exact converter everywhere, counts included.
    x = _special_bit_patterns().view(np.float32)
    convert = packing.float_to_half_splatvjs if splatvjs else packing.float_to_half
    counts = packing.HalfCounts()
    got = convert(x, counts)
    want, overflow, underflow, nonfinite = packing.float_to_half_exact(x, splatvjs=splatvjs)
    assert np.array_equal(got, want)
    assert (counts.overflow, counts.underflow, counts.nonfinite) == (
        int(overflow.sum()), int(underflow.sum()), int(nonfinite.sum()))
    # Any shape; 2-D input gives the same bits.
    assert np.array_equal(convert(x[: 1 << 16].reshape(256, 256)).ravel(), want[: 1 << 16])


def test_fast_path_lists_exactly_what_it_cannot_convert():
    x = np.array([1.0, -2.5, 6.1035156e-05, 65504, 65519.996, 0.0, -0.0, 1e-6, -3e-8, 2.9e-8, 65520, np.inf,
                  np.nan], np.float32)
    out = np.empty(len(x), np.uint16)
    # 65519.996 rounds to 65504 but is past it: saturated and counted, so listed;
    # 2.9e-8 (below 2^-25) becomes zero: listed to be counted as underflow.
    assert packing.float_to_half_into(x, out).tolist() == [4, 9, 10, 11, 12]
    assert out[[0, 1, 2, 3, 5, 6, 7, 8]].tolist() == [0x3C00, 0xC100, 0x0400, 0x7BFF, 0x0000, 0x8000, 0x0011,
                                                      0x8001]
    # splaTV's converter: the fast range ends below 32768.
    y = np.array([32767.998, 32768, -0.0, 6e-5], np.float32)
    assert packing.float_to_half_into(y, out[:4], splatvjs=True).tolist() == [1, 3]
    assert out[[0, 2]].tolist() == [0x77FF, 0x8000]
    # Nothing unusual: nothing listed, and no mask is written.
    assert len(packing.float_to_half_into(np.ones((3, 5), np.float32), np.empty((3, 5), np.uint16))) == 0


def test_unpack_views_do_not_copy_and_are_read_only():
    words = np.array([0x04030201, 0xAABBCCDD], np.uint32)
    lo, hi = packing.unpack_half2(words)
    assert lo.tolist() == [0x0201, 0xCCDD] and hi.tolist() == [0x0403, 0xAABB]
    assert np.shares_memory(lo, words) and not lo.flags.writeable
    strided = np.arange(32, dtype=np.uint32).reshape(8, 4)[:, 1] * np.uint32(0x10001)
    lo, hi = packing.unpack_half2(strided)
    assert np.array_equal(lo, strided & 0xFFFF) and np.array_equal(hi, strided >> 16)
    r, g, b, a = packing.unpack_rgba8(words)
    assert [r[1], g[1], b[1], a[1]] == [0xDD, 0xCC, 0xBB, 0xAA]


@pytest.mark.parametrize("splatvjs", [False, True])
def test_fast_paths_agree_over_the_whole_float32_range(splatvjs):
    # Every 4099th bit pattern of all 2^32 (about a million, each exponent and sign
    # many times over): what the fast path does not list must equal the exact
    # converter and count for nothing. (The full 2^32 sweep, run once by hand,
    # found no difference either.)
    bits = (np.arange(0, 1 << 32, 4099, dtype=np.uint64)).astype(np.uint32)
    x = bits.view(np.float32)
    out = np.empty(len(x), np.uint16)
    listed = packing.float_to_half_into(x, out, splatvjs=splatvjs)
    kept = np.ones(len(x), bool)
    kept[listed] = False
    want, overflow, underflow, nonfinite = packing.float_to_half_exact(x[kept], splatvjs=splatvjs)
    assert np.array_equal(out[kept], want)
    assert not (overflow | underflow | nonfinite).any()
    assert kept.sum() > 100_000  # the half range's share of all patterns: plenty checked
