"""The ``.splatvq`` format: a quantized ``.splatv`` in independently decodable blocks.

Layout (see ``specs/splatvq.md``): a fixed preamble (magic, version, coder and
the quantizer's setting), a UTF-8 JSON object (count, cameras) as raw deflate, a block table
(per block: splats quantized, splats verbatim, payload bytes, stored bytes), then
each block's raw-deflate stream. Blocks follow the importance order of a ``.splatv``, so a
player draws the most important splats first. A block decodes to ``.splatv``
texture records exactly (:mod:`splatconv.formats.splatvq_codec`); reading then
decodes those records as a ``.splatv`` reader does, so every command reads it.

Undrawable splats (:func:`splatconv.viewer.undrawable`) are left out when
writing: every frame the viewer draws is unchanged by it; the notes say how many.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import struct
import zlib
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from ..cameras import camera_for_box, framing_box, validate_cameras
from ..errors import FormatError, UnsupportedError, UsageError
from ..files.inputs import open_input
from ..jsonutil import loads_strict
from ..model import Scene, lite_rows
from ..progress import SILENT
from ..viewer import UNDRAWABLE_KINDS, importance_order, sort_ends, undrawable_kinds
from ..wording import kinds_text, plural
from . import splatv
from . import splatv_engine as engine
from . import splatvq_codec as codec
from .base import Format, Scan, WriteReport
from .splatv_layout import SPLATS_PER_ROW, WORDS_PER_SPLAT

#: Quality settings (best first; see :data:`splatvq_codec.SETTINGS`): the ``quality`` write option.
QUALITIES = tuple(codec.SETTINGS)
#: Colour and opacity keep the texture's bytes; every other group is quantized
#: (error bounds in ``specs/splatvq.md``), judged by the frames drawn.
STORAGE = {"position": "quantized", "rotation": "quantized", "scale": "quantized", "color": "byte",
           "opacity": "byte", "motion": "quantized", "omega": "quantized", "trbf": "quantized"}

MAGIC = b"SPVQ"
VERSION = 6
#: magic, version, coder, the setting's twelve numbers, chunk size (log2), the header JSON's stored (raw
#: deflate) and inflated lengths, block count.
PREAMBLE = struct.Struct("<4sBBbBBBBBbBBBBBBIII")
#: One block table entry: splats quantized, splats verbatim, payload (inflated) bytes, stored (compressed) bytes.
BLOCK_ENTRY = struct.Struct("<IIII")
#: Largest JSON header read: inflated, and as stored.
MAX_JSON_BYTES = 64 << 20
#: Most splats a file holds: as many as a ``.splatv`` texture (65536 rows of 1024).
MAX_SPLATS = 65536 * SPLATS_PER_ROW
#: The setting's fields in preamble order.
SETTING_ORDER = ("position_shift", "rotation_bits", "scale_step", "trbf_scale_step", "time_shift", "omega_shift",
                 "motion_shift", "acceleration_shift", "jerk_shift", "alpha_levels", "flat_octaves", "boost_step")

class Block(NamedTuple):
    """A block table entry, checked, and where the block's stored bytes start in the file."""

    coded: int
    raw: int
    payload: int
    stored: int
    offset: int


__all__ = ["FORMAT", "read", "write", "encode", "prepare", "decode", "check", "info_fields", "splat_count", "most_splats",
           "storage", "read_records", "converted_texture", "scan", "header_deflated", "MAGIC", "VERSION", "PREAMBLE",
           "BLOCK_ENTRY"]


# --------------------------------------------------------------------------
# Writing


def _setting_name(quality: str | None) -> str:
    name = quality or codec.DEFAULT_SETTING
    if name not in codec.SETTINGS:
        raise UsageError(f"unknown .splatvq setting {name!r} (expected one of {', '.join(codec.SETTINGS)})")
    return name


