"""glTF 2.0 with ``KHR_gaussian_splatting``: a static scene as a point primitive (specs/gltf.md).

Two containers, one format: ``.glb`` (a 12-byte header, a JSON chunk, a BIN chunk) and
``.gltf`` (the JSON alone, its buffer in a ``.bin`` file beside it, written with it, all or
nothing). Both are read by their first bytes, whatever the suffix; a ``.gltf`` buffer may also
be a ``data:`` URI. Written, one mesh primitive of mode POINTS, its attributes float32, one
tightly packed buffer view each, in this order::

    POSITION                                   VEC3   float   the scene's x, y, z turned (below)
    COLOR_0                                    VEC4   ubyte   normalised: clamped RGB and sigmoid(opacity), for
                                                              viewers without the extension
    KHR_gaussian_splatting:ROTATION            VEC4   float   unit quaternion x, y, z, w, turned
    KHR_gaussian_splatting:SCALE               VEC3   float   exp(scale): linear
    KHR_gaussian_splatting:OPACITY             SCALAR float   sigmoid(opacity)
    KHR_gaussian_splatting:SH_DEGREE_0_COEF_0  VEC3   float   (rgb - 0.5) / SH_C0: the DC coefficient
    KHR_gaussian_splatting:SH_DEGREE_l_COEF_n  VEC3   float   the scene's SH bands, turned

The turn is PlayCanvas splat-transform's (3.7): a PLY's frame is glTF's turned 180 degrees about
z, so x, y, z are written as -x, -y, z, each quaternion is multiplied by that turn, and each SH
coefficient whose basis function changes sign under it is negated. Reading undoes it exactly.
Header cameras become perspective cameras on nodes (with their pixel sizes in ``extras``).
A scene that moves or fades is refused (bake a moment first); reading gives a static scene.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import os
import struct
import urllib.parse

import numpy as np

from .. import model, sh
from ..cameras import MAX_CAMERA_PIXELS, validate_cameras
from ..errors import FormatError, UnsupportedError
from ..files.inputs import open_input
from ..jsonutil import is_finite_number, loads_strict
from ..model import Scene
from ..progress import SILENT
from ..viewer import importance, importance_order, logit, sigmoid, wide
from ..wording import plural
from . import spz
from .base import Format, Scan, WriteReport, refuse_nonfinite_positions, refuse_time_varying
from .ply import SH_C0  # rgb = 0.5 + SH_C0 * f_dc: the model keeps RGB, glTF the coefficient

MAGIC = 0x46546C67  # "glTF"
VERSION = 2
HEADER = struct.Struct("<III")  # magic, version, total length
CHUNK = struct.Struct("<II")  # chunk length, chunk type
CHUNK_JSON = 0x4E4F534A  # "JSON"
CHUNK_BIN = 0x004E4942  # "BIN\0"
#: Largest JSON read (a chunk or a ``.gltf``): a glTF's JSON is a few kilobytes, its data in buffers.
MAX_JSON_BYTES = 64 << 20
#: Largest ``.glb`` written: its header counts bytes in 32 bits (a ``.gltf`` has no such limit).
MAX_GLB_BYTES = (1 << 32) - 1

EXTENSION = "KHR_gaussian_splatting"
MODE_POINTS = 0
ARRAY_BUFFER = 34962
#: The extension object written: the spec's defaults, stated.
PRIMITIVE_EXTENSION = {"kernel": "ellipse", "colorSpace": "srgb_rec709_display",
                       "sortingMethod": "cameraDistance", "projection": "perspective"}

BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
#: componentType -> numpy dtype, and the divisor of a normalised integer (glTF 2.0, 3.11).
COMPONENTS = {BYTE: ("i1", 127.0), UNSIGNED_BYTE: ("u1", 255.0), SHORT: ("<i2", 32767.0),
              UNSIGNED_SHORT: ("<u2", 65535.0), UNSIGNED_INT: ("<u4", None), FLOAT: ("<f4", None)}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}

POSITION = "POSITION"
ROTATION = f"{EXTENSION}:ROTATION"
SCALE = f"{EXTENSION}:SCALE"
OPACITY = f"{EXTENSION}:OPACITY"
COLOR_0 = "COLOR_0"


def sh_attribute(degree: int, n: int) -> str:
    """The attribute of SH degree ``degree``'s coefficient ``n`` (degree 0: the DC colour)."""
    return f"{EXTENSION}:SH_DEGREE_{degree}_COEF_{n}"


#: Attributes read: name -> (accessor type, the (componentType, normalized) pairs the spec allows).
READ_TYPES = {
    POSITION: ("VEC3", {(FLOAT, False)}),
    ROTATION: ("VEC4", {(FLOAT, False), (BYTE, True), (SHORT, True)}),
    SCALE: ("VEC3", {(FLOAT, False), (BYTE, False), (BYTE, True), (SHORT, False), (SHORT, True)}),
    OPACITY: ("SCALAR", {(FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True)}),
    COLOR_0: ("VEC4", {(FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True)}),  # the fallback: not read
}
SH_TYPE = ("VEC3", {(FLOAT, False)})
REQUIRED = (POSITION, ROTATION, SCALE, OPACITY, sh_attribute(0, 0))

#: The turn between the scene's frame and the file's (splat-transform's PLY frame to glTF's): 180 degrees
#: about z, x, y, z -> -x, -y, z. Its own inverse.
TURN = np.diag([-1.0, -1.0, 1.0])
#: Camera axes: the scene's cameras look along +z with y down (OpenCV), glTF's along -z with y up.
CAMERA_AXES = np.diag([1.0, -1.0, -1.0])
#: Sign of each SH coefficient (degrees 1 to 3, 3DGS order) under :data:`TURN`: the turn maps every
#: basis function to plus or minus itself (:func:`splatconv.sh.rotation_matrix` is diagonal).
SH_SIGNS = np.rint(np.diag(sh.rotation_matrix(TURN, 3))).astype(np.float32)
#: Near plane written for a camera (glTF requires one; splatconv's cameras have none).
ZNEAR = 0.01
#: Opacity read is kept off 0 and 1 so that its logit is finite (sigmoid gives the value back to 1e-12).
OPACITY_EDGE = 1e-12

