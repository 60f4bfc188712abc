"""The ``.splatv`` writer's engine: records packed a block of rows at a time, by threads.

:mod:`splatconv.formats.splatv_layout` says what a record holds; this module
makes the records, sorted, fast (``bench/bench_convert.py`` measures it; the
measurements behind each choice are in ``bench/README.md``). What a reader
needs to change it:

* Work in the record's own layout. A block of input rows is copied, a few runs
  of adjacent fields at a time, into a working block ``W`` of float32 columns,
  one per half slot of the record from word 3 on (26 a row). One flat float ->
  half conversion of ``W`` gives the record's last 52 bytes as stored; the
  position words come straight from the input, the colour word is made beside.
* Few, long numpy calls: threads hand the GIL over at every call, so blocks are
  large; the half conversion runs on groups of rows small enough for a cache.
* Reuse memory: working arrays (:class:`Scratch`) belong to a thread and are
  reused block after block; output blocks come from a ring.
* Exponentials on contiguous values only, so that every row gets numpy's same
  SIMD ``exp`` (a strided loop may use another implementation, whose last bit
  can differ): the byte-identical mode depends on it.

Sorted output takes two passes: one in input order for the importance key,
then, after the sort, one in output order that gathers each block's rows from
the input, packs them and hands them to the writing thread. Drivers:
:class:`Plan` with :func:`helpers`, :func:`prepare`, then :func:`blocks` (a
stream) or :func:`into` (an array).
"""

from __future__ import annotations

import math
import os
import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import packing
from ..cameras import camera_for_box, framing_box
from ..model import COLUMNS, row_fields
from ..viewer import importance, importance_order_into
from .base import WriteReport
from .splatv_layout import COLOR_WORD, EXP_ATTRIBUTES, HALF_WORDS, LOG_OF_HALF, POSITION_WORDS, WORDS_PER_SPLAT

#: Rows packed at a time: long numpy calls, few GIL hand-overs.
BLOCK = 1 << 14
#: Rows of the input-order (importance key) pass at a time.
KEY_BLOCK = 1 << 16
#: Rows of a block converted to halves at a time: the conversion's temporaries
#: (three uint32 per value) stay in a core's cache.
HALF_ROWS = 1 << 11
#: Packing threads (the calling thread writes meanwhile). More only add GIL
#: hand-overs: two beat three even on two cores (medians of interleaved runs).
WORKERS = max(1, min(os.cpu_count() or 2, 2))

# --------------------------------------------------------------------------
# The working layouts, derived from the record layout.

#: Half slots of a record (two per word).
SLOTS = 2 * WORDS_PER_SPLAT
#: Half slot -> attribute it stores (None: position, colour or an unused zero half).
SLOT_NAMES = [None] * SLOTS
for _w, _pair in HALF_WORDS.items():
    for _k, _name in enumerate(_pair):
        SLOT_NAMES[2 * _w + _k] = _name
#: The working block covers the slots from the first half word to the end of
#: the record: the position words come first, in the record and in the model.
_FIRST = 2 * min(HALF_WORDS)
_WIDTH = SLOTS - _FIRST
_POSITIONS = tuple(POSITION_WORDS[w] for w in range(min(HALF_WORDS)))
#: Working column -> attribute whose half it holds (None: always zero; the
#: colour word's two slots are overwritten).
_W_NAMES = SLOT_NAMES[_FIRST:]
_W_COLUMN = {name: j for j, name in enumerate(_W_NAMES) if name is not None}
#: The exp() attributes: logarithms in, linear values into ``W``.
_EXP_NAMES = tuple(name for name in SLOT_NAMES if name in EXP_ATTRIBUTES)
#: The values the exponentials are taken of, per row: -opacity then the logs.
_EXPONENTS = ("opacity",) + _EXP_NAMES
#: Colour and opacity, per row (opacity becomes alpha in place).
_RGBA = ("f_dc_0", "f_dc_1", "f_dc_2", "opacity")
#: What the importance key reads, per row.
KEY_COLUMNS = ("opacity", "scale_0", "scale_1", "scale_2")
#: Names of the half attributes in slot order, as reports list them.
HALF_NAMES = tuple(name for name in SLOT_NAMES if name is not None)


