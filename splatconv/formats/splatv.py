"""The splaTV ``.splatv`` format: JSON header plus an RGBA32UI texture.

Layout (see ``specs/splatv.md``): uint32 LE magic, uint32 LE JSON length, a UTF-8
JSON array of chunks, then each chunk's bytes in order. The ``splat`` chunk is a
4096-texel-wide RGBA32UI texture, 16 uint32 words (4 texels) per splat, 1024
splats per texture row. The word table below is the whole record layout.
"""

from __future__ import annotations

import json
import math
import os
import struct
import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .. import packing
from ..cameras import camera_for_box, framing_box, validate_cameras
from ..errors import FormatError, UnsupportedError
from ..model import COLUMNS, Scene, lite_rows, row_fields

NAME = "splatv"
SUFFIXES = (".splatv",)

MAGIC = 0x674B
PREAMBLE = struct.Struct("<II")
TEXWIDTH = 4096
WORDS_PER_SPLAT = 16
SPLATS_PER_ROW = TEXWIDTH * 4 // WORDS_PER_SPLAT  # 1024: the shader's index & 0x3ff
RECORD_BYTES = WORDS_PER_SPLAT * 4
#: Largest JSON header read (a header is cameras and a few numbers).
MAX_JSON_BYTES = 64 << 20
#: Largest texture height accepted: past any GPU's MAX_TEXTURE_SIZE (4 GiB of data).
MAX_TEXHEIGHT = 65536

#: Record words 0-2: position as float32 bits.
POSITION_WORDS = {0: "x", 1: "y", 2: "z"}
#: Record words holding two halves (low 16 bits first); None is an unused zero half.
HALF_WORDS = {
    3: ("rot_0", "rot_1"),
    4: ("rot_2", "rot_3"),
    5: ("scale_0", "scale_1"),
    6: ("scale_2", None),
    8: ("motion_0", "motion_1"),
    9: ("motion_2", "motion_3"),
    10: ("motion_4", "motion_5"),
    11: ("motion_6", "motion_7"),
    12: ("motion_8", None),
    13: ("omega_0", "omega_1"),
    14: ("omega_2", "omega_3"),
    15: ("trbf_center", "trbf_scale"),
}
#: Record word 7: RGBA8, R in the low byte.
COLOR_WORD = 7
#: Attributes the texture stores as exp(value) (the model keeps logarithms).
EXP_ATTRIBUTES = frozenset({"scale_0", "scale_1", "scale_2", "trbf_scale"})

#: Logit written for alpha bytes 0 and 255 (kept finite): sigmoid(-40)*255 is
#: below 1e-15 and sigmoid(40)*255 is exactly 255.0 in double precision, so both
#: writers (rounding and truncating) give the byte back.
ALPHA_LOGIT_LIMIT = np.float32(40.0)

# --------------------------------------------------------------------------
# Inverse tables: texture value -> model value, chosen so that both writers
# give the same texture value back.


def _nudge_up(start: np.ndarray, ok) -> np.ndarray:
    """Smallest float32 at or above ``start`` (element-wise) where ``ok`` holds.

    A handful of ulp steps always suffices for the tables below; the loop runs
    over steps, not values.
    """
    value = start.astype(np.float32)
    for _ in range(64):
        bad = ~ok(value)
        if not bad.any():
            return value
        value[bad] = np.nextafter(value[bad], np.float32(np.inf))
    raise AssertionError("inverse table did not converge")  # pragma: no cover


def _log_table() -> np.ndarray:
    """Model value (a logarithm) for each half stored in an exp() slot."""
    v = packing.HALF_TO_FLOAT
    bits = np.arange(1 << 16, dtype=np.uint32)
    table = np.full(1 << 16, np.nan, dtype=np.float32)
    pos = (bits & 0x8000 == 0) & np.isfinite(v) & (v > 0)
    target = v[pos].astype(np.float64)
    with np.errstate(divide="ignore"):
        start = np.log(target)
    # float32(exp(L)) >= v makes truncation give v back; rounding does too since
    # each step moves exp(L) by far less than half a half-ulp.
    table[pos] = _nudge_up(start, lambda L: np.exp(L.astype(np.float64)).astype(np.float32) >= target)
    table[bits == 0x0000] = -np.inf
    table[bits == 0x8000] = -np.inf  # -0 has no logarithm; exp(-inf) gives +0 (reported)
    table[bits == 0x7C00] = np.inf
    nan = np.isnan(v)
    table[nan] = v[nan]  # NaN passes through both ways with its payload
    table.flags.writeable = False
    return table


def _color_table() -> np.ndarray:
    """Model colour for each byte: smallest float32 f >= c/255 with f*255 >= c."""
    c = np.arange(256, dtype=np.float64)
    table = _nudge_up(c / 255.0, lambda f: f.astype(np.float64) * 255.0 >= c)
    table.flags.writeable = False
    return table


def _sigmoid255(logit: np.ndarray) -> np.ndarray:
    """Alpha byte value before rounding, computed the way splaTV's JS does (double)."""
    return 1.0 / (1.0 + np.exp(-np.asarray(logit, dtype=np.float64))) * 255.0


def _alpha_table() -> np.ndarray:
    """Model opacity (a logit) for each alpha byte."""
    a = np.arange(1, 255, dtype=np.float64)
    p = a / 255.0
    # A margin of 1e-9 above the byte keeps truncation safe from a last-bit
    # difference between this libm's exp and a browser's.
    mid = _nudge_up(np.log(p / (1.0 - p)), lambda L: _sigmoid255(L) >= a + 1e-9)
    table = np.concatenate([[-ALPHA_LOGIT_LIMIT], mid, [ALPHA_LOGIT_LIMIT]]).astype(np.float32)
    table.flags.writeable = False
    return table


LOG_OF_HALF = _log_table()
COLOR_OF_BYTE = _color_table()
LOGIT_OF_BYTE = _alpha_table()


# --------------------------------------------------------------------------
# Writing