#: How each attribute group is stored (see :data:`splatconv.compare.STORAGE_KINDS`).
STORAGE = {"position": "exact", "scale": "float32", "color": "float32", "opacity": "float32",
           "rotation": "unit_quaternion", "motion": "none", "omega": "none", "trbf": "none"}

#: A quaternion whose length is within this of 1 is written as it is: a float32 unit quaternion's length
#: (four components, each rounded by at most 2^-24 relative) misses 1 by less than 2^-22.
UNIT_TOLERANCE = 2.0**-22

#: The draft SPZ compression extension (specs/gltf.md): nested in the primitive's ``KHR_gaussian_splatting``
#: object, its ``bufferView`` an SPZ version 2 stream. Written as ``layout="spz"``.
SPZ_EXTENSION = "KHR_gaussian_splatting_compression_spz_2"
#: Names it is read under: its own, and the one the draft's text also uses (``extensionsUsed``, conformance).
SPZ_NAMES = (SPZ_EXTENSION, "KHR_gaussian_splatting_compression_spz")
SPZ_VERSION = 2
LAYOUT_SPZ = "spz"
#: The stream's frame: the draft packs glTF's (left-up-front) with the SPZ library's ``LUF`` option, which
#: stores its own right-up-back: x and z of glTF's negated. After :data:`TURN`, y and z of the scene's
#: negated (180 degrees about x; its own inverse): what the library stores of a PLY packed as ``RDF``.
SPZ_TURN = TURN @ np.diag([-1.0, 1.0, -1.0])
#: Sign of each SH coefficient (degrees 1 to 3, 3DGS order) under :data:`SPZ_TURN`.
SPZ_SH_SIGNS = np.rint(np.diag(sh.rotation_matrix(SPZ_TURN, 3))).astype(np.float32)

#: Rows converted at a time when writing, and rows a piece of :func:`scan`.
BLOCK = 1 << 16


# --------------------------------------------------------------------------
# Reading


