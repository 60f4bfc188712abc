"""Findings as data: what a scene file holds (``info``), what a conversion costs and loses
(``stats``). Never prints (:mod:`splatconv.text` does)."""

from __future__ import annotations

import contextlib
import math
import os

import numpy as np

from . import viewer
from .cameras import framing_camera
from .compare import Comparison, pair
from .errors import UnsupportedError
from .formats import format_for, quantized_formats, texture_format
from .io import holding, note_undrawable, reading, scanning
from .model import COLUMNS, GROUPS, SCALE, Scene
from .packing import float_to_half, float_to_half_splatvjs
from .progress import SILENT
from .zstd import DEFAULT_LEVEL, compressed_bytes


def _finite_range(values: np.ndarray):
    v = viewer.wide(values)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    return [float(v.min()), float(v.max())]


#: Version of the ``info`` JSON (``specs/json.md``); raised when a key changes meaning or goes.
#: 2: ``nonfinite`` counts only values the viewer gives no meaning (what ``--drop-nonfinite``
#: removes): no longer a log scale of -inf (a flat splat, counted in ``flat``), a temporal
#: scale of +inf (counted in ``visible_always``), or an infinite opacity or colour.
INFO_SCHEMA = "splatconv.info/2"


def describe(scene: Scene, path: str, fmt) -> dict:
    """Facts about a scene file, as JSON-able data (keys documented in ``specs/json.md``).

    The same keys for every format, in the same order; what only the file's
    format has (its ``info_fields``) is under ``details``. Computed :data:`BLOCK`
    rows at a time, as :func:`describe_file` does from a file read a piece at a time.

    Parameters
    ----------
    scene : Scene
    path : str
    fmt : splatconv.formats.base.Format
        The file's format (:func:`splatconv.formats.format_for`).

    Returns
    -------
    dict
        Keys: schema, path, format, variant, count, file_bytes (uncompressed),
        compressed_bytes (on disk, for .zst files, else None), cameras, texture,
        time_range, visible_time_range, visible_always, bounds, nonfinite, flat,
        undrawable, details, notes.
    """
    cols = scene.columns
    facts = _Facts()
    for start in range(0, scene.count, BLOCK):
        facts.add({name: np.asarray(cols[name])[start:start + BLOCK] for name in COLUMNS})
    return facts.result(path, fmt, scene.variant, scene.cameras, scene.meta, scene.notes)


def describe_file(path: str, *, color: str = "auto", progress=SILENT) -> dict:
    """:func:`describe` of the scene file at ``path``, read a piece at a time (:func:`splatconv.io.scanning`):
    the memory it takes is a piece's (a block, some thousands of rows), never the scene's."""
    facts = _Facts()
    with scanning(path, color=color, progress=progress) as scan:
        for piece in scan.pieces:
            facts.add(piece)
        note_undrawable(facts.undrawable, facts.count, path)
        return facts.result(path, format_for(path), scan.variant, scan.cameras, scan.meta, scan.notes)