def new_counts() -> WriteReport:
    """Counters in the order the notes list them: halves in slot order, colour, alpha."""
    return WriteReport(half={name: packing.HalfCounts() for name in HALF_NAMES},
                       clamped={"color": 0, "alpha": 0}, nan_bytes={"color": 0, "alpha": 0})


def merge_counts(report: WriteReport, part: WriteReport) -> None:
    """Add a block's counts to ``report``."""
    for name, c in part.half.items():
        report.half.setdefault(name, packing.HalfCounts()).add(c)
    for table, other in ((report.clamped, part.clamped), (report.nan_bytes, part.nan_bytes)):
        for name, count in other.items():
            table[name] = table.get(name, 0) + count


# --------------------------------------------------------------------------
# Reading blocks of rows


def _runs(pairs) -> list:
    """Group ``(destination column, source field)`` pairs into runs adjacent in both.

    Returns a list of ``(destination start, source start, length)``.
    """
    runs = []
    for dst, src in sorted(pairs):
        if runs and runs[-1][0] + runs[-1][2] == dst and runs[-1][1] + runs[-1][2] == src:
            runs[-1][2] += 1
        else:
            runs.append([dst, src, 1])
    return [tuple(r) for r in runs]


def _copy_runs(dst: np.ndarray, src: np.ndarray, runs) -> None:
    """Copy column runs between ``(M, *)`` float32 arrays whose rows are contiguous.

    A run of several columns moves as one item per row (a void view), which
    costs about what one column does.
    """
    for d, s, k in runs:
        if k == 1:
            np.copyto(dst[:, d], src[:, s])
        else:
            item = np.dtype((np.void, 4 * k))
            np.copyto(dst[:, d:d + k].view(item)[:, 0], src[:, s:s + k].view(item)[:, 0])


class RowSource:
    """Blocks of a scene's rows as ``(M, F)`` float32 arrays, and where each attribute is in them.

    When every column is a float32 field of one row-major buffer (a
    memory-mapped binary PLY, or a table from :func:`splatconv.model.lite_rows`),
    a block is a slice of that buffer, or its rows gathered whole. Otherwise the
    columns are copied into a block laid out as :data:`splatconv.model.COLUMNS`.
    """

    def __init__(self, columns: dict):
        self.columns = [np.asarray(columns[name]) for name in COLUMNS]
        found = row_fields(self.columns)
        if found is not None:
            self.matrix, fields = found
            # One void item per row, to gather whole rows.
            self.items = self.matrix.view(np.dtype((np.void, self.matrix.shape[1] * 4)))[:, 0]
        else:
            self.matrix = None
            fields = range(len(COLUMNS))
        self.field = dict(zip(COLUMNS, fields))
        self.width = self.matrix.shape[1] if self.matrix is not None else len(COLUMNS)
        # Runs from a block into the working arrays, and into the position words.
        self.w_runs = _runs((_W_COLUMN[name], self.field[name]) for name in _W_COLUMN
                            if name not in EXP_ATTRIBUTES)
        self.position_runs = _runs((w, self.field[name]) for w, name in enumerate(_POSITIONS))
        self.exp_runs = _runs((i, self.field[name]) for i, name in enumerate(_EXPONENTS))
        self.rgba_runs = _runs((i, self.field[name]) for i, name in enumerate(_RGBA))

    @property
    def rows_whole(self) -> bool:
        """Whether blocks come from one row buffer (see the class docstring)."""
        return self.matrix is not None

    def block(self, rows, scratch: "Scratch") -> np.ndarray:
        """The rows ``rows`` (a slice, or an ``(M,)`` index array): ``(M, F)`` float32."""
        if self.matrix is not None:
            if isinstance(rows, slice):
                return self.matrix[rows]
            m = len(rows)
            # mode="clip": with mode="raise" (the default) numpy buffers ``out``.
            taken = np.take(self.items, rows, out=scratch.get("rows", m, self.items.dtype), mode="clip")
            return taken[:, None].view(np.float32)
        m = len(range(*rows.indices(len(self.columns[0])))) if isinstance(rows, slice) else len(rows)
        block = scratch.get("rows", (m, self.width), np.float32)
        with np.errstate(over="ignore", invalid="ignore"):  # float64 columns built outside the model
            for i, col in enumerate(self.columns):
                block[:, i] = col[rows]
        return block

    def column(self, name: str, rows) -> np.ndarray:
        """One attribute of some rows (a copy or a view): ``(M,)``."""
        return self.columns[COLUMNS.index(name)][rows]


