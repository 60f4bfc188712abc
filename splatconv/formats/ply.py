"""PLY: Spacetime Gaussians (lite) and plain 3DGS splat files, via plyfile.

Reading accepts binary (either endianness) and ASCII PLY, float or double
properties (narrowed to float32 once, here), CRLF headers, comments and
obj_info, any property order, extra properties and extra elements. Writing
produces the Spacetime Gaussians lite layout or the plain 3DGS layout (SH
degree 0), float32 little endian.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import struct
import warnings

import numpy as np
import plyfile

from .. import model
from ..cameras import validate_cameras
from ..errors import FormatError, UnsupportedError, UsageError
from ..files.inputs import open_input
from ..files.paging import populate
from ..jsonutil import loads_strict
from ..model import COLUMNS, GROUPS, Scene, constant_column
from ..progress import SILENT
from ..viewer import importance, importance_order, wide
from .base import Format, WriteReport, refuse_time_varying

# The largest structured dtype numpy makes: its itemsize must fit a C int.
_MAX_DTYPE_BYTES = 2**31 - 1

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
def _newline(head: bytes):
    """The line ending a PLY header uses, as plyfile decides it from the first line; None if not PLY."""
    if head[3:5] == b"\r\n":
        return b"\r\n"
    return head[3:4] if head[:3] == b"ply" and head[3:4] in (b"\r", b"\n") else None


def _header_lines(head: bytes):
    """The header's lines (bytes, without endings) and the offset of the body; (lines, None) when incomplete.

    Split as plyfile splits them, on the first line's ending, and ended by the
    first line that is ``end_header`` once stripped (as plyfile strips: Python
    ``str.strip`` of the ASCII text).
    """
    nl = _newline(head)
    if nl is None:
        return [], None
    lines, pos = [], 0
    while True:
        stop = head.find(nl, pos)
        if stop < 0:
            return lines, None
        line = head[pos:stop]
        pos = stop + len(nl)
        if line.decode("latin-1").strip() == "end_header":
            return lines, pos
        lines.append(line)


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
        if b"end_header" in head[-len(chunk) - 12:] and _header_lines(head)[1] is not None:
            break
        step *= 4
    return head


class _Layout:
    """What a PLY header says, as far as sizes go: format, elements, their counts and row sizes.

    ``elements`` holds ``[name, count, fixed_row_bytes, n_properties, has_list]``
    in header order; ``header_bytes`` is the offset of the body; ``lines`` the
    header lines. Only sizes are read here; plyfile parses and validates the
    header for real (from :meth:`zeroed`).
    """

    def __init__(self, head: bytes, path: str):
        self.format = None
        self.elements = []
        self.lines, self.header_bytes = _header_lines(head)
        if self.header_bytes is None:
            return  # let plyfile name the problem
        for line in self.lines:
            words = line.decode("latin-1").split()
            if len(words) >= 2 and words[0] == "format":
                self.format = words[1]
            elif len(words) == 3 and words[0] == "element":
                if not (words[2].isascii() and words[2].isdigit()):
                    raise FormatError(f"row count {words[2][:24]!r} is not a non-negative integer", path,
                                      (f"element '{words[1][:40]}'",))
                self.elements.append([words[1], int(words[2]), 0, 0, False])
            elif words[:1] == ["property"] and self.elements:
                self.elements[-1][3] += 1
                if len(words) == 3:
                    self.elements[-1][2] += _SIZES.get(words[1], 1)
                elif len(words) == 5 and words[1] == "list":
                    self.elements[-1][2] += _SIZES.get(words[2], 1)
                    self.elements[-1][4] = True

    def zeroed(self, head: bytes) -> bytes:
        """The header with every element's row count replaced by 0 (the same lines, the same endings)."""
        nl = _newline(head)
        out = []
        for line in self.lines:
            text = line.decode("latin-1")
            words = text.split()
            if len(words) == 3 and words[0] == "element":
                kept = text.rstrip()
                text = kept[: len(kept) - len(words[2])] + "0" + text[len(kept):]
            out.append(text.encode("latin-1"))
        return nl.join(out + [head[len(nl.join(self.lines)) + len(nl):self.header_bytes]])

    def fixed_size(self):
        """Bytes of a binary file whose rows are all fixed-size; None when unknown (ASCII, lists)."""
        if self.header_bytes is None or self.format not in ("binary_little_endian", "binary_big_endian"):
            return None
        if any(e[4] for e in self.elements):
            return None
        return self.header_bytes + sum(count * row for _name, count, row, _props, _list in self.elements)


