"""antimatter15's ``.splat``: a static scene, 32 bytes a splat, no header.

Each record, little endian::

    bytes  0..11  float32 x, y, z            position
    bytes 12..23  float32 scale_0..2         linear scales (the model keeps their logarithm)
    bytes 24..27  uint8 r, g, b, a           colour and opacity, value * 255
    bytes 28..31  uint8 rot_0..3             quaternion (w, x, y, z) as q * 128 + 128

Viewers decode the rotation as (byte - 128) / 128. The format holds no time, no
motion and no cameras: a scene that moves or fades is refused (bake a moment
first), and reading gives a static scene (the model's static temporal basis,
zero motion).

Writing rounds colour, opacity and rotation to the nearest byte (antimatter15's
converter truncates; rounding halves the error) and normalises each quaternion
first, as antimatter15's viewer uses them without normalising. Bytes read from
a ``.splat`` come back as the same bytes: colours and opacities are read to
values that round to their byte, and a quaternion already on the byte grid
(and of unit length to within its rounding) is written unchanged.
Records are written in importance order by default (largest, most opaque
first), as antimatter15's converter does, so a viewer can draw while loading.
"""

from __future__ import annotations

import os

import numpy as np

from .. import model
from ..errors import FormatError
from ..files.inputs import open_input
from ..files.paging import populate, release
from ..model import Scene
from ..packing import F32_EXP_MASK, F32_MANT_MASK, F32_QUIET_BIT
from ..progress import SILENT
from ..viewer import importance, importance_order, opacity, scales, wide
from ..wording import plural
from .base import Format, Scan, WriteReport, fixed_storage, meta_fields, refuse_time_varying
from .splatv import COLOR_OF_BYTE, LOGIT_OF_BYTE
from .splatv_layout import MAGIC as SPLATV_MAGIC

#: How each attribute group is stored (see :data:`splatconv.compare.STORAGE_KINDS`):
#: no time or motion at all, the rest as the record table above says.
STORAGE = {"position": "exact", "scale": "float32", "color": "byte", "opacity": "byte",
           "rotation": "unit_quaternion_byte", "motion": "none", "omega": "none", "trbf": "none"}

#: One record, as the table at the top of this module lays it out.
RECORD = np.dtype([("position", "<f4", (3,)), ("scale", "<f4", (3,)), ("rgba", "u1", (4,)), ("rot", "u1", (4,))])
RECORD_BYTES = RECORD.itemsize
#: Quaternion byte = q * ROT_STEPS + ROT_STEPS.
ROT_STEPS = 128.0

#: Records written per step.
BLOCK = 1 << 16
#: Rows encoded per step: their columns' stretch of a row table (a PLY read in place) and the float64
#: temporaries stay in cache.
ENCODE_BLOCK = 1 << 14
#: The model columns a record is made of.
_READS = model.POSITION + model.SCALE + model.COLOR + model.OPACITY + model.ROTATION