class Scratch:
    """Working arrays reused block after block (for one thread).

    Temporaries of a few hundred kilobytes or more go through mmap and back on
    every allocation, and fresh pages are slow to touch; reusing a few buffers
    avoids both.
    """

    def __init__(self):
        self.buffers = {}

    def get(self, name: str, shape, dtype, zero: bool = False) -> np.ndarray:
        """An array of ``shape`` and ``dtype``, the same memory on every call with ``name``.

        Uninitialised, or zeros when first made with ``zero`` (callers keep
        some columns zero by never writing them).
        """
        dtype = np.dtype(dtype)
        size = math.prod(shape if isinstance(shape, tuple) else (shape,)) * dtype.itemsize
        buf = self.buffers.get(name)
        if buf is None or len(buf) < size:
            buf = self.buffers[name] = (np.zeros if zero else np.empty)(size, dtype=np.uint8)
        return buf[:size].view(dtype).reshape(shape)


# --------------------------------------------------------------------------
# Packing one block


def pack_rows(source: RowSource, rows, out: np.ndarray, compat: bool, counts: WriteReport, scratch: Scratch) -> None:
    """Pack the records of some rows.

    Parameters
    ----------
    source : RowSource
    rows : slice or (M,) intp ndarray
        The rows, in output order.
    out : (M, 16) uint32 ndarray, C-contiguous
        Every word is written.
    compat : bool
        Model splaTV's JavaScript converter bit for bit instead of rounding.
    counts : WriteReport
        Counts are added to it (from :func:`new_counts`).
    scratch : Scratch
    """
    block = source.block(rows, scratch)
    m = len(block)
    if not m:
        return
    work = scratch.get("work", (m, _WIDTH), np.float32, zero=True)
    _copy_runs(work, block, source.w_runs)
    logs = scratch.get("logs", (m, len(_EXPONENTS)), np.float32)
    _copy_runs(logs, block, source.exp_runs)
    rgba = scratch.get("rgba", (m, 4), np.float32)
    _copy_runs(rgba, block, source.rgba_runs)

    # Exponentials in double, rounded to float32 as the texture stores them
    # (splaTV's JavaScript does the same arithmetic in double).
    wide = scratch.get("exp", logs.shape, np.float64)
    with np.errstate(all="ignore"):  # hostile values overflow and give NaN by design
        np.copyto(wide, logs)
        np.negative(wide[:, 0], out=wide[:, 0])  # sigmoid's exp(-opacity)
        np.exp(wide, out=wide)
        linear = scratch.get("linear", logs.shape, np.float32)
        np.copyto(linear, wide, casting="same_kind")
    for i, name in enumerate(_EXP_NAMES, start=1):
        np.copyto(work[:, _W_COLUMN[name]], linear[:, i])

    halves = scratch.get("halves", (m, _WIDTH), np.uint16)
    _halves(work, halves, logs, compat, counts, scratch)
    tail = np.dtype((np.void, 2 * _WIDTH))
    np.copyto(out.view(np.uint16)[:, _FIRST:].view(tail)[:, 0], halves.view(tail)[:, 0])

    # Positions: the float32 bits as they are.
    _copy_runs(out.view(np.float32), block, source.position_runs)
    if compat:
        # The browser reads positions through DataView.getFloat32 into a double,
        # which quiets signalling NaNs (sets the top mantissa bit).
        position = out[:, :len(_POSITIONS)]
        nan = np.isnan(position.view(np.float32))
        if nan.any():
            position[nan] |= np.uint32(packing.F32_QUIET_BIT)

    _colour(rgba, wide[:, 0], out, compat, counts, scratch)