@dataclass
class WriteReport:
    """What a write did, for the user. ``notes`` are human sentences."""

    count: int = 0
    texheight: int = 0
    half: dict = field(default_factory=dict)  # attribute -> packing.HalfCounts
    clamped: dict = field(default_factory=dict)  # "color"/"alpha" -> count
    nan_bytes: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)


def texture_height(count: int) -> int:
    """Rows of the texture for ``count`` splats: ceil(count / 1024)."""
    return -(-count // SPLATS_PER_ROW)


def importance(cols: dict) -> np.ndarray:
    """exp(scale_0)*exp(scale_1)*exp(scale_2)*sigmoid(opacity) in double, ``(N,) float64``."""
    with np.errstate(over="ignore", invalid="ignore"):
        size = (np.exp(cols["scale_0"].astype(np.float64)) * np.exp(cols["scale_1"].astype(np.float64))
                * np.exp(cols["scale_2"].astype(np.float64)))
        return size * (1.0 / (1.0 + np.exp(-cols["opacity"].astype(np.float64))))


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
    return _importance_order(key, np.empty(len(key), dtype=np.uint64), lambda rows: key[rows])


def _importance_order(key: np.ndarray, packed: np.ndarray, key_of) -> np.ndarray:
    """:func:`importance_order` in ``packed``, ``(N,) uint64``, which may be ``key``'s own memory.

    ``key_of(rows)`` gives the full keys of some rows again, for kept-bit ties
    (``key`` may be overwritten by then). The order returned is a view of ``packed``.
    """
    n = len(key)
    wide = key.dtype == np.float64
    row_bits = max(1, (n - 1).bit_length())
    if row_bits > (64 - 13 if wide else 32) or np.dtype(np.intp).itemsize != 8:  # pragma: no cover
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
    full = _descending_bits(key_of(order[ties])), _descending_bits(key_of(order[ties + 1]))
    wrong = full[0] != full[1]
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


# --------------------------------------------------------------------------
# Packing. Blocks of rows are copied into a float32 working array with one row
# per attribute (numpy's loops are fast on contiguous values) and packed there;
# blocks are independent, so threads pack them side by side (numpy releases the
# GIL in its loops). Sorted output takes two passes: one in input order for the
# importance key (and the scale halves and alpha bytes, which come from the
# same exponentials), then one in output order that gathers each block's rows
# from the input, packs them and hands them to the writer, so the texture is
# never held whole and the write overlaps the packing.

#: Rows packed at a time. Large, so that each numpy call is long next to the
#: cost of handing the GIL between threads; small enough to stay in cache.
BLOCK = 1 << 15
#: Rows of the input-order (importance) pass at a time: it has fewer arrays.
KEY_BLOCK = 1 << 16
#: Packing threads (the calling thread writes meanwhile). Beyond the cores,
#: more only add GIL hand-overs.
WORKERS = max(1, min(os.cpu_count() or 2, 3))
#: Values converted to halves at a time (rows of a block): bounds the temporaries.
_HALF_GROUP = 1 << 18
#: Elements per step of whole-array passes that would otherwise need N-sized
#: temporaries; small enough that the temporaries come from the heap, not mmap.
_CHUNK = 1 << 13

#: Half slots of a record in slot order: (uint16 index in the record, attribute).
_HALF_SLOTS = tuple((2 * w + k, name) for w, pair in HALF_WORDS.items() for k, name in enumerate(pair)
                    if name is not None)
#: uint16 slots of the unused (always zero) halves.
_ZERO_SLOTS = tuple(2 * w + k for w, pair in HALF_WORDS.items() for k, name in enumerate(pair) if name is None)
_SLOT = {name: slot for slot, name in _HALF_SLOTS}
_SCALES = ("scale_0", "scale_1", "scale_2")
#: Halves packed in the output-order pass, in slot order (trbf_scale last).
_RECORD_HALVES = tuple(name for _, name in _HALF_SLOTS if name not in _SCALES)
#: Attributes as rows of a working block. Contiguous groups: the record halves,
#: then what the importance pass reads (scales, opacity, and the centres a
#: framing camera needs), then colour.
_LAYOUT = _RECORD_HALVES + _SCALES + ("opacity", "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2")
assert sorted(_LAYOUT) == sorted(COLUMNS) and _RECORD_HALVES[-1] == "trbf_scale"
_N_RECORD_HALVES = len(_RECORD_HALVES)
_ROW = {name: i for i, name in enumerate(_LAYOUT)}
_SCALE_ROWS = slice(_ROW["scale_0"], _ROW["scale_0"] + 3)
_OPACITY_ROW = _ROW["opacity"]
_POSITION_ROWS = slice(_ROW["x"], _ROW["x"] + 3)
_COLOR_ROWS = slice(_ROW["f_dc_0"], _ROW["f_dc_0"] + 3)
#: Byte of the colour word within a record.
_COLOR_BYTE = COLOR_WORD * 4
#: Record word of scale_0 and scale_1; the next holds scale_2 and a zero half.
_SCALE_WORD = _SLOT["scale_0"] // 2
assert (_SLOT["scale_1"], _SLOT["scale_2"], _SLOT["scale_2"] + 1) == (
    2 * _SCALE_WORD + 1, 2 * _SCALE_WORD + 2, _ZERO_SLOTS[0])


class _BlockSource:
    """Reads blocks of a scene's rows as working arrays (rows in :data:`_LAYOUT` order).

    :meth:`take` gets the rows, :meth:`fill` splits them into attributes. When
    every column is a float32 field of one row-major buffer (a memory-mapped
    binary PLY, or a table from :func:`splatconv.model.lite_rows`), rows are
    taken whole (sliced, or gathered as one item each) and split by a few
    transposed copies of runs of adjacent fields, instead of 29 strided gathers.
    """

    def __init__(self, columns: dict):
        self.columns = [np.asarray(columns[name]) for name in _LAYOUT]
        self.fields = row_fields(self.columns)
        if self.fields is not None:
            matrix, self.fields = self.fields
            # One void item per row, to gather whole rows.
            self.rows = matrix.view(np.dtype((np.void, matrix.shape[1] * 4)))[:, 0]
        self._runs = {}

    def take(self, rows):
        """The rows ``rows`` (a slice or an ``(M,)`` index array), for :meth:`fill`."""
        if self.fields is None:
            return rows
        return self.rows[rows] if isinstance(rows, slice) else np.take(self.rows, rows)

    def fill(self, taken, out: np.ndarray, ranges, first: int = 0) -> None:
        """Copy attributes of taken rows into a working block.

        Parameters
        ----------
        taken : from :meth:`take`
        out : (K, M) float32 ndarray
            Row ``i - first`` receives working row ``i``.
        ranges : tuple of (lo, hi)
            Working rows to fill.
        first : int
            Working row of ``out[0]``.
        """
        if self.fields is None:
            with np.errstate(over="ignore", invalid="ignore"):  # float64 columns (outside the model)
                for lo, hi in ranges:
                    for i in range(lo, hi):
                        out[i - first] = self.columns[i][taken]
            return
        block = taken[:, None].view(np.float32)  # (M, W), strided like the source rows
        for lo, hi in ranges:
            for row, last, at in self._field_runs(lo, hi):
                np.copyto(out[row - first:last - first], block[:, at:at + last - row].T)

    def _field_runs(self, lo: int, hi: int) -> list:
        """Runs ``(first, last, at)``: working rows first:last are fields at:at + last - first."""
        if (lo, hi) not in self._runs:
            runs = []
            for i in range(lo, hi):
                f = self.fields[i]
                if runs and runs[-1][1] == i and runs[-1][2] + i - runs[-1][0] == f:
                    runs[-1][1] = i + 1
                else:
                    runs.append([i, i + 1, f])
            self._runs[lo, hi] = [tuple(r) for r in runs]
        return self._runs[lo, hi]


def _new_counts() -> WriteReport:
    """Counters in the order the notes list them: halves in slot order, colour, alpha."""
    return WriteReport(half={name: packing.HalfCounts() for _, name in _HALF_SLOTS},
                       clamped={"color": 0, "alpha": 0}, nan_bytes={"color": 0, "alpha": 0})


def _merge_counts(report: WriteReport, part: WriteReport) -> None:
    for name, c in part.half.items():
        report.half.setdefault(name, packing.HalfCounts()).add(c)
    for table, other in ((report.clamped, part.clamped), (report.nan_bytes, part.nan_bytes)):
        for name, count in other.items():
            table[name] = table.get(name, 0) + count


class _Scratch:
    """Working arrays reused block after block (for one thread).

    Temporaries of a few hundred kilobytes or more go through mmap and back on
    every allocation, and fresh pages are slow to touch (each one faults, and a
    virtual machine's host may fault again behind it); reusing a few buffers
    avoids both.
    """

    def __init__(self):
        self.buffers = {}

    def get(self, name: str, shape, dtype) -> np.ndarray:
        """An uninitialised array of ``shape`` and ``dtype``, the same memory on every call with ``name``."""
        dtype = np.dtype(dtype)
        size = math.prod(shape if isinstance(shape, tuple) else (shape,)) * dtype.itemsize
        buf = self.buffers.get(name)
        if buf is None or len(buf) < size:
            buf = self.buffers[name] = np.empty(size, dtype=np.uint8)
        return buf[:size].view(dtype).reshape(shape)


def _exp(values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """exp() in double of float32 values (any shape, strided is fine): ``float64`` ndarray."""
    with np.errstate(over="ignore", invalid="ignore"):
        return np.exp(values, out=out, dtype=np.float64)


def _exp_neg(values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """exp(-v) in double of float32 values: ``float64`` ndarray (sigmoid's exponential)."""
    with np.errstate(over="ignore", invalid="ignore"):
        out = np.negative(values, out=out, dtype=np.float64)
        return np.exp(out, out=out)


def _importance_parts(linear: np.ndarray, exp_neg_opacity: np.ndarray, logs: list, compat: bool,
                      counts: WriteReport, key: np.ndarray | None, parts: np.ndarray,
                      scratch: _Scratch) -> None:
    """What the scales and opacity give: the importance key, the scale halves, the alpha byte.

    Parameters
    ----------
    linear : (3, M) float64 ndarray
        exp(scale_0..2) (from :func:`_exp`).
    exp_neg_opacity : (M,) float64 ndarray
        exp(-opacity) (from :func:`_exp_neg`); overwritten.
    logs : list of 3 (M,) float32 ndarrays
        The log scales: a NaN logarithm is stored as itself, not as exp(NaN).
    compat : bool
        Model splaTV's JavaScript converter bit for bit instead of rounding.
    counts : WriteReport
        Counts are added to it (from :func:`_new_counts`).
    key : (M,) float64 ndarray or None
        Receives :func:`importance` of each row, from the same exponentials.
    parts : (M,) uint64 ndarray
        Receives, per row, the halves of exp(scale_0..2) in bits 0-47 (record
        words 5 and 6 as they are stored) and the alpha byte in bits 56-63: one
        value to gather per row in the output-order pass.
    scratch : _Scratch
    """
    m = linear.shape[1]
    with np.errstate(all="ignore"):  # hostile values overflow and give NaN by design
        # sigmoid(opacity) = 1 / (1 + exp(-opacity)), in double as splaTV's JS does.
        sig = exp_neg_opacity
        sig += 1.0
        np.divide(1.0, sig, out=sig)
        if key is not None:
            np.multiply(linear[0], linear[1], out=key)
            key *= linear[2]
            key *= sig
        linear32 = scratch.get("linear32", (3, m), np.float32)
        np.copyto(linear32, linear, casting="same_kind")  # rounded to float32, as the texture stores them
        halves = scratch.get("scale_halves", (3, m), np.uint16)
        _halves(linear32, _SCALES, dict(enumerate(logs)), halves, compat, counts, scratch)
        sig *= 255.0
        _unorm8_rows(sig[None], ("alpha",), compat, counts)
        np.copyto(parts, sig, casting="unsafe")
        parts <<= np.uint64(56)
        wide = scratch.get("wide", m, np.uint64)
        for i in range(3):
            np.copyto(wide, halves[i])
            wide <<= np.uint64(16 * i)
            parts |= wide


def _pack_records(block: np.ndarray, linear_trbf: np.ndarray, parts: np.ndarray, out: np.ndarray,
                  compat: bool, counts: WriteReport, scratch: _Scratch) -> None:
    """Pack a working block into records.

    Parameters
    ----------
    block : (len(_LAYOUT), M) float32 ndarray
        Model values, rows in :data:`_LAYOUT` order (the scale and opacity rows
        are not read; the trbf_scale row is overwritten).
    linear_trbf : (M,) float64 ndarray
        exp(trbf_scale).
    parts : (M,) uint64 ndarray
        Scale halves and alpha bytes from :func:`_importance_parts`.
    out : (M, 16) uint32 ndarray
        Every word is written.
    compat : bool
    counts : WriteReport
    scratch : _Scratch
    """
    m = block.shape[1]
    out16 = out.view(np.uint16)
    out8 = out.view(np.uint8)
    with np.errstate(all="ignore"):
        trbf = _ROW["trbf_scale"]
        log_trbf = scratch.get("log_trbf", m, np.float32)
        np.copyto(log_trbf, block[trbf])
        block[trbf] = linear_trbf  # rounded to float32, as the texture stores it
        halves = scratch.get("record_halves", (_N_RECORD_HALVES, m), np.uint16)
        _halves(block[:_N_RECORD_HALVES], _RECORD_HALVES, {trbf: log_trbf}, halves, compat, counts, scratch)
        for row, name in enumerate(_RECORD_HALVES):
            out16[:, _SLOT[name]] = halves[row]
        for slot in _ZERO_SLOTS:
            out16[:, slot] = 0
        wide = scratch.get("wide", m, np.uint64)
        np.copyto(out[:, _SCALE_WORD], parts, casting="unsafe")  # the low 32 bits: scale_0, scale_1
        np.right_shift(parts, np.uint64(32), out=wide)
        wide &= np.uint64(0xFFFF)
        np.copyto(out[:, _SCALE_WORD + 1], wide, casting="unsafe")  # scale_2, zero
        np.right_shift(parts, np.uint64(56), out=wide)
        np.copyto(out8[:, _COLOR_BYTE + 3], wide, casting="unsafe")  # alpha

        position = block[_POSITION_ROWS].view(np.uint32)
        if compat:
            # The browser reads positions through DataView.getFloat32 into a double,
            # which quiets signalling NaNs (sets the top mantissa bit).
            nan = np.isnan(block[_POSITION_ROWS])
            if nan.any():
                position = np.where(nan, position | np.uint32(0x00400000), position)
        for w in POSITION_WORDS:
            out[:, w] = position[w]

        scaled = scratch.get("color", (3, m), np.float64)
        np.multiply(block[_COLOR_ROWS], 255.0, out=scaled, dtype=np.float64)
        _unorm8_rows(scaled, ("color",) * 3, compat, counts)
        for channel in range(3):
            np.copyto(out8[:, _COLOR_BYTE + channel], scaled[channel], casting="unsafe")


def _halves(values: np.ndarray, names: tuple, logs: dict, out: np.ndarray, compat: bool,
            counts: WriteReport, scratch: _Scratch | None = None) -> None:
    """Half bits of working rows, exact where the fast path flags, counted per attribute.

    Parameters
    ----------
    values : (K, M) float32 ndarray, C-contiguous
        What to store (linear values for the exp() attributes).
    names : tuple of K str
    logs : dict of int to (M,) float32 ndarray
        For the rows of exp() attributes, the logarithms: a NaN logarithm is
        stored as itself (payload kept), not as exp(NaN).
    out : (K, M) uint16 ndarray, C-contiguous
    compat : bool
    counts : WriteReport
    scratch : _Scratch, optional
    """
    k, m = values.shape
    # A few rows at a time: the fast path's temporaries stay small.
    step = max(1, _HALF_GROUP // m)
    flagged = []
    for r in range(0, k, step):
        group = values[r:r + step]
        work = None if scratch is None else scratch.get("half", packing.scratch_size(group.size), np.uint32)
        found = np.flatnonzero(packing.float_to_half_into(group, out[r:r + step], splatvjs=compat, scratch=work))
        if len(found):
            flagged.append(found + r * m)
    if not flagged:
        return
    flagged = np.concatenate(flagged)
    # The flagged few (zeros, tiny, huge, non-finite) of all rows in one go:
    # the cost per block stays constant however many rows have some.
    flat = out.reshape(-1)
    picked = values.reshape(-1)[flagged]
    bits = picked.view(np.uint32)
    zero = (bits & np.uint32(0x7FFFFFFF)) == 0
    if zero.any():
        # +-0 is flagged only for the fast path's sake: it is exact and counts nothing.
        flat[flagged[zero]] = (bits[zero] >> np.uint32(16)).astype(np.uint16)
        flagged, picked = flagged[~zero], picked[~zero]
        if not len(flagged):
            return
    rows, cols = np.divmod(flagged, values.shape[1])
    nan_at, nan_logs = [], []
    for row, log in logs.items():
        at = np.flatnonzero(rows == row)
        raw = log[cols[at]]
        nan = np.isnan(raw)
        nan_at.append(at[nan])
        nan_logs.append(raw[nan])
    nan_at = np.concatenate(nan_at) if nan_at else np.zeros(0, np.intp)
    nan_logs = np.concatenate(nan_logs) if nan_logs else np.zeros(0, np.float32)
    if compat:
        picked[nan_at] = nan_logs
    half, overflow, underflow, nonfinite = packing.float_to_half_exact(picked, splatvjs=compat)
    if not compat and len(nan_at):
        half[nan_at] = packing.float_to_half_exact(nan_logs)[0]
    flat[flagged] = half
    for what, mask in (("overflow", overflow), ("underflow", underflow), ("nonfinite", nonfinite)):
        per_row = np.bincount(rows[mask], minlength=len(names))
        for row in np.flatnonzero(per_row):
            c = counts.half[names[row]]
            setattr(c, what, getattr(c, what) + int(per_row[row]))


def _unorm8_rows(scaled: np.ndarray, names: tuple, compat: bool, counts: WriteReport) -> None:
    """Colour or alpha (x255, ``(K, M) float64``) -> byte values in place, counting clamps and NaN.

    Same results as :func:`packing.unorm8_nearest` / :func:`packing.unorm8_truncate`
    (whose float -> uint8 cast the caller does): a row whose minimum and maximum
    lie in [0, 255] (so no NaN) needs no clamping and adds no counts.
    """
    low, high = scaled.min(axis=1), scaled.max(axis=1)
    for row, name in enumerate(names):
        if low[row] >= 0 and high[row] <= 255:
            continue
        v = scaled[row]
        nan = np.isnan(v)
        counts.clamped[name] += int(np.count_nonzero((v < 0) | (v > 255)))
        counts.nan_bytes[name] += int(np.count_nonzero(nan))
        v[nan] = 0.0
        np.clip(v, 0.0, 255.0, out=v)
    if not compat:
        np.rint(scaled, out=scaled)
    # compat truncates, which the float -> uint8 cast does for values in [0, 255].


def pack_block(cols: dict, compat: bool, report: WriteReport) -> np.ndarray:
    """Pack a block of rows into texture records.

    Parameters
    ----------
    cols : dict of str to (M,) float32 ndarray
        One block of every model column.
    compat : bool
        Model splaTV's JavaScript converter bit for bit instead of rounding.
    report : WriteReport
        Counts are added to it.

    Returns
    -------
    (M, 16) uint32 ndarray
    """
    m = len(cols["x"])
    block = np.empty((len(_LAYOUT), m), dtype=np.float32)
    source = _BlockSource(cols)
    source.fill(source.take(slice(0, m)), block, ((0, len(_LAYOUT)),))
    counts = _new_counts()
    scratch = _Scratch()
    parts = np.empty(m, dtype=np.uint64)
    scales = block[_SCALE_ROWS]
    _importance_parts(_exp(scales), _exp_neg(block[_OPACITY_ROW]), list(scales), compat, counts, None, parts,
                      scratch)
    out = np.empty((m, WORDS_PER_SPLAT), dtype="<u4")
    _pack_records(block, _exp(block[_ROW["trbf_scale"]]), parts, out, compat, counts, scratch)
    _merge_counts(report, counts)
    return out


def header_bytes(count: int, cameras: list) -> bytes:
    """The preamble and JSON header for a file of ``count`` splats."""
    texheight = texture_height(count)
    chunk = {
        "type": "splat",
        "size": TEXWIDTH * texheight * 16,
        "texwidth": TEXWIDTH,
        "texheight": texheight,
        "cameras": cameras,
    }
    text = json.dumps([chunk], separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
    return PREAMBLE.pack(MAGIC, len(text)) + text


class _Plan:
    """A scene's records in output order, packed a block at a time.

    The constructor runs the input-order pass (importance key, scale halves and
    alpha bytes; centres for a framing camera), sorts and frames; :meth:`blocks`
    then packs the records in output order.

    Threads: blocks are independent, so helper threads pack them side by side
    while the calling thread writes finished ones (numpy and file writes release
    the GIL). Blocks are large because handing the GIL over costs about as much
    as a short numpy call: threads that make many short calls run no faster
    than one. Working arrays are per thread and reused, and record blocks come
    from a ring: fresh memory is slow to touch on some machines.
    """

    def __init__(self, scene: Scene, compat: bool, sort: str | None, camera: bool, report: WriteReport,
                 helpers, *, streaming: bool = True):
        n = scene.count
        self.n = n
        self.compat = compat
        self.helpers = helpers
        self.source = _BlockSource(scene.columns)
        self.sorted = (sort or "importance") != "none"
        self.key = np.empty(n, dtype=np.float64) if self.sorted else None
        self.parts = np.empty(n, dtype=np.uint64) if self.sorted else None
        self.xyz = np.empty((3, n), dtype=np.float32) if camera else None
        self.order = None
        self.cameras = None
        self.local = threading.local()
        # Blocks in flight on the helpers; a record block's ring slot is reused
        # once the caller is done with it.
        self.ahead = 2 * WORKERS if helpers is not None else 0
        self.outs = [None] * (self.ahead + 1) if streaming else None
        if self.sorted or camera:
            for counts in self._ahead(self._key_block, range(0, n, KEY_BLOCK)):
                _merge_counts(report, counts)
        if camera:
            report.notes.append("no cameras given; wrote one camera that frames the scene")
            camera_job = self._run(self._frame)  # its three sorts, while this thread sorts the keys
        if self.sorted:
            key = self.key
            if compat:
                # splaTV keeps the key in a Float32Array and sorts with (b, a) => s[a] - s[b].
                with np.errstate(over="ignore"):
                    key = key.astype(np.float32)
                nan = int(np.count_nonzero(np.isnan(key)))
                if nan:
                    report.notes.append(
                        f"{nan} splats have a NaN importance; splaTV's comparator makes their order "
                        "engine-defined, splatconv puts them last")
            # The key's memory becomes the order's.
            self.order = _importance_order(key, self.key.view(np.uint64), self._key_of)
            self.key = None
        if camera:
            self.cameras = [camera_job()]

    def _run(self, fn, *args):
        """Run ``fn`` on a helper (or now, without one); returns a callable giving its result."""
        if self.helpers is None:
            result = fn(*args)
            return lambda: result
        return self.helpers.submit(fn, *args).result

    def _ahead(self, fn, starts):
        """Yield ``fn(start)`` for each start in order, helpers up to ``self.ahead`` blocks ahead.

        When ``fn`` starts on a block, the caller is done with every block
        ``self.ahead + 1`` or more before it.
        """
        if self.helpers is None:
            yield from map(fn, starts)
            return
        pending = deque()
        for start in starts:
            pending.append(self.helpers.submit(fn, start))
            if len(pending) > self.ahead:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()

    def _scratch(self) -> _Scratch:
        """This thread's working arrays."""
        scratch = getattr(self.local, "scratch", None)
        if scratch is None:
            scratch = self.local.scratch = _Scratch()
        return scratch

    def _key_of(self, rows: np.ndarray) -> np.ndarray:
        """:func:`importance` of some rows, computed again from the scene (the same bits)."""
        columns = self.source.columns
        return importance({name: columns[_ROW[name]][rows] for name in (*_SCALES, "opacity")})

    def _frame(self) -> dict:
        return camera_for_box(*framing_box(*self.xyz, overwrite_input=True))

    def _rows(self, start: int, size: int) -> slice:
        return slice(start, min(start + size, self.n))

    def _key_block(self, start: int) -> WriteReport:
        """Input-order pass over one block: key, scale halves and alpha bytes; centres."""
        rows = self._rows(start, KEY_BLOCK)
        m = rows.stop - rows.start
        scratch = self._scratch()
        counts = _new_counts()
        # Working rows scale_0 .. z only (the block's first row is scale_0).
        lo = _SCALE_ROWS.start if self.sorted else _POSITION_ROWS.start
        hi = _POSITION_ROWS.stop if self.xyz is not None else _OPACITY_ROW + 1
        block = scratch.get("block", (hi - lo, m), np.float32)
        self.source.fill(self.source.take(rows), block, ((lo, hi),), first=lo)
        if self.xyz is not None:
            self.xyz[:, rows] = block[_POSITION_ROWS.start - lo:]
        if self.sorted:
            scales = block[:3]
            linear = _exp(scales, out=scratch.get("linear", (3, m), np.float64))
            exp_neg = _exp_neg(block[_OPACITY_ROW - lo], out=scratch.get("exp_neg", m, np.float64))
            _importance_parts(linear, exp_neg, list(scales), self.compat, counts, self.key[rows],
                              self.parts[rows], scratch)
        return counts

    def _record_block(self, start: int, out: np.ndarray | None = None):
        """Output records ``start:start + BLOCK``, ``(M, 16) uint32`` (into ``out`` or a ring slot), and counts."""
        rows = self._rows(start, BLOCK)
        m = rows.stop - rows.start
        if out is None:
            slot = (start // BLOCK) % len(self.outs)
            if self.outs[slot] is None:
                self.outs[slot] = np.empty((BLOCK, WORDS_PER_SPLAT), dtype="<u4")
            out = self.outs[slot][:m]
        scratch = self._scratch()
        counts = _new_counts()
        block = scratch.get("block", (len(_LAYOUT), m), np.float32)
        if self.sorted:
            rows = self.order[rows]
            if self.source.fields is not None:
                # mode="clip": with mode="raise" (the default) numpy buffers ``out``.
                taken = np.take(self.source.rows, rows, out=scratch.get("rows", m, self.source.rows.dtype),
                                mode="clip")
            else:
                taken = rows
            self.source.fill(taken, block, ((0, _N_RECORD_HALVES), (_POSITION_ROWS.start, len(_LAYOUT))))
            parts = np.take(self.parts, rows, out=scratch.get("parts", m, np.uint64), mode="clip")
        else:
            self.source.fill(self.source.take(rows), block, ((0, len(_LAYOUT)),))
            scales = block[_SCALE_ROWS]
            parts = scratch.get("parts", m, np.uint64)
            _importance_parts(_exp(scales, out=scratch.get("linear", (3, m), np.float64)),
                              _exp_neg(block[_OPACITY_ROW], out=scratch.get("exp_neg", m, np.float64)),
                              list(scales), self.compat, counts, None, parts, scratch)
        linear_trbf = _exp(block[_ROW["trbf_scale"]], out=scratch.get("trbf", m, np.float64))
        _pack_records(block, linear_trbf, parts, out, self.compat, counts, scratch)
        return out, counts

    def blocks(self, report: WriteReport):
        """Yield ``(M, 16) uint32`` record blocks in output order, adding their counts to ``report``.

        A yielded block's memory is reused once the next one is asked for.
        """
        for out, counts in self._ahead(self._record_block, range(0, self.n, BLOCK)):
            _merge_counts(report, counts)
            yield out

    def into(self, records: np.ndarray, report: WriteReport) -> None:
        """Pack every record into ``records`` (``(N, 16) uint32``), adding the counts to ``report``."""
        def job(start):
            return self._record_block(start, records[start:min(start + BLOCK, self.n)])[1]

        for counts in self._ahead(job, range(0, self.n, BLOCK)):
            _merge_counts(report, counts)


def _helpers(n: int):
    """Helper threads when there is more than one block to pack, else None."""
    return ThreadPoolExecutor(max_workers=WORKERS) if n > BLOCK and WORKERS > 1 else None


def write(scene: Scene, stream, *, compat: str | None = None, sort: str | None = "importance") -> WriteReport:
    """Write ``scene`` to a binary stream as ``.splatv``.

    Parameters
    ----------
    scene : Scene
    stream : binary file object
    compat : {None, "splatv-js"}
        ``"splatv-js"``: texture bytes identical to splaTV's in-browser converter.
    sort : {"importance", "none"}
        Order records by importance, largest first, or keep the input order.

    Returns
    -------
    WriteReport
    """
    n = scene.count
    if n == 0:
        raise UnsupportedError("no splats to write; the viewer cannot show an empty texture")
    is_compat = compat == "splatv-js"
    report = WriteReport(count=n, texheight=texture_height(n))
    helpers = _helpers(n)
    try:
        plan = _Plan(scene, is_compat, sort, not scene.cameras, report, helpers)
        stream.write(header_bytes(n, plan.cameras or scene.cameras))
        for block in plan.blocks(report):
            stream.write(memoryview(block))
    finally:
        if helpers is not None:
            helpers.shutdown(cancel_futures=True)
    padding = report.texheight * SPLATS_PER_ROW - n
    stream.write(bytes(padding * RECORD_BYTES))
    report.notes.extend(_write_notes(report, is_compat))
    return report


def encode(scene: Scene, *, compat: str | None = None, sort: str | None = "importance"):
    """The texture a write would produce, in memory (for rendering).

    Returns
    -------
    records : (texheight * 1024, 16) uint32 ndarray
        Padding records included, all zero.
    report : WriteReport
    """
    is_compat = compat == "splatv-js"
    n = scene.count
    report = WriteReport(count=n, texheight=texture_height(n))
    records = np.empty((report.texheight * SPLATS_PER_ROW, WORDS_PER_SPLAT), dtype="<u4")
    records[n:] = 0
    helpers = _helpers(n)
    try:
        _Plan(scene, is_compat, sort, False, report, helpers, streaming=False).into(records, report)
    finally:
        if helpers is not None:
            helpers.shutdown(cancel_futures=True)
    report.notes.extend(_write_notes(report, is_compat))
    return records, report


def _write_notes(report: WriteReport, compat: bool) -> list:
    notes = []
    for name, c in report.half.items():
        if c.overflow:
            what = "became infinity (splaTV's converter)" if compat else "saturated to +-65504"
            notes.append(f"{name}: {c.overflow} values past the half-float range {what}")
        if c.underflow:
            notes.append(f"{name}: {c.underflow} nonzero values became zero")
    for key, count in report.clamped.items():
        if count:
            notes.append(f"{key}: {count} values outside [0, 1] clamped")
    for key, count in report.nan_bytes.items():
        if count:
            notes.append(f"{key}: {count} NaN values written as 0")
    return notes


# --------------------------------------------------------------------------
# Reading


def _reject_constant(name):
    raise ValueError(f"{name} is not allowed in strict JSON")


def _is_count(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


def read_header(f, path: str, file_size: int) -> tuple[list, int]:
    """Read and check the preamble and JSON header.

    Returns
    -------
    chunks : list of dict
    data_offset : int
        File offset of the first chunk's bytes.
    """
    if file_size < PREAMBLE.size:
        raise FormatError(f"{file_size} bytes is too short for a .splatv file (8-byte preamble)", path)
    magic, json_len = PREAMBLE.unpack(f.read(PREAMBLE.size))
    if magic != MAGIC:
        raise FormatError(f"not a .splatv file: magic 0x{magic:08x}, expected 0x{MAGIC:08x}", path)
    if json_len > MAX_JSON_BYTES:
        raise FormatError(f"header declares {json_len} bytes of JSON, more than the {MAX_JSON_BYTES} allowed", path)
    if PREAMBLE.size + json_len > file_size:
        raise FormatError(f"header declares {json_len} bytes of JSON but the file ends after "
                          f"{file_size - PREAMBLE.size}", path)
    raw = f.read(json_len)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise FormatError(f"header JSON is not UTF-8 (byte {e.start})", path) from None
    try:
        chunks = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as e:
        raise FormatError(f"header JSON: {e.msg} (line {e.lineno}, column {e.colno})", path) from None
    except ValueError as e:
        raise FormatError(f"header JSON: {e}", path) from None
    if not isinstance(chunks, list):
        raise FormatError("header JSON must be an array of chunks", path)
    for i, chunk in enumerate(chunks):
        if not isinstance(chunk, dict):
            raise FormatError("expected an object", path, (f"chunk {i}",))
        if not isinstance(chunk.get("type"), str):
            raise FormatError("'type' must be a string", path, (f"chunk {i}",))
        if not _is_count(chunk.get("size")):
            raise FormatError(f"'size' must be a non-negative integer, got {chunk.get('size')!r}",
                              path, (f"chunk {i}",))
    return chunks, PREAMBLE.size + json_len


def _check_splat_chunk(chunk: dict, path: str, where: tuple) -> None:
    if chunk.get("texwidth") != TEXWIDTH or isinstance(chunk.get("texwidth"), bool):
        raise FormatError(f"'texwidth' is {chunk.get('texwidth')!r}; the viewer's shader needs {TEXWIDTH}",
                          path, where)
    texheight = chunk.get("texheight")
    if not _is_count(texheight):
        raise FormatError(f"'texheight' must be a non-negative integer, got {texheight!r}", path, where)
    if texheight > MAX_TEXHEIGHT:
        raise FormatError(f"'texheight' {texheight} is past the largest texture any GPU takes ({MAX_TEXHEIGHT})",
                          path, where)
    expected = TEXWIDTH * texheight * 16
    if chunk["size"] != expected:
        raise FormatError(f"'size' is {chunk['size']} but texwidth*texheight*16 is {expected}", path, where)
    cameras = chunk.get("cameras", [])
    try:
        validate_cameras(cameras, path)
    except Exception as e:
        raise FormatError(e.message, path, where + ("cameras",) + e.where) from None


def read_records(path: str | os.PathLike):
    """Read the raw texture records of a ``.splatv`` file.

    Returns
    -------
    records : (count, 16) uint32 ndarray
        Records up to the last one that is not all zero.
    chunk : dict
        The splat chunk's header object.
    meta : dict
        Sizes and chunk list for ``info``.
    notes : list of str
    """
    path = os.fspath(path)
    notes = []
    try:
        f = open(path, "rb")
    except OSError as e:
        raise FormatError(f"cannot open: {e.strerror}", path) from None
    with f:
        file_size = os.fstat(f.fileno()).st_size
        chunks, offset = read_header(f, path, file_size)
        splat = None
        skipped = []
        for i, chunk in enumerate(chunks):
            if splat is None and offset + chunk["size"] > file_size and chunk["type"] != "splat":
                raise FormatError(f"declares {chunk['size']} bytes but the file ends {file_size - offset} "
                                  "bytes after its start, before any splat chunk", path,
                                  (f"chunk {i} ({chunk['type']!r})",))
            if chunk["type"] == "splat" and splat is None:
                _check_splat_chunk(chunk, path, (f"chunk {i}",))
                splat = (i, chunk, offset)
            else:
                skipped.append({"type": chunk["type"], "size": chunk["size"]})
            offset += chunk["size"]
        if splat is None:
            raise FormatError("header has no 'splat' chunk", path)
        index, chunk, start = splat
        declared = chunk["size"]
        actual = max(0, min(declared, file_size - start))
        if actual < declared:
            notes.append(f"texture data is {declared - actual} bytes shorter than the {declared} declared "
                         "(the writer did not pad); the rest is read as zeros")
        if offset < file_size:
            notes.append(f"{file_size - offset} bytes after the last chunk ignored")
        n_records = -(-actual // RECORD_BYTES)
        # np.empty, not np.zeros: the read fills every page once; only a partial
        # last record needs zeros.
        buf = np.empty(n_records * WORDS_PER_SPLAT, dtype="<u4")
        raw = memoryview(buf).cast("B")
        f.seek(start)
        got = f.readinto(raw[:actual])
        if got != actual:  # pragma: no cover - the file changed under us
            raise FormatError(f"read {got} of {actual} texture bytes", path)
        raw[actual:] = bytes(len(raw) - actual)
    records = buf.reshape(-1, WORDS_PER_SPLAT)
    count = _records_used(records)
    if skipped:
        notes.append(f"skipped {len(skipped)} chunk(s) of other types: "
                     + ", ".join(sorted({c['type'] for c in skipped})))
    meta = {
        "texwidth": chunk["texwidth"],
        "texheight": chunk["texheight"],
        "declared_bytes": declared,
        "actual_bytes": actual,
        "chunks": [{"type": c["type"], "size": c["size"]} for c in chunks],
        "file_bytes": file_size,
    }
    return records[:count], chunk, meta, notes


def _records_used(records: np.ndarray) -> int:
    """Records up to the last one that is not all zero, ``records`` being ``(N, 16) uint32``.

    Searches back from the end in growing steps: the zero padding is at most a
    texture row in files splatconv writes, so this rarely reads more than that.
    """
    words = records.reshape(len(records), -1)
    stop = len(words)
    step = SPLATS_PER_ROW
    while stop > 0:
        start = max(0, stop - step)
        used = np.flatnonzero(words[start:stop].any(axis=1))
        if len(used):
            return start + int(used[-1]) + 1
        stop = start
        step *= 2
    return 0


#: Half patterns that are negative numbers (not NaN): no logarithm for an exp() slot.
_NEGATIVE_HALF = ((np.arange(1 << 16) & 0x8000) != 0) & ~np.isnan(packing.HALF_TO_FLOAT)
_NEGATIVE_HALF.flags.writeable = False


def decode_records(records: np.ndarray) -> tuple[dict, list]:
    """Texture records -> model columns, the exact inverse of the default writer.

    Parameters
    ----------
    records : (N, 16) uint32 ndarray

    Returns
    -------
    columns : dict of str to (N,) float32 ndarray
        Views of one table in the lite PLY row layout (see
        :func:`splatconv.model.lite_rows`), which the PLY writer writes whole.
    notes : list of str
        Values the lite PLY layout cannot hold (negative values in exp() slots,
        data in the unused halves).
    """
    n = len(records)
    _rows, cols = lite_rows(n)
    stray = dict.fromkeys(HALF_WORDS, 0)
    negative = dict.fromkeys(EXP_ATTRIBUTES, 0)
    values = np.empty(min(n, BLOCK), dtype=np.float32)  # one temporary, reused for every column
    # A block of rows at a time: the table's rows stay in cache while each of
    # their 29 fields is written.
    for start in range(0, n, BLOCK):
        block = records[start:start + BLOCK]
        rows = slice(start, start + len(block))
        out = values[:len(block)]
        for w, name in POSITION_WORDS.items():
            cols[name][rows] = block[:, w].view(np.float32)
        for w, (lo_name, hi_name) in HALF_WORDS.items():
            lo, hi = packing.unpack_half2(block[:, w])
            for name, h in ((lo_name, lo), (hi_name, hi)):
                if name is None:
                    stray[w] += int(np.count_nonzero(h))
                    continue
                table = packing.HALF_TO_FLOAT
                if name in EXP_ATTRIBUTES:
                    negative[name] += int(np.count_nonzero(_NEGATIVE_HALF[h]))
                    table = LOG_OF_HALF
                cols[name][rows] = np.take(table, h, out=out, mode="clip")
        r, g, b, a = packing.unpack_rgba8(block[:, COLOR_WORD])
        for i, byte in enumerate((r, g, b)):
            cols[f"f_dc_{i}"][rows] = np.take(COLOR_OF_BYTE, byte, out=out, mode="clip")
        cols["opacity"][rows] = np.take(LOGIT_OF_BYTE, a, out=out, mode="clip")
    notes = []
    for w, (lo_name, hi_name) in HALF_WORDS.items():
        for name in (lo_name, hi_name):
            if name is None and stray[w]:
                notes.append(f"word {w}: {stray[w]} records carry data in the unused upper half; dropped")
            elif name in EXP_ATTRIBUTES and negative[name]:
                notes.append(f"{name}: {negative[name]} negative values have no logarithm; written as "
                             "NaN (-0 as -inf)")
    return cols, notes


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a ``.splatv`` file into a :class:`Scene`.

    Texture data shorter than declared is padded with zeros (noted once); the
    splat count excludes trailing all-zero records. NaN, infinities, subnormal
    halves and zero scales are read as they are.
    """
    records, chunk, meta, notes = read_records(path)
    columns, decode_notes = decode_records(records)
    meta["records"] = int(records.shape[0])
    return Scene(columns=columns, cameras=list(chunk.get("cameras", [])), variant="splatv",
                 meta=meta, notes=notes + decode_notes)
