"""The PLY container: the header, the element layout it declares, and reading rows.

Knows nothing of splats (:mod:`splatconv.formats.ply` maps properties to model
columns). One parser reads the header (:func:`parse_header`): it splits the
lines once and reads each once, into what the sizes say (:class:`Header`'s
``sizes``, enough to bound a file before its grammar is checked) and into the
grammar's elements and properties. The grammar, the types it accepts and its
messages are plyfile's (``plyfile._PlyHeaderParser``), so files plyfile reads
are read alike and a bad header is named as plyfile names it.

Rows are read in bulk: binary rows as views of the mapped file (list properties
assumed of constant length, checked at once, walked one by one only where they
vary); ASCII rows by ``np.loadtxt``. Only an ASCII file the bulk parse refuses
is read again by plyfile, whose row-by-row parser names the row and property
that is wrong.
"""

from __future__ import annotations

import contextlib
import io
import os
import struct
import warnings
from dataclasses import dataclass, field

import numpy as np
import plyfile

from ..errors import FormatError
from ..files.inputs import open_input

#: PLY type names and numpy codes, as plyfile relates them (a header may use either).
_TYPE_RELATION = (("int8", "i1"), ("char", "i1"), ("uint8", "u1"), ("uchar", "b1"), ("uchar", "u1"),
                  ("int16", "i2"), ("short", "i2"), ("uint16", "u2"), ("ushort", "u2"), ("int32", "i4"),
                  ("int", "i4"), ("uint32", "u4"), ("uint", "u4"), ("float32", "f4"), ("float", "f4"),
                  ("float64", "f8"), ("double", "f8"))
_CODE_NAME = dict((code, name) for name, code in _TYPE_RELATION)
#: The numpy code of each type a header may name (a name, or a code itself).
TYPE_CODES = {**{code: dict(_TYPE_RELATION)[name] for code, name in _CODE_NAME.items()}, **dict(_TYPE_RELATION)}
#: Bytes a value of each type (an unknown type: 1, the least a value takes).
_TYPE_BYTES = {word: np.dtype(code).itemsize for word, code in TYPE_CODES.items()}
#: The types in the order plyfile lists them in its message.
_TYPES_LISTED = list(dict.fromkeys(word for pair in _TYPE_RELATION for word in pair))
#: Byte order of each PLY format ("=": text).
BYTE_ORDERS = {"ascii": "=", "binary_little_endian": "<", "binary_big_endian": ">"}
# The largest structured dtype numpy makes: its itemsize must fit a C int.
_MAX_DTYPE_BYTES = 2**31 - 1
_MAX_HEADER = 16 << 20


@dataclass(frozen=True)
class Property:
    """One property of an element: its name, value type and, for a list, the length's type (numpy codes)."""

    name: str
    val_dtype: str
    len_dtype: str | None = None

    @property
    def is_list(self) -> bool:
        return self.len_dtype is not None

    def dtype(self, byte_order: str) -> str:
        """The value's numpy type in ``byte_order`` ("<", ">" or "=")."""
        return byte_order + self.val_dtype

    def list_dtype(self, byte_order: str) -> tuple[str, str]:
        """A list's length and value numpy types in ``byte_order``."""
        return byte_order + self.len_dtype, byte_order + self.val_dtype


@dataclass
class Element:
    """One element of the header: its name, row count, properties (:class:`Property`) and comments."""

    name: str
    count: int
    properties: list = field(default_factory=list)
    comments: list = field(default_factory=list)

    @property
    def has_list(self) -> bool:
        return any(p.is_list for p in self.properties)


@dataclass
class Header:
    """What a PLY header says.

    ``sizes`` is what the lines say of sizes whatever their grammar:
    ``[name, count, fixed_row_bytes, n_properties, has_list]`` per well-formed
    ``element`` line, in order (a count that is not a non-negative integer is
    refused as it is met); ``format`` the last ``format`` line's word. The
    grammar's result is ``elements``, ``comments`` and ``obj_info``, valid
    only when ``error`` is None: the first thing wrong with the header
    (raised by :func:`check`, after the sizes are checked against the file).
    ``header_bytes`` is the offset of the body, None when the bytes read hold
    no ``end_header`` line.
    """

    format: str | None = None
    sizes: list = field(default_factory=list)
    elements: list = field(default_factory=list)
    comments: list = field(default_factory=list)
    obj_info: list = field(default_factory=list)
    header_bytes: int | None = None
    error: FormatError | None = None

    @property
    def text(self) -> bool:
        return self.format == "ascii"

    @property
    def byte_order(self) -> str:
        return BYTE_ORDERS[self.format]

    def element(self, name: str):
        """The element called ``name``, None if there is none (names are unique once checked)."""
        return next((e for e in self.elements if e.name == name), None)

    def declared_count(self, name: str):
        """The row count the first well-formed ``element name`` line declares (read from ``sizes``)."""
        return next((count for element, count, *_rest in self.sizes if element == name), None)

    def fixed_size(self):
        """Bytes of a binary file whose rows are all fixed-size; None when unknown (ASCII, lists)."""
        if self.header_bytes is None or self.format not in ("binary_little_endian", "binary_big_endian"):
            return None
        if any(e[4] for e in self.sizes):
            return None
        return self.header_bytes + sum(count * row for _name, count, row, _props, _list in self.sizes)