class _Facts:
    """What :func:`describe` says of a scene, gathered a piece of rows at a time (:meth:`add`)."""

    def __init__(self):
        self.count = 0
        self.bounds = None  # (min, max), (3,) float64 each
        self.centre = None  # [least, greatest] finite temporal centre
        self.visible = None  # [earliest, latest] of the timed splats
        self.always = 0
        self.nonfinite = dict.fromkeys(COLUMNS, 0)
        self.flat = 0
        self.undrawable = viewer.undrawable_counts({name: np.zeros(0, np.float32) for name in COLUMNS})

    def add(self, cols: dict) -> None:
        """Count the rows of ``cols`` (``(M,) float32`` columns, every name of the model) in."""
        self.count += len(cols["x"])
        pos = viewer.positions(cols)
        pos = pos[np.isfinite(pos).all(axis=1)]
        if len(pos):
            least, most = pos.min(axis=0), pos.max(axis=0)
            self.bounds = (least, most) if self.bounds is None else (np.minimum(self.bounds[0], least),
                                                                    np.maximum(self.bounds[1], most))
        self.centre = _widen(self.centre, _finite_range(cols["trbf_center"]))
        centre = viewer.wide(cols["trbf_center"])
        lo, hi = viewer.visible_interval(cols)
        # A splat with an infinite or NaN centre, or a NaN scale, has no interval
        # on the time axis (counted under ``nonfinite``).
        timed = np.isfinite(centre) & ~np.isnan(lo) & ~np.isnan(hi)
        if timed.any():
            span = [float(lo[timed].min()), float(hi[timed].max())]
            self.visible = _widen(self.visible, span)
        self.always += int(np.count_nonzero(timed & np.isinf(hi)))
        for name in COLUMNS:
            self.nonfinite[name] += _nonfinite(cols[name], name)
        self.flat += int(np.count_nonzero(_flat(cols)))
        counts = viewer.undrawable_counts(cols)
        self.undrawable = {kind: self.undrawable[kind] + n for kind, n in counts.items()}

    def result(self, path: str, fmt, variant: str, cameras, meta: dict, notes: list) -> dict:
        """The facts (keys of :func:`describe`)."""
        visible = None if self.visible is None else [v if math.isfinite(v) else None for v in self.visible]
        return {
            "schema": INFO_SCHEMA,
            "path": path,
            "format": fmt.name,
            "variant": variant,
            "count": self.count,
            "file_bytes": meta.get("file_bytes"),
            "compressed_bytes": meta.get("compressed_bytes"),
            "cameras": [{"id": c.get("id"), "img_name": c.get("img_name"), "width": c.get("width"),
                         "height": c.get("height")} for c in (cameras or [])],
            "texture": _texture(meta, self.count),
            "time_range": self.centre,
            "visible_time_range": visible,
            "visible_always": self.always,
            "bounds": None if self.bounds is None else {"min": self.bounds[0].tolist(), "max": self.bounds[1].tolist()},
            "nonfinite": self.nonfinite,
            "flat": self.flat,
            "undrawable": self.undrawable,
            "details": fmt.info_fields(meta),
            "notes": list(notes),
        }


def _widen(span, more):
    """The least and greatest of two ``[least, greatest]`` ranges (either None: none)."""
    if more is None:
        return span
    if span is None:
        return list(more)
    return [min(span[0], more[0]), max(span[1], more[1])]


def _nonfinite(values: np.ndarray, name: str) -> int:
    """Values of column ``name`` the viewer gives no meaning (:func:`splatconv.viewer.without_meaning`):
    NaN, and infinities but a log scale of -inf (a flat splat, counted by :func:`_flat`), a temporal
    scale of +inf (visible at every time, counted in ``visible_always``) and an opacity or colour
    of either sign (sigmoid and clamp give them 0 or 1): what ``--drop-nonfinite`` removes."""
    return int(np.count_nonzero(viewer.without_meaning(values, name)))


def _flat(cols: dict) -> np.ndarray:
    """Splats with a linear scale of exactly 0 on some axis (a log scale of -inf): ``(N,) bool``."""
    out = np.zeros(len(cols["x"]), dtype=bool)
    for name in SCALE:
        out |= np.asarray(cols[name]) == -np.inf
    return out


def _texture(meta: dict, count: int) -> dict:
    """The texture the viewer holds for a scene of ``count`` splats: as a .splatv declares it (its ``meta``),
    or as converting would make it."""
    height = meta.get("texheight", viewer.texture_height(count))
    return {"width": viewer.TEXWIDTH, "height": height,
            "declared_bytes": meta.get("declared_bytes", viewer.texture_bytes(height)),
            "actual_bytes": meta.get("actual_bytes")}


# --------------------------------------------------------------------------
# ``stats``: sizes, transport size and what a conversion loses.

