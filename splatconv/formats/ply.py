"""PLY: Spacetime Gaussians (lite) and plain 3DGS splat files: which properties are which columns.

Reading accepts binary (either endianness) and ASCII PLY, float or double
properties (narrowed to float32 once, here), CRLF headers, comments and
obj_info, any property order, extra properties and extra elements. A plain 3DGS
file's SH bands (``f_rest_*`` of degree 1, 2 or 3) are kept in the scene. Writing
produces the Spacetime Gaussians lite layout (colour only: SH bands dropped, said
so) or the plain 3DGS layout (with the scene's SH bands), float32 little endian. The container (header, elements, rows)
is :mod:`splatconv.formats.ply_container`; this module maps the ``vertex``
properties to the model's columns and back.
"""

from __future__ import annotations

import json
import os
import re

import numpy as np

from .. import model
from ..cameras import validate_cameras
from ..errors import FormatError, UnsupportedError, UsageError
from ..files.paging import populate, release
from ..jsonutil import loads_strict
from ..model import COLUMNS, GROUPS, Scene
from ..progress import SILENT
from ..viewer import importance, importance_order, wide
from . import compressed_ply
from . import ply_container as container
from .base import Format, Scan, WriteReport, refuse_time_varying

#: Property order of the lite layout as SpacetimeGaussians writes it.
LITE_LAYOUT = model.LITE_ROW
NORMALS = model.NORMALS
#: Properties a plain 3DGS file must have.
GS_REQUIRED = model.POSITION + model.COLOR + model.OPACITY + model.SCALE + model.ROTATION
#: Properties a lite file must have.
LITE_REQUIRED = tuple(name for name in LITE_LAYOUT if name not in NORMALS)
#: SH degree-0 basis constant: rgb = 0.5 + SH_C0 * f_dc.
SH_C0 = 0.28209479177387814
#: Header comment that carries the cameras through a splatv -> PLY -> splatv trip.
CAMERA_COMMENT = "splatconv-cameras "

_FULL_FEATURE = re.compile(r"^f_t_\d+$|^f_dc_([3-9]|\d\d+)$")


def declared_size(head: bytes):
    """File size a binary PLY header at the start of ``head`` declares (None: ASCII, lists or unknown).

    Used to bound the decompression of a ``.ply.zst``.
    """
    return container.declared_size(head)


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats :func:`read` gives for ``path``: its header's vertex count, read without the rows.

    None when only reading tells: no ``vertex`` element, or a header or size
    :func:`read` refuses (reading says why).
    """
    return container.vertex_count(os.fspath(path))


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats :func:`read` gives for ``path``: its header's vertex count (0: one it refuses).

    The count is checked against the file's size (a byte a value at least).
    """
    return splat_count(path) or 0


def detect_variant(names) -> str:
    """Name the kind of splat file a vertex property list describes.

    Raises
    ------
    UnsupportedError
        For the Spacetime Gaussians full model, or when properties are missing.
    """
    names = set(names)
    temporal = bool(names & set(model.TRBF + model.MOTION + model.OMEGA))
    if temporal and any(_FULL_FEATURE.match(n) for n in names):
        raise UnsupportedError(
            f"{model.VARIANT_FULL} model (f_dc_0..5 and f_t_* features): its colour comes from a neural "
            "decoder the splaTV viewer does not run; the viewer needs the lite model, which stores RGB in "
            "f_dc_0..2 (train with the lite configuration)")
    required = LITE_REQUIRED if temporal else GS_REQUIRED
    missing = [n for n in required if n not in names]
    if missing:
        kind = model.VARIANT_LITE if temporal else model.VARIANT_3DGS
        raise UnsupportedError(f"not a splat file: missing properties {', '.join(missing)} "
                               f"(needed for {kind})")
    return model.VARIANT_LITE if temporal else model.VARIANT_3DGS


def _column(data: np.ndarray, name: str, overflow: dict) -> np.ndarray:
    """Column ``name`` of the vertex rows ``data`` as float32, counting into ``overflow[name]`` the finite
    doubles that became infinite."""
    col = data[name]
    if col.dtype == np.dtype("<f4") or (col.dtype == np.float32 and col.dtype.isnative):
        return col  # a view into the mapped file: no copy
    with np.errstate(over="ignore", invalid="ignore"):  # reported below
        out = col.astype(np.float32)
    if col.dtype.kind == "f" and col.dtype.itemsize > 4:
        overflow[name] = overflow.get(name, 0) + int(np.count_nonzero(np.isinf(out) & np.isfinite(col)))
    return out