def _newline(head: bytes):
    """The line ending a PLY header uses, as plyfile decides it from the first line; None if not PLY."""
    if head[3:5] == b"\r\n":
        return b"\r\n"
    return head[3:4] if head[:3] == b"ply" and head[3:4] in (b"\r", b"\n") else None


def _header_lines(head: bytes):
    """The header's lines after ``ply`` (bytes, without endings), the offset of the body (None: incomplete).

    Split as plyfile splits them, on the first line's ending, and ended by the
    first line that is ``end_header`` once stripped (as plyfile strips: Python
    ``str.strip`` of the ASCII text). Without a complete line the rest is
    returned as the last line.
    """
    nl = _newline(head)
    if nl is None:
        return [], None
    lines, pos = [], 3 + len(nl)
    while True:
        stop = head.find(nl, pos)
        if stop < 0:
            return lines + [head[pos:]], None
        line = head[pos:stop]
        pos = stop + len(nl)
        lines.append(line)
        if line.decode("latin-1").strip() == "end_header":
            return lines, pos


def read_header_bytes(f, file_size: int) -> bytes:
    """The file's first bytes up to its ``end_header`` line (at most 16 MiB).

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


class _BadHeader(Exception):
    """A grammar error at header line ``line``, worded as plyfile's ``PlyHeaderParseError`` words it."""

    def __init__(self, message: str, line: int | None):
        super().__init__(message)
        self.message, self.line = message, line


def _decode_error(line: bytes) -> str | None:
    """plyfile's message for the first non-ASCII byte of ``line`` (it decodes a byte at a time); None if ASCII."""
    if line.isascii():
        return None
    byte = next(b for b in line if b > 127)
    return f"cannot parse: {UnicodeDecodeError('ascii', bytes([byte]), 0, 1, 'ordinal not in range(128)')}"


class _Grammar:
    """plyfile's header grammar, a line at a time: what may come next, and the elements read so far."""

    def __init__(self, header: Header):
        self.header = header
        self.allowed = ["format", "comment", "obj_info"]
        self.line = 1

    def consume(self, text: str) -> None:
        self.line += 1
        if not text:
            raise _BadHeader("early end-of-file", self.line)
        text = text.strip()
        if text == "":
            return  # plyfile skips blank lines (not strictly PLY)
        keyword = text.split(None, 1)[0]
        if keyword not in self.allowed:
            raise _BadHeader("expected one of {%s}" % ", ".join(self.allowed), self.line)
        getattr(self, "_" + keyword)(text[len(keyword) + 1:])

    def _format(self, data: str) -> None:
        fields = data.strip().split()
        if len(fields) != 2:
            raise _BadHeader('expected "format {format} 1.0"', self.line)
        if fields[0] not in BYTE_ORDERS:
            raise _BadHeader(f"don't understand format {fields[0]!r}", self.line)
        if fields[1] != "1.0":
            raise _BadHeader("expected version '1.0'", self.line)
        self.header.format = fields[0]
        self.allowed = ["element", "comment", "obj_info", "end_header"]

    def _comment(self, data: str) -> None:
        (self.header.elements[-1].comments if self.header.elements else self.header.comments).append(data)

    def _obj_info(self, data: str) -> None:
        self.header.obj_info.append(data)

    def _element(self, data: str) -> None:
        fields = data.strip().split()
        if len(fields) != 2:
            raise _BadHeader('expected "element {name} {count}"', self.line)
        try:
            count = int(fields[1])
        except ValueError:
            raise _BadHeader("expected integer count", self.line) from None
        self.header.elements.append(Element(fields[0], count))
        self.allowed = ["element", "comment", "property", "end_header"]

    def _type(self, word: str) -> str:
        if word not in TYPE_CODES:
            raise _BadHeader(f"field type {word!r} not in {_TYPES_LISTED!r}", self.line)
        return TYPE_CODES[word]

    def _property(self, data: str) -> None:
        fields = data.strip().split()
        if len(fields) < 2:
            raise _BadHeader("bad 'property' line", self.line)
        if fields[0] == "list":
            if len(fields) != 4:
                raise _BadHeader('expected "property list {len_type} {val_type} {name}"', self.line)
            value = self._type(fields[2])  # plyfile checks the value type first
            prop = Property(fields[3], value, self._type(fields[1]))
        else:
            if len(fields) != 2:
                raise _BadHeader('expected "property {type} {name}"', self.line)
            prop = Property(fields[1], self._type(fields[0]))
        self.header.elements[-1].properties.append(prop)

    def _end_header(self, data: str) -> None:
        if data:
            raise _BadHeader("unexpected data after 'end_header'", self.line)
        self.allowed = []