class _Source:
    """A parsed file: the JSON, the splat primitive's accessors as views of the buffers, its cameras."""

    def __init__(self, path: str):
        self.path = path
        self.doc, self.bin, self.container, self.size = _container(path)
        self.buffers = {}
        self.meta = {}
        self.notes = []
        self.primitive = _primitive(self.doc, path)
        attributes = self.primitive["attributes"]
        self.degree = _sh_degree(attributes, path)
        self.count = None
        self.views = {}
        self.spz = None  # a compressed primitive's stream: (bytes, header fields); decoded on first use
        self._decoded = None
        compression = _compression(self.primitive)
        if compression is not None:
            self._spz_stream(*compression, attributes)
            return
        for name in REQUIRED + _sh_rest_attributes(self.degree):
            self.views[name] = self._accessor(attributes[name], name)

    def _spz_stream(self, name: str, ext, attributes: dict) -> None:
        """Check a compressed primitive's SPZ stream (``ext``, the object named ``name``) against its
        accessors by the stream's header; the arrays are inflated by :meth:`columns`."""
        where = (f"{name}",)
        if not isinstance(ext, dict) or "bufferView" not in ext:
            raise FormatError("needs a bufferView", self.path, where)
        raw = self._view(ext["bufferView"])
        head = spz.legacy_header(raw)
        if head is None or head[0] != spz.MAGIC:
            raise FormatError("its bufferView is not an SPZ version 2 stream (gzip of the NGSP header)", self.path,
                              where)
        _magic, version, n, degree, _bits, _flags, _ = head
        if version != SPZ_VERSION:
            raise UnsupportedError(f"SPZ version {version} in its stream; the extension holds version {SPZ_VERSION}",
                                   self.path, where)
        acc = _item(self.doc, "accessors", attributes[POSITION], self.path)
        count = _int(acc, "count", self.path, (f"accessor {attributes[POSITION]} ({POSITION})",))
        if count != n:
            raise FormatError(f"the SPZ stream holds {n:,} splats, the accessors {count:,}", self.path, where)
        if degree != self.degree:
            raise FormatError(f"the SPZ stream holds SH degree {degree}, the attributes declare {self.degree}",
                              self.path, where)
        self.count = n
        self.spz = (raw, where)

    def _view(self, index) -> np.ndarray:
        """Buffer view ``index``'s bytes (``(byteLength,) uint8``), checked to lie inside its buffer."""
        view = _item(self.doc, "bufferViews", index, self.path)
        vwhere = (f"bufferView {index}",)
        data = self._buffer(view.get("buffer"))
        start = _int(view, "byteOffset", self.path, vwhere, 0)
        length = _int(view, "byteLength", self.path, vwhere)
        if start + length > len(data):
            raise FormatError(f"bytes {start:,} to {start + length:,} lie past its buffer's {len(data):,}", self.path,
                              vwhere)
        return data[start:start + length]

    def _spz_columns(self) -> dict:
        """The model columns of the compressed primitive, in the scene's frame (inflated once)."""
        if self._decoded is None:
            raw, where = self.spz
            version, n, degree, bits, flags, arrays = spz.unpack(raw, self.path, where)
            self.meta["antialiased"] = bool(flags & spz.FLAG_ANTIALIASED)
            self._decoded = _spz_frame(spz.decode(version, n, degree, bits, arrays), degree)
        return self._decoded

    def _accessor(self, index, name: str):
        """Accessor ``index`` of attribute ``name``: ``(values (count, width) view, componentType, normalized)``."""
        want_type, allowed = READ_TYPES.get(name, SH_TYPE)
        acc = _item(self.doc, "accessors", index, self.path)
        where = (f"accessor {index} ({name})",)
        if acc.get("type") != want_type:
            raise FormatError(f"type {_shown(acc.get('type'))}, expected {want_type}", self.path, where)
        component = acc.get("componentType")
        normalized = acc.get("normalized", False)
        if not (isinstance(component, int) and isinstance(normalized, bool)) or (component, normalized) not in allowed:
            raise FormatError(f"componentType {_shown(component)}{' normalized' if normalized is True else ''} is "
                              "not one the spec allows for it", self.path, where)
        count = _int(acc, "count", self.path, where)
        if count < 1:
            raise FormatError("count must be at least 1", self.path, where)
        if self.count is None:
            self.count = count
        elif count != self.count:
            raise FormatError(f"count {count:,} differs from POSITION's {self.count:,}", self.path, where)
        if "sparse" in acc:
            raise UnsupportedError("sparse accessors are not read", self.path, where)
        if "bufferView" not in acc:
            raise UnsupportedError("an accessor without a bufferView (all zeros) is not read", self.path, where)
        data = self._view(acc["bufferView"])
        view = self.doc["bufferViews"][acc["bufferView"]]
        vwhere = (f"bufferView {acc['bufferView']}",)
        length = len(data)
        dtype = np.dtype(COMPONENTS[component][0])
        width = WIDTHS[want_type]
        element = dtype.itemsize * width
        stride = _int(view, "byteStride", self.path, vwhere, element)
        if stride < element:
            raise FormatError(f"byteStride {stride} is less than the {element} bytes of an element", self.path, vwhere)
        offset = _int(acc, "byteOffset", self.path, where, 0)
        if offset + (count - 1) * stride + element > length:
            raise FormatError(f"{count:,} elements of {element} bytes, {stride} apart, from byte {offset:,}, run past "
                              f"its bufferView's {length:,} bytes", self.path, where)
        values = np.ndarray((count, width), dtype, buffer=data, offset=offset, strides=(stride, dtype.itemsize))
        return values, component, normalized

    def _buffer(self, index) -> np.ndarray:
        """Buffer ``index``'s bytes (``(byteLength,) uint8``), loaded once."""
        if isinstance(index, int) and index in self.buffers:
            return self.buffers[index]
        buf = _item(self.doc, "buffers", index, self.path)
        where = (f"buffer {index}",)
        length = _int(buf, "byteLength", self.path, where)
        uri = buf.get("uri")
        if uri is None:
            if index != 0 or self.bin is None:
                raise FormatError("has no uri and the file has no BIN chunk", self.path, where)
            data = self.bin
        elif not isinstance(uri, str):
            raise FormatError("uri must be a string", self.path, where)
        elif uri.startswith("data:"):
            data = _data_uri(uri, self.path, where)
        else:
            data = _external(uri, self.path, where)
        if len(data) < length:
            raise FormatError(f"byteLength {length:,} but it holds {len(data):,} bytes; truncated?", self.path, where)
        self.buffers[index] = data[:length]
        return self.buffers[index]

    def columns(self, rows: slice, tally: dict) -> dict:
        """The model columns of rows ``rows``, counting into ``tally`` what :func:`_notes_of` says."""
        if self.spz is not None:
            return {name: values[rows] for name, values in self._spz_columns().items()}
        pos = _quiet(_values(self.views[POSITION], rows))
        cols = {"x": -pos[:, 0], "y": -pos[:, 1], "z": pos[:, 2]}  # the turn undone: exact
        q = _quiet(_values(self.views[ROTATION], rows))  # x, y, z, w in the file's frame
        # The scene's quaternion is the turn's inverse times the file's: exact sign changes and swaps.
        cols.update(rot_0=q[:, 2], rot_1=q[:, 1], rot_2=-q[:, 0], rot_3=-q[:, 3])
        linear = wide(_values(self.views[SCALE], rows))
        tally["negative"] += int(np.count_nonzero(linear < 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            log_scale = np.log(linear).astype(np.float32)
        for i, name in enumerate(model.SCALE):
            cols[name] = log_scale[:, i]
        alpha = wide(_values(self.views[OPACITY], rows))[:, 0]
        outside = (alpha < 0) | (alpha > 1)
        tally["opacity"] += int(np.count_nonzero(outside))
        cols["opacity"] = logit(np.clip(alpha, OPACITY_EDGE, 1 - OPACITY_EDGE)).astype(np.float32)
        dc = wide(_values(self.views[sh_attribute(0, 0)], rows))
        rgb = (0.5 + SH_C0 * dc).astype(np.float32)
        for i, name in enumerate(model.COLOR):
            cols[name] = rgb[:, i]
        cols.update(model.static_columns(len(alpha)))
        out = {name: cols[name] for name in model.COLUMNS}
        k = model.SH_COEFFS[self.degree]
        for j, name in enumerate(_sh_rest_attributes(self.degree)):
            v = _quiet(_values(self.views[name], rows)) * SH_SIGNS[j]
            for c in range(3):
                out[f"f_rest_{c * k + j}"] = v[:, c]
        return out


def _container(path: str) -> tuple:
    """``(json, bin chunk or None, "glb" or "gltf", file size)`` of the file at ``path``."""
    with open_input(path) as f:
        size = os.fstat(f.fileno()).st_size
        if size == 0:
            raise FormatError("file is empty", path)
        head = f.read(HEADER.size)
        if head[:4] != b"glTF":
            if head[:1] not in (b"{", b" ", b"\t", b"\r", b"\n", b"\xef"):
                raise FormatError("not a glTF file (neither the GLB magic 'glTF' nor JSON)", path)
            if size > MAX_JSON_BYTES:
                raise FormatError(f"JSON of {size:,} bytes is larger than the {MAX_JSON_BYTES:,} read", path)
            f.seek(0)
            return _json(f.read(), path), None, "gltf", size
        if len(head) < HEADER.size:
            raise FormatError(f"GLB header needs {HEADER.size} bytes, the file holds {size}", path)
        _, version, length = HEADER.unpack(head)
        if version != VERSION:
            raise UnsupportedError(f"GLB version {version} (read: {VERSION})", path)
        if length != size:
            raise FormatError(f"GLB header says {length:,} bytes, the file holds {size:,}; truncated?", path)
        json_length, json_type = _chunk(f, HEADER.size, size, path, 0)
        if json_type != CHUNK_JSON:
            raise FormatError(f"first chunk is of type 0x{json_type:08x}, not JSON", path)
        if json_length > MAX_JSON_BYTES:
            raise FormatError(f"JSON chunk of {json_length:,} bytes is larger than the {MAX_JSON_BYTES:,} read", path)
        doc = _json(f.read(json_length), path)
        at = HEADER.size + CHUNK.size + json_length
        data = None
        if at < size:
            bin_length, bin_type = _chunk(f, at, size, path, 1)
            if bin_type == CHUNK_BIN:
                data = (np.memmap(f, dtype=np.uint8, mode="r", offset=at + CHUNK.size, shape=(bin_length,))
                        if bin_length else np.zeros(0, np.uint8))
        return doc, data, "glb", size


def _chunk(f, at: int, size: int, path: str, number: int) -> tuple:
    """Chunk ``number``'s ``(length, type)``, its header at byte ``at``; its data must lie inside the file."""
    if at + CHUNK.size > size:
        raise FormatError(f"chunk {number}: its header at byte {at:,} runs past the end of the file; truncated?", path)
    f.seek(at)
    length, kind = CHUNK.unpack(f.read(CHUNK.size))
    if at + CHUNK.size + length > size:
        raise FormatError(f"chunk {number}: {length:,} bytes from byte {at + CHUNK.size:,} run past the end of the "
                          f"file ({size:,} bytes); truncated?", path)
    return length, kind


def _json(raw: bytes, path: str) -> dict:
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    doc = loads_strict(raw, path, "glTF JSON")
    if not isinstance(doc, dict):
        raise FormatError("glTF JSON must be an object", path)
    version = doc.get("asset", {}).get("version") if isinstance(doc.get("asset"), dict) else None
    if not (isinstance(version, str) and version.startswith("2.")):
        raise UnsupportedError(f"asset.version {_shown(version)} (read: glTF 2.x)", path)
    required = doc.get("extensionsRequired", [])
    if not isinstance(required, list):
        raise FormatError("extensionsRequired must be a list", path)
    unknown = [name for name in required if name != EXTENSION and name not in SPZ_NAMES]
    if unknown:
        raise UnsupportedError(f"requires {', '.join(map(_shown, unknown))}, which splatconv does not read", path)
    return doc


def _data_uri(uri: str, path: str, where: tuple) -> np.ndarray:
    head, sep, payload = uri.partition(",")
    if not sep or not head.endswith(";base64"):
        raise UnsupportedError("data URI is not base64 (read: data:...;base64,...)", path, where)
    try:
        raw = base64.b64decode(payload, validate=True)
    except (binascii.Error, ValueError) as e:
        raise FormatError(f"data URI is not valid base64 ({e})", path, where) from None
    return np.frombuffer(raw, np.uint8)


def _external(uri: str, path: str, where: tuple) -> np.ndarray:
    """The file a relative ``uri`` names, beside the ``.gltf`` at ``path``, mapped."""
    parts = urllib.parse.urlsplit(uri)
    if parts.scheme or parts.netloc or uri.startswith("/"):
        raise UnsupportedError(f"uri {_shown(uri)}: read are files beside the .gltf and data: URIs", path, where)
    target = os.path.join(os.path.dirname(os.path.abspath(path)), urllib.parse.unquote(parts.path))
    if "\0" in target:
        raise FormatError(f"uri {_shown(uri)} holds a NUL character", path, where)
    try:
        with open_input(target) as f:
            size = os.fstat(f.fileno()).st_size
            return np.memmap(f, dtype=np.uint8, mode="r", shape=(size,)) if size else np.zeros(0, np.uint8)
    except FormatError as e:
        raise FormatError(f"{uri}: {e.message}", path, where) from None


def _primitive(doc: dict, path: str) -> dict:
    """The one mesh primitive with the extension, checked: mode POINTS, placed by no transform."""
    found = []
    meshes = doc.get("meshes", [])
    if not isinstance(meshes, list):
        raise FormatError("meshes must be a list", path)
    for m, mesh in enumerate(meshes):
        prims = mesh.get("primitives", []) if isinstance(mesh, dict) else []
        for p, prim in enumerate(prims if isinstance(prims, list) else []):
            if isinstance(prim, dict) and isinstance(prim.get("extensions"), dict) and EXTENSION in prim["extensions"]:
                found.append((m, p, prim))
    if not found:
        raise FormatError(f"no mesh primitive has the {EXTENSION} extension: no splats", path)
    if len(found) > 1:
        raise UnsupportedError(f"{len(found)} primitives hold splats; splatconv reads files with one", path)
    m, p, prim = found[0]
    where = (f"mesh {m} primitive {p}",)
    if prim.get("mode", 4) != MODE_POINTS:
        raise FormatError(f"mode {_shown(prim.get('mode', 4))}, the extension needs POINTS ({MODE_POINTS})", path,
                          where)
    attributes = prim.get("attributes")
    if not isinstance(attributes, dict):
        raise FormatError("attributes must be an object", path, where)
    # A compressed primitive's attributes are placeholders; its POSITION gives the count to check.
    missing = [name for name in ((POSITION,) if _compression(prim) else REQUIRED) if name not in attributes]
    if missing:
        ext = prim["extensions"][EXTENSION]
        inner = ext.get("extensions") if isinstance(ext, dict) else None
        if isinstance(inner, dict) and inner:
            raise UnsupportedError(f"splats encoded by {', '.join(map(_shown, inner))}, which splatconv does not "
                                   "read", path, where)
        raise FormatError(f"missing attribute {', '.join(missing)}", path, where)
    worlds = _world_matrices(doc, path)
    for i, node in enumerate(doc.get("nodes", [])):
        if isinstance(node, dict) and node.get("mesh") == m and not np.allclose(worlds[i], np.eye(4), atol=1e-12):
            raise UnsupportedError(f"node {i} places the splats with a transform; splatconv reads splats placed "
                                   "by none", path)
    return prim


def _compression(prim: dict) -> tuple | None:
    """``(name, object)`` of the SPZ compression extension nested in the primitive's extension object, or None."""
    ext = prim["extensions"][EXTENSION]
    inner = ext.get("extensions") if isinstance(ext, dict) else None
    if isinstance(inner, dict):
        for name in SPZ_NAMES:
            if name in inner:
                return name, inner[name]
    return None


def _spz_frame(cols: dict, degree: int) -> dict:
    """``cols`` turned by :data:`SPZ_TURN` (its own inverse): the scene's frame to the SPZ stream's and back.
    Sign changes only: exact."""
    out = dict(cols)
    for name in ("y", "z", "rot_2", "rot_3"):  # positions' y, z; the quaternion's (w, x, y, z) y and z
        out[name] = -np.asarray(cols[name])
    k = model.SH_COEFFS[degree]
    for j in range(k):
        if SPZ_SH_SIGNS[j] < 0:
            for c in range(3):
                out[f"f_rest_{c * k + j}"] = -np.asarray(cols[f"f_rest_{c * k + j}"])
    return out


def _sh_degree(attributes: dict, path: str) -> int:
    """The SH degree whose attributes ``attributes`` holds, every lower degree complete."""
    degree = 0
    for d in (1, 2, 3):
        present = [sh_attribute(d, n) in attributes for n in range(2 * d + 1)]
        if any(present):
            if not all(present) or degree != d - 1:
                raise FormatError(f"SH degree {d} attributes are incomplete or a lower degree's are missing "
                                  "(each degree is whole, every lower degree too)", path)
            degree = d
    return degree


def _sh_rest_attributes(degree: int) -> tuple:
    """The SH attributes of degrees 1 to ``degree``, in 3DGS coefficient order."""
    return tuple(sh_attribute(d, n) for d in range(1, degree + 1) for n in range(2 * d + 1))


def _values(view: tuple, rows: slice) -> np.ndarray:
    """Rows ``rows`` of an accessor as float32 ``(M, width)``: normalised integers as glTF 2.0 decodes them."""
    values, component, normalized = view
    part = np.asarray(values[rows])
    if component == FLOAT:
        return part.astype(np.float32)
    scaled = part.astype(np.float32)
    if normalized:
        scaled = np.maximum(scaled / np.float32(COMPONENTS[component][1]), np.float32(-1))
    return scaled


def _quiet(values: np.ndarray) -> np.ndarray:
    """float32 ``values`` with every NaN a quiet NaN (a signalling one warns when widened)."""
    nan = np.isnan(values)
    return np.where(nan, np.float32(np.nan), values) if nan.any() else values


def _int(obj: dict, key: str, path: str, where: tuple, default=None) -> int:
    value = obj.get(key, default)
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < 1 << 53:
        raise FormatError(f"{key} must be a whole number from 0, got {_shown(value)}", path, where)
    return value


def _item(doc: dict, key: str, index, path: str) -> dict:
    items = doc.get(key)
    if not isinstance(items, list):
        raise FormatError(f"{key} must be a list", path)
    if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
        raise FormatError(f"{key} index {_shown(index)} is out of range (it holds {len(items)})", path)
    if not isinstance(items[index], dict):
        raise FormatError(f"{key} {index} must be an object", path)
    return items[index]


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _local_matrix(node: dict) -> np.ndarray:
    """A node's own transform, ``(4, 4)``: its ``matrix`` (column-major) or its translation, rotation, scale."""
    if "matrix" in node:
        m = np.asarray(node["matrix"], dtype=np.float64)
        if m.shape != (16,):
            raise ValueError("matrix")
        return m.reshape(4, 4).T
    t = np.asarray(node.get("translation", [0, 0, 0]), dtype=np.float64)
    q = np.asarray(node.get("rotation", [0, 0, 0, 1]), dtype=np.float64)
    s = np.asarray(node.get("scale", [1, 1, 1]), dtype=np.float64)
    if t.shape != (3,) or q.shape != (4,) or s.shape != (3,):
        raise ValueError("trs")
    out = np.eye(4)
    out[:3, :3] = _quaternion_matrix(q) * s
    out[:3, 3] = t
    return out


def _world_matrices(doc: dict, path: str) -> list:
    """Each node's world transform ``(4, 4)`` (the product of its own and its ancestors')."""
    nodes = doc.get("nodes", [])
    if not isinstance(nodes, list) or not all(isinstance(n, dict) for n in nodes):
        raise FormatError("nodes must be a list of objects", path)
    parent = {}
    for i, node in enumerate(nodes):
        for child in node.get("children", []) if isinstance(node.get("children", []), list) else []:
            if isinstance(child, int) and 0 <= child < len(nodes):
                parent[child] = i
    try:
        local = [_local_matrix(n) for n in nodes]
    except (ValueError, TypeError):
        raise FormatError("a node's matrix, translation, rotation or scale is malformed", path) from None
    worlds = [None] * len(nodes)
    with np.errstate(all="ignore"):  # a hostile matrix may overflow: its NaN or inf is refused by the caller
        for i in range(len(nodes)):
            chain = [i]  # up to the first node whose world is known (or the root): each node is done once
            while worlds[chain[-1]] is None and chain[-1] in parent:
                chain.append(parent[chain[-1]])
                if len(chain) > len(nodes):
                    raise FormatError("nodes form a cycle", path)
            top = chain.pop()
            if worlds[top] is None:
                worlds[top] = local[top]
            for node in reversed(chain):
                worlds[node] = worlds[parent[node]] @ local[node]
    return worlds


def _quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of quaternion ``q`` (x, y, z, w), normalised."""
    norm = float(np.sqrt((q * q).sum()))
    x, y, z, w = q / norm if norm else (0.0, 0.0, 0.0, 1.0)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _matrix_quaternion(m: np.ndarray) -> list:
    """The unit quaternion (x, y, z, w) of rotation matrix ``m`` (Shepperd's method), w >= 0."""
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + m[i, i] - m[j, j] - m[k, k], 1e-300))
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i] = 0.25 * s
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
    q = np.asarray(q) / np.linalg.norm(q)
    return [float(v) for v in (q if q[3] >= 0 else -q)]