def declared_size(head: bytes):
    """File size a binary PLY header at the start of ``head`` declares (None: ASCII, lists or unknown).

    Used to bound the decompression of a ``.ply.zst``.
    """
    try:
        return _Layout(head, "").fixed_size()
    except FormatError:
        return None


def _minimum_body(layout: _Layout, path: str, file_size: int) -> None:
    """Fail fast when the header declares more rows than the file can hold.

    plyfile would otherwise try to allocate e.g. 10^12 ASCII rows up front.
    """
    fmt = layout.format
    if layout.header_bytes is None or fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        return
    body = file_size - layout.header_bytes
    need = 0
    for name, count, row_bytes, props, _list in layout.elements:
        # At least one byte a value in binary; a digit and a separator in ASCII (a
        # row of an element without properties: nothing, or an empty line).
        row = row_bytes if fmt != "ascii" else 2 * props or 1
        need += count * row
        if need > body + (fmt == "ascii"):
            what = f"{count * row} bytes" if fmt != "ascii" else f"at least {count * row - 1} bytes"
            raise FormatError(f"header declares {count} rows ({what}) but only {body} bytes follow the "
                              "header: file truncated?", path, (f"element '{name}'",))


class _PlyFile:
    """A parsed PLY: plyfile's header objects, the vertex rows and notes on what was left unread."""

    def __init__(self, header: plyfile.PlyData, vertex_data, notes: list):
        self.header = header
        self.vertex_data = vertex_data
        self.notes = notes


def _plyfile_errors(path: str):
    """A context that turns plyfile's errors into :class:`FormatError` naming where."""

    @contextlib.contextmanager
    def manager():
        try:
            with warnings.catch_warnings():
                # An empty list in an ASCII row: plyfile reads it right, numpy warns.
                warnings.filterwarnings("ignore", "loadtxt: input contained no data")
                yield
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
        except (ValueError, MemoryError, OverflowError) as e:
            raise FormatError(f"cannot parse: {e}", path) from None

    return manager()


def _open(path: str) -> _PlyFile:
    with open_input(path) as f:
        size = os.fstat(f.fileno()).st_size
        if size == 0:
            raise FormatError("file is empty", path)
        head = _read_header_bytes(f, size)
        layout = _Layout(head, path)
        _minimum_body(layout, path, size)
        if layout.header_bytes is None:
            # No end_header line in the first 16 MiB: plyfile names what is wrong
            # from what was read (a header is never longer in practice).
            try:
                with _plyfile_errors(path):
                    plyfile.PlyData.read(io.BytesIO(head))
            except FormatError as e:
                if "codec can't decode" not in e.message:
                    raise
            raise FormatError(f"bad header: no end_header line in the first {len(head):,} bytes", path)
        # plyfile parses the header (its rules, its messages) from a copy whose
        # element counts are zero, so that it reads no rows: the rows are read
        # here, in bulk, and only as far as the vertex element.
        with _plyfile_errors(path):
            header = plyfile.PlyData.read(io.BytesIO(layout.zeroed(head)))
        if len(header.elements) != len(layout.elements):  # pragma: no cover - both parse the same lines
            raise FormatError("bad header: element lines not understood", path)
        counts = [e[1] for e in layout.elements]
        _check_list_types(header, path)
        if "vertex" not in header:
            return _PlyFile(header, None, [])
        if header.text:
            return _read_ascii(f, path, header, layout, counts)
        return _read_binary(f, path, header, layout, counts)


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats :func:`read` gives for ``path``: its header's vertex count, read without the rows.

    None when only reading tells: no ``vertex`` element, or a header or size
    :func:`read` refuses (reading says why).
    """
    path = os.fspath(path)
    try:
        with open_input(path) as f:
            size = os.fstat(f.fileno()).st_size
            layout = _Layout(_read_header_bytes(f, size), path)
            _minimum_body(layout, path, size)
    except FormatError:
        return None
    if layout.header_bytes is None:
        return None
    return next((count for name, count, *_rest in layout.elements if name == "vertex"), None)


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats :func:`read` gives for ``path``: its header's vertex count (0: one it refuses).

    The count is checked against the file's size (a byte a value at least).
    """
    return splat_count(path) or 0