def _overflow_notes(overflow: dict) -> list:
    """The notes of what :func:`_column` counted, in column order."""
    return [f"{name}: {count:,} finite double value{'s' if count != 1 else ''} past the float32 range became "
            "infinite" for name, count in overflow.items() if count]


def _opened(parsed, path: str):
    """The PLY at ``path`` read as far as its vertex rows (``parsed``, not paged in): rows, variant, colour mode,
    meta, notes (those a read knows before its columns)."""
    vertex = _vertex_element(parsed.header, path)
    variant = _variant_of(vertex, path)
    degree = _sh_degree_of(vertex, variant)
    used = _used_properties(variant) | set(model.sh_names(degree))
    ignored = [p.name for p in vertex.properties if p.name not in used]
    doubles = [p.name for p in vertex.properties if p.name in used and p.val_dtype.endswith("8")]
    meta = {
        "format": parsed.header.format,
        "color": None,
        "properties": [p.name for p in vertex.properties],
        "ignored_properties": ignored,
        "extra_elements": [e.name for e in parsed.header.elements if e.name != "vertex"],
        "double_properties": doubles,
        "file_bytes": os.path.getsize(path),
        "sh_degree": degree,
    }
    cameras = _cameras_from_comments(parsed.header.comments, path)
    return parsed.vertex, variant, meta, cameras, parsed.notes + _narrowing_notes(doubles)


def _piece(rows: np.ndarray, variant: str, color: str, overflow: dict, degree: int = 0) -> dict:
    """The model columns of vertex ``rows`` (with the SH bands of ``degree``)."""
    columns = _columns(rows, variant, overflow)
    columns.update((name, _column(rows, name, overflow)) for name in model.sh_names(degree))
    if color == "sh":
        _rgb_from_sh(columns)
    return columns


def _color_mode(color: str, variant: str) -> str:
    return color if color != "auto" else ("rgb" if variant == model.VARIANT_LITE else "sh")


def read(path: str | os.PathLike, *, color: str = "auto", **_options) -> Scene:
    """Read a splat PLY into a :class:`Scene`.

    Parameters
    ----------
    path : path
    color : {"auto", "rgb", "sh"}
        How to read ``f_dc_0..2``: as RGB (Spacetime Gaussians lite) or as the
        degree-0 spherical-harmonic coefficient (plain 3DGS). ``auto`` picks by
        the variant.

    A PLY of PlayCanvas's compressed layout (:mod:`splatconv.formats.compressed_ply`) is read as such,
    whatever its name.
    """
    path = os.fspath(path)
    parsed = container.read_rows(path)
    if compressed_ply.is_compressed(parsed.header):
        return compressed_ply.scene_from(parsed, path)
    rows, variant, meta, cameras, notes = _opened(parsed, path)
    populate(rows)
    meta["color"] = _color_mode(color, variant)
    overflow = {}
    columns = _piece(rows, variant, meta["color"], overflow, meta["sh_degree"])
    notes += _overflow_notes(overflow) + _dropped_sh_notes(meta["ignored_properties"], variant)
    return Scene(columns=columns, cameras=cameras, variant=variant, meta=meta, notes=notes)


#: Rows a piece of :func:`scan`.
SCAN_ROWS = 1 << 16


def scan(path: str | os.PathLike, *, color: str = "auto", **_options) -> Scan:
    """Read a splat PLY a piece at a time (:class:`~splatconv.formats.base.Scan`): what :func:`read` gives,
    :data:`SCAN_ROWS` rows a piece, each piece's pages of the mapped file let go after it."""
    path = os.fspath(path)
    out = Scan()

    def pieces():
        parsed = container.read_rows(path)
        if compressed_ply.is_compressed(parsed.header):
            yield from compressed_ply.pieces_from(parsed, path, out)
            return
        rows, variant, meta, cameras, notes = _opened(parsed, path)
        meta["color"] = _color_mode(color, variant)
        out.variant, out.cameras = variant, cameras
        out.meta.update(meta)
        overflow = {}
        for start in range(0, len(rows), SCAN_ROWS):
            part = rows[start:start + SCAN_ROWS]
            yield _piece(part, variant, meta["color"], overflow, meta["sh_degree"])
            release(part)
        out.notes.extend(notes + _overflow_notes(overflow) + _dropped_sh_notes(meta["ignored_properties"], variant))

    out.pieces = pieces()
    return out