def _cameras(doc: dict, path: str) -> list | None:
    """The scene's cameras from the file's perspective cameras on nodes (None when it has none)."""
    cams = doc.get("cameras", [])
    if not isinstance(cams, list):
        raise FormatError("cameras must be a list", path)
    worlds = _world_matrices(doc, path)
    out = []
    for i, node in enumerate(doc.get("nodes", [])):
        index = node.get("camera")
        if index is None:
            continue
        cam = _item(doc, "cameras", index, path)
        persp = cam.get("perspective")
        if cam.get("type") != "perspective" or not isinstance(persp, dict):
            continue
        yfov, aspect = persp.get("yfov"), persp.get("aspectRatio")
        extras = cam.get("extras") if isinstance(cam.get("extras"), dict) else {}
        where = (f"camera {index}",)
        if not (isinstance(yfov, (int, float)) and 0 < yfov < math.pi):
            raise FormatError(f"yfov must be in (0, pi), got {_shown(yfov)}", path, where)
        if _pixel_sizes(extras):
            width, height, fx, fy = extras["width"], extras["height"], extras["fx"], extras["fy"]
        else:
            if not (isinstance(aspect, (int, float)) and 0 < aspect < 1e6):
                aspect = 16 / 9
            height = 720
            width = max(1, round(height * aspect))
            fy = fx = height / (2 * math.tan(yfov / 2))
        world = worlds[i]
        with np.errstate(all="ignore"):  # a degenerate node (zero scale) gives NaN, which validation refuses
            axes = world[:3, :3] / np.linalg.norm(world[:3, :3], axis=0)
        rotation = TURN @ axes @ CAMERA_AXES
        position = TURN @ world[:3, 3]
        out.append({"id": len(out), "img_name": cam["name"] if isinstance(cam.get("name"), str) else f"camera_{index}",
                    "width": width, "height": height, "position": [float(v) for v in position],
                    "rotation": [[float(v) for v in row] for row in rotation], "fy": fy, "fx": fx})
    validate_cameras(out, path)
    return out or None