#: Version of the ``stats`` JSON (``specs/json.md``); raised when a key changes meaning or goes.
#: 2: ``time.visible`` leaves out the splats the viewer can never draw (``undrawable``).
#: 3: ``attributes.rotation`` and ``.omega`` of a file that does not keep the rotation's own values (a
#: ``.splatvq``) compare them as the viewer turns a splat; ``quantized`` is new.
#: 4: rows are paired by content (colour word, then nearest position; ``pairing`` counts what could not be);
#: ``attributes.*.nonfinite`` leaves out the NaN and infinities SOURCE holds too; ``motion`` is over the
#: drawable splats; ``described`` and ``viewer.role``/``viewer.path`` say which file the summary describes.
STATS_SCHEMA = "splatconv.stats/4"
#: Time steps at which the number of drawn splats is counted.
TIME_STEPS = 20
#: GPU texture size limits the findings check the texture height against.
MAX_TEXTURE_SIZES = (8192, 16384)
#: Groups stored as halves (colour and opacity are bytes, positions float32).
HALF_GROUPS = ("rotation", "scale", "motion", "omega", "trbf")
#: Rows compared at a time: a block's float64 temporaries stay a few MB, whatever the scene's size.
BLOCK = 1 << 16
#: Bytes read at a time while a file's zstd size is measured.
_READ_BYTES = 1 << 22
#: Bytes a splat of the source takes at the peak of ``stats SOURCE`` (its table, the conversion
#: simulated in memory and its zstd size, each quality setting's encoding, the motion
#: percentiles), and a splat of either file at the peak of ``stats SOURCE CONVERTED`` (two
#: tables, the pairing, the percentiles): what the decompression ceiling counts
#: (:func:`splatconv.io.holding`; ``bench/bench_memory.py`` measures 383 and 144).
STATS_MEMORY_BYTES = 400
STATS_PAIR_MEMORY_BYTES = 160
#: Smallest normal half: converted values below it (and not zero) are subnormal.
_HALF_MIN_NORMAL = 2.0**-14
#: float32 magnitude from which the nearest half is infinite: the largest half,
#: 65504, plus half its step of 32. Below it a value rounds to a finite half:
#: ordinary rounding, not overflow (a .splatv's 65504 read back through exp() is
#: 65504.000000000015, which must not count).
HALF_ROUNDS_TO_INF = 65520.0
#: Magnitudes of the motion summary, and the columns each is the norm of.
MOTION_TERMS = {
    "velocity": ("motion_0", "motion_1", "motion_2"),
    "acceleration": ("motion_3", "motion_4", "motion_5"),
    "jerk": ("motion_6", "motion_7", "motion_8"),
    "omega": tuple(f"omega_{i}" for i in range(4)),
}
#: Per-group counts of the ``attributes`` block, in report order.
COUNT_KEYS = ("nonfinite", "overflow", "underflow", "subnormal", "clamped")


def _percentiles(v: np.ndarray) -> dict:
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"p50": None, "p90": None, "p99": None, "max": None}
    p = np.percentile(v, [50, 90, 99])
    return {"p50": float(p[0]), "p90": float(p[1]), "p99": float(p[2]), "max": float(v.max())}


def _times(steps: int = TIME_STEPS) -> np.ndarray:
    return np.linspace(viewer.TIME_RANGE[0], viewer.TIME_RANGE[1], steps)


def _visible_counts(cols: dict, times: np.ndarray, drawable: np.ndarray) -> np.ndarray:
    """Splats the viewer draws at each time: ``(steps,) int64``.

    Of the ``drawable`` rows (``(N,) bool``: not :func:`splatconv.viewer.undrawable`),
    those whose temporal opacity is not below the viewer's cut
    (:func:`splatconv.viewer.visible`: a NaN temporal opacity is drawn, as the
    viewer's test does not reject it).
    """
    return np.array([np.count_nonzero(viewer.visible(cols, t) & drawable) for t in times], dtype=np.int64)


def _magnitudes(cols: dict, names) -> np.ndarray:
    """Euclidean norm of columns ``names`` per row: ``(N,) float64`` (float64 squares cannot overflow
    from float32 values)."""
    total = np.zeros(len(cols[names[0]]), dtype=np.float64)
    for name in names:
        v = viewer.wide(cols[name])
        total += v * v
    return np.sqrt(total)