def _check_list_types(header, path: str) -> None:
    """A list's length must be an integer type (plyfile takes ``property list float int x``)."""
    for element in header.elements:
        for prop in element.properties:
            if isinstance(prop, plyfile.PlyListProperty):
                len_t = np.dtype(prop.list_dtype("<")[0])
                if len_t.kind not in "iu":
                    name = {4: "float", 8: "double"}.get(len_t.itemsize, len_t.name)
                    raise FormatError(f"list length type '{name}' is not an integer type", path,
                                      (f"element '{element.name}'", f"property '{prop.name}'"))


def _element_dtype(element, byte_order: str, list_lengths=None) -> np.dtype:
    """Row dtype of ``element``; each list property as a length field plus a fixed array of values."""
    fields = []
    for i, prop in enumerate(element.properties):
        if isinstance(prop, plyfile.PlyListProperty):
            len_t, val_t = prop.list_dtype(byte_order)
            fields.append((f"\n{i}len", len_t))
            fields.append((prop.name, val_t, (list_lengths[i],)))
        else:
            fields.append((prop.name, prop.dtype(byte_order)))
    return np.dtype(fields)


def _list_lengths_at(buf: np.ndarray, start: int, element, byte_order: str):
    """Lengths of the list properties of the row at ``start`` of ``buf`` (uint8), None past the end."""
    lengths = {}
    pos = start
    for i, prop in enumerate(element.properties):
        if isinstance(prop, plyfile.PlyListProperty):
            len_t, val_t = (np.dtype(t) for t in prop.list_dtype(byte_order))
            if pos + len_t.itemsize > len(buf):
                return None, pos
            n = int(buf[pos:pos + len_t.itemsize].view(len_t)[0])
            # A list that runs past the end of the file ends the row there: its
            # length may be any 32-bit count, past what a numpy dtype can hold.
            if n < 0 or pos + len_t.itemsize + n * val_t.itemsize > len(buf):
                return None, pos
            lengths[i] = n
            pos += len_t.itemsize + n * val_t.itemsize
        else:
            pos += np.dtype(prop.dtype(byte_order)).itemsize
    return lengths, pos


def _binary_rows(buf: np.ndarray, offset: int, element, count: int, byte_order: str, path: str,
                 need_rows: bool = True, walk: bool = True):
    """Read ``count`` rows of ``element`` at ``offset``: ``(rows, bytes)``.

    Fixed-size rows are a view of ``buf``. With list properties every row is
    first assumed to have the first row's list lengths (true of the files met
    in practice); that is checked for all rows at once, and only where it fails
    are the rows walked one by one; the rows returned then hold the properties
    that are not lists (lists are never splat attributes).
    """
    has_list = any(isinstance(p, plyfile.PlyListProperty) for p in element.properties)
    where = (f"element '{element.name}'",)
    if count == 0:
        return np.zeros(0, _element_dtype(element, byte_order, dict.fromkeys(range(len(element.properties)), 0))), 0
    lengths, end = None, offset
    if has_list:
        lengths, end = _list_lengths_at(buf, offset, element, byte_order)
        if lengths is None:
            raise FormatError("row 0: unexpected end of file", path, where)
    if has_list and end - offset > _MAX_DTYPE_BYTES:
        # Row 0 is more than one numpy dtype can describe: walk the rows instead.
        return _walk_rows(buf, offset, element, count, byte_order, path, need_rows) if walk else (None, None)
    dtype = _element_dtype(element, byte_order, lengths)
    if dtype.itemsize == 0:
        return np.zeros(count, dtype), 0  # an element without properties
    if offset + count * dtype.itemsize <= len(buf):
        rows = buf[offset:offset + count * dtype.itemsize].view(dtype)
        if not has_list or all((rows[f"\n{i}len"] == n).all() for i, n in lengths.items()):
            return rows, count * dtype.itemsize
    elif not has_list:
        available = (len(buf) - offset) // dtype.itemsize
        raise FormatError(f"row {available}: unexpected end of file", path, where)
    if not walk:
        return None, None  # lists of varying lengths, and the caller would rather not walk them
    return _walk_rows(buf, offset, element, count, byte_order, path, need_rows)


