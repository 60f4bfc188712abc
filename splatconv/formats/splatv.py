"""The splaTV ``.splatv`` format: JSON header plus an RGBA32UI texture.

Layout (see ``specs/splatv.md``): uint32 LE magic, uint32 LE JSON length, a UTF-8
JSON array of chunks, then each chunk's bytes in order. The ``splat`` chunk is a
4096-texel-wide RGBA32UI texture, 16 uint32 words (4 texels) per splat, 1024
splats per texture row. The word table below is the whole record layout.
"""

from __future__ import annotations

import contextlib
import os

import numpy as np

from .. import packing
from ..cameras import validate_cameras
from ..errors import FormatError, UnsupportedError
from ..files.inputs import open_input
from ..jsonutil import decode as decode_json
from ..jsonutil import loads_strict
from ..model import Scene, lite_rows
from ..progress import SILENT
from ..viewer import importance
from ..wording import plural
from . import splatv_engine as engine
from .base import Format, Scan, Texture, WriteReport
from .splatv_layout import (ALPHA_LOGIT_LIMIT, COLOR_OF_BYTE, COUNT_KEY, LOG_OF_HALF, LOGIT_OF_BYTE,
                            COLOR_WORD, EXP_ATTRIBUTES, HALF_WORDS, MAGIC, MAX_JSON_BYTES,
                            MAX_TEXHEIGHT, POSITION_WORDS, PREAMBLE, RECORD_BYTES, SPLATS_PER_ROW, TEXEL_BYTES,
                            TEXWIDTH, WORDS_PER_SPLAT, header_bytes, texture_bytes, texture_height)

#: How the viewer's texture stores each attribute group (:data:`splatconv.compare.STORAGE_KINDS`):
#: positions as float32 bits, colour and alpha as bytes, everything else as halves.
STORAGE = {"position": "exact", "rotation": "half", "scale": "half", "color": "byte", "opacity": "byte",
           "motion": "half", "omega": "half", "trbf": "half"}

__all__ = ["FORMAT", "STORAGE", "read", "write", "encode", "pieces", "info_fields", "read_records", "decode_records",
           "texture_key",
           "read_texture", "scan", "decode_rows", "decode_notes", "new_tally", "header_bytes", "texture_height",
           "texture_bytes", "TEXWIDTH", "SPLATS_PER_ROW",
           "WORDS_PER_SPLAT", "RECORD_BYTES", "HALF_WORDS", "POSITION_WORDS", "COLOR_WORD", "EXP_ATTRIBUTES",
           "MAGIC", "PREAMBLE", "LOG_OF_HALF", "COLOR_OF_BYTE", "LOGIT_OF_BYTE", "ALPHA_LOGIT_LIMIT"]


# --------------------------------------------------------------------------
# Writing


@contextlib.contextmanager
def _packing(scene: Scene, compat: str | None, sort: str | None, camera: bool = False):
    """What a packing of ``scene``'s records takes: ``(plan, report, pool, cameras)``, its key pass and sort
    done (and a framing camera made where ``camera``: :func:`engine.prepare`); the helper threads shut
    down after, and the write notes added to the report once every record is packed."""
    is_compat = compat == "splatv-js"
    report = WriteReport(count=scene.count, texheight=texture_height(scene.count))
    plan = engine.Plan(scene, is_compat, sort)
    pool = engine.helpers(scene.count)
    try:
        yield plan, report, pool, engine.prepare(plan, camera, report, pool)
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    report.notes.extend(write_notes(report, is_compat))