def _size_line(header: Header, line: bytes, path: str) -> None:
    """What one line says of sizes (whatever its grammar): a format, an element and its count, a property."""
    words = line.decode("latin-1").split()
    if len(words) >= 2 and words[0] == "format":
        header.format = words[1]
    elif len(words) == 3 and words[0] == "element":
        if not (words[2].isascii() and words[2].isdigit()):
            raise FormatError(f"row count {words[2][:24]!r} is not a non-negative integer", path,
                              (f"element '{words[1][:40]}'",))
        header.sizes.append([words[1], int(words[2]), 0, 0, False])
    elif words[:1] == ["property"] and header.sizes:
        sizes = header.sizes[-1]
        sizes[3] += 1
        if len(words) == 3:
            sizes[2] += _TYPE_BYTES.get(words[1], 1)
        elif len(words) == 5 and words[1] == "list":
            sizes[2] += _TYPE_BYTES.get(words[2], 1)
            sizes[4] = True


def _first_line_error(head: bytes) -> str | None:
    """What plyfile says of a file whose first line is not ``ply`` and an ending; None when it is."""
    try:
        first = head[:4].decode("ascii")
        if first[:3] == "ply" and first[3:] == "\r":
            head[4:5].decode("ascii")
    except UnicodeDecodeError as e:
        return f"cannot parse: {e}"
    if first[:3] != "ply":
        return "expected 'ply'"
    return None if _newline(head) else "unexpected characters after 'ply'"


def parse_header(head: bytes, path: str, sizes_only: bool = False) -> Header:
    """Parse the PLY header at the start of ``head`` (bytes up to its ``end_header`` line).

    One pass over the lines: each is read for sizes and, until the first error,
    by the grammar. Raises only for a row count that is not a non-negative
    integer (the sizes cannot be read past it); any other error is kept in
    ``error`` for :func:`check`, which first checks the sizes against the file.
    ``sizes_only``: only the sizes are read (``elements`` stays empty, ``error``
    None), for callers that bound a file before reading it.

    Raises
    ------
    FormatError
    """
    header = Header()
    lines, header.header_bytes = _header_lines(head)
    complete = header.header_bytes is not None
    for line in lines if complete else ():
        _size_line(header, line, path)
    if sizes_only:
        return header
    grammar = _Grammar(Header())
    bad = _grammar_error(head, lines, complete, grammar)
    if not complete:
        # Whatever the grammar met first, unless it was a byte that is not ASCII: then what is
        # wrong is most likely that the header never ends (a binary file, or not a PLY at all).
        if bad[0].startswith("cannot parse:"):
            bad = (f"no end_header line in the first {len(head):,} bytes", None)
        header.error = _header_error(bad, path)
        return header
    bad = bad or _duplicates(grammar.header.elements)
    if bad is not None:
        header.error = _header_error(bad, path)
        return header
    parsed = grammar.header
    header.format, header.elements, header.comments, header.obj_info = (parsed.format, parsed.elements,
                                                                        parsed.comments, parsed.obj_info)
    header.error = _list_type_error(header.elements, path)
    return header


def _grammar_error(head: bytes, lines: list, complete: bool, grammar: _Grammar):
    """The first thing plyfile would refuse in the header: ``(message, line number or None)``; None if nothing.

    Lines are given to ``grammar`` in order, as plyfile reads them: a byte that
    is not ASCII stops it where it is met; in an incomplete header the stream
    ends inside the last line.
    """
    error = _first_line_error(head)
    if error:
        return error, 1
    for i, line in enumerate(lines):
        decode = _decode_error(line)
        if decode:
            return decode, None
        if not complete and i == len(lines) - 1:
            return "early end-of-file", i + 2
        try:
            grammar.consume(line.decode("ascii"))
        except _BadHeader as e:
            return e.message, e.line
    if complete and lines[-1] != b"end_header":
        # plyfile ends a header at a line that is exactly "end_header"; at one that is so only
        # once stripped it reads on, past the header, and finds the end of what it was given.
        return "early end-of-file", grammar.line + 1
    return None