def _walk_rows(buf: np.ndarray, offset: int, element, count: int, byte_order: str, path: str, need_rows: bool):
    """Rows whose lists vary in length: one step a row to find where each starts, the rest in bulk."""
    props = element.properties
    steps = []  # per property: (struct of the list length or None, bytes a value / of the value)
    for prop in props:
        if isinstance(prop, plyfile.PlyListProperty):
            len_t, val_t = (np.dtype(t) for t in prop.list_dtype(byte_order))
            steps.append((struct.Struct(byte_order + len_t.char), val_t.itemsize))
        else:
            steps.append((None, np.dtype(prop.dtype(byte_order)).itemsize))
    list_index = [i for i, (st, _size) in enumerate(steps) if st is not None]
    # The walk steps over runs of fixed-size properties at once: per list, the
    # bytes before its length field, the length's struct and the value size.
    segments, fixed = [], 0
    for st, size in steps:
        if st is None:
            fixed += size
        else:
            segments.append((fixed, st.unpack_from, st.size, size))
            fixed = 0
    tail = fixed
    starts, found = [], []  # Python lists: appending beats numpy item assignment in this loop
    raw = memoryview(buf)
    end = len(buf)
    pos = offset
    row = 0
    try:
        if len(segments) == 1:  # the usual case, in the tightest loop Python has
            before, unpack, len_size, size = segments[0]
            step = before + len_size + tail
            add_start, add_length = starts.append, found.append
            for row in range(count):
                add_start(pos)
                n = unpack(raw, pos + before)[0]
                add_length(n)
                pos += step + n * size
            if found and min(found) < 0:
                row = next(i for i, n in enumerate(found) if n < 0)
                raise FormatError(f"row {row}: negative list length {found[row]}", path,
                                  (f"element '{element.name}'", f"property '{props[list_index[0]].name}'"))
            if pos > end:
                row = count - 1
                raise struct.error("past the end")
        for row in range(count if len(segments) > 1 else 0):
            starts.append(pos)
            for k, (before, unpack, len_size, size) in enumerate(segments):
                pos += before
                n = unpack(raw, pos)[0]  # struct.error past the end
                if n < 0:
                    raise FormatError(f"row {row}: negative list length {n}", path,
                                      (f"element '{element.name}'", f"property '{props[list_index[k]].name}'"))
                found.append(n)
                pos += len_size + n * size
            pos += tail
            if pos > end:
                raise struct.error("past the end")
    except struct.error:
        raise FormatError(f"row {row}: unexpected end of file", path, (f"element '{element.name}'",)) from None
    starts = np.array(starts, np.int64)
    lengths = np.array(found, np.int64).reshape(count, len(list_index))
    if not need_rows:
        return None, pos - offset
    fields = [(p.name, p.dtype(byte_order)) for p in props if not isinstance(p, plyfile.PlyListProperty)]
    rows = np.empty(count, np.dtype(fields))
    within = np.zeros(count, np.int64)  # offset inside the row of the property at hand
    k = 0
    for prop, (st, size) in zip(props, steps):
        if st is None:
            at = starts + within
            rows[prop.name] = buf[at[:, None] + np.arange(size)].reshape(-1).view(rows.dtype[prop.name])
            within += size
        else:
            within += st.size + lengths[:, k] * size
            k += 1
    return rows, pos - offset