def _counts(a: np.ndarray, b: np.ndarray, raw: dict, group: str) -> dict:
    """Per-group counts: nonfinite, overflow, underflow, subnormal, clamped.

    Parameters
    ----------
    a, b : (N, k) float64 ndarray
        Source and converted values in viewer units (``viewer.group_values``).
    raw : dict of str to (N,) ndarray
        The source's model columns (colour and opacity as stored, before clamping).
    """
    finite = np.isfinite(a)
    out = dict.fromkeys(COUNT_KEYS, 0)
    # A NaN or an infinity SOURCE holds too is no loss: only those the conversion made count.
    shared = (np.isnan(a) & np.isnan(b)) | (np.isinf(a) & (a == b))
    out["nonfinite"] = int(np.count_nonzero(~np.isfinite(b) & ~shared))
    if group in HALF_GROUPS:
        # Both writers round to float32 first; compared there, a value a hair past
        # 65504 in double (exp of a stored half's logarithm) is 65504 again.
        with np.errstate(over="ignore"):
            a32 = np.abs(a.astype(np.float32))
            b32 = np.abs(b.astype(np.float32))
        out["overflow"] = int(np.count_nonzero(finite & (a32 >= HALF_ROUNDS_TO_INF)))
        # Compared in float32: a half read back through exp() may land a hair
        # below 2^-14 in double, never in float32.
        out["subnormal"] = int(np.count_nonzero((b32 != 0) & (b32 < _HALF_MIN_NORMAL)))
        # Halves keep relative precision, so a nonzero value becoming zero is lost; a colour or
        # alpha below half a byte step becoming byte 0 is the bytes' ordinary rounding.
        out["underflow"] = int(np.count_nonzero(finite & (a != 0) & (b == 0)))
    if group == "color":
        # Clamped where the nearest byte falls outside 0..255 (a value a hair below 0
        # rounds to byte 0 anyway: nothing changed), as the writers count it. NaN is
        # clamped too: the writers store it as 0.
        stored = np.rint(np.stack([viewer.wide(raw[n]) for n in GROUPS[group]], axis=1) * 255.0)
        out["clamped"] = int(np.count_nonzero((stored < 0) | (stored > 255) | np.isnan(stored)))
    elif group == "opacity":
        out["clamped"] = int(np.count_nonzero(np.isnan(raw["opacity"])))  # sigmoid(NaN): stored as alpha 0
    return out


def splatvjs_damage(cols: dict) -> dict:
    """What splaTV's own converter would corrupt in these attributes, per group.

    Parameters
    ----------
    cols : dict of str to (N,) ndarray
        Model columns of the source.

    Returns
    -------
    dict
        For each group stored as halves, ``infinity``: finite values (after
        exp for scales) it writes as infinity, those of magnitude 32768 or more
        once rounded to float32; ``garbled``: values it writes as a nonzero half
        where the nearest half is zero -- its shift count wraps modulo 32, and it
        keeps a float32 subnormal's top mantissa bits -- which are exactly the
        magnitudes in [2^-136, 2^-126), [2^-120, 2^-109), [2^-88, 2^-77) and
        [2^-56, 2^-45).
    """

    out = {}
    for group in HALF_GROUPS:
        with np.errstate(over="ignore", invalid="ignore"):
            exact = viewer.group_values(cols, group).ravel()
            v = exact.astype(np.float32)  # the converter stores through a Float32Array
        garbled = ((float_to_half_splatvjs(v) & 0x7FFF) != 0) & ((float_to_half(v) & 0x7FFF) == 0)
        out[group] = {"infinity": int(np.count_nonzero(np.isfinite(exact) & (np.abs(v) >= 32768))),
                      "garbled": int(np.count_nonzero(garbled))}
    return out


def _file_pieces(path: str):
    with open(path, "rb") as f:
        while chunk := f.read(_READ_BYTES):
            yield chunk


def _read_measured(path: str, color: str, level: int, progress) -> tuple:
    """(scene, bytes, zstd bytes at ``level``) of a file: sizes of its content, a ``.zst`` file's decompressed
    (decompressed once, for the scene and the sizes alike)."""
    with contextlib.ExitStack() as held:
        with progress.stage("reading", 1, "file") as advance:
            scene, plain = held.enter_context(reading(path, color=color, progress=progress))
            advance()
        size = os.path.getsize(plain)
        return scene, size, compressed_bytes(_file_pieces(plain), size, level, progress=progress,
                                             label=f"zstd-{level} {os.path.basename(path)}")


def _file_entry(role: str, path, fmt: str, size: int, count: int, zstd_bytes: int, level: int,
                source_bytes: int) -> dict:
    return {
        "role": role,
        "path": path,
        "format": fmt,
        "bytes": size,
        "bytes_per_splat": round(size / count, 3) if count else None,
        "zstd_bytes": zstd_bytes,
        "zstd_level": level,
        "ratio": round(size / source_bytes, 6) if source_bytes else None,
        "zstd_ratio": round(zstd_bytes / source_bytes, 6) if source_bytes else None,
    }


