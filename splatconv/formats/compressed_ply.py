"""PlayCanvas / SuperSplat ``compressed.ply``: a static scene quantized in chunks of 256 splats.

The layout is written down in specs/compressed_ply.md.

A binary PLY of three elements, in this order::

    chunk   ceil(N / 256) rows of 18 floats: each chunk's bounds of position, log scale and colour (RGB)
    vertex  N rows of four uint32 words:
            packed_position  x, y, z within the chunk's bounds, 11-10-11 bits (x in the top 11)
            packed_rotation  smallest three: the largest component's index (rot_0..3) in the top 2 bits,
                             then the other three in index order, 10 bits each, q * sqrt(1/2) + 1/2
            packed_scale     log scales within the chunk's bounds, 11-10-11 bits
            packed_color     r, g, b within the chunk's bounds, then sigmoid(opacity), 8 bits each (r on top)
    sh      N rows of uchar f_rest_0..3K-1 (optional): trunc((f_rest / 8 + 1/2) * 256), K = 3, 8, 15

A value is quantized to ``floor(t * (2^bits - 1) + 1/2)`` of ``t``, its place between
the chunk's minimum (0) and maximum (1), and read back as ``lerp(min, max, q / (2^bits - 1))``.
Written as PlayCanvas splat-transform writes it: splats in Morton (Z) order so that
a chunk holds neighbours, the last chunk's bounds from its splats alone, log-scale
bounds clamped to [-20, 20]. Read: the chunk element with or without its colour
bounds (SuperSplat's first files had none: the colour bytes are then RGB themselves),
and a compressed PLY named ``.ply`` (:mod:`splatconv.formats.ply` hands it here).
A scene that moves or fades is refused (bake a moment first).
"""

from __future__ import annotations

import os

import numpy as np

from .. import model, packing
from ..errors import FormatError, UnsupportedError
from ..model import Scene
from ..progress import SILENT
from ..viewer import importance, logit, sigmoid, wide
from ..wording import plural
from . import ply_container as container
from .base import Format, Scan, WriteReport, fixed_storage, refuse_nonfinite_positions, refuse_time_varying

#: Splats a chunk.
CHUNK_SPLATS = 256
#: The chunk element's properties, float32, as written; SuperSplat's first files stop after the scales.
CHUNK_PROPERTIES = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                    "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z",
                    "min_r", "min_g", "min_b", "max_r", "max_g", "max_b")
CHUNK_PROPERTIES_NO_COLOR = CHUNK_PROPERTIES[:12]
#: The vertex element's properties, uint32.
PACKED = ("packed_position", "packed_rotation", "packed_scale", "packed_color")
#: The property whose presence in ``vertex`` marks the layout (as splat-transform decides it).
MARKER = PACKED[0]
#: (shift, bits) of each field of an 11-10-11 word (positions, scales) and of the colour word.
WORD_111011 = ((21, 11), (11, 10), (0, 11))
WORD_8888 = ((24, 8), (16, 8), (8, 8), (0, 8))
#: Bits of each rotation component; the largest component's index sits above the three.
ROTATION_BITS = 10
#: A stored rotation component is q * ROTATION_NORM + 1/2 (|q| <= sqrt(1/2) for all but the largest).
ROTATION_NORM = np.sqrt(0.5)
#: Log-scale bounds are clamped to +-this (infinite scales, as the reference writer does).
SCALE_LIMIT = 20.0
#: A splat more than this many robust scene extents from the middle (:func:`splatconv.model.far_rows`)
#: is put in a chunk of far splats only.
FAR_EXTENTS = 4096.0
#: A chunk's range below this stores every value as its minimum.
MIN_RANGE = 1e-5
#: An SH coefficient v is stored as trunc((v / SH_RANGE + 1/2) * 256): [-4, 4) in 256 steps of 1/32.
SH_RANGE = 8.0
#: The PLY element and value types, as written.
ELEMENT_TYPES = {"chunk": "f4", "vertex": "u4", "sh": "u1"}
#: What ``meta["layout"]`` says of a scene read from this layout (also through ``.ply``).
LAYOUT = "compressed"
#: How each attribute group is stored (see :data:`splatconv.compare.STORAGE_KINDS`).
STORAGE = {"position": "quantized", "scale": "quantized", "color": "quantized", "opacity": "byte",
           "rotation": "quantized", "motion": "none", "omega": "none", "trbf": "none"}