def prepare(scene: Scene, kinds: np.ndarray | None = None) -> tuple:
    """What every write of ``scene`` shares, whatever its setting and step: ``(kinds, ends)``.

    Its :func:`~splatconv.viewer.undrawable_kinds` (``kinds``, where the caller has
    them) and the splats the viewer's depth sort turns on
    (:func:`~splatconv.viewer.sort_ends`), computed once for a proof that writes the
    scene at several steps (:attr:`~splatconv.formats.base.Format.prepare`).
    """
    kinds = undrawable_kinds(scene.columns) if kinds is None else kinds
    return kinds, sort_ends(scene.columns, scene.cameras, kinds)


def encode(scene: Scene, *, sort: str | None = None, quality: str | None = None, precision: int = 0,
           tune: tuple = (), level: int = 9, progress=SILENT, prepared: tuple | None = None,
           weights: np.ndarray | None = None) -> tuple:
    """A scene as ``.splatvq`` bytes, in memory (:func:`write`'s parameters; see :func:`_encode_to`).

    Returns
    -------
    data : bytes
    report : WriteReport
    """
    out = io.BytesIO()
    report = _encode_to(scene, out, sort=sort, quality=quality, precision=precision, tune=tune, level=level,
                        progress=progress, prepared=prepared, weights=weights)
    return out.getvalue(), report


