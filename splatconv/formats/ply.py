"""PLY: Spacetime Gaussians (lite) and plain 3DGS splat files, via plyfile.

Reading accepts binary (either endianness) and ASCII PLY, float or double
properties (narrowed to float32 once, here), CRLF headers, comments and
obj_info, any property order, extra properties and extra elements. Writing
produces the Spacetime Gaussians lite layout, float32 little endian.
"""

from __future__ import annotations

import json
import os
import re
import warnings

import numpy as np
import plyfile

from .. import model
from ..cameras import validate_cameras
from ..errors import FormatError, UnsupportedError
from ..fsutil import open_input, populate
from ..jsonutil import loads_strict
from ..model import COLUMNS, Scene, constant_column
from ..progress import SILENT
from ..viewer import importance, importance_order
from .base import WriteReport

NAME = "ply"
SUFFIXES = (".ply",)
CAN_READ = True
CAN_WRITE = True
COMPAT_MODES = ()
#: Input order: a PLY is a training format, its row order is the user's.
DEFAULT_SORT = "none"
#: A PLY may hold zero rows.
HOLDS_EMPTY = True
DYNAMIC = True
#: A PLY holds attributes, not the viewer's texture.
STORES_TEXTURE = False

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

_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
          "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
          "double": 8, "float64": 8}
_FULL_FEATURE = re.compile(r"^f_t_\d+$|^f_dc_([3-9]|\d\d+)$")
_MAX_HEADER = 16 << 20


def _read_header_bytes(f, file_size: int) -> bytes:
    """The file's first bytes up to its ``end_header`` line (at most ``_MAX_HEADER``).

    Reads in growing steps: headers are usually well under a kilobyte, and a
    16 MB read up front would cost more than the rest of opening the file.
    """
    head = b""
    step = 1 << 16
    limit = min(file_size, _MAX_HEADER)
    while len(head) < limit:
        chunk = f.read(min(step, limit - len(head)))
        if not chunk:
            break
        head += chunk
        if re.search(rb"end_header\r?\n", head[-len(chunk) - 12:]):
            break
        step *= 4
    return head


def _minimum_body(f, path: str, file_size: int) -> None:
    """Fail fast when the header declares more rows than the file can hold.

    plyfile would otherwise try to allocate e.g. 10^12 ASCII rows up front. Only
    sizes are checked here; plyfile parses and validates the header for real.
    """
    head = _read_header_bytes(f, file_size)
    f.seek(0)
    end = re.search(rb"end_header\r?\n", head)
    if not head.startswith(b"ply") or end is None:
        return  # let plyfile name the problem
    body = file_size - end.end()
    fmt = None
    elements = []
    for line in head[:end.start()].decode("ascii", "replace").splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] == "format":
            fmt = words[1]
        elif len(words) == 3 and words[0] == "element" and words[2].isdigit():
            elements.append([words[1], int(words[2]), 0, 0])
        elif words[:1] == ["property"] and elements:
            elements[-1][3] += 1
            if len(words) == 3:
                elements[-1][2] += _SIZES.get(words[1], 1)
            elif len(words) == 5 and words[1] == "list":
                elements[-1][2] += _SIZES.get(words[2], 1)
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        return
    need = 0
    for name, count, row_bytes, props in elements:
        # At least one byte a value in binary; a digit and a separator in ASCII.
        row = max(row_bytes, 1) if fmt != "ascii" else 2 * max(props, 1)
        need += count * row
        if need > body + (fmt == "ascii"):
            what = f"{count * row} bytes" if fmt != "ascii" else f"at least {count * row - 1} bytes"
            raise FormatError(f"header declares {count} rows ({what}) but only {body} bytes follow the "
                              "header: file truncated?", path, (f"element '{name}'",))


def _open(path: str) -> plyfile.PlyData:
    with open_input(path) as f:
        size = os.fstat(f.fileno()).st_size
        if size == 0:
            raise FormatError("file is empty", path)
        _minimum_body(f, path, size)
        try:
            with warnings.catch_warnings():
                # An empty list in an ASCII row: plyfile reads it right, numpy warns.
                warnings.filterwarnings("ignore", "loadtxt: input contained no data")
                return plyfile.PlyData.read(f, mmap="r")
        except plyfile.PlyHeaderParseError as e:
            raise FormatError(f"bad header: {e.message}", path,
                              (f"line {e.line}",) if e.line else ()) from None
        except plyfile.PlyElementParseError as e:
            where = [f"element '{e.element.name}'"] if e.element is not None else []
            if e.row is not None:
                where.append(f"row {e.row}")
            if e.prop is not None:
                where.append(f"property '{e.prop.name}'")
            raise FormatError(e.message, path, where) from None
        except (ValueError, MemoryError) as e:
            raise FormatError(f"cannot parse: {e}", path) from None


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


def _column(data: np.ndarray, name: str) -> np.ndarray:
    col = data[name]
    if col.dtype == np.dtype("<f4") or (col.dtype == np.float32 and col.dtype.isnative):
        return col  # a view into the mapped file: no copy
    return col.astype(np.float32)