def _halves(work: np.ndarray, halves: np.ndarray, logs: np.ndarray, compat: bool, counts: WriteReport,
            scratch: Scratch) -> None:
    """Half bits of the working block, exact where the fast path says it is not.

    Parameters
    ----------
    work : (M, 26) float32 ndarray
    halves : (M, 26) uint16 ndarray
    logs : (M, len(_EXPONENTS)) float32 ndarray
        The logarithms of the exp() attributes: a NaN logarithm is stored as
        itself (payload kept), not as exp(NaN).
    """
    m = len(work)
    step = min(m, HALF_ROWS)
    temp = scratch.get("half", packing.scratch_size(step * _WIDTH), np.uint32)
    listed = []
    for r in range(0, m, step):
        found = packing.float_to_half_into(work[r:r + step], halves[r:r + step], splatvjs=compat, scratch=temp)
        if len(found):
            listed.append(found + r * _WIDTH)
    if listed:
        _exceptions(work, halves, logs, np.concatenate(listed), compat, counts)


#: Working column -> index in the ``logs`` array, for the exp() attributes (else -1).
_LOG_INDEX = np.array([_EXPONENTS.index(name) if name in EXP_ATTRIBUTES else -1 for name in _W_NAMES])
#: Working columns whose halves are stored.
_STORED = np.array([name is not None for name in _W_NAMES])


def _exceptions(work: np.ndarray, halves: np.ndarray, logs: np.ndarray, listed: np.ndarray, compat: bool,
                counts: WriteReport) -> None:
    """The exact converters on the values the fast path listed (tiny, huge, non-finite), counted."""
    rows, cols = np.divmod(listed, _WIDTH)
    keep = _STORED[cols]
    rows, cols = rows[keep], cols[keep]
    if not len(rows):
        return
    picked = work[rows, cols]
    # NaN logarithms of exp() attributes: the logarithm itself is stored.
    at = np.flatnonzero(_LOG_INDEX[cols] >= 0)
    raw = logs[rows[at], _LOG_INDEX[cols[at]]]
    nan = np.isnan(raw)
    nan_at, nan_logs = at[nan], raw[nan]
    if compat:
        picked[nan_at] = nan_logs
    half, overflow, underflow, nonfinite = packing.float_to_half_exact(picked, splatvjs=compat)
    if not compat and len(nan_at):
        half[nan_at] = packing.float_to_half_exact(nan_logs)[0]
    halves[rows, cols] = half
    # A logarithm that reads back as itself lost nothing, though exp() of it
    # rounds past the half range: exp(log 65504) is 65504.000000000015.
    at = at[~nan]
    if len(at):
        same = LOG_OF_HALF[half[at]].view(np.uint32) == logs[rows[at], _LOG_INDEX[cols[at]]].view(np.uint32)
        overflow[at[same]] = False
    for what, mask in (("overflow", overflow), ("underflow", underflow), ("nonfinite", nonfinite)):
        per_column = np.bincount(cols[mask], minlength=_WIDTH)
        for col in np.flatnonzero(per_column):
            c = counts.half[_W_NAMES[col]]
            setattr(c, what, getattr(c, what) + int(per_column[col]))