def _narrowing_notes(doubles: list) -> list:
    """The note that ``doubles``, used properties of type double, were narrowed to float32 (none: none)."""
    if not doubles:
        return []
    return [f"{len(doubles)} double properties narrowed to float32: {', '.join(doubles[:6])}"
            + (", ..." if len(doubles) > 6 else "")]


def _dropped_sh_notes(ignored: list, variant: str) -> list:
    """The note that a 3DGS file's higher-order SH coefficients (among ``ignored``: they are not those of
    one degree, 9, 24 or 45 of them) were dropped."""
    rest = [p for p in ignored if p.startswith("f_rest_")]
    if variant != model.VARIANT_3DGS or not rest:
        return []
    return [f"{len(rest)} higher-order SH coefficients (f_rest_*) dropped: not the 9, 24 or 45 of SH degree "
            "1, 2 or 3"]


def _sh_degree_of(vertex, variant: str) -> int:
    """The SH degree whose bands a plain 3DGS file's vertex properties hold (0: none, or not the
    ``f_rest_*`` of exactly one degree, which are then ignored)."""
    if variant != model.VARIANT_3DGS:
        return 0
    rest = {p.name for p in vertex.properties if p.name.startswith("f_rest_") and not p.is_list}
    for degree in (3, 2, 1):
        if rest == set(model.sh_names(degree)):
            return degree
    return 0


def _vertex_element(header, path: str):
    """The header's ``vertex`` element: the splats.

    Raises
    ------
    UnsupportedError
        A PLY without one.
    """
    vertex = header.element("vertex")
    if vertex is None:
        names = ", ".join(e.name for e in header.elements) or "none"
        raise UnsupportedError(f"not a splat file: no 'vertex' element (elements: {names})", path)
    return vertex


def _variant_of(vertex, path: str) -> str:
    """The splat variant the vertex properties describe (:func:`detect_variant`), naming ``path``.

    A list property is never a splat attribute: ignored like any extra
    property, unless it takes an attribute's name.
    """
    list_props = [p.name for p in vertex.properties if p.is_list]
    try:
        return detect_variant([p.name for p in vertex.properties if not p.is_list])
    except UnsupportedError as e:
        clash = [p for p in list_props if p in set(LITE_REQUIRED) | set(GS_REQUIRED)]
        if clash:
            raise UnsupportedError(f"property {', '.join(clash)} is a list, not one number a splat", path) from None
        raise UnsupportedError(e.message, path) from None


def _used_properties(variant: str) -> set:
    """The vertex properties a ``variant`` file maps to model columns (normals too, always zero)."""
    return set(LITE_REQUIRED if variant == model.VARIANT_LITE else GS_REQUIRED) | set(NORMALS)


def _columns(data: np.ndarray, variant: str, overflow: dict) -> dict:
    """The model columns of the vertex rows ``data``: a lite file holds them all, a 3DGS file no time."""
    if variant == model.VARIANT_LITE:
        return {name: _column(data, name, overflow) for name in COLUMNS}
    columns = {name: _column(data, name, overflow) for name in GS_REQUIRED}
    columns.update(model.static_columns(len(data)))
    return columns


def _rgb_from_sh(columns: dict) -> None:
    """Read the colour columns as the degree-0 SH coefficient: rgb = 0.5 + SH_C0 * f_dc."""
    with np.errstate(invalid="ignore"):  # a signalling NaN warns when widened; it stays NaN
        for name in model.COLOR:
            columns[name] = (0.5 + SH_C0 * wide(columns[name])).astype(np.float32)


def _cameras_from_comments(comments, path: str):
    for comment in comments:
        if comment.startswith(CAMERA_COMMENT):
            cameras = loads_strict(comment[len(CAMERA_COMMENT):], path, "cameras comment")
            try:
                return validate_cameras(cameras, path)
            except FormatError as e:
                raise FormatError(e.message, path, ("cameras comment", *e.where)) from None
    return None


#: Row type of the written lite layout.
LITE_DTYPE = np.dtype([(name, "<f4") for name in LITE_LAYOUT])
#: Property order of the written 3DGS layout of SH degree 0, as 3DGS tools and web viewers read it;
#: a scene with SH bands has its ``f_rest_*`` after ``f_dc_2`` (:func:`gs_layout`).
GS_LAYOUT = model.POSITION + NORMALS + model.COLOR + model.OPACITY + model.SCALE + model.ROTATION