def read(path: str | os.PathLike, *, color: str = "auto", **_options) -> Scene:
    """Read a splat PLY into a :class:`Scene`.

    Parameters
    ----------
    path : path
    color : {"auto", "rgb", "sh"}
        How to read ``f_dc_0..2``: as RGB (Spacetime Gaussians lite) or as the
        degree-0 spherical-harmonic coefficient (plain 3DGS). ``auto`` picks by
        the variant.
    """
    path = os.fspath(path)
    ply = _open(path)
    if "vertex" not in ply:
        names = ", ".join(e.name for e in ply.elements) or "none"
        raise UnsupportedError(f"not a splat file: no 'vertex' element (elements: {names})", path)
    vertex = ply["vertex"]
    names = [p.name for p in vertex.properties]
    # A list property is never a splat attribute: ignored like any extra
    # property, unless it takes an attribute's name.
    list_props = [p.name for p in vertex.properties if isinstance(p, plyfile.PlyListProperty)]
    try:
        variant = detect_variant([p for p in names if p not in list_props])
    except UnsupportedError as e:
        clash = [p for p in list_props if p in set(LITE_REQUIRED) | set(GS_REQUIRED)]
        if clash:
            raise UnsupportedError(f"property {', '.join(clash)} is a list, not one number a splat", path) from None
        raise UnsupportedError(e.message, path) from None
    data = vertex.data
    populate(data)
    n = len(data)
    notes = []
    used = set(LITE_REQUIRED if variant == model.VARIANT_LITE else GS_REQUIRED) | set(NORMALS)
    ignored = [p for p in names if p not in used]
    doubles = [p.name for p in vertex.properties if p.name in used and p.val_dtype.endswith("8")]
    if doubles:
        notes.append(f"{len(doubles)} double properties narrowed to float32: {', '.join(doubles[:6])}"
                     + (", ..." if len(doubles) > 6 else ""))
    columns = {}
    if variant == model.VARIANT_LITE:
        for name in COLUMNS:
            columns[name] = _column(data, name)
    else:
        for name in GS_REQUIRED:
            columns[name] = _column(data, name)
        columns["trbf_center"] = constant_column(model.STATIC_TRBF_CENTER, n)
        columns["trbf_scale"] = constant_column(model.STATIC_TRBF_SCALE, n)
        for name in model.MOTION + model.OMEGA:
            columns[name] = constant_column(0.0, n)
        rest = [p for p in ignored if p.startswith("f_rest_")]
        if rest:
            notes.append(f"{len(rest)} higher-order SH coefficients (f_rest_*) dropped: the viewer draws "
                         "view-independent colour")
    color_mode = color if color != "auto" else ("rgb" if variant == model.VARIANT_LITE else "sh")
    if color_mode == "sh":
        for name in model.COLOR:
            columns[name] = (0.5 + SH_C0 * columns[name].astype(np.float64)).astype(np.float32)
    cameras = _cameras_from_comments(ply.comments, path)
    meta = {
        "format": ply.text and "ascii" or ("binary_" + ("little" if ply.byte_order == "<" else "big") + "_endian"),
        "color": color_mode,
        "properties": names,
        "ignored_properties": ignored,
        "extra_elements": [e.name for e in ply.elements if e.name != "vertex"],
        "double_properties": doubles,
        "file_bytes": os.path.getsize(path),
    }
    return Scene(columns=columns, cameras=cameras, variant=variant, meta=meta, notes=notes)


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


def header_bytes(count: int, cameras) -> bytes:
    """The PLY header of a lite file of ``count`` rows."""
    lines = ["ply", "format binary_little_endian 1.0"]
    if cameras:
        text = json.dumps(cameras, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
        lines.append("comment " + CAMERA_COMMENT + text)
    lines.append(f"element vertex {count}")
    lines.extend(f"property float {name}" for name in LITE_LAYOUT)
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


BLOCK = 1 << 16


def write(scene: Scene, stream, *, sort: str | None = None, progress=SILENT, **_options):
    """Write ``scene`` in the Spacetime Gaussians lite layout (float32 LE, normals 0).

    Parameters
    ----------
    scene : Scene
    stream : binary file object
    sort : {None, "none", "importance"}
        ``importance`` orders rows largest first as the splatv writer does; the
        default keeps the input order.

    Returns
    -------
    WriteReport
    """
    n = scene.count
    report = WriteReport(count=n)
    order = None
    if sort == "importance":
        order = importance_order(importance(scene.columns))
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


def info_fields(scene: Scene) -> dict:
    """What ``info`` shows of a scene read from a PLY: encoding, colour reading, what was ignored."""
    meta = scene.meta
    return {
        "ply_format": meta.get("format"),
        "color": meta.get("color"),
        "ignored_properties": meta.get("ignored_properties", []),
        "extra_elements": meta.get("extra_elements", []),
    }