CHUNK_DTYPE = np.dtype([(name, "<f4") for name in CHUNK_PROPERTIES])
VERTEX_DTYPE = np.dtype([(name, "<u4") for name in PACKED])
#: Rows a piece of :func:`scan` (a whole number of chunks).
SCAN_ROWS = 1 << 16


def is_compressed(header) -> bool:
    """Whether a parsed PLY header (:class:`~splatconv.formats.ply_container.Header`) is of this layout:
    its ``vertex`` element has a ``packed_position`` property."""
    vertex = header.element("vertex")
    return vertex is not None and any(p.name == MARKER for p in vertex.properties)


# --------------------------------------------------------------------------
# Reading


def _element(header, name: str, needed, path: str, optional: bool = False):
    """The element ``name``, checked to hold each of ``needed`` (or, with ``needed`` None, only ``f_rest_*``)
    as one value of its layout type (:data:`ELEMENT_TYPES`)."""
    element = header.element(name)
    if element is None:
        if optional:
            return None
        raise FormatError(f"compressed PLY without a '{name}' element", path)
    code = ELEMENT_TYPES[name]
    props = {p.name: p for p in element.properties}
    for prop_name in needed if needed is not None else props:
        prop = props.get(prop_name)
        if prop is None:
            raise FormatError(f"compressed PLY: no property '{prop_name}'", path, (f"element '{name}'",))
        if prop.is_list or prop.val_dtype != code:
            kind = "a list" if prop.is_list else np.dtype(prop.val_dtype).name
            raise FormatError(f"{kind}, not the {np.dtype(code).name} a compressed PLY stores", path,
                              (f"element '{name}'", f"property '{prop_name}'"))
    return element


def _sh_degree(element, path: str) -> int:
    """The SH degree the ``sh`` element's ``f_rest_*`` properties hold (0 without the element)."""
    if element is None:
        return 0
    names = [p.name for p in element.properties]
    for degree in (1, 2, 3):
        if sorted(names) == sorted(model.sh_names(degree)):
            return degree
    raise FormatError(f"{len(names)} properties, not the f_rest_* of SH degree 1, 2 or 3 (9, 24 or 45)", path,
                      ("element 'sh'",))