#: The values that truncate to 0..255: (-1, 256), as closed bounds.
_TRUNCATED_TO_A_BYTE = (float(np.nextafter(-1.0, 0.0)), float(np.nextafter(256.0, 0.0)))


def _colour(rgba: np.ndarray, exp_neg_opacity: np.ndarray, out: np.ndarray, compat: bool, counts: WriteReport,
            scratch: Scratch) -> None:
    """The colour word: RGB x255 and sigmoid(opacity) x255, rounded or truncated, then clamped.

    ``counts.clamped`` counts the values whose byte the clamp changed (none for a
    value a hair outside [0, 1] that rounds to 0 or 255 anyway).

    Parameters
    ----------
    rgba : (M, 4) float32 ndarray
        f_dc_0..2 and opacity (the last is not read).
    exp_neg_opacity : (M,) float64 ndarray
        exp(-opacity).
    out : (M, 16) uint32 ndarray
    """
    m = len(rgba)
    scaled = scratch.get("scaled", (m, 4), np.float64)
    with np.errstate(all="ignore"):
        np.copyto(scaled, rgba)
        alpha = scaled[:, 3]
        np.add(exp_neg_opacity, 1.0, out=alpha)
        np.divide(1.0, alpha, out=alpha)  # sigmoid, in double as splaTV's JS does
        scaled *= 255.0
        # Rounded (or truncated) first, a value clamps only where its byte would
        # fall outside 0..255: -1.5e-8 rounds to byte 0 anyway, a change of nothing.
        # compat truncates, which the float -> uint8 cast does for values in (-1, 256).
        if not compat:
            np.rint(scaled, out=scaled)
        lo, hi = _TRUNCATED_TO_A_BYTE if compat else (0.0, 255.0)
        if not (scaled.min() >= lo and scaled.max() <= hi):  # also true for NaN
            for channel, name in enumerate(("color", "color", "color", "alpha")):
                v = scaled[:, channel]
                nan = np.isnan(v)
                counts.clamped[name] += int(np.count_nonzero((v < lo) | (v > hi)))
                counts.nan_bytes[name] += int(np.count_nonzero(nan))
                v[nan] = 0.0
                np.clip(v, 0.0, 255.0, out=v)
        rgba8 = scratch.get("rgba8", (m, 4), np.uint8)
        np.copyto(rgba8, scaled, casting="unsafe")
    np.copyto(out[:, COLOR_WORD], rgba8.view("<u4")[:, 0])


# --------------------------------------------------------------------------
# The whole texture


class Plan:
    """What writing a scene's texture takes, in pieces the drivers below run.

    :meth:`keys` computes the importance key of a range of input rows,
    :meth:`sort` turns the key into the output order, and :meth:`block` packs
    one block of output records. Working arrays belong to a thread.
    """

    def __init__(self, scene, compat: bool, sort: str | None):
        self.n = scene.count
        self.compat = compat
        self.sorted = (sort or "importance") != "none"
        self.columns = scene.columns
        self.source = RowSource(scene.columns)
        self.order = None
        self.local = threading.local()

    def scratch(self) -> Scratch:
        """This thread's working arrays."""
        scratch = getattr(self.local, "scratch", None)
        if scratch is None:
            scratch = self.local.scratch = Scratch()
        return scratch

    def frame(self) -> dict:
        """The camera that frames the scene, for a scene that has none."""
        return camera_for_box(*framing_box(self.columns["x"], self.columns["y"], self.columns["z"]))

    def keys(self, start: int, stop: int, key: np.ndarray) -> None:
        """:func:`importance` of input rows ``start:stop`` into ``key[start:stop]``."""
        for first in range(start, stop, KEY_BLOCK):
            rows = slice(first, min(first + KEY_BLOCK, stop))
            key[rows] = self._key_of(rows)

    def sort(self, key: np.ndarray, report: WriteReport | None) -> None:
        """Set the output order from the key, ``(N,) float64``, whose memory it takes.

        ``report`` (None: say nothing) gets the note about NaN keys in compat mode.
        """
        sort_key = key
        if self.compat:
            # splaTV keeps the key in a Float32Array and sorts with (b, a) => s[a] - s[b].
            with np.errstate(over="ignore"):
                sort_key = key.astype(np.float32)
            nan = int(np.count_nonzero(np.isnan(sort_key)))
            if nan and report is not None:
                report.notes.append(
                    f"{nan} splats have a NaN importance; splaTV's comparator makes their order "
                    "engine-defined, splatconv puts them last")
        self.order = importance_order_into(sort_key, key.view(np.uint64), self._key_of)

    def _key_of(self, rows) -> np.ndarray:
        """:func:`importance` of some rows (a slice or an index array), from the scene."""
        return importance({name: self.source.column(name, rows) for name in KEY_COLUMNS})

    def block(self, start: int, out: np.ndarray) -> WriteReport:
        """Pack output records ``start:start + len(out)`` into ``out``; their counts."""
        rows = slice(start, start + len(out))
        counts = new_counts()
        pack_rows(self.source, rows if self.order is None else self.order[rows], out, self.compat, counts,
             self.scratch())
        return counts