def _read_binary(f, path: str, header, layout: _Layout, counts: dict) -> _PlyFile:
    byte_order = header.byte_order
    buf = np.memmap(f, dtype=np.uint8, mode="r") if os.fstat(f.fileno()).st_size else np.zeros(0, np.uint8)
    offset = layout.header_bytes
    notes = []
    vertex = None
    for element, count in zip(header.elements, counts):
        after = vertex is not None
        rows, nbytes = _binary_rows(buf, offset, element, count, byte_order, path, element.name == "vertex",
                                    walk=not after)
        if nbytes is None:
            # Rows after the vertex element, not needed, whose lists vary: their extent
            # would cost a walk, only to check for bytes after them. Stop here.
            return _PlyFile(header, vertex, notes)
        if element.name == "vertex" and vertex is None:  # the first, as ply["vertex"] is
            vertex = rows
        offset += nbytes
    extra = len(buf) - offset
    if extra > 0:
        last = header.elements[-1]
        row_bytes = _element_dtype(last, byte_order, {}).itemsize if not any(
            isinstance(p, plyfile.PlyListProperty) for p in last.properties) else 0
        rows_more = f" ({extra // row_bytes} more rows of '{last.name}' than its header declares?)" if (
            row_bytes and extra % row_bytes == 0) else ""
        notes.append(f"{extra} bytes after the last element ignored{rows_more}")
    return _PlyFile(header, vertex, notes)


def _read_ascii(f, path: str, header, layout: _Layout, counts: dict) -> _PlyFile:
    """ASCII rows: one line a row, parsed in bulk by ``np.loadtxt`` where every property is a number.

    Anything the bulk parse refuses (a malformed value, a short line, a list
    property before the vertex rows) is read again by plyfile, whose row-by-row
    parser names the row and property that is wrong.
    """
    f.seek(layout.header_bytes)
    lines = f.read().split(b"\n")
    if lines and lines[-1].strip() == b"":
        lines.pop()  # the newline that ends the last row
    at = 0
    vertex = None
    notes = []
    for element, count in zip(header.elements, counts):
        if vertex is None:
            if any(isinstance(p, plyfile.PlyListProperty) for p in element.properties):
                return _read_ascii_plyfile(f, path)
            dtype = _element_dtype(element, "=")
            if count == 0:
                rows = np.zeros(0, dtype)
            else:
                try:
                    text = [line.decode("ascii") for line in lines[at:at + count]]
                    rows = np.loadtxt(text, dtype=dtype, comments=None, ndmin=1)
                except (ValueError, OverflowError, UnicodeDecodeError):
                    return _read_ascii_plyfile(f, path)
                if len(rows) != count:
                    return _read_ascii_plyfile(f, path)
            if element.name == "vertex":
                vertex = rows
        at += count
    extra = sum(1 for line in lines[at:] if line.strip())
    if extra:
        notes.append(f"{extra} lines after the last element ignored (more rows than the header declares?)")
    return _PlyFile(header, vertex, notes)


def _read_ascii_plyfile(f, path: str) -> _PlyFile:
    f.seek(0)
    with _plyfile_errors(path):
        # From memory: plyfile wraps a file in a text reader it never closes (a ResourceWarning).
        ply = plyfile.PlyData.read(io.BytesIO(f.read()))
    return _PlyFile(ply, ply["vertex"].data, [])


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