def gs_layout(degree: int = 0) -> tuple:
    """Property order of the written 3DGS layout of SH ``degree``: 3DGS's own."""
    at = GS_LAYOUT.index(model.COLOR[-1]) + 1
    return GS_LAYOUT[:at] + model.sh_names(degree) + GS_LAYOUT[at:]
#: Layouts :func:`write` produces, by ``layout=`` name.
LAYOUTS = {"lite": LITE_LAYOUT, "3dgs": GS_LAYOUT}


def header_bytes(count: int, cameras, layout: str = "lite", degree: int = 0) -> bytes:
    """The PLY header of a file of ``count`` rows in ``layout`` (a :data:`LAYOUTS` name; 3DGS with the SH
    bands of ``degree``)."""
    lines = ["ply", "format binary_little_endian 1.0"]
    if cameras:
        text = json.dumps(cameras, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
        lines.append("comment " + CAMERA_COMMENT + text)
    lines.append(f"element vertex {count}")
    names = gs_layout(degree) if layout == "3dgs" else LAYOUTS[layout]
    lines.extend(f"property float {name}" for name in names)
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


BLOCK = 1 << 16


def default_layout(scene: Scene) -> str:
    """The layout a scene is written in when none is asked: a plain 3DGS scene stays 3DGS, all else lite."""
    return "3dgs" if scene.variant == model.VARIANT_3DGS else "lite"


def write(scene: Scene, stream, *, sort: str | None = None, layout: str | None = None,
          progress=SILENT, **_options):
    """Write ``scene`` as a binary little-endian float32 PLY.

    Parameters
    ----------
    scene : Scene
    stream : binary file object
    sort : {None, "none", "importance"}
        ``importance`` orders rows largest first as the splatv writer does; the
        default keeps the input order.
    layout : {None, "lite", "3dgs"}
        ``lite``: the Spacetime Gaussians lite layout (normals 0, RGB in
        f_dc_0..2; SH bands dropped, noted). ``3dgs``: the plain 3DGS layout (colour
        as the degree-0 SH coefficient (rgb - 0.5) / SH_C0, the scene's SH bands as
        f_rest_*, log scales, logit opacity),
        refused for a scene that moves or fades (see
        :func:`splatconv.formats.base.refuse_time_varying`). None: 3DGS for a
        scene read as plain 3DGS, lite otherwise (:func:`default_layout`).

    Returns
    -------
    WriteReport
    """
    layout = layout or default_layout(scene)
    if layout not in LAYOUTS:
        raise UsageError(f"unknown PLY layout {layout!r} (expected one of {', '.join(LAYOUTS)})")
    if layout == "3dgs":
        return _write_3dgs(scene, stream, sort, progress)
    n = scene.count
    report = WriteReport(count=n, notes=model.sh_dropped_note(scene.sh_degree, "a Spacetime Gaussians lite PLY"))
    order = _order(scene, sort)
    stream.write(header_bytes(n, scene.cameras))
    rows = _lite_rows_of(scene)
    with progress.stage("writing", n, "splat") as advance:
        if rows is not None:
            # The columns are fields of rows already in the written layout: write them whole.
            for start in range(0, n, BLOCK):
                block = rows[start:start + BLOCK] if order is None else np.take(rows, order[start:start + BLOCK],
                                                                               axis=0)
                stream.write(memoryview(block))
                advance(len(block))
            return report
        block = np.zeros(min(BLOCK, max(n, 1)), dtype=LITE_DTYPE)
        for start in range(0, n, BLOCK):
            stop = min(start + BLOCK, n)
            rows = slice(start, stop) if order is None else order[start:stop]
            out = block[: stop - start]
            for name in COLUMNS:
                out[name] = np.asarray(scene.columns[name])[rows]
            stream.write(memoryview(out).cast("B"))
            advance(stop - start)
    return report


def _order(scene: Scene, sort: str | None):
    """The written row order: None for the input order."""
    return importance_order(importance(scene.columns)) if sort == "importance" else None


def _write_3dgs(scene: Scene, stream, sort: str | None, progress) -> WriteReport:
    """The plain 3DGS layout; see :func:`write`."""
    cols = scene.columns
    refuse_time_varying(cols, "a 3DGS PLY")
    n = scene.count
    report = WriteReport(count=n)
    static_basis = (_all_equal(cols["trbf_center"], model.STATIC_TRBF_CENTER)
                    and _all_equal(cols["trbf_scale"], model.STATIC_TRBF_SCALE))
    if n and not static_basis:
        report.notes.append("trbf: temporal basis dropped (every splat is within half an alpha step of full "
                            "opacity over the whole clip)")
    order = _order(scene, sort)
    degree = scene.sh_degree
    stream.write(header_bytes(n, scene.cameras, "3dgs", degree))
    block = np.zeros(min(BLOCK, max(n, 1)), dtype=[(name, "<f4") for name in gs_layout(degree)])  # normals stay 0
    with progress.stage("writing", n, "splat") as advance:
        for start in range(0, n, BLOCK):
            stop = min(start + BLOCK, n)
            rows = slice(start, stop) if order is None else order[start:stop]
            out = block[: stop - start]
            for name in model.POSITION + model.OPACITY + model.SCALE + model.ROTATION + model.sh_names(degree):
                out[name] = np.asarray(cols[name])[rows]
            for name in model.COLOR:
                rgb = wide(np.asarray(cols[name])[rows])
                with np.errstate(over="ignore", invalid="ignore"):
                    out[name] = (rgb - 0.5) / SH_C0
            stream.write(memoryview(out).cast("B"))
            advance(stop - start)
    return report


def _all_equal(column, value) -> bool:
    """Whether every value of ``column`` is ``value`` (a constant column is checked at no cost)."""
    column = np.asarray(column)
    if column.ndim == 1 and column.strides[0] == 0:
        column = column[:1]
    return bool(np.all(column == value))


def _lite_rows_of(scene: Scene):
    """The scene's rows as the lite layout writes them, ``(N, 128) uint8``, if they already are; else None.

    True of a scene read from a ``.splatv`` (see :func:`splatconv.model.lite_rows`)
    or from a little-endian float32 lite PLY in the standard order whose normals
    are zero: the rows can then be written as they are.
    """
    if not np.little_endian or scene.count == 0:
        return None
    found = model.row_fields([np.asarray(scene.columns[name]) for name in COLUMNS])
    if found is None:
        return None
    matrix, fields = found
    if (fields != [LITE_LAYOUT.index(name) for name in COLUMNS] or matrix.shape[1] != len(LITE_LAYOUT)
            or matrix.strides[0] != LITE_DTYPE.itemsize):
        return None
    normals = matrix[:, LITE_LAYOUT.index(NORMALS[0]):LITE_LAYOUT.index(NORMALS[-1]) + 1]
    if normals.view(np.uint32).any():
        return None  # the writer writes zero normals (+0.0)
    return matrix.view(np.uint8)


def storage(scene: Scene) -> dict:
    """How a PLY read as ``scene`` stores each attribute group (see :mod:`splatconv.compare`).

    Float32 as the model holds it; colour read as spherical harmonics goes through
    one float32 conversion each way; a plain 3DGS PLY holds no time or motion.
    """
    if scene.meta.get("layout") == compressed_ply.LAYOUT:
        return compressed_ply.STORAGE
    kinds = dict.fromkeys(GROUPS, "exact")  # SH bands too, as float32 (verify judges the groups only)
    if scene.meta.get("color") == "sh":
        kinds["color"] = "float32"
    if scene.variant == model.VARIANT_3DGS:
        kinds.update(dict.fromkeys(("motion", "omega", "trbf"), "none"))
    return kinds


def info_fields(meta: dict) -> dict:
    """What ``info`` shows of a scene read from a PLY (its ``meta``): encoding, colour reading, what was ignored."""
    if meta.get("layout") == compressed_ply.LAYOUT:
        return compressed_ply.info_fields(meta)
    return {
        "ply_format": meta.get("format"),
        "color": meta.get("color"),
        "ignored_properties": meta.get("ignored_properties", []),
        "sh_degree": meta.get("sh_degree", 0),
        "extra_elements": meta.get("extra_elements", []),
    }


FORMAT = Format(
    name="ply",
    suffixes=(".ply",),
    default_sort="none",  # a PLY is a training format: its row order is the user's
    holds_empty=True,  # a PLY may hold zero rows
    dynamic=True,
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats, declared_size=declared_size,
    write=write, layouts=tuple(LAYOUTS), holds_sh=True,
    info_fields=info_fields, storage=storage,
    # Attributes, not the viewer's texture.
)