def _encode_to(scene: Scene, out, *, sort: str | None = None, quality: str | None = None, precision: int = 0,
               tune: tuple = (), level: int = 9, progress=SILENT, prepared: tuple | None = None,
               weights: np.ndarray | None = None) -> WriteReport:
    """Write a scene as ``.splatvq`` to ``out``, a seekable binary stream, from where it stands: each block as
    it is encoded, then the block table in the place the header left for it (no block held once written).

    Parameters
    ----------
    scene : Scene
    sort : {None, "importance", "none"}
        Blocks in importance order (default) or in the input order.
    quality : {None, "default", "small"}
        The quality setting (:data:`QUALITIES`).
    precision : int
        Half steps finer (or, below 0, coarser) than the setting (:func:`splatvq_codec.refined`,
        one of :data:`splatvq_codec.PRECISIONS`); the header names step 2 ``"default+1"``.
    tune : tuple of str
        Quantizers coarsened a notch each beyond the step (:func:`splatvq_codec.tuned`, names of
        :data:`splatvq_codec.TUNINGS`, a name once a notch): ``convert``'s tuning to a scene.
        The header names the setting ``"default+1, tuned"`` and stores its numbers.
    level : int
        Deflate level.
    progress : splatconv.progress.Progress
        A "writing" stage of the splats written (the drawable ones), advanced as each block is encoded.
    prepared : tuple, optional
        :func:`prepare` of this very scene, when already computed.
    weights : (N,) float ndarray, optional
        What each splat of the scene adds to the frames a user will see, in units
        of what a typical splat adds (:func:`splatconv.render.proof.frame_weights`):
        the splats above 1 take the higher boost levels, the finer steps
        (:func:`splatvq_codec.boost_levels`). Without it, the levels follow the size
        each splat is seen at from the nearest header camera, times its opacity.

    Returns
    -------
    WriteReport
    """
    base = _setting_name(quality)
    if weights is not None and len(weights) != scene.count:
        raise ValueError(f"{len(weights)} weights for {scene.count} splats")
    if precision not in codec.PRECISIONS:
        raise UsageError(f"precision {precision} is not one of {codec.PRECISIONS[0]}..{codec.PRECISIONS[-1]}")
    try:
        setting = codec.tuned(codec.refined(codec.SETTINGS[base], precision), tune)
    except ValueError as e:
        raise UsageError(str(e)) from None
    name = codec.tuned_name(codec.precision_name(base, precision), tune)
    kinds, exact = prepare(scene) if prepared is None else prepared
    drawable = kinds == -1
    if not drawable.any():
        raise UnsupportedError(f"none of the {plural(scene.count, 'splat')} can be drawn by the viewer; "
                               "a .splatvq file holds drawable splats, and the undrawable ones its sort needs")
    cameras = scene.cameras
    report = WriteReport()
    if not cameras:
        cameras = [camera_for_box(*framing_box(*(np.asarray(scene.columns[a])[drawable] for a in "xyz")))]
        report.notes.append("no cameras given; wrote one camera that frames the scene")
    # The splats the viewer's depth sort turns on (:func:`splatconv.viewer.sort_ends`) are stored
    # verbatim, undrawable or not: the frames then drop and repeat the records a .splatv's do.
    keep = np.flatnonzero(drawable | exact)
    shaping = int(np.count_nonzero(exact & ~drawable))
    dropped = np.bincount(kinds[~drawable & ~exact].astype(np.intp), minlength=len(UNDRAWABLE_KINDS))
    n = report.count = len(keep)
    # Records are packed a block of rows at a time, as the .splatv writer packs them (never the
    # whole texture at once: a block's records are all the memory a block needs).
    plan = engine.Plan(scene, False, "none")  # its row source and per-thread scratch; blocks chosen here

    def packed(rows):
        out = np.empty((len(rows), WORDS_PER_SPLAT), dtype="<u4")
        counts = engine.new_counts()
        # The .splatv writer's block at a time: its working arrays (a thread's) stay that size.
        for start in range(0, len(rows), engine.BLOCK):
            engine.pack_rows(plan.source, rows[start:start + engine.BLOCK], out[start:start + engine.BLOCK], False,
                             counts, plan.scratch())
        return out, counts

    starts = range(0, n, codec.BLOCK)
    header = {"count": n, "setting": name, "cameras": cameras}
    if setting.color_shift:
        header["color_shift"] = setting.color_shift  # colours rounded: verify judges them as quantized
    if scene.meta.get("pruned"):
        header["pruned"] = int(scene.meta["pruned"])  # splats pruned from the scene (splatconv.ops.prune)
    text = json.dumps(header, separators=(",", ":"),
                      ensure_ascii=False, allow_nan=False).encode("utf-8")
    values = [getattr(setting, f) for f in SETTING_ORDER]
    first = out.tell()
    stored = header_deflated(text)
    out.write(PREAMBLE.pack(MAGIC, VERSION, codec.CODER_DEFLATE_RAW, *values, codec.CHUNK_LOG2, len(stored), len(text),
                            len(starts)))
    out.write(stored)
    table_at = out.tell()
    out.write(bytes(BLOCK_ENTRY.size * len(starts)))  # the block table, written once the blocks are
    with ThreadPoolExecutor(max_workers=2) if len(starts) > 1 else contextlib.nullcontext() as pool:
        each = pool.map if pool is not None else map
        key = np.empty(n) if (sort or FORMAT.default_sort) != "none" else None
        # Boost levels from the frames where the caller weighed the splats by them, else from the size
        # each splat is seen at from the nearest camera, as it decodes (codec.boost_levels).
        sizes = np.empty(n) if setting.boost_step and weights is None else None
        eyes = np.array([c["position"] for c in cameras], dtype=np.float64).reshape(-1, 3)

        def key_job(start):  # the importance key of the records as they decode, and their sizes
            records = packed(keep[start:start + codec.BLOCK])[0]
            if key is not None:
                key[start:start + codec.BLOCK] = codec.quantized_key(records, setting)
            if sizes is not None:
                sizes[start:start + codec.BLOCK] = codec.seen_size(records, setting, eyes)

        if key is not None or sizes is not None:
            list(each(key_job, starts))
        levels = None
        if sizes is not None:
            levels = codec.boost_levels(sizes, codec.LEVELS_PER_OCTAVE["size"])
        elif setting.boost_step:
            with np.errstate(divide="ignore", invalid="ignore"):
                levels = codec.boost_levels(np.log2(np.asarray(weights, dtype=np.float64)[keep]),
                                            codec.LEVELS_PER_OCTAVE["frames"], centre=0.0)
        ranks = importance_order(key) if key is not None else np.arange(n)
        order = keep[ranks]
        if levels is not None:
            levels = levels[ranks]
        key = sizes = ranks = None  # freed before the blocks are encoded

        def job(start):
            rows = order[start:start + codec.BLOCK]
            records, counts = packed(rows)
            return codec.encode_block(records, setting, level, exact=exact[rows],
                                      levels=None if levels is None else levels[start:start + codec.BLOCK]), counts

        blocks, counts, forced = [], engine.new_counts(), 0  # each block's table entry, once written
        with progress.stage("writing", n, "splat") as advance:
            for start, ((stored, coded, raw, payload, block_forced), part) in zip(starts, each(job, starts)):
                out.write(stored)
                blocks.append((coded, raw, payload, len(stored)))
                engine.merge_counts(counts, part)
                forced += block_forced
                advance(min(codec.BLOCK, n - start))
    end = out.tell()
    out.seek(table_at)
    out.write(b"".join(BLOCK_ENTRY.pack(*entry) for entry in blocks))
    out.seek(end)
    if dropped.any():
        what = kinds_text({kind: int(c) for kind, c in zip(UNDRAWABLE_KINDS, dropped)})
        report.notes.append(f"left out {plural(int(dropped.sum()), 'undrawable splat')} ({what}): "
                            "no frame the viewer draws changes"
                            + (f"; kept {shaping:,} that the viewer's depth sort needs" if shaping else ""))
    elif shaping:
        report.notes.append(f"kept {plural(shaping, 'undrawable splat')}: the viewer's depth sort needs them")
    raw = sum(r for _, r, _, _ in blocks) - forced
    # A scene read from a .splatvq of this very setting is on its grid already (the quantizers are
    # projections), but for a splat whose boost level comes out otherwise this time (at a level's edge).
    kept = scene.variant == FORMAT.name and scene.meta.get("setting") == name
    how = f"kept the source's {name!r} setting (a splat at the edge of a boost level may move a step)" \
        if kept else f"quantized with the {name!r} setting"
    report.notes.append(f"{how} ({(end - first) / n:.1f} bytes a splat)"
                        + (f"; {plural(raw, 'splat')} kept verbatim (a zero rotation, an axis-aligned flat splat, or NaN, infinite or far values)" if raw else "")
                        + (f"; {plural(forced, 'splat')} at the ends of the viewer's depth sort kept exactly"
                           if forced else ""))
    # What packing the drawable splats' records changed, as the .splatv writer says it.
    report.notes.extend(splatv.write_notes(counts, False))
    return report