def write(scene: Scene, stream, *, compat: str | None = None, sort: str | None = None, progress=SILENT,
          **_options) -> WriteReport:
    """Write ``scene`` to a binary stream as ``.splatv``.

    Parameters
    ----------
    scene : Scene
    stream : binary file object
    compat : {None, "splatv-js"}
        ``"splatv-js"``: texture bytes identical to splaTV's in-browser converter.
    sort : {None, "importance", "none"}
        Order records by importance, largest first (the default), or keep the input order.

    Returns
    -------
    WriteReport
    """
    n = scene.count
    if n == 0:
        raise UnsupportedError("no splats to write; the viewer cannot show an empty texture")
    with _packing(scene, compat, sort, camera=not scene.cameras) as (plan, report, pool, cameras):
        stream.write(header_bytes(n, cameras or scene.cameras))
        with progress.stage("writing", n, "splat") as advance:
            for block in engine.blocks(plan, report, pool):
                stream.write(memoryview(block))
                advance(len(block))
        stream.write(bytes((report.texheight * SPLATS_PER_ROW - n) * RECORD_BYTES))  # the padding
    return report


def encode(scene: Scene, *, compat: str | None = None, sort: str | None = None):
    """The texture a write would produce, in memory (for rendering).

    Returns
    -------
    records : (texheight * 1024, 16) uint32 ndarray
        Padding records included, all zero.
    report : WriteReport
    """
    with _packing(scene, compat, sort) as (plan, report, pool, _):
        records = np.empty((report.texheight * SPLATS_PER_ROW, WORDS_PER_SPLAT), dtype="<u4")
        records[scene.count:] = 0
        engine.into(plan, records, report, pool)
    return records, report


def pieces(scene: Scene, put, *, compat: str | None = None, sort: str | None = None) -> WriteReport:
    """What :func:`encode` gives, a block at a time: ``put(records)`` with each ``(M, 16) uint32`` block in
    texture order, the padding left out; a block's memory is reused once ``put`` returns."""
    with _packing(scene, compat, sort) as (plan, report, pool, _):
        for block in engine.blocks(plan, report, pool):
            put(block)
    return report


def write_notes(report: WriteReport, compat: bool) -> list:
    notes = []
    for name, c in report.half.items():
        if c.overflow:
            what = "became infinity (splaTV's converter)" if compat else "saturated to +-65504"
            notes.append(f"{name}: {plural(c.overflow, 'value')} past the half-float range {what}")
        if c.underflow:
            notes.append(f"{name}: {plural(c.underflow, 'nonzero value')} became zero")
    return notes + report.byte_notes()


# --------------------------------------------------------------------------
# Reading


#: Largest size or count taken: 2**53 - 1, the largest integer a JavaScript viewer reads exactly.
MAX_SAFE_INTEGER = (1 << 53) - 1