def _header_error(bad: tuple, path: str) -> FormatError:
    """The error for a header plyfile refuses: its message, under "bad header" with the line where it has one."""
    message, line = bad
    if message.startswith("cannot parse:"):
        return FormatError(message, path)
    return FormatError(f"bad header: {message}", path, (f"line {line}",) if line else ())


def _duplicates(elements):
    """plyfile refuses two properties of an element, or two elements, of the same name (as a ValueError)."""
    for element in elements:
        if len({p.name for p in element.properties}) != len(element.properties):
            return "cannot parse: two properties with same name", None
    if len({e.name for e in elements}) != len(elements):
        return "cannot parse: two elements with same name", None
    return None


def _list_type_error(elements, path: str):
    """A list's length must be an integer type (plyfile takes ``property list float int x``)."""
    for element in elements:
        for prop in element.properties:
            if prop.is_list and np.dtype(prop.len_dtype).kind not in "iu":
                len_t = np.dtype(prop.len_dtype)
                name = {4: "float", 8: "double"}.get(len_t.itemsize, len_t.name)
                return FormatError(f"list length type '{name}' is not an integer type", path,
                                   (f"element '{element.name}'", f"property '{prop.name}'"))
    return None


def check_sizes(header: Header, path: str, file_size: int) -> None:
    """Refuse a header that declares more rows than ``file_size`` bytes can hold.

    Checked before the grammar's error is raised (see :func:`check`): a reader
    would otherwise try to allocate e.g. 10^12 ASCII rows up front.

    Raises
    ------
    FormatError
    """
    fmt = header.format
    if header.header_bytes is not None and fmt in BYTE_ORDERS:
        body = file_size - header.header_bytes
        need = 0
        for name, count, row_bytes, props, _list in header.sizes:
            # At least one byte a value in binary; a digit and a separator in ASCII (a
            # row of an element without properties: nothing, or an empty line).
            row = row_bytes if fmt != "ascii" else 2 * props or 1
            need += count * row
            if need > body + (fmt == "ascii"):
                what = f"{count * row} bytes" if fmt != "ascii" else f"at least {count * row - 1} bytes"
                raise FormatError(f"header declares {count} rows ({what}) but only {body} bytes follow the "
                                  "header: file truncated?", path, (f"element '{name}'",))


def check(header: Header, path: str, file_size: int) -> None:
    """Refuse a header whose rows cannot fit in ``file_size`` bytes (:func:`check_sizes`), then one with an error.

    Raises
    ------
    FormatError
    """
    check_sizes(header, path, file_size)
    if header.error is not None:
        raise header.error


def declared_size(head: bytes):
    """File size a binary PLY header at the start of ``head`` declares (None: ASCII, lists or unknown)."""
    try:
        return parse_header(head, "", sizes_only=True).fixed_size()
    except FormatError:
        return None


def _plyfile_errors(path: str):
    """A context that turns plyfile's errors into :class:`FormatError` naming where."""

    @contextlib.contextmanager
    def manager():
        try:
            with warnings.catch_warnings():
                # An empty list in an ASCII row: plyfile reads it right, numpy warns.
                warnings.filterwarnings("ignore", "loadtxt: input contained no data")
                yield
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


def _element_dtype(element, byte_order: str, list_lengths=None) -> np.dtype:
    """Row dtype of ``element``; each list property as a length field plus a fixed array of values."""
    fields = []
    for i, prop in enumerate(element.properties):
        if prop.is_list:
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
        if prop.is_list:
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
    has_list = element.has_list
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
        if prop.is_list:
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
    fields = [(p.name, p.dtype(byte_order)) for p in props if not p.is_list]
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