class _Layout:
    """A compressed PLY read as far as its rows: chunk bounds (float64), packed words, SH bytes, facts."""

    def __init__(self, parsed, path: str):
        header = parsed.header
        if header.format == "ascii":
            raise UnsupportedError("an ASCII compressed PLY (the layout is binary)", path)
        chunk = _element(header, "chunk", CHUNK_PROPERTIES_NO_COLOR, path)
        _element(header, "vertex", PACKED, path)
        has_color = all(any(p.name == name for p in chunk.properties) for name in CHUNK_PROPERTIES[12:])
        if has_color:
            _element(header, "chunk", CHUNK_PROPERTIES, path)
        sh = _element(header, "sh", None, path, optional=True)
        self.degree = _sh_degree(sh, path)
        rows = parsed.elements
        for element in ("chunk", "vertex") + (("sh",) if sh is not None else ()):
            if element not in rows:  # after an element of lists of varying length, left unread
                raise UnsupportedError(f"element '{element}' after an element of lists of varying length", path)
        self.vertex = rows["vertex"]
        n = len(self.vertex)
        if sh is not None and sh.count != n:
            raise FormatError(f"{sh.count:,} rows for {plural(n, 'splat')}", path, ("element 'sh'",))
        need = -(-n // CHUNK_SPLATS)
        if chunk.count < need:
            raise FormatError(f"{chunk.count:,} chunks for {plural(n, 'splat')}: {need:,} needed, one per "
                              f"{CHUNK_SPLATS}", path, ("element 'chunk'",))
        self.notes = [] if chunk.count == need else [f"{chunk.count - need:,} chunks past the {need:,} the splats "
                                                      "use ignored"]
        names = CHUNK_PROPERTIES if has_color else CHUNK_PROPERTIES_NO_COLOR
        bounds = rows["chunk"][:need]
        self.bounds = {name: wide(bounds[name]) for name in names}
        for name in names:
            bad = np.flatnonzero(~np.isfinite(self.bounds[name]))
            if bad.size:
                raise FormatError(f"row {bad[0]}: {self.bounds[name][bad[0]]} is not a finite bound", path,
                                  ("element 'chunk'", f"property '{name}'"))
        self.has_color = has_color
        self.sh = rows["sh"] if sh is not None else None
        self.parsed = parsed
        self.chunks = chunk.count

    def meta(self, path: str) -> dict:
        return {"file_bytes": os.path.getsize(path), "layout": LAYOUT, "format": self.parsed.header.format,
                "chunk_count": self.chunks, "chunk_color": self.has_color, "sh_degree": self.degree}

    def piece(self, start: int, stop: int) -> dict:
        """The model columns of splats ``start`` to ``stop`` (``start`` a multiple of :data:`CHUNK_SPLATS`)."""
        v = self.vertex[start:stop]
        first, last = start // CHUNK_SPLATS, -(-stop // CHUNK_SPLATS)

        def bound(name: str) -> np.ndarray:  # each splat's chunk's bound
            return np.repeat(self.bounds[name][first:last], CHUNK_SPLATS)[:stop - start]

        def lerp(lo: str, hi: str, word, shift: int, bits: int) -> np.ndarray:
            t = ((word >> np.uint32(shift)) & np.uint32((1 << bits) - 1)) / float((1 << bits) - 1)
            return (bound(lo) * (1.0 - t) + bound(hi) * t).astype(np.float32)

        cols = {}
        word = np.asarray(v["packed_position"], dtype=np.uint32)
        for name, axis, (shift, bits) in zip(model.POSITION, "xyz", WORD_111011):
            cols[name] = lerp(f"min_{axis}", f"max_{axis}", word, shift, bits)
        word = np.asarray(v["packed_scale"], dtype=np.uint32)
        for name, axis, (shift, bits) in zip(model.SCALE, "xyz", WORD_111011):
            cols[name] = lerp(f"min_scale_{axis}", f"max_scale_{axis}", word, shift, bits)
        word = np.asarray(v["packed_color"], dtype=np.uint32)
        for name, axis, (shift, bits) in zip(model.COLOR, "rgb", WORD_8888):
            if self.has_color:
                cols[name] = lerp(f"min_{axis}", f"max_{axis}", word, shift, bits)
            else:
                cols[name] = _UNIT_BYTE[((word >> np.uint32(shift)) & np.uint32(255)).astype(np.intp)]
        cols["opacity"] = _OPACITY_BYTE[(word & np.uint32(255)).astype(np.intp)]
        cols.update(zip(model.ROTATION, _unpack_rotation(np.asarray(v["packed_rotation"], dtype=np.uint32))))
        cols.update(model.static_columns(stop - start))
        if self.sh is not None:
            block = self.sh[start:stop]
            for name in model.sh_names(self.degree):
                # A table indexed by intp: numpy's gather by a uint8 index is many times slower.
                cols[name] = _SH_BYTE[np.asarray(block[name]).astype(np.intp)]
        return cols


#: What a byte reads as, by table: colour without chunk bounds (b / 255), opacity (the logit of b / 255,
#: kept off 0 and 1 so that it is finite), an SH coefficient (0: -4, 255: +4, else (b + 1/2) / 256 * 8 - 4).
_BYTES = np.arange(256, dtype=np.float64)
_UNIT_BYTE = (_BYTES / 255).astype(np.float32)
_OPACITY_BYTE = logit(np.clip(_BYTES / 255, 1e-6, 1 - 1e-6)).astype(np.float32)
_SH_BYTE = ((np.where(_BYTES == 0, 0.0, np.where(_BYTES == 255, 1.0, (_BYTES + 0.5) / 256)) - 0.5)
            * SH_RANGE).astype(np.float32)


def _unpack_rotation(word: np.ndarray) -> list:
    """The ``rot_0..3`` columns (``(N,) float32`` each) of smallest-three words ``(N,) uint32``."""
    mask = np.uint32((1 << ROTATION_BITS) - 1)
    three = [((word >> np.uint32(shift)) & mask) * np.float32(1 / (float(mask) * ROTATION_NORM))
             - np.float32(0.5 / ROTATION_NORM) for shift in (20, 10, 0)]
    largest = word >> np.uint32(3 * ROTATION_BITS)
    rest = np.sqrt(np.maximum(np.float32(0), np.float32(1) - (three[0] ** 2 + three[1] ** 2 + three[2] ** 2)))
    # Component i is the largest, or the i-th of the three when the largest comes after it, else the (i-1)-th.
    out = []
    for i in range(4):
        after, before = three[min(i, 2)], three[max(i - 1, 0)]
        out.append(np.where(largest == i, rest, np.where(largest > i, after, before)).astype(np.float32))
    return out


def scene_from(parsed, path: str) -> Scene:
    """The :class:`Scene` of a PLY of this layout read as far as its rows (``container.read_rows``)."""
    layout = _Layout(parsed, path)
    columns = layout.piece(0, len(layout.vertex))
    return Scene(columns=columns, variant=model.VARIANT_3DGS, meta=layout.meta(path),
                 notes=parsed.notes + layout.notes)


def pieces_from(parsed, path: str, out: Scan):
    """What :func:`scan` yields of a PLY of this layout read as far as its rows, filling ``out``."""
    layout = _Layout(parsed, path)
    out.variant = model.VARIANT_3DGS
    out.meta.update(layout.meta(path))
    n = len(layout.vertex)
    for start in range(0, n, SCAN_ROWS):
        yield layout.piece(start, min(start + SCAN_ROWS, n))
    out.notes.extend(parsed.notes + layout.notes)


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a compressed PLY as a static :class:`Scene`, with its SH bands."""
    path = os.fspath(path)
    parsed = container.read_rows(path)
    _refuse_plain(parsed, path)
    return scene_from(parsed, path)


def _refuse_plain(parsed, path: str) -> None:
    if not is_compressed(parsed.header):
        raise FormatError(f"not a compressed PLY: element 'vertex' has no '{MARKER}' (a plain PLY reads as .ply)",
                          path)


def scan(path: str | os.PathLike, **_options) -> Scan:
    """Read a compressed PLY a piece at a time (:data:`SCAN_ROWS` splats a piece) for ``info``."""
    path = os.fspath(path)
    out = Scan(variant=model.VARIANT_3DGS)

    def pieces():
        parsed = container.read_rows(path)
        _refuse_plain(parsed, path)
        yield from pieces_from(parsed, path, out)

    out.pieces = pieces()
    return out


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats the header declares (its vertex count), or None when only reading tells."""
    return container.vertex_count(os.fspath(path))


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats a read gives: the header's vertex count (0 for one it refuses)."""
    return splat_count(path) or 0


def declared_size(head: bytes):
    """File size the header at the start of ``head`` declares (bounds the decompression of a ``.zst``)."""
    return container.declared_size(head)


# --------------------------------------------------------------------------
# Writing


def morton_order(xyz: np.ndarray) -> np.ndarray:
    """Indices that put positions ``(N, 3)`` (finite) in Morton (Z) order within their bounds: ``(N,) intp``,
    equal codes in input order.

    Each axis gets as many bits (at most 21) as leave room, in one 64-bit key, for the index below the
    code: sorting the keys (unique) is a stable sort of the codes, and quicker than sorting indices.
    """
    n = len(xyz)
    if not n:
        return np.zeros(0, np.intp)
    index_bits = max(1, (n - 1).bit_length())
    bits = min(21, (64 - index_bits) // 3)
    lo = xyz.min(axis=0)
    span = xyz.max(axis=0) - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        cell = np.where(span > 0, (xyz - lo) / np.where(span > 0, span, 1.0) * (1 << bits), 0.0)
    cell = np.clip(cell, 0, (1 << bits) - 1).astype(np.uint64)
    code = packing.morton_code(cell)
    key = np.sort((code << np.uint64(index_bits)) | np.arange(n, dtype=np.uint64))
    return (key & np.uint64((1 << index_bits) - 1)).astype(np.intp)


def _unorm(t: np.ndarray, bits: int) -> np.ndarray:
    """``t`` in [0, 1] as the nearest of 0 .. 2^bits - 1 (NaN as 0): ``uint32``."""
    top = (1 << bits) - 1
    q = t * np.float32(top)
    q += np.float32(0.5)
    np.floor(q, out=q)
    return np.minimum(np.fmax(q, 0, out=q), top, out=q).astype(np.uint32)  # fmax: NaN -> 0


def _normalized(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``values`` ``(C, 256)`` float32 placed between their chunk's ``lo`` and ``hi`` ``(C, 1)``, as the reference
    does: 0 at or below ``lo``, 1 at or above ``hi``, 0 in a range under :data:`MIN_RANGE`."""
    span = hi - lo
    narrow = span < MIN_RANGE
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        t = (values - lo) / np.where(narrow, np.float32(1), span)
    t[np.broadcast_to(narrow, t.shape) | (values <= lo)] = 0
    t[values >= hi] = 1
    return t


def _bounds(values: np.ndarray, limit: float | None = None) -> tuple:
    """Each chunk's least and greatest of ``values`` ``(C, 256)``, NaN left out (0 for a chunk of NaN),
    clamped to +-``limit``: two ``(C, 1)`` float32."""
    lo = np.nan_to_num(np.fmin.reduce(values, axis=1, keepdims=True), nan=0.0)  # fmin, fmax: NaN only if all are
    hi = np.nan_to_num(np.fmax.reduce(values, axis=1, keepdims=True), nan=0.0)
    if limit is not None:
        lo, hi = np.clip(lo, -limit, limit), np.clip(hi, -limit, limit)
    return lo.astype(np.float32), hi.astype(np.float32)


def _pack_rotation(q: np.ndarray) -> tuple:
    """Quaternions ``(M, 4)`` (rot_0..3) as smallest-three words ``(M,) uint32``, and how many had no direction
    (zero or not finite: written as the identity)."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        u = q / np.sqrt(np.einsum("ij,ij->i", q, q))[:, None]
    lost = ~np.isfinite(u).all(axis=1)
    if lost.any():
        u[lost] = (1.0, 0.0, 0.0, 0.0)
    largest = np.argmax(np.abs(u), axis=1)
    # The sign that makes the largest component positive, folded into the scale of the other three.
    scale = np.where(np.take_along_axis(u, largest[:, None], axis=1)[:, 0] < 0, -ROTATION_NORM, ROTATION_NORM)
    word = largest.astype(np.uint32)
    for i in range(4):
        part = _unorm(u[:, i] * scale + 0.5, ROTATION_BITS)
        word = np.where(largest != i, (word << np.uint32(ROTATION_BITS)) | part, word)
    return word, int(np.count_nonzero(lost))


def encode(scene: Scene) -> tuple:
    """The chunk rows ``(C,) CHUNK_DTYPE``, vertex rows ``(N,) VERTEX_DTYPE`` and SH bytes ``(N, 3K) uint8``
    of ``scene`` in Morton order, and counts of what the quantization changed."""
    cols = scene.columns
    n = scene.count
    xyz = np.stack([wide(cols[name]) for name in model.POSITION], axis=1)
    refuse_nonfinite_positions(int(np.count_nonzero(~np.isfinite(xyz).all(axis=1))),
                               "a compressed PLY holds positions within chunk bounds")
    # Splats far from the rest go last: in a chunk of near ones, a far splat's bounds would leave its
    # neighbours a step as wide as the scene. The chunk where near and far meet takes the least important
    # near splats (the viewer's importance: scales and opacity).
    far = model.far_rows(xyz, FAR_EXTENTS)
    shared = 0
    if far.any():
        near, out = np.flatnonzero(~far), np.flatnonzero(far)
        shared = len(near) % CHUNK_SPLATS
        least = np.argsort(importance({name: np.asarray(cols[name])[near] for name in ("opacity", *model.SCALE)}),
                           kind="stable")[:shared]
        spilled = np.zeros(len(near), bool)
        spilled[least] = True
        kept = near[~spilled]
        order = np.concatenate([kept[morton_order(xyz[kept])], near[spilled], out[morton_order(xyz[out])]])
    else:
        order = morton_order(xyz)
    c = -(-n // CHUNK_SPLATS)
    # The last chunk is filled with its last splat again: the bounds are its splats' alone.
    take = order[np.minimum(np.arange(c * CHUNK_SPLATS), n - 1)]

    def chunked(name: str) -> np.ndarray:
        return np.asarray(cols[name], dtype=np.float32)[take].reshape(c, CHUNK_SPLATS)

    chunks = np.zeros(c, CHUNK_DTYPE)
    words = {}
    counts = {"nan": 0, "scale_clamped": 0, "far": int(np.count_nonzero(far)), "shared": shared}
    groups = (("packed_position", model.POSITION, ("x", "y", "z"), "", None),
              ("packed_scale", model.SCALE, ("x", "y", "z"), "scale_", SCALE_LIMIT),
              ("packed_color", model.COLOR, ("r", "g", "b"), "", None))
    for key, names, axes, prefix, limit in groups:
        fields = WORD_111011 if key != "packed_color" else WORD_8888
        word = np.zeros((c, CHUNK_SPLATS), np.uint32)
        for name, axis, (shift, bits) in zip(names, axes, fields):
            values = chunked(name)
            lo, hi = _bounds(values, limit)
            chunks[f"min_{prefix}{axis}"], chunks[f"max_{prefix}{axis}"] = lo[:, 0], hi[:, 0]
            written = values.reshape(-1)[:n]  # not the last chunk's repeats
            counts["nan"] += int(np.count_nonzero(np.isnan(written)))
            if limit is not None:
                counts["scale_clamped"] += int(np.count_nonzero(np.abs(written) > limit))
            word |= _unorm(_normalized(values, lo, hi), bits) << np.uint32(shift)
        words[key] = word
    with np.errstate(over="ignore", invalid="ignore"):
        alpha = sigmoid(chunked("opacity"))
    counts["nan"] += int(np.count_nonzero(np.isnan(alpha.reshape(-1)[:n])))
    words["packed_color"] |= _unorm(alpha, 8)
    q = np.stack([np.asarray(cols[name], dtype=np.float32)[order] for name in model.ROTATION], axis=1)
    rotation, counts["no_direction"] = _pack_rotation(q)
    vertex = np.zeros(n, VERTEX_DTYPE)
    for key in ("packed_position", "packed_scale", "packed_color"):
        vertex[key] = words[key].reshape(-1)[:n]
    vertex["packed_rotation"] = rotation
    # SH: each column quantized in the scene's order (sequential), then whole rows of bytes put in Morton order.
    names = model.sh_names(scene.sh_degree)
    sh = np.empty((n, len(names)), np.uint8)
    counts["sh_clamped"] = 0
    for j, name in enumerate(names):
        stored = np.asarray(cols[name], dtype=np.float32) * np.float32(256 / SH_RANGE)  # (v / 8 + 1/2) * 256
        stored += np.float32(128)
        counts["sh_clamped"] += int(np.count_nonzero(stored < 0) + np.count_nonzero(stored >= 256))
        np.trunc(stored, out=stored)
        sh[:, j] = np.minimum(np.fmax(stored, 0, out=stored), 255, out=stored)  # fmax: NaN -> 0
    return chunks, vertex, np.take(sh, order, axis=0), counts


def header_bytes(n: int, degree: int) -> bytes:
    """The header of a compressed PLY of ``n`` splats with the SH bands of ``degree``."""
    lines = ["ply", "format binary_little_endian 1.0", f"element chunk {-(-n // CHUNK_SPLATS)}"]
    lines += [f"property float {name}" for name in CHUNK_PROPERTIES]
    lines += [f"element vertex {n}"] + [f"property uint {name}" for name in PACKED]
    if degree:
        lines += [f"element sh {n}"] + [f"property uchar {name}" for name in model.sh_names(degree)]
    return ("\n".join(lines + ["end_header"]) + "\n").encode("ascii")


def write(scene: Scene, stream, *, sort: str | None = None, progress=SILENT, **_options) -> WriteReport:
    """Write ``scene`` as a compressed PLY (see the module docstring), splats in Morton order.

    Raises
    ------
    UnsupportedError
        For a scene that moves or fades over time, or one with a non-finite position.
    """
    refuse_time_varying(scene.columns, "a compressed PLY")
    n = scene.count
    report = WriteReport(count=n)
    with progress.stage("writing", n, "splat") as advance:
        chunks, vertex, sh, counts = encode(scene)
        stream.write(header_bytes(n, scene.sh_degree))
        for block in (chunks, vertex, sh):
            if block.size:  # a view of nothing cannot be cast to bytes
                stream.write(memoryview(np.ascontiguousarray(block)).cast("B"))
        advance(n)
    report.notes.extend(_notes(scene.sh_degree, counts, sort))
    return report


def _notes(degree: int, counts: dict, sort: str | None) -> list:
    notes = [f"quantized to a compressed PLY: per chunk of {CHUNK_SPLATS} splats, positions and log scales to "
             "11-10-11 bits and colour to 8 bits within the chunk's bounds, opacity to a byte, rotation to "
             "10 bits a component" + (f", SH degree 1-{degree} bands to bytes (steps of 1/32 in [-4, 4])"
                                      if degree else "")]
    if sort == "importance":
        notes.append("splats in Morton order, not by importance: a chunk's bounds need neighbours")
    if counts["far"]:
        notes.append(f"position: {plural(counts['far'], 'splat')} more than {FAR_EXTENTS:g} scene extents from the "
                     "rest put in chunks of their own, after the others (their positions coarse)"
                     + (f"; the {plural(counts['shared'], 'least important splat')} of the rest share their first "
                        "chunk and its coarse positions" if counts["shared"] else ""))
    if counts["scale_clamped"]:
        notes.append(f"scale: {plural(counts['scale_clamped'], 'log scale')} past +-{SCALE_LIMIT:g} clamped")
    if counts["sh_clamped"]:
        notes.append(f"sh: {plural(counts['sh_clamped'], 'coefficient')} outside [-4, 4) clamped")
    if counts["nan"]:
        notes.append(f"{plural(counts['nan'], 'NaN value')} of scale, colour or opacity written as the chunk's least "
                     "(opacity as 0)")
    if counts["no_direction"]:
        notes.append(f"rotation: {plural(counts['no_direction'], 'quaternion')} with no direction (zero or not "
                     "finite) written as the identity; `convert --drop-undrawable` leaves such splats out")
    return notes



def info_fields(meta: dict) -> dict:
    """What ``info`` shows of a compressed PLY (its ``meta``): the PLY encoding, the layout, its chunks, SH degree."""
    return {"ply_format": meta.get("format"), "layout": meta.get("layout"), "chunk_count": meta.get("chunk_count"),
            "chunk_color": meta.get("chunk_color"), "sh_degree": meta.get("sh_degree")}


FORMAT = Format(
    name="compressed_ply",
    suffixes=(".compressed.ply",),
    default_sort="none",  # the writer orders splats itself (Morton)
    holds_empty=False,
    dynamic=False,
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats, declared_size=declared_size,
    write=write, holds_sh=True,
    info_fields=info_fields, storage=fixed_storage(STORAGE),
)
