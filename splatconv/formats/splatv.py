"""The splaTV ``.splatv`` format: JSON header plus an RGBA32UI texture.

Layout (see ``specs/splatv.md``): uint32 LE magic, uint32 LE JSON length, a UTF-8
JSON array of chunks, then each chunk's bytes in order. The ``splat`` chunk is a
4096-texel-wide RGBA32UI texture, 16 uint32 words (4 texels) per splat, 1024
splats per texture row. The word table below is the whole record layout.
"""

from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass, field

import numpy as np

from .. import packing
from ..cameras import validate_cameras
from ..errors import FormatError, UnsupportedError
from ..fsutil import open_input
from ..jsonutil import decode as decode_json
from ..jsonutil import loads_strict
from ..model import Scene, lite_rows

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
#: Key of the splat chunk holding the number of splats (splatconv's; the viewer
#: ignores it). Without it a splat whose record is all zero cannot be told from padding.
COUNT_KEY = "count"

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


#: Elements per step of whole-array passes that would otherwise need N-sized
#: temporaries; small enough that the temporaries come from the heap, not mmap.
_CHUNK = 1 << 13


# --------------------------------------------------------------------------
# Packing: the engine is in :mod:`splatconv.formats._splatv_writer`.


def pack_block(cols: dict, compat: bool, report: WriteReport) -> np.ndarray:
    """Pack a block of rows into texture records, in the given order.

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
    from . import _splatv_writer as engine

    m = len(cols["x"])
    out = np.empty((m, WORDS_PER_SPLAT), dtype="<u4")
    counts = engine.new_counts()
    engine.pack(engine._Source(cols), slice(0, m), out, compat, counts, engine._Scratch())
    engine.merge_counts(report, counts)
    return out


def header_bytes(count: int, cameras: list) -> bytes:
    """The preamble and JSON header for a file of ``count`` splats."""
    texheight = texture_height(count)
    chunk = {
        "type": "splat",
        "size": TEXWIDTH * texheight * 16,
        "texwidth": TEXWIDTH,
        "texheight": texheight,
        COUNT_KEY: count,
        "cameras": cameras,
    }
    text = json.dumps([chunk], separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
    return PREAMBLE.pack(MAGIC, len(text)) + text


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
    from . import _splatv_writer as engine

    is_compat = compat == "splatv-js"
    report = WriteReport(count=n, texheight=texture_height(n))
    plan = engine.Plan(scene, is_compat, sort)
    pool = engine.helpers(n)
    try:
        cameras = engine.prepare(plan, not scene.cameras, report, pool)
        stream.write(header_bytes(n, cameras or scene.cameras))
        for block in engine.blocks(plan, report, pool):
            stream.write(memoryview(block))
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
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
    from . import _splatv_writer as engine

    is_compat = compat == "splatv-js"
    n = scene.count
    report = WriteReport(count=n, texheight=texture_height(n))
    records = np.empty((report.texheight * SPLATS_PER_ROW, WORDS_PER_SPLAT), dtype="<u4")
    records[n:] = 0
    plan = engine.Plan(scene, is_compat, sort)
    pool = engine.helpers(n)
    try:
        engine.prepare(plan, False, report, pool)
        engine.into(plan, records, report, pool)
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
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
    chunks = loads_strict(f.read(json_len), path, "header JSON")
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
    except FormatError as e:
        raise FormatError(e.message, path, where + ("cameras",) + e.where) from None


def declared_size(head: bytes):
    """File size the header at the start of ``head`` declares: preamble, JSON and every chunk.

    None when ``head`` does not hold the whole header or it is not valid (the
    reader says why). Used to bound the decompression of a ``.splatv.zst``.
    """
    if len(head) < PREAMBLE.size:
        return None
    magic, json_len = PREAMBLE.unpack_from(head)
    if magic != MAGIC or PREAMBLE.size + json_len > len(head):
        return None
    try:
        chunks = decode_json(head[PREAMBLE.size:PREAMBLE.size + json_len])
    except ValueError:
        return None
    if not isinstance(chunks, list) or not all(isinstance(c, dict) and _is_count(c.get("size")) for c in chunks):
        return None
    return PREAMBLE.size + json_len + sum(c["size"] for c in chunks)


def read_records(path: str | os.PathLike):
    """Read the raw texture records of a ``.splatv`` file.

    Returns
    -------
    records : (count, 16) uint32 ndarray
        The splats' records: as many as the header's ``count`` says where it
        can be trusted, else up to the last record that is not all zero.
    chunk : dict
        The splat chunk's header object.
    meta : dict
        Sizes and chunk list for ``info``.
    notes : list of str
    """
    path = os.fspath(path)
    notes = []
    with open_input(path) as f:
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
            if actual % RECORD_BYTES:
                notes.append(f"record {actual // RECORD_BYTES} is cut after {actual % RECORD_BYTES} of its "
                             f"{RECORD_BYTES} bytes: file truncated? its missing words read as zeros")
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
    count = _splat_count(records, chunk, notes)
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


def _splat_count(records: np.ndarray, chunk: dict, notes: list) -> int:
    """Splats in ``records`` (``(N, 16) uint32``, all present): the header's count where it can be trusted.

    The count splatconv writes (:data:`COUNT_KEY`) is used when it is an integer
    within the texture and every record after it is zero padding; a splat whose
    record is all zero is then kept. Otherwise (files of other writers, or a
    count that disagrees with the data: noted) the splats are the records up to
    the last one that is not all zero.
    """
    if COUNT_KEY not in chunk:
        return _records_used(records)
    count = chunk[COUNT_KEY]
    capacity = chunk["texheight"] * SPLATS_PER_ROW
    if not _is_count(count) or count > capacity:
        shown = repr(count) if not isinstance(count, int) or abs(count) < 1 << 64 else "a huge number"
        notes.append(f"header '{COUNT_KEY}' {shown[:40]} is not a splat count within the texture "
                     f"({capacity} records); splats counted up to the last record that is not all zero")
        return _records_used(records)
    used = _records_used(records[count:])
    if used:
        notes.append(f"header '{COUNT_KEY}' says {count} splats but the records after it hold data; splats "
                     f"counted up to the last record that is not all zero ({count + used})")
        return count + used
    if count > len(records):
        notes.append(f"header '{COUNT_KEY}' says {count} splats but the texture data holds only "
                     f"{len(records)} records")
        return len(records)
    return count


def _records_used(records: np.ndarray) -> int:
    """Records up to the last one that is not all zero, ``records`` being ``(N, 16) uint32``.

    Searches back from the end in growing steps: the zero padding is at most a
    texture row in files splatconv writes, so this rarely reads more than that.
    """
    if len(records) == 0:
        return 0
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


#: Records decoded at a time: a block's rows of the output table stay in cache.
_DECODE_BLOCK = 1 << 15
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
    values = np.empty(min(n, _DECODE_BLOCK), dtype=np.float32)  # one temporary, reused for every column
    # A block of rows at a time: the table's rows stay in cache while each of
    # their 29 fields is written.
    for start in range(0, n, _DECODE_BLOCK):
        block = records[start:start + _DECODE_BLOCK]
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
    splat count is the header's ``count`` (see :func:`_splat_count`), or, in
    files without one, excludes trailing all-zero records. NaN, infinities, subnormal
    halves and zero scales are read as they are.
    """
    records, chunk, meta, notes = read_records(path)
    columns, decode_notes = decode_records(records)
    meta["records"] = int(records.shape[0])
    return Scene(columns=columns, cameras=list(chunk.get("cameras", [])), variant="splatv",
                 meta=meta, notes=notes + decode_notes)