def _is_count(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= MAX_SAFE_INTEGER


def _count_message(key: str, v) -> str:
    if isinstance(v, int) and not isinstance(v, bool) and v > MAX_SAFE_INTEGER:
        return f"'{key}' {_shown(v)} is past 2**53-1, the largest integer the viewer reads exactly"
    return f"'{key}' must be a non-negative integer, got {_shown(v)}"


def _shown(v) -> str:
    """``repr`` of a header value for a message, cut short."""
    text = repr(v) if not isinstance(v, int) or abs(v) < 1 << 64 else f"an integer of {len(str(abs(v)))} digits"
    return text if len(text) <= 40 else text[:37] + "..."


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
            raise FormatError(_count_message("size", chunk.get("size")),
                              path, (f"chunk {i}",))
    return chunks, PREAMBLE.size + json_len


def _check_splat_chunk(chunk: dict, path: str, where: tuple) -> None:
    if chunk.get("texwidth") != TEXWIDTH or isinstance(chunk.get("texwidth"), bool):
        raise FormatError(f"'texwidth' is {_shown(chunk.get('texwidth'))}; the viewer's shader needs {TEXWIDTH}",
                          path, where)
    texheight = chunk.get("texheight")
    if not _is_count(texheight):
        raise FormatError(_count_message("texheight", texheight), path, where)
    if texheight > MAX_TEXHEIGHT:
        raise FormatError(f"'texheight' {texheight} is past the largest texture any GPU takes ({MAX_TEXHEIGHT})",
                          path, where)
    expected = texture_bytes(texheight)
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


def _splat_chunk(f, path: str, file_size: int):
    """Read the header and find the first splat chunk (checked).

    Returns
    -------
    chunks : list of dict
    chunk : dict
        The splat chunk's header object.
    start : int
        File offset of its bytes.
    end : int
        File offset after the last chunk.
    skipped : list of dict
        The other chunks' types and sizes.
    """
    chunks, offset = read_header(f, path, file_size)
    splat = None
    skipped = []
    for i, chunk in enumerate(chunks):
        if splat is None and offset + chunk["size"] > file_size and chunk["type"] != "splat":
            raise FormatError(f"declares {chunk['size']} bytes but the file ends {file_size - offset} "
                              "bytes after its start, before any splat chunk", path,
                              (f"chunk {i} ({_shown(chunk['type'])})",))
        if chunk["type"] == "splat" and splat is None:
            _check_splat_chunk(chunk, path, (f"chunk {i}",))
            splat = (chunk, offset)
        else:
            skipped.append({"type": chunk["type"], "size": chunk["size"]})
        offset += chunk["size"]
    if splat is None:
        raise FormatError("header has no 'splat' chunk", path)
    return chunks, splat[0], splat[1], offset, skipped


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats :func:`read` gives for ``path``, found without reading them; None when only reading tells.

    The header's count (:data:`COUNT_KEY`) where :func:`_splat_count` would
    trust it: within the texture, and the records after it (at most a texture
    row, read here) all zero. Files without a count, with a bad one, or with
    more padding give None, as does a header :func:`read` refuses (reading says why).
    """
    path = os.fspath(path)
    try:
        with open_input(path) as f:
            file_size = os.fstat(f.fileno()).st_size
            _chunks, chunk, start, _end, _skipped = _splat_chunk(f, path, file_size)
            count = chunk.get(COUNT_KEY)
            if not _is_count(count) or count > chunk["texheight"] * SPLATS_PER_ROW:
                return None
            actual = max(0, min(chunk["size"], file_size - start))
            records = -(-actual // RECORD_BYTES)
            if count >= records:
                return records
            tail = actual - count * RECORD_BYTES
            if tail > TEXWIDTH * TEXEL_BYTES:
                return None
            f.seek(start + count * RECORD_BYTES)
            return count if f.read(tail).count(0) == tail else None
    except FormatError:
        return None


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats :func:`read` gives for ``path``: the records its texture holds (0: a header it refuses)."""
    path = os.fspath(path)
    try:
        with open_input(path) as f:
            file_size = os.fstat(f.fileno()).st_size
            _chunks, chunk, start, _end, _skipped = _splat_chunk(f, path, file_size)
    except FormatError:
        return 0
    return -(-max(0, min(chunk["size"], file_size - start)) // RECORD_BYTES)


#: Records read from the file at a time (4 MiB): what reading a texture holds besides the scene.
_READ_RECORDS = 1 << 16


class _Texture:
    """A ``.splatv``'s texture records, read from the open file a range at a time (bytes past the data as zeros)."""

    def __init__(self, f, path: str, start: int, actual: int):
        self.f, self.path, self.start, self.actual = f, path, start, actual
        self.records = -(-actual // RECORD_BYTES)

    def rows(self, first: int, stop: int) -> np.ndarray:
        """Records ``first`` to ``stop``: ``(stop - first, 16) uint32``."""
        # np.empty, not np.zeros: the read fills every page once; only a partial last record needs zeros.
        buf = np.empty((stop - first) * WORDS_PER_SPLAT, dtype="<u4")
        raw = memoryview(buf).cast("B")
        begin = first * RECORD_BYTES
        size = max(0, min(stop * RECORD_BYTES, self.actual) - begin)
        self.f.seek(self.start + begin)
        got = self.f.readinto(raw[:size])
        if got != size:  # pragma: no cover - the file changed under us
            raise FormatError(f"read {got} of {size} texture bytes", self.path)
        raw[size:] = bytes(len(raw) - size)
        return buf.reshape(-1, WORDS_PER_SPLAT)


def _open_texture(f, path: str):
    """Check the header of the open ``.splatv`` ``f`` and find its splats, without reading them all.

    Returns
    -------
    texture : _Texture
    count : int
        The splats (see :func:`_splat_count`).
    chunk : dict
        The splat chunk's header object.
    meta : dict
        Sizes and chunk list for ``info``.
    notes : list of str
    """
    notes = []
    file_size = os.fstat(f.fileno()).st_size
    chunks, chunk, start, offset, skipped = _splat_chunk(f, path, file_size)
    declared = chunk["size"]
    actual = max(0, min(declared, file_size - start))
    # Texture data that stops after its last record is how splaTV's converter
    # writes every file: the rest reads as zeros and nothing is lost, so no
    # note (``info`` shows the bytes present). A record cut short is damage.
    if actual < declared and actual % RECORD_BYTES:
        notes.append(f"record {actual // RECORD_BYTES} is cut after {actual % RECORD_BYTES} of its "
                     f"{RECORD_BYTES} bytes: file truncated? its missing words read as zeros")
    if offset < file_size:
        notes.append(f"{file_size - offset} bytes after the last chunk ignored")
    texture = _Texture(f, path, start, actual)
    count = _splat_count(texture, chunk, notes)
    if skipped:
        types = sorted({c['type'] for c in skipped})
        notes.append(f"skipped {plural(len(skipped), 'chunk')} of other types: "
                     + ", ".join(t if len(t) <= 40 else t[:37] + "..." for t in types[:10])
                     + (f" and {len(types) - 10} more" if len(types) > 10 else ""))
    meta = {
        "texwidth": chunk["texwidth"],
        "texheight": chunk["texheight"],
        "declared_bytes": declared,
        "actual_bytes": actual,
        "chunks": [{"type": c["type"], "size": c["size"]} for c in chunks],
        "file_bytes": file_size,
    }
    return texture, count, chunk, meta, notes


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
    with open_input(path) as f:
        texture, count, chunk, meta, notes = _open_texture(f, path)
        return texture.rows(0, count), chunk, meta, notes


def _splat_count(texture: _Texture, chunk: dict, notes: list) -> int:
    """Splats in ``texture`` (its records all present): the header's count where it can be trusted.

    The count splatconv writes (:data:`COUNT_KEY`) is used when it is an integer
    within the texture and every record after it is zero padding; a splat whose
    record is all zero is then kept. Otherwise (files of other writers, or a
    count that disagrees with the data: noted) the splats are the records up to
    the last one that is not all zero.
    """
    records = texture.records
    if COUNT_KEY not in chunk:
        return _records_used(texture, 0, records)
    count = chunk[COUNT_KEY]
    capacity = chunk["texheight"] * SPLATS_PER_ROW
    if not _is_count(count) or count > capacity:
        shown = repr(count) if not isinstance(count, int) or abs(count) < 1 << 64 else "a huge number"
        notes.append(f"header '{COUNT_KEY}' {shown[:40]} is not a splat count within the texture "
                     f"({capacity} records); splats counted up to the last record that is not all zero")
        return _records_used(texture, 0, records)
    used = _records_used(texture, count, records)
    if used > count:
        notes.append(f"header '{COUNT_KEY}' says {count} splats but the records after it hold data; splats "
                     f"counted up to the last record that is not all zero ({used})")
        return used
    if count > records:
        notes.append(f"header '{COUNT_KEY}' says {count} splats but the texture data holds only "
                     f"{records} records")
        return records
    return count


def _records_used(texture: _Texture, first: int, stop: int) -> int:
    """Where the records ``first`` to ``stop`` of ``texture`` end once trailing all-zero ones are left out
    (``first`` when all are zero).

    Searches back from ``stop`` in growing steps (of at most :data:`_READ_RECORDS`): the zero padding is
    at most a texture row in files splatconv writes, so this rarely reads more than that.
    """
    step = SPLATS_PER_ROW
    while stop > first:
        start = max(first, stop - step)
        used = np.flatnonzero(texture.rows(start, stop).any(axis=1))
        if len(used):
            return start + int(used[-1]) + 1
        stop = start
        step = min(2 * step, _READ_RECORDS)
    return first


#: Records decoded at a time: a block's rows of the output table stay in cache.
_DECODE_BLOCK = 1 << 15
#: Half patterns that are negative numbers (not NaN): no logarithm for an exp() slot.
_NEGATIVE_HALF = ((np.arange(1 << 16) & packing.HALF_SIGN_BIT) != 0) & ~np.isnan(packing.HALF_TO_FLOAT)
_NEGATIVE_HALF.flags.writeable = False


def new_tally() -> dict:
    """What :func:`decode_rows` counts, nothing yet: data in unused halves (by word), negative exp() halves
    (by name)."""
    return {"stray": dict.fromkeys(HALF_WORDS, 0), "negative": dict.fromkeys(EXP_ATTRIBUTES, 0)}


def decode_rows(records: np.ndarray, cols: dict, at: int, tally: dict) -> None:
    """Decode texture records into rows ``at ..`` of model columns, counting into ``tally`` (:func:`new_tally`).

    Parameters
    ----------
    records : (M, 16) uint32 ndarray
    cols : dict of str to (N,) float32 ndarray
        Writeable columns (:func:`splatconv.model.lite_rows`), rows ``at`` to ``at + M`` filled here.
    at : int
    tally : dict
    """
    stray, negative = tally["stray"], tally["negative"]
    values = np.empty(min(len(records), _DECODE_BLOCK), dtype=np.float32)  # one temporary, reused for every column
    # A block of rows at a time: the table's rows stay in cache while each of
    # their 29 fields is written.
    for start in range(0, len(records), _DECODE_BLOCK):
        block = records[start:start + _DECODE_BLOCK]
        rows = slice(at + start, at + start + len(block))
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


def decode_notes(tally: dict) -> list:
    """The notes of what :func:`decode_rows` counted: values the lite PLY layout cannot hold."""
    notes = []
    for w, (lo_name, hi_name) in HALF_WORDS.items():
        for name in (lo_name, hi_name):
            if name is None and tally["stray"][w]:
                notes.append(f"word {w}: {tally['stray'][w]} records carry data in the unused upper half; dropped")
            elif name in EXP_ATTRIBUTES and tally["negative"][name]:
                notes.append(f"{name}: {tally['negative'][name]} negative values have no logarithm; written as "
                             "NaN (-0 as -inf)")
    return notes


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
    _rows, cols = lite_rows(len(records))
    tally = new_tally()
    decode_rows(records, cols, 0, tally)
    return cols, decode_notes(tally)


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a ``.splatv`` file into a :class:`Scene`.

    Texture data shorter than declared is padded with zeros (noted only when it
    ends inside a record; ``info`` shows the bytes present); the
    splat count is the header's ``count`` (see :func:`_splat_count`), or, in
    files without one, excludes trailing all-zero records. NaN, infinities, subnormal
    halves and zero scales are read as they are. The records are read and decoded
    :data:`_READ_RECORDS` at a time: the scene's table is all the memory a read takes.
    """
    path = os.fspath(path)
    with open_input(path) as f:
        texture, count, chunk, meta, notes = _open_texture(f, path)
        _rows, columns = lite_rows(count)
        tally = new_tally()
        for start in range(0, count, _READ_RECORDS):
            decode_rows(texture.rows(start, min(count, start + _READ_RECORDS)), columns, start, tally)
    meta["records"] = count
    return Scene(columns=columns, cameras=list(chunk.get("cameras", [])), variant="splatv",
                 meta=meta, notes=notes + decode_notes(tally))


def scan(path: str | os.PathLike, **_options) -> Scan:
    """Read a ``.splatv`` file a piece at a time (:class:`~splatconv.formats.base.Scan`): what :func:`read`
    gives, :data:`_READ_RECORDS` splats a piece."""
    path = os.fspath(path)
    out = Scan(variant="splatv")

    def pieces():
        with open_input(path) as f:
            texture, count, chunk, meta, notes = _open_texture(f, path)
            out.cameras = list(chunk.get("cameras", []))
            out.meta.update(meta, records=count)
            tally = new_tally()
            for start in range(0, count, _READ_RECORDS):
                stop = min(count, start + _READ_RECORDS)
                _rows, columns = lite_rows(stop - start)
                decode_rows(texture.rows(start, stop), columns, 0, tally)
                yield columns
        out.notes.extend(notes + decode_notes(tally))

    out.pieces = pieces()
    return out


def storage(scene: Scene) -> dict:
    """How a ``.splatv`` stores each attribute group: :data:`STORAGE`, the viewer's texture."""
    return STORAGE


def info_fields(meta: dict) -> dict:
    """What ``info`` shows of a scene read from a ``.splatv`` (its ``meta``) besides the common facts: its chunks."""
    return {"chunks": meta.get("chunks", [])}


def texture_key(records: np.ndarray) -> np.ndarray:
    """The importance key a write sorts the scene decoded from ``records`` by: ``(N,) float64``.

    A write's records decode and encode again unchanged, so :func:`encode` of the
    scene :func:`decode_records` gives is ``records[importance_order(key)]``
    (:func:`splatconv.viewer.importance_order`), zero padded: the key is
    :func:`splatconv.viewer.importance` of the four columns it reads, decoded as
    :func:`decode_rows` decodes them, and the writer sorts it so. A block at a
    time gives the same keys: what the proof of a ``.splatvq`` draws (its records
    in a conversion's order) without decoding the rest of the scene.

    Parameters
    ----------
    records : (N, 16) uint32 ndarray
    """
    cols = {"opacity": np.take(LOGIT_OF_BYTE, np.asarray(records[:, COLOR_WORD], np.uint32) >> np.uint32(24))}
    for w, names in HALF_WORDS.items():
        for name, h in zip(names, packing.unpack_half2(records[:, w])):
            if name in engine.KEY_COLUMNS:
                cols[name] = np.take(LOG_OF_HALF, h)
    return importance(cols)


def read_texture(path: str | os.PathLike):
    """A .splatv file's texture as the viewer holds it, and its decoded scene.

    Returns
    -------
    padded : (rows * 1024, 16) uint32 ndarray
        The records with zero padding, as drawn (the viewer sorts the padding too).
    scene : Scene
        The records decoded to model columns (one read of the file serves both).
    """
    path = os.fspath(path)
    with open_input(path) as f:
        texture, count, chunk, meta, notes = _open_texture(f, path)
        rows = texture_height(count)
        if meta["texheight"] * SPLATS_PER_ROW > rows * SPLATS_PER_ROW == count:
            rows += 1  # keep one zero record at the origin, which the viewer's sort also sees
        padded = np.zeros((max(rows, 1) * SPLATS_PER_ROW, WORDS_PER_SPLAT), dtype="<u4")
        _rows, columns = lite_rows(count)
        tally = new_tally()
        # Read into the padded texture a piece at a time, each decoded from there: no third copy.
        for start in range(0, count, _READ_RECORDS):
            stop = min(count, start + _READ_RECORDS)
            padded[start:stop] = texture.rows(start, stop)
            decode_rows(padded[start:stop], columns, start, tally)
    meta["records"] = count
    scene = Scene(columns=columns, cameras=list(chunk.get("cameras", [])), variant="splatv", meta=meta,
                  notes=notes + decode_notes(tally))
    return padded, scene


FORMAT = Format(
    name="splatv",
    suffixes=(".splatv",),
    default_sort="importance",  # largest, most opaque first: the viewer draws them first while streaming
    holds_empty=False,  # the viewer cannot show an empty texture
    dynamic=True,  # motion and a temporal basis
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats, declared_size=declared_size,
    write=write,
    compat_modes=("splatv-js",),  # texture bytes identical to splaTV's in-browser converter
    info_fields=info_fields, storage=storage,
    # The file holds the viewer's texture itself: drawn, played and measured as stored.
    texture=Texture(encode=encode, pieces=pieces, decode=decode_records, header=header_bytes, read=read_texture),
    check_playable=read_records,  # the page plays a .splatv's bytes as they are
)