# --------------------------------------------------------------------------
# Reading


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a ``.splat`` file as a static :class:`Scene`.

    Colour bytes become the smallest float32 that gives the byte back, alpha
    bytes the logit that does (0 and 255 map to finite logits, as in
    :mod:`splatconv.formats.splatv`), quaternion bytes (b - 128) / 128 (not
    normalised: the viewer normalises). A scale of 0 is read as log 0 = -inf;
    a negative or NaN scale as NaN (noted).

    Raises
    ------
    FormatError
        For an empty file or one whose size is not a whole number of records.
    """
    path = os.fspath(path)
    with open_input(path) as f:
        records = _open(f, path)
        # Mapped, not read: the scene's table is four times the file, the file need not be held too.
        populate(records)
    size = len(records) * RECORD_BYTES
    tally = {"signalling": 0, "negative": 0}
    cols = _columns(records, tally)
    meta = {"file_bytes": size, "records": len(records)}
    return Scene(columns=cols, cameras=None, variant=model.VARIANT_3DGS, meta=meta, notes=_notes_of(tally))


def _open(f, path: str) -> np.memmap:
    """The records of the open ``.splat`` ``f``, mapped (its size checked)."""
    size = os.fstat(f.fileno()).st_size
    if size == 0:
        raise FormatError("file is empty", path)
    _refuse_other_formats(f.read(8), path)
    f.seek(0)
    if size % RECORD_BYTES:
        raise FormatError(f"size {size:,} bytes is not a whole number of {RECORD_BYTES}-byte records: "
                          f"{size % RECORD_BYTES} bytes after record {size // RECORD_BYTES:,}; file truncated?",
                          path)
    return np.memmap(f, dtype=RECORD, mode="r", shape=(size // RECORD_BYTES,))


def _columns(records: np.ndarray, tally: dict) -> dict:
    """The model columns of ``.splat`` records, counting into ``tally`` what :func:`_notes_of` says."""
    n = len(records)
    cols = {}
    position = _quiet_nans(records["position"], tally)
    for i, name in enumerate(model.POSITION):
        cols[name] = position[:, i]  # views of the mapped file when nothing was quieted: no copy
    linear = records["scale"]
    tally["negative"] += int(np.count_nonzero(linear < 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, name in enumerate(model.SCALE):
            cols[name] = np.log(linear[:, i])
    for i, name in enumerate(model.COLOR):
        cols[name] = COLOR_OF_BYTE[records["rgba"][:, i]]
    cols["opacity"] = LOGIT_OF_BYTE[records["rgba"][:, 3]]
    rot = (records["rot"].astype(np.float32) - np.float32(ROT_STEPS)) / np.float32(ROT_STEPS)
    for i, name in enumerate(model.ROTATION):
        cols[name] = rot[:, i]
    # A static scene: the same constants for every splat, held once.
    cols.update(model.static_columns(n))
    return {name: cols[name] for name in model.COLUMNS}


def _notes_of(tally: dict) -> list:
    """The notes of what :func:`_columns` counted."""
    notes = []
    if tally["signalling"]:
        notes.append(f"position: {tally['signalling']:,} signalling NaN values read as quiet NaN")
    if tally["negative"]:
        notes.append(f"scale: {tally['negative']:,} negative values have no logarithm; read as NaN")
    return notes


#: Records a piece of :func:`scan`.
SCAN_RECORDS = 1 << 16


def scan(path: str | os.PathLike, **_options) -> Scan:
    """Read a ``.splat`` file a piece at a time (:class:`~splatconv.formats.base.Scan`): what :func:`read`
    gives, :data:`SCAN_RECORDS` records a piece, each piece's pages of the mapped file let go after it."""
    path = os.fspath(path)
    out = Scan(variant=model.VARIANT_3DGS)

    def pieces():
        with open_input(path) as f:
            records = _open(f, path)
        out.meta.update(file_bytes=len(records) * RECORD_BYTES, records=len(records))
        tally = {"signalling": 0, "negative": 0}
        for start in range(0, len(records), SCAN_RECORDS):
            part = records[start:start + SCAN_RECORDS]
            yield _columns(part, tally)
            release(part)
        out.notes.extend(_notes_of(tally))

    out.pieces = pieces()
    return out


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats :func:`read` gives for ``path``, from its size; None for a size :func:`read` refuses."""
    path = os.fspath(path)
    try:
        with open_input(path) as f:
            size = os.fstat(f.fileno()).st_size
    except FormatError:
        return None
    return size // RECORD_BYTES if size and size % RECORD_BYTES == 0 else None


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats :func:`read` gives for ``path``: its whole records."""
    return os.path.getsize(path) // RECORD_BYTES


def _quiet_nans(values: np.ndarray, tally: dict) -> np.ndarray:
    """``values`` (float32), with signalling NaNs made quiet: a copy only when there are any.

    A signalling NaN raises numpy's "invalid value" warning when it is widened
    to float64, as everything that reads the viewer's values does; it is NaN
    either way, so only its quiet bit is set (counted in ``tally``).
    """
    bits = values.view(np.uint32)
    signalling = ((bits & np.uint32(F32_EXP_MASK)) == np.uint32(F32_EXP_MASK)) & (
        (bits & np.uint32(F32_MANT_MASK)) != 0) & ((bits & np.uint32(F32_QUIET_BIT)) == 0)
    count = int(np.count_nonzero(signalling))
    if not count:
        return values
    values = np.array(values)
    values.view(np.uint32)[signalling] |= np.uint32(F32_QUIET_BIT)
    tally["signalling"] += count
    return values


