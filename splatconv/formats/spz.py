"""Niantic's ``.spz``: a static scene, quantized attribute by attribute and compressed (specs/spz.md).

Read: versions 2 and 3 (one gzip stream: a 16-byte header, then the attribute
arrays) and 4 (a 32-byte plain header, a table of contents, one zstd stream an
array). Written: version 4, what PlayCanvas splat-transform 3.7 writes by
default (and the reference library's latest), zstd level 12 as the reference; a version 2 stream
(:func:`legacy_stream`) for glTF's SPZ compression extension (:mod:`splatconv.formats.gltf`).
Arrays, N splats, in this order::

    positions  9 N   x, y, z as 24-bit signed fixed point (value * 2^fractional_bits)
    alphas     N     sigmoid(opacity) * 255
    colors     3 N   f_dc * 0.15 * 255 + 127.5 (the degree-0 SH coefficient, not RGB)
    scales     3 N   (log scale + 10) * 16
    rotations  4 N   smallest three: 2 bits the largest component's index (x, y, z, w),
                     then three 10-bit (sign, 9-bit magnitude of |q| / sqrt(1/2)); 3 N in v2
    sh         K N   per splat, coefficient-major, channel-minor: (byte - 128) / 128; degree 1
                     rounded to 5 bits, higher degrees to 4 (written), as the reference does

Coordinates are stored as the scene holds them (no axis flip), as splat-transform
writes and reads them (the reference library's ``UNSPECIFIED``). A scene that moves
or fades is refused (bake a moment first); reading gives a static scene.
"""

from __future__ import annotations

import gzip
import os
import struct
import zlib

import numpy as np
import zstandard

from .. import model
from ..errors import FormatError, UnsupportedError
from ..files.inputs import open_input
from ..model import Scene
from ..progress import SILENT
from ..viewer import importance, importance_order, logit, sigmoid, wide
from ..wording import plural
from .base import (Format, Scan, WriteReport, fixed_storage, meta_fields, refuse_nonfinite_positions,
                   refuse_time_varying)
from .ply import SH_C0  # rgb = 0.5 + SH_C0 * f_dc: the model keeps RGB, .spz the coefficient

MAGIC = 0x5053474E  # "NGSP"
#: Version written; versions read.
VERSION = 4
READ_VERSIONS = (2, 3, 4)
LEGACY_HEADER = struct.Struct("<IIIBBBB")  # magic, version, points, sh degree, fractional bits, flags, reserved
V4_HEADER = struct.Struct("<IIIBBBBI12x")  # ... flags, streams, table of contents offset, 12 reserved bytes
TOC_ENTRY = struct.Struct("<QQ")  # compressed size, uncompressed size
FLAG_ANTIALIASED = 0x1
#: Fractional bits written when the positions fit (the reference's default): 1/4096 steps to +-2048.
FRACTIONAL_BITS = 12
COLOR_SCALE = 0.15
ZSTD_LEVEL = 12
#: Bits kept of each SH byte, degree 1 and the rest (the reference's defaults).
SH1_BITS, SH_REST_BITS = 5, 4
SQRT1_2 = np.sqrt(0.5)

#: How each attribute group is stored (see :data:`splatconv.compare.STORAGE_KINDS`).
STORAGE = {"position": "float32", "scale": "byte", "color": "byte", "opacity": "byte",
           "rotation": "unit_quaternion_byte", "motion": "none", "omega": "none", "trbf": "none"}


def _array_sizes(n: int, degree: int, version: int) -> list:
    """Bytes of each array: positions, alphas, colors, scales, rotations, sh."""
    return [9 * n, n, 3 * n, 3 * n, (3 if version == 2 else 4) * n, 3 * model.SH_COEFFS[degree] * n]


# --------------------------------------------------------------------------
# Reading


def _payload(path: str) -> tuple:
    """The header fields and the six arrays (bytes) of the ``.spz`` at ``path``."""
    with open_input(path) as f:
        raw = f.read()
    return unpack(raw, path)