def write(scene: Scene, stream, *, compat: str | None = None, sort: str | None = None, progress=SILENT,
          quality: str | None = None, precision: int = 0, tune: tuple = (), prepared: tuple | None = None,
          weights: np.ndarray | None = None, **_options) -> WriteReport:
    """Write ``scene`` to a binary stream as ``.splatvq`` (see :func:`encode`): ``progress`` counts the
    splats written, not those read (undrawable splats are left out)."""
    options = {"sort": sort, "quality": quality, "precision": precision, "tune": tune, "progress": progress,
               "prepared": prepared, "weights": weights}
    if _seekable(stream):  # each block written as it is encoded
        return _encode_to(scene, stream, **options)
    data, report = encode(scene, **options)
    stream.write(data)
    return report


def _seekable(stream) -> bool:
    """Whether ``stream`` can take the block table after the blocks (not a file opened to append to)."""
    try:
        return stream.seekable() and "a" not in getattr(stream, "mode", "")
    except (AttributeError, ValueError, OSError):
        return False


def header_deflated(text: bytes) -> bytes:
    """The header JSON's UTF-8 ``text`` as stored: raw deflate (a file's cameras are most of it, and
    their numbers' digits deflate to some two thirds)."""
    comp = zlib.compressobj(9, zlib.DEFLATED, -15, 9)
    return comp.compress(text) + comp.flush()


# --------------------------------------------------------------------------
# Reading


