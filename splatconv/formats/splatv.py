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
from ..cameras import framing_camera, validate_cameras
from ..errors import FormatError, UnsupportedError
from ..model import COLUMNS, Scene

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

#: Rows packed at a time: bounds temporary memory and keeps work in cache.
BLOCK = 1 << 16


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


def _order(scene: Scene, sort: str, compat: bool, report: WriteReport) -> np.ndarray | None:
    """Row order of the output: None keeps the input order."""
    if sort == "none":
        return None
    key = importance(scene.columns)
    if compat:
        # splaTV keeps the key in a Float32Array and sorts with (b, a) => s[a] - s[b].
        with np.errstate(over="ignore"):
            key = key.astype(np.float32)
        nan = int(np.count_nonzero(np.isnan(key)))
        if nan:
            report.notes.append(
                f"{nan} splats have a NaN importance; splaTV's comparator makes their order "
                "engine-defined, splatconv puts them last")
    with np.errstate(invalid="ignore"):
        return np.argsort(-key, kind="stable")


def _halves(name: str, values: np.ndarray, compat: bool, counts: dict) -> np.ndarray:
    """Model column block -> half bits, applying exp() for logarithmic attributes."""
    c = counts.setdefault(name, packing.HalfCounts())
    if name in EXP_ATTRIBUTES:
        with np.errstate(over="ignore", invalid="ignore"):
            linear = np.exp(values.astype(np.float64))
            linear32 = linear.astype(np.float32) if compat else None
        nan = np.isnan(values)
        if compat:
            linear32[nan] = values[nan]
            return packing.float_to_half_splatvjs(linear32, c)
        out = packing.float_to_half(linear, c)
        if nan.any():
            out[nan] = packing.float_to_half(values[nan])
        return out
    if compat:
        return packing.float_to_half_splatvjs(values, c)
    return packing.float_to_half(values, c)


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
    words = np.zeros((m, WORDS_PER_SPLAT), dtype="<u4")
    for w, name in POSITION_WORDS.items():
        bits = packing.f32_bits(cols[name])
        if compat:
            # The browser reads positions through DataView.getFloat32 into a double,
            # which quiets signalling NaNs (sets the top mantissa bit).
            snan = ((bits & packing.F32_EXP_MASK) == packing.F32_EXP_MASK) & (bits & 0x007FFFFF != 0)
            bits = np.where(snan, bits | np.uint32(0x00400000), bits)
        words[:, w] = bits
    zero = np.zeros(m, dtype=np.uint16)
    for w, (lo, hi) in HALF_WORDS.items():
        low = _halves(lo, cols[lo], compat, report.half)
        high = zero if hi is None else _halves(hi, cols[hi], compat, report.half)
        words[:, w] = packing.pack_half2(low, high)
    with np.errstate(over="ignore", invalid="ignore"):
        rgb = [cols[f"f_dc_{i}"].astype(np.float64) * 255.0 for i in range(3)]
        alpha = _sigmoid255(cols["opacity"])
    channels = []
    for key, v in zip(("color", "color", "color", "alpha"), rgb + [alpha]):
        byte, clamped, nan = packing.unorm8_truncate(v) if compat else packing.unorm8_nearest(v)
        report.clamped[key] = report.clamped.get(key, 0) + clamped
        report.nan_bytes[key] = report.nan_bytes.get(key, 0) + nan
        channels.append(byte)
    words[:, COLOR_WORD] = packing.pack_rgba8(*channels)
    return words


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
    cameras = scene.cameras
    if not cameras:
        cameras = [framing_camera(scene.columns["x"], scene.columns["y"], scene.columns["z"])]
        report.notes.append("no cameras given; wrote one camera that frames the scene")
    stream.write(header_bytes(n, cameras))
    for block in _blocks(scene, sort, is_compat, report):
        stream.write(memoryview(block))
    padding = report.texheight * SPLATS_PER_ROW - n
    stream.write(bytes(padding * RECORD_BYTES))
    report.notes.extend(_write_notes(report, is_compat))
    return report


def _blocks(scene: Scene, sort: str | None, compat: bool, report: WriteReport):
    """Yield ``(M, 16) uint32`` record blocks of the scene in output order."""
    order = _order(scene, sort or "importance", compat, report)
    for start in range(0, scene.count, BLOCK):
        stop = min(start + BLOCK, scene.count)
        rows = slice(start, stop) if order is None else order[start:stop]
        yield pack_block(scene.take(rows), compat, report)


def encode(scene: Scene, *, compat: str | None = None, sort: str | None = "importance"):
    """The texture a write would produce, in memory (for rendering).

    Returns
    -------
    records : (texheight * 1024, 16) uint32 ndarray
        Padding records included, all zero.
    report : WriteReport
    """
    is_compat = compat == "splatv-js"
    report = WriteReport(count=scene.count, texheight=texture_height(scene.count))
    records = np.zeros((report.texheight * SPLATS_PER_ROW, WORDS_PER_SPLAT), dtype="<u4")
    start = 0
    for block in _blocks(scene, sort, is_compat, report):
        records[start:start + len(block)] = block
        start += len(block)
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
        buf = np.zeros(n_records * WORDS_PER_SPLAT, dtype="<u4")
        f.seek(start)
        got = f.readinto(memoryview(buf).cast("B")[:actual])
        if got != actual:  # pragma: no cover - the file changed under us
            raise FormatError(f"read {got} of {actual} texture bytes", path)
    records = buf.reshape(-1, WORDS_PER_SPLAT)
    used = np.flatnonzero(records.any(axis=1))
    count = int(used[-1]) + 1 if len(used) else 0
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


def decode_records(records: np.ndarray) -> tuple[dict, list]:
    """Texture records -> model columns, the exact inverse of the default writer.

    Parameters
    ----------
    records : (N, 16) uint32 ndarray

    Returns
    -------
    columns : dict of str to (N,) float32 ndarray
    notes : list of str
        Values the lite PLY layout cannot hold (negative values in exp() slots,
        data in the unused halves).
    """
    cols = {}
    notes = []
    for w, name in POSITION_WORDS.items():
        cols[name] = records[:, w].view(np.float32)
    for w, (lo_name, hi_name) in HALF_WORDS.items():
        lo, hi = packing.unpack_half2(records[:, w])
        for name, h in ((lo_name, lo), (hi_name, hi)):
            if name is None:
                stray = int(np.count_nonzero(h))
                if stray:
                    notes.append(f"word {w}: {stray} records carry data in the unused upper half; dropped")
                continue
            if name in EXP_ATTRIBUTES:
                negative = int(np.count_nonzero((h & 0x8000 != 0) & ~np.isnan(packing.HALF_TO_FLOAT[h])))
                if negative:
                    notes.append(f"{name}: {negative} negative values have no logarithm; written as "
                                 "NaN (-0 as -inf)")
                cols[name] = LOG_OF_HALF[h]
            else:
                cols[name] = packing.HALF_TO_FLOAT[h]
    r, g, b, a = packing.unpack_rgba8(records[:, COLOR_WORD])
    for i, byte in enumerate((r, g, b)):
        cols[f"f_dc_{i}"] = COLOR_OF_BYTE[byte]
    cols["opacity"] = LOGIT_OF_BYTE[a]
    return {name: cols[name] for name in COLUMNS}, notes


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