def ahead(pool, fn, items, depth: int):
    """Yield ``fn(item)`` for each item in order, computed by ``pool`` up to ``depth`` items ahead.

    The items are drawn in the calling thread, one as each result is taken (a reader of a file can
    produce them), and the results come back in their order whichever finishes first.
    """
    if pool is None:
        yield from map(fn, items)
        return
    pending = deque()
    for item in items:
        pending.append(pool.submit(fn, item))
        if len(pending) > depth:
            yield pending.popleft().result()
    while pending:
        yield pending.popleft().result()


def helpers(n: int):
    """Helper threads when there is more than one block to pack, else None."""
    return ThreadPoolExecutor(max_workers=WORKERS) if n > BLOCK and WORKERS > 1 else None


def prepare(plan: Plan, camera: bool, report: WriteReport, pool) -> list | None:
    """The key pass and the sort (if sorted), and a framing camera (if asked): threads.

    Returns the cameras to write, or None to keep the scene's.
    """
    framed = pool.submit(plan.frame).result if camera and pool is not None else (plan.frame if camera else None)
    if plan.sorted:
        key = np.empty(plan.n, dtype=np.float64)
        for _ in ahead(pool, lambda start: plan.keys(start, min(start + KEY_BLOCK, plan.n), key),
                        range(0, plan.n, KEY_BLOCK), WORKERS):
            pass
        plan.sort(key, report)
    if camera:
        report.notes.append("no cameras given; wrote one camera that frames the scene")
        return [framed()]
    return None


def blocks(plan: Plan, report: WriteReport, pool):
    """Yield ``(M, 16) uint32`` output blocks in order, adding their counts to ``report``: threads.

    A yielded block's memory is reused once the next one is asked for: blocks
    come from a ring as long as the helpers can be ahead.
    """
    depth = 2 * WORKERS if pool is not None else 0
    ring = [np.empty((BLOCK, WORDS_PER_SPLAT), dtype="<u4") for _ in range(min(depth + 1, -(-plan.n // BLOCK)))]

    def job(start):
        out = ring[(start // BLOCK) % len(ring)][:min(BLOCK, plan.n - start)]
        return out, plan.block(start, out)

    for out, counts in ahead(pool, job, range(0, plan.n, BLOCK), depth):
        merge_counts(report, counts)
        yield out


def into(plan: Plan, records: np.ndarray, report: WriteReport, pool) -> None:
    """Pack every record into ``records`` (``(N, 16) uint32``), adding the counts to ``report``: threads."""
    def job(start):
        return plan.block(start, records[start:min(start + BLOCK, plan.n)])

    for counts in ahead(pool, job, range(0, plan.n, BLOCK), 2 * WORKERS):
        merge_counts(report, counts)