def unpack(raw, path: str, where: tuple = ()) -> tuple:
    """``(version, N, SH degree, fractional bits, flags, the six arrays)`` of a ``.spz``'s bytes ``raw`` (a file,
    or a glTF buffer view holding one); errors name ``path`` and ``where``."""
    raw = bytes(raw)
    if not raw:
        raise FormatError("file is empty", path, where)
    if raw[:2] == b"\x1f\x8b":
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError, zlib.error) as e:
            raise FormatError(f"gzip stream is damaged ({e})", path, where) from None
        if len(raw) < LEGACY_HEADER.size:
            raise FormatError(f"header needs {LEGACY_HEADER.size} bytes, the stream holds {len(raw)}", path, where)
        magic, version, n, degree, bits, flags, _ = LEGACY_HEADER.unpack_from(raw)
        _check_header(magic, version, degree, path, where, legacy=True)
        sizes = _array_sizes(n, degree, version)
        need = LEGACY_HEADER.size + sum(sizes)
        if len(raw) < need:
            raise FormatError(f"{n:,} splats need {need:,} bytes, the stream holds {len(raw):,}; file truncated?",
                              path, where)
        arrays, at = [], LEGACY_HEADER.size
        for size in sizes:
            arrays.append(np.frombuffer(raw, np.uint8, size, at))
            at += size
        return version, n, degree, bits, flags, arrays
    if len(raw) < V4_HEADER.size:
        raise FormatError("not a .spz file (neither gzip nor a version 4 header)", path, where)
    magic, version, n, degree, bits, flags, streams, toc = V4_HEADER.unpack_from(raw)
    _check_header(magic, version, degree, path, where, legacy=False)
    sizes = [s for s in _array_sizes(n, degree, version) if s] if n else []
    if streams != len(sizes) and not (n == 0 and streams in (5, 6)):
        raise FormatError(f"header says {streams} streams; {n:,} splats of SH degree {degree} need {len(sizes)}",
                          path, where)
    if toc < V4_HEADER.size or toc + TOC_ENTRY.size * streams > len(raw):
        raise FormatError(f"table of contents at byte {toc:,} lies outside the file", path, where)
    arrays, at = [], toc + TOC_ENTRY.size * streams
    expected = _array_sizes(n, degree, version)
    for i in range(streams):
        packed, plain = TOC_ENTRY.unpack_from(raw, toc + i * TOC_ENTRY.size)
        if plain != expected[i] or at + packed > len(raw):
            raise FormatError(f"stream {i}: {plain:,} bytes declared, {expected[i]:,} expected, or it runs past "
                              "the end of the file; file truncated?", path, where)
        try:
            data = zstandard.ZstdDecompressor().decompress(raw[at:at + packed], max_output_size=plain)
        except zstandard.ZstdError as e:
            raise FormatError(f"stream {i}: zstd data is damaged ({e})", path, where) from None
        if len(data) != plain:
            raise FormatError(f"stream {i}: {len(data):,} bytes decompressed, {plain:,} declared", path, where)
        arrays.append(np.frombuffer(data, np.uint8))
        at += packed
    while len(arrays) < 6:
        arrays.append(np.zeros(0, np.uint8))
    return version, n, degree, bits, flags, arrays


def _check_header(magic: int, version: int, degree: int, path: str, where: tuple, legacy: bool) -> None:
    if magic != MAGIC:
        raise FormatError(f"not a .spz file (magic 0x{magic:08x}, expected 0x{MAGIC:08x})", path, where)
    if version not in READ_VERSIONS or (version == 4) == legacy:
        raise UnsupportedError(f".spz version {version} in a {'gzip' if legacy else 'plain'} container "
                               f"(read: {', '.join(map(str, READ_VERSIONS))})", path, where)
    if degree not in model.SH_COEFFS:
        raise UnsupportedError(f"SH degree {degree} (read: 0 to 3)", path, where)


def decode(version: int, n: int, degree: int, bits: int, arrays: list) -> dict:
    """The model columns of a ``.spz``'s six arrays (``(size,) uint8`` each): ``(N,) float32`` each."""
    pos, alpha, color, scale, rot, shb = arrays
    cols = {}
    xyz = decode_positions(pos, n, bits)
    for i, name in enumerate(model.POSITION):
        cols[name] = xyz[:, i]
    a = np.clip(alpha.astype(np.float64) / 255.0, 1e-6, 1 - 1e-6)
    cols["opacity"] = logit(a).astype(np.float32)  # clamped off 0 and 1, as splat-transform reads it
    dc = (color.reshape(n, 3).astype(np.float64) / 255.0 - 0.5) / COLOR_SCALE
    rgb = 0.5 + SH_C0 * dc
    for i, name in enumerate(model.COLOR):
        cols[name] = rgb[:, i].astype(np.float32)
    s = scale.reshape(n, 3).astype(np.float32) / np.float32(16) - np.float32(10)
    for i, name in enumerate(model.SCALE):
        cols[name] = s[:, i]
    q = _quaternions(rot, n, version)  # (n, 4) x, y, z, w
    for i, name in zip((3, 0, 1, 2), model.ROTATION):
        cols[name] = q[:, i]
    cols.update(model.static_columns(n))
    k = model.SH_COEFFS[degree]
    if k:
        values = (shb.reshape(n, k, 3).astype(np.float32) - np.float32(128)) / np.float32(128)
        for c in range(3):
            for j in range(k):
                cols[f"f_rest_{c * k + j}"] = values[:, j, c]
    return cols