def _pixel_sizes(extras: dict) -> bool:
    """Whether a camera's ``extras`` hold the size and focal lengths splatconv writes there, valid."""
    sizes = [extras.get(k) for k in ("width", "height")]
    focal = [extras.get(k) for k in ("fx", "fy")]
    return (all(isinstance(v, int) and not isinstance(v, bool) and 0 < v <= MAX_CAMERA_PIXELS for v in sizes)
            and all(is_finite_number(v) and v > 0 for v in focal))


def _load(path: str) -> _Source:
    src = _Source(path)
    ext = src.primitive["extensions"][EXTENSION]
    ext = ext if isinstance(ext, dict) else {}
    asset = src.doc.get("asset", {})
    src.meta = {"file_bytes": src.size, "container": src.container,
                "generator": asset.get("generator") if isinstance(asset.get("generator"), str) else None,
                "sh_degree": src.degree, "kernel": ext.get("kernel"), "color_space": ext.get("colorSpace"),
                "compression": _compression(src.primitive)[0] if src.spz is not None else None}
    if ext.get("kernel", "ellipse") != "ellipse":
        src.notes.append(f"kernel {_shown(ext.get('kernel'))} drawn as the ellipse kernel")
    if ext.get("colorSpace", "srgb_rec709_display") != "srgb_rec709_display":
        src.notes.append(f"colour space {_shown(ext.get('colorSpace'))} drawn as sRGB (srgb_rec709_display)")
    src.cameras = _cameras(src.doc, path)
    return src