def _column(data: np.ndarray, name: str, notes: list) -> np.ndarray:
    col = data[name]
    if col.dtype == np.dtype("<f4") or (col.dtype == np.float32 and col.dtype.isnative):
        return col  # a view into the mapped file: no copy
    with np.errstate(over="ignore", invalid="ignore"):  # reported below
        out = col.astype(np.float32)
    if col.dtype.kind == "f" and col.dtype.itemsize > 4:
        overflowed = int(np.count_nonzero(np.isinf(out) & np.isfinite(col)))
        if overflowed:
            notes.append(f"{name}: {overflowed:,} finite double value{'s' if overflowed != 1 else ''} past the "
                         "float32 range became infinite")
    return out


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
    opened = _open(path)
    ply = opened.header
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
    data = opened.vertex_data
    populate(data)
    n = len(data)
    notes = list(opened.notes)
    used = set(LITE_REQUIRED if variant == model.VARIANT_LITE else GS_REQUIRED) | set(NORMALS)
    ignored = [p for p in names if p not in used]
    doubles = [p.name for p in vertex.properties if p.name in used and p.val_dtype.endswith("8")]
    if doubles:
        notes.append(f"{len(doubles)} double properties narrowed to float32: {', '.join(doubles[:6])}"
                     + (", ..." if len(doubles) > 6 else ""))
    columns = {}
    if variant == model.VARIANT_LITE:
        for name in COLUMNS:
            columns[name] = _column(data, name, notes)
    else:
        for name in GS_REQUIRED:
            columns[name] = _column(data, name, notes)
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
        with np.errstate(invalid="ignore"):  # a signalling NaN warns when widened; it stays NaN
            for name in model.COLOR:
                columns[name] = (0.5 + SH_C0 * wide(columns[name])).astype(np.float32)
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
#: Property order of the written 3DGS layout: SH degree 0 only (the viewer draws
#: view-independent colour), as 3DGS tools and web viewers read it.
GS_LAYOUT = model.POSITION + NORMALS + model.COLOR + model.OPACITY + model.SCALE + model.ROTATION
#: Row type of the written 3DGS layout.
GS_DTYPE = np.dtype([(name, "<f4") for name in GS_LAYOUT])
#: Layouts :func:`write` produces, by ``layout=`` name.
LAYOUTS = {"lite": LITE_LAYOUT, "3dgs": GS_LAYOUT}


def header_bytes(count: int, cameras, layout: str = "lite") -> bytes:
    """The PLY header of a file of ``count`` rows in ``layout`` (a :data:`LAYOUTS` name)."""
    lines = ["ply", "format binary_little_endian 1.0"]
    if cameras:
        text = json.dumps(cameras, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
        lines.append("comment " + CAMERA_COMMENT + text)
    lines.append(f"element vertex {count}")
    lines.extend(f"property float {name}" for name in LAYOUTS[layout])
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
        f_dc_0..2). ``3dgs``: the plain 3DGS layout (colour as the degree-0 SH
        coefficient (rgb - 0.5) / SH_C0, no f_rest, log scales, logit opacity),
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
    report = WriteReport(count=n)
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
    stream.write(header_bytes(n, scene.cameras, "3dgs"))
    block = np.zeros(min(BLOCK, max(n, 1)), dtype=GS_DTYPE)  # normals stay 0
    with progress.stage("writing", n, "splat") as advance:
        for start in range(0, n, BLOCK):
            stop = min(start + BLOCK, n)
            rows = slice(start, stop) if order is None else order[start:stop]
            out = block[: stop - start]
            for name in model.POSITION + model.OPACITY + model.SCALE + model.ROTATION:
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
    kinds = dict.fromkeys(GROUPS, "exact")
    if scene.meta.get("color") == "sh":
        kinds["color"] = "float32"
    if scene.variant == model.VARIANT_3DGS:
        kinds.update(dict.fromkeys(("motion", "omega", "trbf"), "none"))
    return kinds


def info_fields(scene: Scene) -> dict:
    """What ``info`` shows of a scene read from a PLY: encoding, colour reading, what was ignored."""
    meta = scene.meta
    return {
        "ply_format": meta.get("format"),
        "color": meta.get("color"),
        "ignored_properties": meta.get("ignored_properties", []),
        "extra_elements": meta.get("extra_elements", []),
    }


FORMAT = Format(
    name="ply",
    suffixes=(".ply",),
    default_sort="none",  # a PLY is a training format: its row order is the user's
    holds_empty=True,  # a PLY may hold zero rows
    dynamic=True,
    read=read, splat_count=splat_count, most_splats=most_splats, declared_size=declared_size,
    write=write, layouts=tuple(LAYOUTS),
    info_fields=info_fields, storage=storage,
    # Attributes, not the viewer's texture; one scene a file (several inputs for one
    # output are a frame sequence, not a page's segments).
)