def decode_positions(pos: np.ndarray, n: int, bits: int) -> np.ndarray:
    """Positions ``(n, 3) float32`` of the positions array (``(9 n,) uint8``: 24-bit fixed point)."""
    p = pos.reshape(n, 3, 3).astype(np.int32)
    fixed = p[:, :, 0] | (p[:, :, 1] << 8) | (p[:, :, 2] << 16)
    fixed = np.where(fixed & 0x800000, fixed - (1 << 24), fixed)
    return (fixed.astype(np.float64) / float(1 << bits)).astype(np.float32)


def legacy_header(raw) -> tuple | None:
    """The header fields ``(magic, version, N, SH degree, fractional bits, flags, reserved)`` at the start of
    a gzip stream ``raw`` (versions 2, 3), without inflating the rest; None when it holds no header."""
    try:
        head = zlib.decompressobj(31).decompress(bytes(raw[:1 << 16]), LEGACY_HEADER.size)
    except zlib.error:
        return None
    return LEGACY_HEADER.unpack_from(head) if len(head) >= LEGACY_HEADER.size else None


def _quaternions(rot: np.ndarray, n: int, version: int) -> np.ndarray:
    """Unit quaternions (x, y, z, w) ``(n, 4) float32`` of the rotation bytes."""
    if version == 2:
        xyz = rot.reshape(n, 3).astype(np.float32) / np.float32(127.5) - np.float32(1)
        w = np.sqrt(np.maximum(0.0, 1.0 - (xyz * xyz).sum(axis=1)))
        return np.concatenate([xyz, w[:, None]], axis=1).astype(np.float32)
    word = rot.reshape(n, 4).copy().view("<u4")[:, 0].astype(np.uint32)
    largest = (word >> 30).astype(np.intp)
    q = np.zeros((n, 4), np.float32)
    # The three smaller components, last first, fill the indices other than the largest, in order.
    others = np.array([[j for j in range(4) if j != i] for i in range(4)])[largest]  # (n, 3)
    for slot in (2, 1, 0):
        mag = (word & np.uint32(511)).astype(np.float32)
        neg = ((word >> 9) & np.uint32(1)).astype(bool)
        word = word >> 10
        v = np.float32(SQRT1_2) * mag / np.float32(511)
        q[np.arange(n), others[:, slot]] = np.where(neg, -v, v)
    q[np.arange(n), largest] = np.sqrt(np.maximum(0.0, 1.0 - (q * q).sum(axis=1)))
    return q


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a ``.spz`` file (version 2, 3 or 4) as a static :class:`Scene`, with its SH bands."""
    path = os.fspath(path)
    version, n, degree, bits, flags, arrays = _payload(path)
    meta = {"file_bytes": os.path.getsize(path), "version": version, "sh_degree": degree,
            "fractional_bits": bits, "antialiased": bool(flags & FLAG_ANTIALIASED)}
    notes = []
    if flags & FLAG_ANTIALIASED:
        notes.append("trained with antialiasing (the flag is kept in no other format)")
    return Scene(columns=decode(version, n, degree, bits, arrays), variant=model.VARIANT_3DGS, meta=meta,
                 notes=notes)


def scan(path: str | os.PathLike, **options) -> Scan:
    """Read a ``.spz`` for ``info``: the arrays are compressed whole, so the scene comes as one piece
    (a ``.spz`` is a fifth of the scene it holds)."""
    out = Scan(variant=model.VARIANT_3DGS)

    def pieces():
        scene = read(path, **options)
        out.meta.update(scene.meta)
        out.notes.extend(scene.notes)
        yield {name: scene.columns[name] for name in model.COLUMNS}

    out.pieces = pieces()
    return out


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats a ``.spz`` declares (its header), or None when only reading tells."""
    try:
        with open_input(os.fspath(path)) as f:
            head = f.read(1 << 16)
        if head[:2] == b"\x1f\x8b":
            fields = legacy_header(head)
            return fields[2] if fields else None
        return V4_HEADER.unpack_from(head)[2] if len(head) >= V4_HEADER.size else None
    except (FormatError, zlib.error, struct.error):
        return None


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats a ``.spz`` gives: its header's count (0 for one it refuses)."""
    return splat_count(path) or 0