def _notes_of(tally: dict) -> list:
    notes = []
    if tally["negative"]:
        notes.append(f"scale: {plural(tally['negative'], 'negative value')} read as NaN (no logarithm)")
    if tally["opacity"]:
        notes.append(f"opacity: {plural(tally['opacity'], 'value')} outside [0, 1] clamped")
    return notes


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a ``.glb`` or ``.gltf`` (by its first bytes) as a static :class:`Scene`, with its SH bands.

    Raises
    ------
    FormatError
        For a damaged or truncated file, a missing attribute, a type the spec does not allow.
    UnsupportedError
        For what splatconv does not read: several splat primitives, a node transform, sparse
        accessors, required extensions other than ``KHR_gaussian_splatting``.
    """
    path = os.fspath(path)
    src = _load(path)
    tally = {"negative": 0, "opacity": 0}
    cols = src.columns(slice(None), tally)
    return Scene(columns=cols, cameras=src.cameras, variant=model.VARIANT_3DGS, meta=src.meta,
                 notes=src.notes + _notes_of(tally))


def scan(path: str | os.PathLike, **_options) -> Scan:
    """Read a glTF file a piece at a time (:class:`~splatconv.formats.base.Scan`): :data:`BLOCK` rows a piece."""
    path = os.fspath(path)
    out = Scan(variant=model.VARIANT_3DGS)

    def pieces():
        src = _load(path)
        out.meta.update(src.meta)
        out.cameras = src.cameras
        tally = {"negative": 0, "opacity": 0}
        for start in range(0, src.count, BLOCK):
            yield src.columns(slice(start, start + BLOCK), tally)
        out.notes.extend(src.notes + _notes_of(tally))

    out.pieces = pieces()
    return out


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats :func:`read` gives (the POSITION accessor's count), or None for a file it refuses."""
    try:
        return _Source(os.fspath(path)).count
    except (FormatError, UnsupportedError):
        return None


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats :func:`read` gives: :func:`splat_count` (0 for a file it refuses)."""
    return splat_count(path) or 0


# --------------------------------------------------------------------------
# Writing


def _position(block: dict, tally: dict) -> np.ndarray:
    return np.stack([-block["x"], -block["y"], block["z"]], axis=1).astype(np.float32)


def _color(block: dict, tally: dict) -> np.ndarray:
    rgba = np.stack([wide(block[name]) for name in model.COLOR] + [sigmoid(wide(block["opacity"]))], axis=1)
    return np.clip(np.nan_to_num(np.rint(rgba * 255.0), nan=0.0), 0, 255).astype(np.uint8)


def _rotation(block: dict, tally: dict) -> np.ndarray:
    q = np.stack([wide(block[name]) for name in model.ROTATION], axis=1)  # w, x, y, z
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        length = np.sqrt((q * q).sum(axis=1, keepdims=True))
        unit = q / length
    # A quaternion of unit length to float32 rounding (one read from a glTF) is kept as it is.
    unit = np.where(np.abs(length - 1.0) <= UNIT_TOLERANCE, q, unit)
    bad = ~np.isfinite(unit).all(axis=1)
    unit[bad] = (1.0, 0.0, 0.0, 0.0)
    unit = unit.astype(np.float32)
    tally["degenerate"] += int(np.count_nonzero(bad))
    tally["normalised"] += int(np.count_nonzero(~bad & (unit != q.astype(np.float32)).any(axis=1)))
    w, x, y, z = unit.T
    return np.stack([-y, x, w, -z], axis=1)  # the turn times the quaternion, x, y, z, w: exact


def _scale(block: dict, tally: dict) -> np.ndarray:
    with np.errstate(over="ignore"):
        linear = np.exp(np.stack([wide(block[name]) for name in model.SCALE], axis=1)).astype(np.float32)
    tally["overflow"] += int(np.count_nonzero(np.isinf(linear)))
    return linear


def _opacity(block: dict, tally: dict) -> np.ndarray:
    alpha = sigmoid(wide(block["opacity"]))
    nan = np.isnan(alpha)
    tally["nan_opacity"] += int(np.count_nonzero(nan))
    return np.where(nan, 0.0, alpha).astype(np.float32)[:, None]


def _dc(block: dict, tally: dict) -> np.ndarray:
    return ((np.stack([wide(block[name]) for name in model.COLOR], axis=1) - 0.5) / SH_C0).astype(np.float32)


def _sh_rest(j: int, k: int):
    """The encoder of SH coefficient ``j`` (of ``k`` a channel): its three channels, turned."""
    names = tuple(f"f_rest_{c * k + j}" for c in range(3))

    def encode(block: dict, tally: dict) -> np.ndarray:
        return np.stack([block[name] for name in names], axis=1).astype(np.float32) * SH_SIGNS[j]

    return names, encode


def segments(degree: int, compressed: bool = False) -> list:
    """What a write stores, in file order: ``(attribute, type, componentType, normalized, columns, encode)``;
    ``compressed``: the accessors declared beside the SPZ stream, each of its values' type once decoded
    (``COLOR_0`` float)."""
    color = (COLOR_0, "VEC4", FLOAT, False) if compressed else (COLOR_0, "VEC4", UNSIGNED_BYTE, True)
    out = [(POSITION, "VEC3", FLOAT, False, model.POSITION, _position),
           (*color, model.COLOR + model.OPACITY, _color),
           (ROTATION, "VEC4", FLOAT, False, model.ROTATION, _rotation),
           (SCALE, "VEC3", FLOAT, False, model.SCALE, _scale),
           (OPACITY, "SCALAR", FLOAT, False, model.OPACITY, _opacity),
           (sh_attribute(0, 0), "VEC3", FLOAT, False, model.COLOR, _dc)]
    k = model.SH_COEFFS[degree]
    for j, name in enumerate(_sh_rest_attributes(degree)):
        columns, encode = _sh_rest(j, k)
        out.append((name, "VEC3", FLOAT, False, columns, encode))
    return out


def bin_name(name: str) -> str:
    """The name of a ``.gltf``'s buffer file: its own with ``.bin`` for ``.gltf``."""
    return os.path.splitext(name)[0] + ".bin"