def _header(f, path: str, file_size: int):
    """Read and check the preamble, JSON and block table: the setting, the header JSON and a :class:`Block` each."""
    if file_size < PREAMBLE.size:
        raise FormatError(f"{file_size} bytes is too short for a .splatvq file ({PREAMBLE.size}-byte preamble)",
                          path)
    fields = PREAMBLE.unpack(f.read(PREAMBLE.size))
    magic, version, coder = fields[:3]
    values = dict(zip(SETTING_ORDER, fields[3:3 + len(SETTING_ORDER)]))
    chunk_log2, json_len, json_size, block_count = fields[3 + len(SETTING_ORDER):]
    if magic != MAGIC:
        raise FormatError(f"not a .splatvq file: magic {magic!r}, expected {MAGIC!r}", path)
    if version != VERSION:
        raise FormatError(f"version {version} is not one this reader knows ({VERSION})", path)
    if coder != codec.CODER_DEFLATE_RAW:
        raise FormatError(f"coder {coder} is not one this reader knows ({codec.CODER_DEFLATE_RAW}: raw deflate)",
                          path)
    if chunk_log2 != codec.CHUNK_LOG2:
        raise FormatError(f"chunk size 2**{chunk_log2} is not 2**{codec.CHUNK_LOG2}", path)
    for key, (lo, hi) in codec.SETTING_LIMITS.items():
        if not lo <= values[key] <= hi:
            raise FormatError(f"setting '{key}' is {values[key]}, outside [{lo}, {hi}]", path)
    setting = codec.Setting(**values)
    if json_size > MAX_JSON_BYTES or json_len > MAX_JSON_BYTES:
        raise FormatError(f"header declares {max(json_size, json_len)} bytes of JSON, more than the "
                          f"{MAX_JSON_BYTES} read", path)
    if PREAMBLE.size + json_len > file_size:
        raise FormatError(f"header declares {json_len} stored bytes of JSON but the file ends after "
                          f"{file_size - PREAMBLE.size}", path)
    if json_size > codec.MAX_RATIO * json_len + 64:
        raise FormatError(f"header declares {json_size} bytes of JSON from {json_len} stored, more than deflate "
                          "can give", path)
    text = codec.inflate(f.read(json_len), json_size, path, ("header JSON",))
    meta = loads_strict(text, path, "header JSON")
    if not isinstance(meta, dict):
        raise FormatError("header JSON must be an object", path)
    table_at = PREAMBLE.size + json_len
    if table_at + block_count * BLOCK_ENTRY.size > file_size:
        raise FormatError(f"header declares {block_count} blocks but the file ends before their table", path)
    table = f.read(block_count * BLOCK_ENTRY.size)
    offset = table_at + block_count * BLOCK_ENTRY.size
    if block_count == 0:
        raise FormatError("its block table lists no blocks; a .splatvq file holds at least one splat", path)
    blocks = []
    total = 0
    for i, (coded, raw, payload, stored) in enumerate(BLOCK_ENTRY.iter_unpack(table)):
        where = (f"block {i}",)
        if coded + raw > codec.BLOCK or coded + raw == 0:
            raise FormatError(f"holds {coded + raw} splats; a block holds 1 to {codec.BLOCK}", path, where)
        if offset + stored > file_size:
            raise FormatError(f"declares {stored} bytes but the file ends {file_size - offset} bytes after its "
                              "start: file truncated?", path, where)
        fewest, most = codec.payload_bounds(coded, raw)
        if not fewest <= payload <= most:
            raise FormatError(f"declares {payload} decoded bytes; {coded} coded and {raw} verbatim splats take "
                              f"{fewest} to {most}", path, where)
        if payload > codec.MAX_RATIO * stored + 64:
            raise FormatError(f"declares {payload} decoded bytes from {stored} stored, more than deflate can give",
                              path, where)
        blocks.append(Block(coded, raw, payload, stored, offset))
        offset += stored
        total += coded + raw
    if offset != file_size:
        raise FormatError(f"the blocks end at byte {offset} but the file has {file_size}", path)
    count = meta.get("count")
    if count != total or isinstance(count, bool):
        raise FormatError(f"header 'count' is {str(count)[:40]} but the blocks hold {total} splats", path)
    if total > MAX_SPLATS:
        raise FormatError(f"holds {total} splats, more than a .splatv texture takes ({MAX_SPLATS})", path)
    cameras = meta.get("cameras", [])
    try:
        validate_cameras(cameras, path)
    except FormatError as e:
        raise FormatError(e.message, path, ("cameras",) + e.where) from None
    return setting, meta, blocks


#: Blocks decoded at once while reading (numpy and zlib work outside the interpreter lock).
READ_WORKERS = 2