# --------------------------------------------------------------------------
# Writing


def _fractional_bits(extent: float) -> int:
    """The most fractional bits (up to :data:`FRACTIONAL_BITS`) at which a position ``extent`` from the
    origin (the farthest coordinate's size) fits 24 bits."""
    bits = FRACTIONAL_BITS
    while bits > 0 and extent * (1 << bits) > (1 << 23) - 1:
        bits -= 1
    if extent * (1 << bits) > (1 << 23) - 1:
        raise UnsupportedError(f"a position {extent:.6g} from the origin is past what .spz holds (+-{(1 << 23) - 1:,})")
    return bits


def _byte(values: np.ndarray) -> np.ndarray:
    """Values in byte units as the nearest of 0..255 (NaN as 0)."""
    return np.clip(np.nan_to_num(np.rint(values)), 0, 255).astype(np.uint8)


def _rounding_table(bits: int) -> np.ndarray:
    """Byte ``b`` of an SH coefficient -> ``b`` rounded to ``bits`` (the reference's quantizeSH): ``(256,) uint8``."""
    bucket = 1 << (8 - bits)
    q = np.arange(256)
    return np.minimum((q + bucket // 2) // bucket * bucket, 255).astype(np.uint8)


def _sh_bytes(values: np.ndarray, rounding: np.ndarray) -> np.ndarray:
    """SH coefficients ``(M, K) float32`` as bytes, ``(M, K) uint8``: rint(v * 128 + 128) (NaN as 128), in
    0..255, rounded by column ``k``'s ``rounding[k]`` (:func:`_rounding_table`).

    In float32: v * 128 is exact, and rint(v * 128 + 128) = rint(v * 128) + 128 for a float32 v (the
    reference computes in double), so clamping rint(v * 128) to -128..127 first gives the same bytes.
    """
    with np.errstate(over="ignore", invalid="ignore"):  # past float32's range: inf, clamped below
        x = np.multiply(values, np.float32(128.0), dtype=np.float32)
        np.rint(x, out=x)
        x[np.isnan(x)] = 0.0
        np.clip(x, -128.0, 127.0, out=x)
    q = (x.astype(np.int16) + 128).astype(np.uint8)
    return _round_columns(q, rounding)


def _round_columns(q: np.ndarray, rounding: np.ndarray) -> np.ndarray:
    """Bytes ``(M, K)`` each rounded by its column's table ``rounding[k]`` (``(K, 256) uint8``)."""
    flat = rounding.reshape(-1)
    offset = (np.arange(q.shape[1], dtype=np.intp) * 256)[None, :]
    return np.take(flat, q.astype(np.intp) + offset)


def _smallest_three(q: np.ndarray) -> np.ndarray:
    """Quaternions (w, x, y, z) ``(n, 4)`` as smallest-three words ``(n,) <u4`` (x, y, z, w order)."""
    xyzw = q[:, [1, 2, 3, 0]].astype(np.float64)
    length = np.sqrt((xyzw * xyzw).sum(axis=1, keepdims=True))
    with np.errstate(invalid="ignore", divide="ignore"):
        xyzw = xyzw / length
    xyzw[~np.isfinite(xyzw).all(axis=1)] = (0.0, 0.0, 0.0, 1.0)
    largest = np.argmax(np.abs(xyzw), axis=1)
    n = len(q)
    negate = xyzw[np.arange(n), largest] < 0
    word = largest.astype(np.uint32)
    for i in range(4):
        take = largest != i
        v = xyzw[:, i]
        neg = ((v < 0) ^ negate).astype(np.uint32)
        mag = np.minimum(np.floor(511.0 * np.abs(v) / SQRT1_2 + 0.5), 511).astype(np.uint32)
        word = np.where(take, (word << np.uint32(10)) | (neg << np.uint32(9)) | mag, word)
    return word.astype("<u4")


def _first_three(q: np.ndarray) -> np.ndarray:
    """Quaternions (w, x, y, z) ``(n, 4)`` as version 2's bytes ``(n, 3) uint8``: x, y, z of the unit
    quaternion with w >= 0, each * 127.5 + 127.5 (w is derived when read)."""
    xyzw = q[:, [1, 2, 3, 0]].astype(np.float64)
    length = np.sqrt((xyzw * xyzw).sum(axis=1, keepdims=True))
    with np.errstate(invalid="ignore", divide="ignore"):
        xyzw = xyzw / length
    xyzw[~np.isfinite(xyzw).all(axis=1)] = (0.0, 0.0, 0.0, 1.0)
    xyzw[xyzw[:, 3] < 0] *= -1.0
    return _byte(xyzw[:, :3] * 127.5 + 127.5)


#: Rows encoded per step: their columns' stretch of a row table (a PLY read in place) and the float64
#: temporaries stay in cache.
ENCODE_BLOCK = 1 << 14


def _positions_checked(cols: dict, n: int) -> int:
    """The fractional bits the positions are written with (:func:`_fractional_bits`), once they are known
    finite.

    Raises
    ------
    UnsupportedError
        For a NaN or infinite position.
    """
    extent, bad = 0.0, 0
    for start in range(0, n, ENCODE_BLOCK):
        xyz = np.stack([np.asarray(cols[name])[start:start + ENCODE_BLOCK] for name in model.POSITION], axis=1)
        finite = np.isfinite(xyz).all(axis=1)
        bad += int(np.count_nonzero(~finite))
        if not bad:
            extent = max(extent, float(np.abs(xyz).max()))
    refuse_nonfinite_positions(bad, ".spz holds fixed point")
    return _fractional_bits(extent)


def encode(scene: Scene, sort: str | None = None, version: int = VERSION) -> tuple:
    """The six arrays (bytes) of ``scene`` as a ``.spz`` of ``version`` holds them, its fractional bits, and
    counts of what the bytes changed.

    Every splat's bytes depend on it alone (and on the fractional bits, from all positions): they are
    encoded in the scene's row order, a block of rows at a time, and put in the asked order at the end.
    """
    cols = scene.columns
    n = scene.count
    degree = scene.sh_degree
    k = model.SH_COEFFS[degree]
    bits = _positions_checked(cols, n)
    pos = np.empty((n, 3, 3), np.uint8)
    alpha = np.empty(n, np.uint8)
    color = np.empty((n, 3), np.uint8)
    scale = np.empty((n, 3), np.uint8)
    rot = np.empty((n, 3), np.uint8) if version == 2 else np.empty(n, "<u4")
    shb = np.empty((n, k, 3), np.uint8)
    sh_names = model.sh_names(degree)
    # Column c * k + j (channel c, coefficient j) is rounded to 5 bits for degree 1 (j < 3), 4 above.
    rounding = np.stack([_rounding_table(SH1_BITS if j < 3 else SH_REST_BITS) for _c in range(3) for j in range(k)]) \
        if k else None
    clamped = {"color": 0, "scale": 0}
    step = np.float32(1 << bits)
    for start in range(0, n, ENCODE_BLOCK):
        rows = slice(start, min(start + ENCODE_BLOCK, n))
        for i, name in enumerate(model.POSITION):
            # x * 2^bits is exact in float32 and within 24 bits: its rint is the fixed-point value.
            fixed = np.rint(np.asarray(cols[name])[rows] * step).astype("<i4")
            pos[rows, i] = fixed.view(np.uint8).reshape(-1, 4)[:, :3]
        with np.errstate(over="ignore", invalid="ignore"):
            alpha[rows] = _byte(255.0 * sigmoid(np.asarray(cols["opacity"])[rows]))
            rgb = np.stack([wide(np.asarray(cols[name])[rows]) for name in model.COLOR], axis=1)
            dc = (rgb - 0.5) / SH_C0
            c = np.rint((dc * COLOR_SCALE + 0.5) * 255.0)
            log_scale = np.stack([wide(np.asarray(cols[name])[rows]) for name in model.SCALE], axis=1)
            s = np.rint((log_scale + 10.0) * 16.0)
            clamped["color"] += int(np.count_nonzero((c < 0) | (c > 255)))
            clamped["scale"] += int(np.count_nonzero((s < 0) | (s > 255)))
        color[rows] = _byte(c)
        scale[rows] = _byte(s)
        q = np.stack([np.asarray(cols[name])[rows] for name in model.ROTATION], axis=1)
        rot[rows] = _first_three(q) if version == 2 else _smallest_three(q)
        if k:
            block = _float32_block([np.asarray(cols[name])[rows] for name in sh_names])
            shb[rows] = _sh_bytes(block, rounding).reshape(-1, 3, k).transpose(0, 2, 1)
    if sort == "importance":
        order = importance_order(importance(cols))
        pos, alpha, color, scale, rot, shb = (a[order] for a in (pos, alpha, color, scale, rot, shb))
    arrays = [pos.reshape(-1), alpha, color.reshape(-1), scale.reshape(-1), rot.reshape(-1).view(np.uint8),
              shb.reshape(-1)]
    return arrays, bits, clamped, degree


def _float32_block(columns: list) -> np.ndarray:
    """Columns ``(M,) float32`` side by side, ``(M, K) float32``: one copy of a stretch of each row when they
    are neighbouring fields of one row table (a PLY read in place), else a stack."""
    found = model.row_fields(columns)
    if found is not None:
        matrix, fields = found
        if fields == list(range(len(columns))):
            return np.array(matrix)
    return np.stack(columns, axis=1).astype(np.float32, copy=False)


def write(scene: Scene, stream, *, sort: str | None = None, progress=SILENT, **_options) -> WriteReport:
    """Write ``scene`` as a version-4 ``.spz`` (see the module docstring).

    Raises
    ------
    UnsupportedError
        For a scene that moves or fades over time, or a position .spz cannot hold.
    """
    refuse_time_varying(scene.columns, "a .spz file")
    n = scene.count
    report = WriteReport(count=n)
    with progress.stage("writing", n, "splat") as advance:
        arrays, bits, clamped, degree = encode(scene, sort)
        streams = [a for a in arrays if a.size] if n else []
        packer = zstandard.ZstdCompressor(level=ZSTD_LEVEL, threads=-1)
        packed = [packer.compress(a.tobytes()) for a in streams]
        stream.write(V4_HEADER.pack(MAGIC, VERSION, n, degree, bits, 0, len(streams), V4_HEADER.size))
        for a, p in zip(streams, packed):
            stream.write(TOC_ENTRY.pack(len(p), a.size))
        for p in packed:
            stream.write(p)
        advance(n)
    report.notes.extend(_notes(n, bits, clamped, degree))
    return report


def legacy_stream(scene: Scene, sort: str | None = None, version: int = 2) -> tuple:
    """``scene`` as the gzip stream of a ``.spz`` of ``version`` 2 or 3 (a 16-byte header, then the arrays;
    specs/spz.md), and the notes on what quantizing it changed. Positions, rotations and SH are stored as
    ``scene`` holds them: a caller wanting another frame turns the scene first.

    Raises
    ------
    UnsupportedError
        For a NaN or infinite position, or one .spz cannot hold.
    """
    n = scene.count
    arrays, bits, clamped, degree = encode(scene, sort, version)
    head = LEGACY_HEADER.pack(MAGIC, version, n, degree, bits, 0, 0)
    # mtime 0: two writes of one scene give identical bytes; level 6 is zlib's default, the reference's.
    data = gzip.compress(head + b"".join(a.tobytes() for a in arrays), compresslevel=6, mtime=0)
    return data, _notes(n, bits, clamped, degree, version)


def _notes(n: int, bits: int, clamped: dict, degree: int, version: int = VERSION) -> list:
    rotation = "rotation to 3 bytes (x, y, z)" if version == 2 else "rotation to bytes"
    notes = [f"quantized to .spz: positions to 1/{1 << bits:,} (24-bit fixed point), colour, opacity, scale "
             f"to bytes, {rotation}" + (f", SH degree 1-{degree} bands to 5 and 4 bits" if degree else "")]
    if bits < FRACTIONAL_BITS:
        notes.append(f"position: {bits} fractional bits (of {FRACTIONAL_BITS}) so that the farthest splat fits")
    if clamped["color"]:
        notes.append(f"color: {plural(clamped['color'], 'value')} outside what a byte holds clamped")
    if clamped["scale"]:
        notes.append(f"scale: {plural(clamped['scale'], 'value')} outside log scale [-10, 5.94] clamped")
    return notes




FORMAT = Format(
    name="spz",
    suffixes=(".spz",),
    default_sort="none",
    holds_empty=False,
    dynamic=False,
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats,
    write=write, holds_sh=True, expands=True,
    info_fields=meta_fields('version', 'sh_degree', 'fractional_bits', 'antialiased'), storage=fixed_storage(STORAGE),
)