def companions(path: str | os.PathLike) -> tuple:
    """The files a write of ``path`` writes beside it: a ``.gltf``'s ``.bin``; none for a ``.glb``."""
    path = os.fspath(path)
    return (bin_name(path),) if path.lower().endswith(".gltf") else ()


def _camera_nodes(cameras: list, tally: dict) -> tuple:
    """glTF cameras and the nodes that place them, for the scene's ``cameras``; those that do not fit skipped."""
    gl_cameras, nodes = [], []
    for cam in cameras or []:
        r = np.asarray(cam["rotation"], dtype=np.float64)
        if not (np.allclose(r @ r.T, np.eye(3), atol=1e-6) and np.linalg.det(r) > 0):
            tally["cameras"] += 1  # not a rotation: no glTF node holds it
            continue
        camera = {"type": "perspective",
                  "perspective": {"aspectRatio": cam["width"] / cam["height"],
                                  "yfov": 2.0 * math.atan(cam["height"] / (2.0 * cam["fy"])), "znear": ZNEAR},
                  "extras": {"width": cam["width"], "height": cam["height"], "fx": cam["fx"], "fy": cam["fy"]}}
        if isinstance(cam.get("img_name"), str):
            camera["name"] = cam["img_name"]
        nodes.append({"camera": len(gl_cameras),
                      "translation": [float(v) for v in TURN @ np.asarray(cam["position"], dtype=np.float64)],
                      "rotation": _matrix_quaternion(TURN @ r @ CAMERA_AXES)})
        gl_cameras.append(camera)
    return gl_cameras, nodes


def _document(scene: Scene, segs: list, lengths: list, bounds: tuple, uri: str | None, tally: dict,
              compressed: bool = False) -> dict:
    """The glTF JSON of a write: one buffer, a view and an accessor per segment, the mesh and camera nodes;
    ``compressed``: one view, the SPZ stream (``lengths[0]`` bytes), and accessors without views."""
    n = scene.count
    views, accessors, attributes, offset = [], [], {}, 0
    for length in lengths:
        view = {"buffer": 0, "byteOffset": offset, "byteLength": length}
        if not compressed:
            view["target"] = ARRAY_BUFFER
        views.append(view)
        offset += _padded(length)
    for i, (name, kind, component, normalized, _columns, _encode) in enumerate(segs):
        accessor = {"componentType": component, "count": n, "type": kind}
        if not compressed:
            accessor = {"bufferView": i, **accessor}
        if normalized:
            accessor["normalized"] = True
        if name == POSITION:
            accessor["min"], accessor["max"] = bounds
        accessors.append(accessor)
        attributes[name] = i
    buffer = {"byteLength": offset}
    if uri is not None:
        buffer["uri"] = uri
    gl_cameras, camera_nodes = _camera_nodes(scene.cameras, tally)
    extension = dict(PRIMITIVE_EXTENSION)
    if compressed:
        extension["extensions"] = {SPZ_EXTENSION: {"bufferView": 0}}
    doc = {"asset": {"version": "2.0", "generator": "splatconv"},
           "extensionsUsed": [EXTENSION, SPZ_EXTENSION] if compressed else [EXTENSION]}
    if compressed:  # the data is in the stream alone: a viewer without the extension has nothing to draw
        doc["extensionsRequired"] = [EXTENSION, SPZ_EXTENSION]
    doc.update({"scene": 0,
                "scenes": [{"nodes": list(range(1 + len(camera_nodes)))}],
                "nodes": [{"mesh": 0}] + camera_nodes,
                "meshes": [{"primitives": [{"attributes": attributes, "mode": MODE_POINTS,
                                            "extensions": {EXTENSION: extension}}]}],
                "buffers": [buffer], "bufferViews": views, "accessors": accessors})
    if gl_cameras:
        doc["cameras"] = gl_cameras
    return doc


def _padded(length: int) -> int:
    return (length + 3) & ~3


def _spz_blob(scene: Scene, sort: str | None) -> tuple:
    """``scene`` as the SPZ version 2 stream of the compression extension (in :data:`SPZ_TURN`'s frame), the
    notes on its quantization, and the bounds (glTF's frame) of the positions it decodes to."""
    stored = Scene(columns=_spz_frame(scene.columns, scene.sh_degree), variant=scene.variant)
    blob, notes = spz.legacy_stream(stored, sort, version=SPZ_VERSION)
    _version, n, _degree, bits, _flags, arrays = spz.unpack(blob, "")
    xyz = spz.decode_positions(arrays[0], n, bits) * np.array([-1.0, 1.0, -1.0], np.float32)  # to glTF's frame
    bounds = ([float(v) for v in xyz.min(axis=0)], [float(v) for v in xyz.max(axis=0)])
    return blob, notes, bounds