def _simulated_conversion(source: Scene, level: int, progress) -> tuple:
    """What ``convert`` would write for ``source``: (scene it decodes to, bytes, zstd bytes).

    The texture is encoded once, in memory; its zstd size is measured from that
    copy (with the header ``convert`` would write) and the scene decoded from it.
    """
    texture = texture_format().texture
    records, _ = texture.encode(source)
    cameras = source.cameras or [framing_camera(source.columns["x"], source.columns["y"], source.columns["z"])]
    header = texture.header(source.count, cameras)
    rows = max(1, _READ_BYTES // (4 * viewer.WORDS_PER_SPLAT))  # uint32 words a record
    pieces = [header] + [memoryview(records[start:start + rows]) for start in range(0, len(records), rows)]
    size = len(header) + records.nbytes
    zstd_bytes = compressed_bytes(pieces, size, level, progress=progress, label=f"zstd-{level} (as converted)")
    columns, _ = texture.decode(records[:source.count])
    return Scene(columns=columns, cameras=cameras), size, zstd_bytes


class _Counter:
    """A binary stream that keeps nothing but the number of bytes written to it."""

    def __init__(self):
        self.bytes = 0

    def write(self, data) -> int:
        n = memoryview(data).nbytes
        self.bytes += n
        return n


def _quantized_sizes(source: Scene, source_bytes: int, progress) -> tuple:
    """What ``source`` takes in each format with quality settings, at each setting: encoded in memory by the
    writer ``convert`` runs, and measured, never stored.

    Returns
    -------
    entries : list of dict
        Keys ``format``, ``quality``, ``splats`` (written: a ``.splatvq`` leaves the undrawable ones
        out), ``bytes``, ``bytes_per_splat`` (per splat written), ``ratio`` (to ``source_bytes``).
    notes : list of str
        Why a format has no entries (a scene it refuses).
    """
    entries, notes = [], []
    for fmt in quantized_formats():
        with progress.stage(f"sizing {fmt.suffixes[0]}", len(fmt.qualities), "setting") as advance:
            for quality in fmt.qualities:
                counter = _Counter()
                try:
                    report = fmt.write(source, counter, sort=fmt.default_sort, quality=quality)
                except UnsupportedError as e:
                    notes.append(f"no {fmt.suffixes[0]} size: {e.message}")
                    break
                entries.append({"format": fmt.name, "quality": quality, "splats": report.count,
                                "bytes": counter.bytes,
                                "bytes_per_splat": round(counter.bytes / report.count, 3) if report.count else None,
                                "ratio": round(counter.bytes / source_bytes, 6) if source_bytes else None})
                advance()
    return entries, notes


def _viewer_limits(scene: Scene, role: str, path) -> dict:
    """The ``viewer`` checks of the file the viewer would load (``scene``, the file of ``role`` at ``path``)."""
    # A .splatv's texture is as tall as its header says, whatever it holds;
    # anything else is as tall as converting it would declare.
    texheight = scene.meta.get("texheight", viewer.texture_height(scene.count))
    nan = np.zeros(scene.count, dtype=bool)
    for c in ("x", "y", "z"):
        nan |= ~np.isfinite(scene.columns[c])
    return {
        "role": role,
        "path": path,
        "texture_height": texheight,
        "fits_max_texture_size": {str(s): texheight <= s for s in MAX_TEXTURE_SIZES},
        "cameras": len(scene.cameras or []),
        "empty_cameras": not scene.cameras,
        "nan_positions": int(np.count_nonzero(nan)),
    }


#: Rows gathered at a time by row number: their cache lines (a PLY row is 128
#: bytes) stay in cache while each column picks its value from them.
_GATHER = 1 << 12


def _rows(cols: dict, index) -> dict:
    """Rows ``index`` (a slice, or row numbers in any order) of every column."""
    if isinstance(index, slice):
        block = {name: np.asarray(cols[name])[index] for name in COLUMNS}
    else:
        # Column by column over all of ``index`` would fetch every row's cache
        # lines once per column: a few thousand rows at a time fetch them once.
        block = {name: np.empty(len(index), dtype=np.asarray(cols[name]).dtype) for name in COLUMNS}
        for start in range(0, len(index), _GATHER):
            part = index[start:start + _GATHER]
            for name in COLUMNS:
                # Indexing, not np.take: take copies a strided (memory-mapped PLY) column whole first.
                block[name][start:start + _GATHER] = np.asarray(cols[name])[part]
    return block


class _Tally:
    """What the ``stats`` findings add up over blocks of rows."""

    def __init__(self, n: int, compare: bool, damage: bool, storage: dict):
        self.times = _times()
        self.visible = np.zeros(len(self.times), dtype=np.int64)
        self.undrawable = np.zeros(len(viewer.UNDRAWABLE_KINDS) + 1, dtype=np.int64)  # [drawable, kinds...]
        self.magnitudes = {term: np.empty(n, dtype=np.float64) for term in MOTION_TERMS}
        self.lo = np.full(3, np.inf)
        self.hi = np.full(3, -np.inf)
        self.comparison = Comparison(storage) if compare else None  # how the converted file stores each group
        self.counts = {g: dict.fromkeys(COUNT_KEYS, 0) for g in GROUPS} if compare else None
        self.damage = {g: {"infinity": 0, "garbled": 0} for g in HALF_GROUPS} if damage else None

    def add(self, rows: slice, src: dict, conv: dict, paired: np.ndarray | None = None) -> None:
        """Rows ``rows`` of the converted scene (``conv``) and the source rows matching them (``src``).

        ``paired`` ``(k,) bool``: the rows of ``conv`` that ``src`` pairs with (all when None); the others,
        which no source splat pairs with, are left out of the comparison.
        """
        kinds = viewer.undrawable_kinds(conv)
        self.undrawable += np.bincount(kinds.astype(np.intp) + 1, minlength=len(self.undrawable))
        self.visible += _visible_counts(conv, self.times, kinds == viewer.DRAWABLE)
        for term, names in MOTION_TERMS.items():
            # The speeds of what the viewer draws: an undrawable splat (a zero rotation's omega 0) says nothing.
            self.magnitudes[term][rows] = np.where(kinds == viewer.DRAWABLE, _magnitudes(conv, names), np.nan)
        pos = viewer.positions(conv)
        pos = pos[np.isfinite(pos).all(axis=1)]
        if len(pos):
            self.lo = np.minimum(self.lo, pos.min(axis=0))
            self.hi = np.maximum(self.hi, pos.max(axis=0))
        if self.comparison is not None:
            mine = conv if paired is None else {name: v[paired] for name, v in conv.items()}
            self.comparison.add(src, mine, each=lambda group, a, b: self._count(group, a, b, src))
        if self.damage is not None:
            for group, d in splatvjs_damage(src).items():
                for key, count in d.items():
                    self.damage[group][key] += count

    def undrawable_counts(self) -> dict:
        return {kind: int(self.undrawable[i + 1]) for i, kind in enumerate(viewer.UNDRAWABLE_KINDS)}

    def _count(self, group: str, a: np.ndarray, b: np.ndarray, src: dict) -> None:
        for key, count in _counts(a, b, src, group).items():
            self.counts[group][key] += count

    def bounds(self):
        if not np.isfinite(self.lo).all():
            return None
        return {"min": self.lo.tolist(), "max": self.hi.tolist()}

    def attributes(self):
        if self.comparison is None:
            return None
        return {g: {"max_abs_error": _finite(e.max_abs_error), "max_rel_error": _finite(e.max_rel_error),
                    "rmse": _finite(e.rmse), **self.counts[g]} for g, e in self.comparison.errors().items()}


def _finite(v: float):
    """``v``, or None (JSON null) where it is infinite: JSON has no infinity."""
    return v if math.isfinite(v) else None


def _pairing(order, n: int) -> dict:
    """The ``pairing`` block: how many of the ``n`` compared rows found their splat (``order`` -1 where none did;
    None: row by row). Counts match on both sides, so as many source splats are left unpaired."""
    unpaired = 0 if order is None else int(np.count_nonzero(order < 0))
    return {"paired": n - unpaired, "unpaired": unpaired}


def stats_findings(source_path: str, converted_path: str | None = None, *, zstd_level: int | None = None,
                 color: str = "auto", progress=SILENT) -> dict:
    """The ``stats`` findings: JSON-able data (keys documented in ``specs/json.md``).

    With one file, the conversion it would get (default writer) is simulated in
    memory and reported as ``converted``, with ``path`` null; a file the viewer
    loads as it is (a ``.splatv``), or an empty PLY (which ``convert`` refuses), is
    reported as stored, with no comparison (``attributes`` null). With one file,
    ``quantized`` gives its size in each format with quality settings, at each
    setting, encoded in memory (null with two files).

    Rows are compared a block at a time, so memory beyond the two scenes stays
    a few MB (plus 32 bytes a splat for the motion percentiles).

    Parameters
    ----------
    source_path, converted_path : str
    zstd_level : int, optional
        Level of the transport sizes (default :data:`splatconv.zstd.DEFAULT_LEVEL`).
    color : {"auto", "rgb", "sh"}
    progress : splatconv.progress.Progress
        Receives a stage per file compressed and one for the comparison.
    """
    level = DEFAULT_LEVEL if zstd_level is None else zstd_level
    with holding(STATS_MEMORY_BYTES if converted_path is None else STATS_PAIR_MEMORY_BYTES):
        source, src_bytes, src_zstd = _read_measured(source_path, color, level, progress)
        if converted_path is not None:
            converted, conv_bytes, conv_zstd = _read_measured(converted_path, color, level, progress)
    quantized, notes = None, []
    src_fmt = format_for(source_path)
    files = [_file_entry("source", source_path, src_fmt.name, src_bytes, source.count, src_zstd, level, src_bytes)]
    compare = True
    if converted_path is not None:
        conv_fmt = format_for(converted_path)
        # Ties between a writer's orders are broken as the viewer's texture would store the values.
        order, notes = pair(source, converted, source_path, converted_path,
                            storage=texture_format().storage(converted), complete=False,
                            colour_kept=conv_fmt.storage(converted)["color"] != "quantized")
        files.append(_file_entry("converted", converted_path, conv_fmt.name, conv_bytes, converted.count, conv_zstd,
                                 level, src_bytes))
    elif src_fmt.stores_texture or source.count == 0:
        converted, conv_fmt, order, compare = source, src_fmt, None, False  # reported as stored
    else:
        converted, size, zstd_bytes = _simulated_conversion(source, level, progress)
        conv_fmt = texture_format()
        order, notes = pair(source, converted, storage=texture_format().storage(converted), complete=False)
        files.append(_file_entry("converted", None, conv_fmt.name, size, source.count, zstd_bytes, level, src_bytes))
    if converted_path is None and source.count:
        quantized, refused = _quantized_sizes(source, src_bytes, progress)
        notes = notes + refused
    n = converted.count
    tally = _Tally(n, compare, damage=not src_fmt.stores_texture, storage=conv_fmt.storage(converted))
    with progress.stage("comparing" if compare else "reading values", n, "splat") as advance:
        for start in range(0, n, BLOCK):
            rows = slice(start, min(start + BLOCK, n))
            conv = _rows(converted.columns, rows)
            paired = None
            if not compare:
                src = conv
            elif order is None:
                src = _rows(source.columns, rows)
            else:
                pick = order[rows]
                paired = pick >= 0
                src = _rows(source.columns, pick[paired])
                paired = None if paired.all() else paired
            tally.add(rows, src, conv, paired)
            advance(rows.stop - rows.start)
    # The viewer loads the texture side; with none (PLY to PLY), the converted file as converting would make it.
    viewed_role = "source" if src_fmt.stores_texture and not conv_fmt.stores_texture else files[-1]["role"]
    viewed = source if viewed_role == "source" else converted
    described = files[-1] if compare else files[0]
    return {
        "schema": STATS_SCHEMA,
        "files": files,
        "quantized": quantized,
        "count": source.count,
        "described": {"role": described["role"], "path": described["path"], "count": n,
                      "omega": "per unit quaternion" if conv_fmt.storage(converted)["rotation"] == "quantized"
                      else "as stored"},
        "undrawable": tally.undrawable_counts(),
        "bounds": tally.bounds(),
        "time": {"times": [round(float(t), 6) for t in tally.times], "visible": tally.visible.tolist()},
        "motion": {term: _percentiles(v) for term, v in tally.magnitudes.items()},
        "attributes": tally.attributes(),
        "pairing": _pairing(order, n) if compare else None,
        "viewer": {**_viewer_limits(viewed, viewed_role, files[0 if viewed_role == "source" else -1]["path"]),
                   "splatv_js_damage": tally.damage},
        "notes": notes,
    }