def _decoded(f, path: str, setting, blocks):
    """Each block's records, ``(n, 16) uint32``, in file order: two blocks decoded at a time, their stored bytes
    read in file order, and a damaged block reported before any block after it."""

    def job(i, data):
        b, where = blocks[i], (f"block {i}",)
        return codec.decode_block(codec.inflate(data, b.payload, path, where), b.coded, b.raw, setting, path, where)

    def stored(i):
        f.seek(blocks[i].offset)
        return f.read(blocks[i].stored)

    # The stored bytes are read here, in file order, as the helpers ask for the next block.
    with ThreadPoolExecutor(max_workers=READ_WORKERS) if len(blocks) > 1 else contextlib.nullcontext() as pool:
        yield from engine.ahead(pool, lambda item: job(*item), ((i, stored(i)) for i in range(len(blocks))),
                                READ_WORKERS)


def _opened(f, path: str):
    """The setting, header JSON and blocks of the open file ``f``, and what ``info`` shows of it."""
    file_size = os.fstat(f.fileno()).st_size
    setting, meta, blocks = _header(f, path, file_size)
    info = {"setting": meta.get("setting"), "blocks": len(blocks), "file_bytes": file_size,
            "records": sum(b.coded + b.raw for b in blocks)}
    for key in ("pruned", "color_shift"):
        value = meta.get(key)
        if isinstance(value, int) and not isinstance(value, bool) and value > 0:
            info[key] = value
    return setting, meta, blocks, info


def read_records(path: str | os.PathLike):
    """Decode a ``.splatvq`` file to the records a ``.splatv`` holds.

    Blocks are independent: two are decoded at a time, their stored bytes read in
    file order, and a damaged block is reported before any block after it.

    Returns
    -------
    records : (N, 16) uint32 ndarray
        Texture words, block after block.
    cameras : list
        The header's cameras.
    info : dict
        Setting, block count, file size and record count.
    """
    path = os.fspath(path)
    with open_input(path) as f:
        setting, meta, blocks, info = _opened(f, path)
        records = np.empty((info["records"], WORDS_PER_SPLAT), dtype="<u4")
        at = 0
        for out in _decoded(f, path, setting, blocks):
            records[at:at + len(out)] = out
            at += len(out)
    return records, list(meta.get("cameras", [])), info


def converted_texture(path: str | os.PathLike, put) -> np.ndarray:
    """The texture a conversion of a ``.splatvq`` file to ``.splatv`` holds, given a block at a time.

    ``put(records)`` is called with each block's records as :func:`read_records`
    decodes them, in file order; the conversion's texture is then ``records[order]``, zero padded to
    whole rows: the records in the order a ``.splatv`` write of the scene
    :func:`read` gives stores them (:func:`splatv.texture_key`; not quite the
    file's own, whose key is of the halves and the alpha byte, not of the decoded
    columns). What :func:`splatconv.render.frames.Source.texture` gives for that
    scene, bit for bit, without the scene or the texture held whole.

    Returns
    -------
    order : (N,) intp ndarray
    """
    path = os.fspath(path)
    with open_input(path) as f:
        setting, _meta, blocks, info = _opened(f, path)
        key = np.empty(info["records"])
        at = 0
        for out in _decoded(f, path, setting, blocks):
            put(out)
            key[at:at + len(out)] = splatv.texture_key(out)
            at += len(out)
    return importance_order(key)


def decode(path: str | os.PathLike) -> np.ndarray:
    """The texture words of a ``.splatvq`` file: ``(N, 16) uint32`` (what the page decodes)."""
    return read_records(path)[0]


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a ``.splatvq`` file into a :class:`Scene`: each block's records decoded as a ``.splatv`` reader
    does, straight into the scene's table (the records of a block or two are all a read holds besides it)."""
    path = os.fspath(path)
    with open_input(path) as f:
        setting, meta, blocks, info = _opened(f, path)
        _rows, columns = lite_rows(info["records"])
        tally = splatv.new_tally()
        at = 0
        for out in _decoded(f, path, setting, blocks):
            splatv.decode_rows(out, columns, at, tally)
            at += len(out)
    return Scene(columns=columns, cameras=list(meta.get("cameras", [])), variant=FORMAT.name, meta=info,
                 notes=splatv.decode_notes(tally))