def write(scene: Scene, stream, *, sort: str | None = None, progress=SILENT, name: str | None = None,
          companions: tuple = (), layout: str | None = None, **_options) -> WriteReport:
    """Write ``scene`` as a ``.glb`` to ``stream``, or, given a companion stream, as a ``.gltf`` whose buffer
    goes to ``companions[0]`` (the ``.bin`` named after ``name``). ``layout="spz"``: the splats as one SPZ
    version 2 stream, the draft ``KHR_gaussian_splatting_compression_spz_2`` (lossy; noted); else float
    attributes.

    Raises
    ------
    UnsupportedError
        For a scene that moves or fades over time, a NaN or infinite position (glTF's bounds must be
        numbers), or a ``.glb`` past 4 GiB.
    """
    cols = scene.columns
    refuse_time_varying(cols, "a glTF file")
    n = scene.count
    order = importance_order(importance(cols)) if sort == "importance" else None
    xyz = np.stack([np.asarray(cols[c]) for c in model.POSITION], axis=1)
    refuse_nonfinite_positions(int(np.count_nonzero(~np.isfinite(xyz).all(axis=1))), "glTF bounds every position")
    compressed = layout == LAYOUT_SPZ
    segs = segments(scene.sh_degree, compressed)
    blob, spz_notes = None, []
    if compressed:
        del xyz
        blob, spz_notes, bounds = _spz_blob(scene, sort)
        lengths = [len(blob)]
    else:
        turned = _position({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}, {})
        bounds = ([float(v) for v in turned.min(axis=0)], [float(v) for v in turned.max(axis=0)])
        del xyz, turned
        itemsizes = {FLOAT: 4, UNSIGNED_BYTE: 1}
        lengths = [n * WIDTHS[kind] * itemsizes[component] for _name, kind, component, *_ in segs]
    tally = {"degenerate": 0, "normalised": 0, "overflow": 0, "nan_opacity": 0, "cameras": 0}
    uri = urllib.parse.quote(bin_name(os.path.basename(name or "scene.gltf"))) if companions else None
    doc = _document(scene, segs, lengths, bounds, uri, tally, compressed)
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")
    total = doc["buffers"][0]["byteLength"]
    if companions:
        stream.write(text)
        data = companions[0]
    else:
        json_length = _padded(len(text))
        size = HEADER.size + CHUNK.size + json_length + CHUNK.size + total
        if size > MAX_GLB_BYTES:
            raise UnsupportedError(f"a .glb holds at most {MAX_GLB_BYTES:,} bytes, this scene needs {size:,}; "
                                   "write a .gltf (its buffer beside it has no limit)")
        stream.write(HEADER.pack(MAGIC, VERSION, size))
        stream.write(CHUNK.pack(json_length, CHUNK_JSON) + text + b" " * (json_length - len(text)))
        stream.write(CHUNK.pack(total, CHUNK_BIN))
        data = stream
    if compressed:
        data.write(blob + b"\0" * (_padded(len(blob)) - len(blob)))
    else:
        _write_segments(data, cols, segs, lengths, order, tally, progress)
    report = WriteReport(count=n)
    report.notes.extend(spz_notes)
    if compressed:
        report.notes.append(f"glTF: splats as SPZ version 2 in {SPZ_EXTENSION}, a draft extension (required: "
                            "a viewer without it draws nothing)")
    report.notes.extend(_write_notes(tally, n))
    if companions:
        report.notes.append(f"buffer: {total:,} bytes in {urllib.parse.unquote(uri)} beside it")
    return report


def _write_segments(data, cols: dict, segs: list, lengths: list, order, tally: dict, progress) -> None:
    """Each segment's values (``order``: rows in that order), :data:`BLOCK` rows at a time, padded to 4 bytes."""
    n = len(cols["x"])
    with progress.stage("writing", n * len(segs), "value") as advance:
        for length, (_name, _kind, _component, _normalized, columns, encode) in zip(lengths, segs):
            for start in range(0, n, BLOCK):
                stop = min(start + BLOCK, n)
                rows = slice(start, stop) if order is None else order[start:stop]
                block = {c: np.asarray(cols[c])[rows] for c in columns}
                data.write(memoryview(np.ascontiguousarray(encode(block, tally))).cast("B"))
                advance(stop - start)
            data.write(b"\0" * (_padded(length) - length))


def _write_notes(tally: dict, n: int) -> list:
    notes = []
    if tally["normalised"]:
        notes.append(f"rotation: {tally['normalised']:,} of {plural(n, 'splat')} normalised to unit quaternions")
    if tally["degenerate"]:
        notes.append(f"rotation: {plural(tally['degenerate'], 'zero or non-finite quaternion')} written as the "
                     "identity (drawn unrotated)")
    if tally["overflow"]:
        notes.append(f"scale: {plural(tally['overflow'], 'value')} past the float32 range written as infinity")
    if tally["nan_opacity"]:
        notes.append(f"opacity: {plural(tally['nan_opacity'], 'NaN value')} written as 0")
    if tally["cameras"]:
        notes.append(f"cameras: {plural(tally['cameras'], 'camera')} whose rotation is not a rotation left out")
    return notes


def storage(scene: Scene) -> dict:
    """How a glTF file stores each attribute group: :data:`STORAGE`, or ``.spz``'s for a compressed one."""
    return spz.STORAGE if scene.meta.get("compression") else STORAGE


def info_fields(meta: dict) -> dict:
    """What ``info`` shows of a glTF file (its ``meta``): container, generator, SH degree, kernel, colour space."""
    return {key: meta.get(key) for key in ("container", "generator", "sh_degree", "kernel", "color_space",
                                           "compression")}


FORMAT = Format(
    name="gltf",
    suffixes=(".glb", ".gltf"),
    default_sort="none",
    holds_empty=False,  # an accessor holds at least one element
    dynamic=False,
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats,
    write=write, layouts=(LAYOUT_SPZ,), holds_sh=True, companions=companions,
    info_fields=info_fields, storage=storage,
)