def _refuse_other_formats(head: bytes, path: str) -> None:
    """A ``.splat`` has no header to check; name the files most often misnamed ``.splat``.

    A PLY's first bytes are ``ply`` and a line end, a ``.splatv``'s its magic
    number; as a first position they would be ~1e-19 and ~4e-41, which no
    scene holds.
    """
    if head.startswith((b"ply\n", b"ply\r\n")):
        raise FormatError("this is a PLY file, not a .splat (name it .ply)", path)
    if len(head) >= 4 and int.from_bytes(head[:4], "little") == SPLATV_MAGIC:
        raise FormatError("this is a .splatv file, not a .splat (name it .splatv)", path)


# --------------------------------------------------------------------------
# Writing


def write(scene: Scene, stream, *, sort: str | None = None, progress=SILENT, **_options) -> WriteReport:
    """Write ``scene`` as ``.splat`` records.

    Parameters
    ----------
    scene : Scene
        A static scene (see :func:`splatconv.formats.base.time_varying`);
        anything that moves or fades is refused.
    stream : binary file object
    sort : {None, "importance", "none"}
        Record order; None keeps the input order.
    progress : splatconv.progress.Progress
        Told the splats written as they are written.

    Returns
    -------
    WriteReport
        ``clamped`` and ``nan_bytes`` count colour and alpha values outside
        [0, 1] or NaN; ``notes`` say how many splats' colour, opacity and
        rotation the bytes changed.

    Raises
    ------
    UnsupportedError
        For a scene that moves or fades over time.
    """
    cols = scene.columns
    refuse_time_varying(cols, "a .splat file")
    n = scene.count
    report = WriteReport(count=n, clamped={"color": 0, "alpha": 0}, nan_bytes={"color": 0, "alpha": 0})
    changed = {"color": 0, "opacity": 0, "rotation": 0, "degenerate": 0, "scale": 0}
    # Each record depends on its own splat alone: encoded in the scene's row order, a block of rows at
    # a time (the columns read in passes over a stretch of memory that stays in cache, only those a
    # record holds), then written in the asked order by gathering whole 32-byte records.
    records = np.empty(n, dtype=RECORD)
    key = np.empty(n, dtype=np.float64) if sort == "importance" else None
    with progress.stage("writing", n, "splat") as advance:
        for start in range(0, n, ENCODE_BLOCK):
            rows = slice(start, min(start + ENCODE_BLOCK, n))
            block = {name: np.asarray(cols[name])[rows] for name in _READS}
            _encode(block, records[rows], report, changed)
            if key is not None:
                key[rows] = importance(block)
        order = importance_order(key) if key is not None else None
        words = records.view(np.uint64).reshape(n, RECORD_BYTES // 8)  # gathered as plain words: faster
        for start in range(0, n, BLOCK):
            stop = min(start + BLOCK, n)
            rec = records[start:stop] if order is None else words[order[start:stop]]
            stream.write(memoryview(rec).cast("B"))
            advance(stop - start)
    report.notes.extend(_notes(report, changed, n))
    return report


def _encode(block: dict, rec: np.ndarray, report: WriteReport, changed: dict) -> None:
    """Fill records ``rec`` from a block of model columns, counting what the bytes change."""
    for i, name in enumerate(model.POSITION):
        rec["position"][:, i] = block[name]
    linear = scales(block)
    with np.errstate(over="ignore"):
        rec["scale"] = linear  # float64 -> float32: past float32's range becomes inf
    changed["scale"] += int(np.count_nonzero(np.isinf(rec["scale"]) & np.isfinite(linear)))
    rgb = np.stack([wide(block[name]) for name in model.COLOR], axis=1)
    alpha = opacity(block)
    rgba = rec["rgba"]
    rgba[:, :3] = _bytes(rgb, report, "color")
    rgba[:, 3] = _bytes(alpha, report, "alpha")
    # A value survives when reading its byte back gives the same number.
    moved = np.zeros(len(rec), dtype=bool)
    for i, name in enumerate(model.COLOR):
        moved |= np.take(COLOR_OF_BYTE, rgba[:, i]) != block[name]
    changed["color"] += int(np.count_nonzero(moved))
    changed["opacity"] += int(np.count_nonzero(np.take(LOGIT_OF_BYTE, rgba[:, 3]) != block["opacity"]))
    rec["rot"], moved, degenerate = _rotation_bytes(np.stack([block[name] for name in model.ROTATION], axis=1))
    changed["rotation"] += moved
    changed["degenerate"] += degenerate


def _bytes(values: np.ndarray, report: WriteReport, key: str) -> np.ndarray:
    """Values in [0, 1] (float64) as the nearest of 0..255; NaN as 0 (counted).

    Clamped after rounding: only a value whose nearest byte falls outside 0..255
    is counted as clamped (-1.5e-8 rounds to byte 0 anyway).
    """
    scaled = np.rint(values * 255.0)
    nan = np.isnan(scaled)
    report.nan_bytes[key] += int(np.count_nonzero(nan))
    report.clamped[key] += int(np.count_nonzero((scaled < 0) | (scaled > 255)))
    scaled[nan] = 0.0
    return np.clip(scaled, 0.0, 255.0, out=scaled).astype(np.uint8)


#: Below this size a float32 q * 128 may be lost when 128 is added in float64 (its lowest bit is then
#: under 2^-43, past the 53 bits of 128 + q * 128): such a component is on the byte grid too.
_ROUNDED_AWAY = 2.0 ** -20


def _rotation_bytes(q: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Quaternions ``(M, 4) float32`` -> ``(M, 4) uint8``, the splats changed, the non-finite ones.

    A quaternion that bytes already hold exactly ((b - 128) / 128 each) and that
    is a unit quaternion rounded or truncated to bytes (its length within 2/128
    of 1: four components each off by at most one step), or zero, is written as those
    bytes: a quaternion read from a ``.splat`` comes back as it was. Others are
    normalised and rounded. A NaN or infinite quaternion has no direction:
    written as 128s (zero), which viewers draw unrotated.
    """
    # On the grid: q * 128 + 128 (float64) whole, in 0..255. A float32 component whose q * 128 is
    # neither whole nor tiny is off it; the first component rules out almost every trained splat.
    with np.errstate(over="ignore", invalid="ignore"):
        t = q[:, 0] * np.float32(ROT_STEPS)  # exact, or infinite (then tested in float64)
        maybe = np.flatnonzero((np.rint(t) == t) | (np.abs(t) < _ROUNDED_AWAY))
    q = wide(q)
    on_grid = np.zeros(len(q), dtype=bool)
    steps = None
    if len(maybe):
        with np.errstate(over="ignore", invalid="ignore"):
            steps = q[maybe] * ROT_STEPS + ROT_STEPS
            on_grid[maybe] = np.all((steps == np.rint(steps)) & (steps >= 0) & (steps <= 255), axis=1)
    # Float32 components: q * q neither overflows nor underflows in float64, so the length is finite and
    # positive exactly when the quaternion is finite and not zero, when q / length is finite.
    length = np.sqrt((q * q).sum(axis=1))
    kept = on_grid & ((np.abs(length - 1.0) <= 2.0 / ROT_STEPS) | (length == 0.0))
    direction = (length > 0.0) & (length < np.inf)
    with np.errstate(invalid="ignore", divide="ignore"):
        scaled = np.divide(q, length[:, None], out=q)
    scaled[~direction] = 0.0
    scaled *= ROT_STEPS
    scaled += ROT_STEPS
    if steps is not None:
        grid = kept[maybe]
        scaled[maybe[grid]] = steps[grid]
    np.clip(scaled, 0.0, 255.0, out=scaled)
    out = np.rint(scaled, out=scaled).astype(np.uint8)
    return out, int(np.count_nonzero(~kept & direction)), int(np.count_nonzero(~kept & ~direction))


def _notes(report: WriteReport, changed: dict, n: int) -> list:
    notes = []
    if changed["color"]:
        notes.append(f"color: {changed['color']:,} of {plural(n, 'splat')} rounded to 8 bits a channel")
    if changed["opacity"]:
        notes.append(f"opacity: {changed['opacity']:,} of {plural(n, 'splat')} rounded to 8 bits")
    if changed["rotation"]:
        notes.append(f"rotation: {changed['rotation']:,} of {plural(n, 'splat')} normalised and rounded to 8 bits a "
                     "component")
    if changed["degenerate"]:
        notes.append(f"rotation: {changed['degenerate']:,} non-finite quaternions written as zero "
                     "(drawn unrotated)")
    if changed["scale"]:
        notes.append(f"scale: {plural(changed['scale'], 'value')} past the float32 range written as infinity")
    return notes + report.byte_notes()




FORMAT = Format(
    name="splat",
    suffixes=(".splat",),
    default_sort="importance",
    holds_empty=False,  # an empty file is refused on reading, so an empty scene is not written
    dynamic=False,
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats,
    write=write,
    info_fields=meta_fields('records'), storage=fixed_storage(STORAGE),
)