def _read_binary(f, path: str, header: Header) -> Rows:
    byte_order = header.byte_order
    buf = np.memmap(f, dtype=np.uint8, mode="r") if os.fstat(f.fileno()).st_size else np.zeros(0, np.uint8)
    offset = header.header_bytes
    notes = []
    vertex = None
    found = {}
    for element in header.elements:
        count = element.count
        after = vertex is not None
        rows, nbytes = _binary_rows(buf, offset, element, count, byte_order, path, element.name == "vertex",
                                    walk=not after)
        if nbytes is None:
            # Rows after the vertex element, not needed, whose lists vary: their extent
            # would cost a walk, only to check for bytes after them. Stop here.
            return Rows(header, vertex, notes, found)
        if element.name == "vertex" and vertex is None:  # the first, as ply["vertex"] is
            vertex = rows
        found.setdefault(element.name, rows)
        offset += nbytes
    extra = len(buf) - offset
    if extra > 0:
        last = header.elements[-1]
        row_bytes = _element_dtype(last, byte_order, {}).itemsize if not last.has_list else 0
        rows_more = f" ({extra // row_bytes} more rows of '{last.name}' than its header declares?)" if (
            row_bytes and extra % row_bytes == 0) else ""
        notes.append(f"{extra} bytes after the last element ignored{rows_more}")
    return Rows(header, vertex, notes, found)


def _read_ascii(f, path: str, header: Header) -> Rows:
    """ASCII rows: one line a row, parsed in bulk by ``np.loadtxt`` where every property is a number.

    Anything the bulk parse refuses (a malformed value, a short line, a list
    property before the vertex rows) is read again by plyfile, whose row-by-row
    parser names the row and property that is wrong.
    """
    f.seek(header.header_bytes)
    lines = f.read().split(b"\n")
    if lines and lines[-1].strip() == b"":
        lines.pop()  # the newline that ends the last row
    at = 0
    vertex = None
    notes = []
    for element in header.elements:
        count = element.count
        if vertex is None:
            if element.has_list:
                return _read_ascii_plyfile(f, path, header)
            dtype = _element_dtype(element, "=")
            if count == 0:
                rows = np.zeros(0, dtype)
            else:
                try:
                    text = [line.decode("ascii") for line in lines[at:at + count]]
                    rows = np.loadtxt(text, dtype=dtype, comments=None, ndmin=1)
                except (ValueError, OverflowError, UnicodeDecodeError):
                    return _read_ascii_plyfile(f, path, header)
                if len(rows) != count:
                    return _read_ascii_plyfile(f, path, header)
            if element.name == "vertex":
                vertex = rows
        at += count
    extra = sum(1 for line in lines[at:] if line.strip())
    if extra:
        notes.append(f"{extra} lines after the last element ignored (more rows than the header declares?)")
    return Rows(header, vertex, notes)


def _read_ascii_plyfile(f, path: str, header: Header) -> Rows:
    """ASCII rows read again by plyfile: what the bulk parse refused, named by row and property."""
    f.seek(0)
    with _plyfile_errors(path):
        # From memory: plyfile wraps a file in a text reader it never closes (a ResourceWarning).
        ply = plyfile.PlyData.read(io.BytesIO(f.read()))
    return Rows(header, ply["vertex"].data, [])


def vertex_count(path: str):
    """The row count of the ``vertex`` element the header at ``path`` declares, read without the rows.

    None when there is none, or the header's sizes are refused (a count that
    is not a number, a file too short for the rows, no ``end_header`` line);
    the header's grammar is not asked (reading the file names what is wrong).
    """
    try:
        with open_input(path) as f:
            size = os.fstat(f.fileno()).st_size
            header = parse_header(read_header_bytes(f, size), path, sizes_only=True)
            check_sizes(header, path, size)
    except FormatError:
        return None
    return None if header.header_bytes is None else header.declared_count("vertex")


@dataclass
class Rows:
    """A PLY read as far as its vertex rows: the header, the rows (None without a vertex element), notes.

    ``vertex`` is a structured array (a view of the mapped file where the
    rows are fixed-size), one field a property that is not a list.
    ``elements``: a binary file's rows of every element read, by name, alike
    (those up to the vertex element and after it, but for lists of varying
    length after it); empty for an ASCII file.
    """

    header: Header
    vertex: np.ndarray | None
    notes: list
    elements: dict = field(default_factory=dict)


def read_rows(path: str) -> Rows:
    """Parse the PLY at ``path`` and read its ``vertex`` rows (see :class:`Rows`).

    Raises
    ------
    FormatError
        An empty file, a bad header, rows past the end of the file, a value
        that does not parse.
    """
    with open_input(path) as f:
        size = os.fstat(f.fileno()).st_size
        if size == 0:
            raise FormatError("file is empty", path)
        header = parse_header(read_header_bytes(f, size), path)
        check(header, path, size)
        if header.element("vertex") is None:
            return Rows(header, None, [])
        if header.text:
            return _read_ascii(f, path, header)
        return _read_binary(f, path, header)