def scan(path: str | os.PathLike, **_options) -> Scan:
    """Read a ``.splatvq`` file a block at a time (:class:`~splatconv.formats.base.Scan`): what :func:`read`
    gives, a block a piece."""
    path = os.fspath(path)
    out = Scan(variant=FORMAT.name)

    def pieces():
        with open_input(path) as f:
            setting, meta, blocks, info = _opened(f, path)
            out.cameras = list(meta.get("cameras", []))
            out.meta.update(info)
            tally = splatv.new_tally()
            for records in _decoded(f, path, setting, blocks):
                _rows, columns = lite_rows(len(records))
                splatv.decode_rows(records, columns, 0, tally)
                yield columns
        out.notes.extend(splatv.decode_notes(tally))

    out.pieces = pieces()
    return out


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats :func:`read` gives, from the block table; None for a header :func:`read` refuses."""
    path = os.fspath(path)
    try:
        with open_input(path) as f:
            _setting, _meta, blocks = _header(f, path, os.fstat(f.fileno()).st_size)
    except FormatError:
        return None
    return sum(b.coded + b.raw for b in blocks)


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats :func:`read` gives for ``path``: its block table's count (0: a header it refuses).

    The table is checked against the file's size before it is trusted, and no
    file holds more than :data:`MAX_SPLATS`.
    """
    return splat_count(path) or 0


def check(path: str | os.PathLike) -> None:
    """Prove a ``.splatvq`` file whole, as :func:`read` would, without holding its records.

    The preamble, header and block table are checked, then every block is
    decoded and checked as :func:`read` decodes it, block by block and each
    dropped once checked: memory stays a few blocks whatever the file's size.
    What the page plays and ``--external`` publishes as it is passes this first.

    Raises
    ------
    FormatError
        Exactly as :func:`read` would.
    """
    path = os.fspath(path)
    with open_input(path) as f:
        setting, _meta, blocks = _header(f, path, os.fstat(f.fileno()).st_size)
        for _ in _decoded(f, path, setting, blocks):
            pass


def storage(scene: Scene) -> dict:
    """How a ``.splatvq`` stores each attribute group: :data:`STORAGE`, its colours quantized where the
    header says the encoder rounded them (``"color_shift"``)."""
    return {**STORAGE, "color": "quantized"} if scene.meta.get("color_shift") else STORAGE


def info_fields(meta: dict) -> dict:
    """What ``info`` shows of a ``.splatvq`` (its ``meta``): its setting, block count, and the splats pruned
    from it when its header says so."""
    fields = {"setting": meta.get("setting"), "blocks": meta.get("blocks")}
    if meta.get("pruned"):
        fields["pruned"] = meta["pruned"]
    return fields


FORMAT = Format(
    name="splatvq",
    suffixes=(".splatvq",),
    default_sort="importance",  # blocks in importance order: the page draws the most important splats first
    holds_empty=False,  # a file holds at least one drawable splat
    drawable_only=True,  # undrawable splats are left out but for those the depth sort needs (a note counts them)
    dynamic=True,  # motion and a temporal basis, quantized
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats,
    write=write,
    info_fields=info_fields, storage=storage,
    # Decoded to the viewer's texture, but not the texture itself: the page decodes
    # it in a worker, so it plays a .splatvq's bytes as they are, once every block
    # decodes as read() decodes it (a damaged file is never published).
    check_playable=check,
    converted_texture=converted_texture,
    prepare=prepare,
    # Its blocks inflate: a small file can declare millions of splats, so a read is held to the
    # decompression ceiling (the block table's count, before a block is decoded).
    expands=True,
    # The quality write option, the default setting first (for the help text).
    qualities=tuple(sorted(QUALITIES, key=lambda name: name != codec.DEFAULT_SETTING)),
    precisions=codec.PRECISIONS,
    tunings=codec.TUNINGS,
    floors=dict(codec.FLOORS),
    weighs=True,
)
