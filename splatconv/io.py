"""Reading and writing scene files: the format by suffix, ``.zst`` transparently, atomically.

:func:`read` and :func:`write` are re-exported by :mod:`splatconv`; a command's whole job
(check, read, operate, write) is :mod:`splatconv.jobs`'s. Nothing here knows a format by name: each format declares
what it supports (see :mod:`splatconv.formats`).
"""

from __future__ import annotations

import contextlib
import contextvars
import os

import numpy as np

from . import viewer
from .errors import FormatError, OutputError, SplatconvError, UnsupportedError, UsageError
from .files.output import atomic_group, check_output
from .formats import REGISTRY, compat_modes, format_for, layouts, qualities
from .model import COLUMNS, LITE_ROW, Scene, sh_dropped_note
from .progress import SILENT
from .wording import kinds_text, plural
from .zstd import (DEFAULT_LEVEL, MAX_DECOMPRESSED_ENV, describe_bytes, inner_name, is_compressed,
                   max_decompressed, output_stream, plain_input)

#: Record orders a writer takes.
SORT_MODES = ("importance", "none")
#: How a PLY's ``f_dc_0..2`` are read.
COLOR_MODES = ("auto", "rgb", "sh")
#: Byte-identical modes some writer offers.
COMPAT_MODES = compat_modes()
#: Record layouts some writer offers (``.ply``: lite, 3dgs).
LAYOUTS = layouts()
#: Quality settings some writer offers (``.splatvq``; a page then embeds one), the default first.
QUALITIES = qualities()
#: Bytes a splat takes in memory once read: a float32 for each field of the lite PLY row the readers
#: decode into (:func:`splatconv.model.lite_rows`: the model's columns and the three zero normals,
#: so that a PLY writer writes the table whole). Reading a ``.splatv`` or ``.splatvq`` holds that
#: table and a piece of records besides; a PLY or ``.splat`` is mapped (rows of the file) and
#: computes at most the columns it does not store (``bench/bench_memory.py``).
SPLAT_MEMORY_BYTES = 4 * len(LITE_ROW)


#: Bytes a splat takes once read with its texture (:func:`read_texture`): the scene's table and the
#: viewer's record of it.
TEXTURE_MEMORY_BYTES = SPLAT_MEMORY_BYTES + viewer.texture_bytes(1) // viewer.SPLATS_PER_ROW

#: What the scenes read in a :func:`holding` block take at the command's peak (None: outside one).
_holding = contextvars.ContextVar("splatconv_holding", default=None)


class _Held:
    """The splats read so far in a :func:`holding` block and the bytes each takes at the command's peak."""

    def __init__(self, each: int):
        self.each = each
        self.splats = 0


@contextlib.contextmanager
def holding(each: int):
    """While the block runs, every scene read is counted at ``each`` bytes a splat, all together.

    A command that builds more from a scene than its table (a texture, a converted copy, float
    reference rows, a second scene) states what a splat read costs it at its peak (its own
    constant, measured by ``bench/bench_memory.py``); :func:`check_memory` then refuses a read
    whose splats, with those of the scenes read before it in the block, would take more than
    the ceiling at that rate. Reads outside a block count their own table (or texture) only.
    """
    token = _holding.set(_Held(each))
    try:
        yield
    finally:
        _holding.reset(token)


def _held(count: int) -> None:
    """Count a scene of ``count`` splats read into the running :func:`holding` block, if any."""
    held = _holding.get()
    if held is not None:
        held.splats += count


#: Share of a scene's splats, undrawable (:func:`splatconv.viewer.undrawable`), from which
#: reading it gives a note suggesting ``--drop-undrawable`` (unless the output leaves them out
#: itself: :func:`splatconv.jobs._steps.reading_for`). Real trained scenes hold a
#: few dozen undrawable splats from NaN positions and faded opacities (well under 1%),
#: which cost nothing worth a note; zero rotations make 17-95% of most of them. From a
#: tenth of the splats on, removing them saves a tenth of the file, of the texture and
#: of the viewer's depth sort on every frame: worth saying.
UNDRAWABLE_NOTE_SHARE = 0.10
#: Rows of a scene probed before it is counted whole for the note: every this-many-th, in
#: scenes of at least _PROBE_FROM splats (smaller ones are counted whole at once).
_PROBE_STEP = 16
_PROBE_FROM = 1 << 16
#: Rows counted at a time for the note.
_COUNT_ROWS = 1 << 16

#: Who is told of scenes read with many undrawable splats (:func:`noting_undrawable`).
_undrawable_listener = contextvars.ContextVar("splatconv_undrawable_listener", default=None)


@contextlib.contextmanager
def noting_undrawable(receive):
    """While the block runs, each scene read whose undrawable splats reach :data:`UNDRAWABLE_NOTE_SHARE`
    is described to ``receive(note)``, a sentence (``receive`` None: to no one).

    Every scene a command reads comes through :func:`reading` or :func:`read_texture`,
    so this one check covers them all; nothing is computed without a listener.
    """
    token = _undrawable_listener.set(receive)
    try:
        yield
    finally:
        _undrawable_listener.reset(token)


def _check_undrawable(scene: Scene, path) -> None:
    """Tell the listener (if any) about ``scene`` when its undrawable splats are a large share of it."""
    receive = _undrawable_listener.get()
    if receive is None or not scene.count:
        return
    cols = scene.columns
    # A large scene is probed first, every _PROBE_STEP-th row: one far below the share (most
    # are) costs a sixteenth of the count (the count takes about 0.08 s a million splats read in
    # place from a PLY, a sixth of a conversion); one near or above it is counted whole, so the
    # note's figures are exact. Only a scene whose undrawable splats avoid the probed rows could
    # miss its note.
    if scene.count >= _PROBE_FROM:
        probe = {name: np.asarray(cols[name])[::_PROBE_STEP] for name in cols}
        if sum(viewer.undrawable_counts(probe).values()) < 0.5 * UNDRAWABLE_NOTE_SHARE * len(probe["x"]):
            return
    note_undrawable(_undrawable_counts(cols, scene.count), scene.count, path)


def _undrawable_counts(cols: dict, count: int) -> dict:
    """:func:`splatconv.viewer.undrawable_counts` of a whole scene, :data:`_COUNT_ROWS` rows at a time: its
    float64 temporaries are a piece's, not the scene's (a scene read is held to the ceiling, its count must
    not double it)."""
    total = None
    for start in range(0, count, _COUNT_ROWS):
        part = viewer.undrawable_counts({name: np.asarray(cols[name])[start:start + _COUNT_ROWS] for name in cols})
        total = part if total is None else {kind: total[kind] + n for kind, n in part.items()}
    return total


def note_undrawable(counts: dict, count: int, path) -> None:
    """Tell the listener (if any) of a scene at ``path`` of ``count`` splats whose undrawable ones (``counts``,
    by kind: :func:`splatconv.viewer.undrawable_counts`) reach :data:`UNDRAWABLE_NOTE_SHARE`."""
    receive = _undrawable_listener.get()
    n = sum(counts.values())
    if receive is not None and count and n >= UNDRAWABLE_NOTE_SHARE * count:
        receive(f"{os.fspath(path)}: {n:,} of {plural(count, 'splat')} ({100 * n / count:.3g}%) "
                f"can never be drawn ({kinds_text(counts)}); `splatconv convert --drop-undrawable` removes "
                f"them")


def _choice(value, allowed, what: str):
    if value is not None and value not in allowed:
        raise UsageError(f"unknown {what} {value!r} (expected one of {', '.join(allowed)})")


def read(path: str | os.PathLike, *, color: str = "auto", progress=SILENT) -> Scene:
    """Read any supported scene file into a :class:`Scene` (format by suffix).

    Parameters
    ----------
    path : path
    color : {"auto", "rgb", "sh"}
        How a PLY's ``f_dc_0..2`` are read (see :func:`splatconv.formats.ply.read`).
    progress : splatconv.progress.Progress
        Told the bytes of a ``.zst`` file decompressed.
    """
    with reading(path, color=color, progress=progress) as (scene, _plain):
        return scene


@contextlib.contextmanager
def reading(path: str | os.PathLike, *, color: str = "auto", progress=SILENT):
    """:func:`read`, keeping the file's uncompressed bytes at hand while the block runs.

    Yields ``(scene, plain)``: ``plain`` is ``path`` itself, or for a ``.zst``
    file the temporary file it was decompressed to (removed when the block
    ends), so a caller that also needs the content (``stats`` measures its
    size) does not decompress it twice.
    """
    _choice(color, COLOR_MODES, "colour mode")
    fmt = format_for(path, purpose="read")
    with plain_input(path, declared_size=fmt.declared_size, progress=progress) as plain:
        if is_compressed(path) or fmt.expands:
            check_memory(fmt, plain, path)
        scene = fmt.read(plain, color=color)
        _held(scene.count)
        if is_compressed(path):
            scene.meta["compressed_bytes"] = os.path.getsize(path)
        _check_undrawable(scene, path)
        yield scene, plain


@contextlib.contextmanager
def scanning(path: str | os.PathLike, *, color: str = "auto", progress=SILENT):
    """Read the scene at ``path`` a piece at a time: yields its :class:`~splatconv.formats.base.Scan`, whose
    pieces are to be read while the block runs.

    What ``info`` reads: the memory it takes is a piece's (a ``.splatvq`` block, some
    thousands of rows of the others), never the scene's, so no scene is held to the
    ceiling of :func:`check_memory`; a ``.zst`` file is still decompressed to a
    temporary file (disk), under the decompression ceiling. Nothing here tells the
    listener of :func:`noting_undrawable`: the caller counts the pieces
    (:func:`note_undrawable`).
    """
    _choice(color, COLOR_MODES, "colour mode")
    fmt = format_for(path, purpose="read")
    with plain_input(path, declared_size=fmt.declared_size, progress=progress) as plain:
        scan = fmt.scan(plain, color=color)
        if is_compressed(path):
            scan.meta["compressed_bytes"] = os.path.getsize(path)
        yield scan


def check_memory(fmt, plain, path, each: int = SPLAT_MEMORY_BYTES) -> None:
    """Refuse a decompressed file (or one that expands, ``fmt.expands``) whose scene would take more memory
    than the decompression ceiling.

    A few hundred kilobytes of zstd (or of ``.splatvq`` blocks) expand to gigabytes, and a
    scene read whole takes ``each`` bytes a splat (:data:`SPLAT_MEMORY_BYTES`, the table the
    readers decode into; :data:`TEXTURE_MEMORY_BYTES` with its texture), or what the command
    reading it takes at its peak (:func:`holding`, counting the scenes it read before this one
    too): a scene read from such a file may take at most :func:`splatconv.zstd.max_decompressed`
    bytes (``--max-decompressed``), so that the command holding it stays within 1.25 times that
    at its peak (``bench/bench_memory.py``). ``info`` holds no scene (:func:`scanning`) and is
    not held to it.

    Parameters
    ----------
    fmt : splatconv.formats.base.Format
        The format of ``plain``.
    plain : path
        The decompressed file.
    path : path
        The ``.zst`` file it came from (named in the error).
    each : int
        Bytes a splat of the scene takes once read.

    Raises
    ------
    FormatError
    """
    ceiling = max_decompressed()
    held = _holding.get()
    before = 0
    if held is not None:
        each = max(each, held.each)
        before = held.splats * each
    most = fmt.most_splats(plain)
    if before + most * each <= ceiling:
        return
    holds = f"holds {most:,} splats" if fmt.splat_count(plain) == most else f"may hold up to {most:,} splats"
    beside = f", beside {before:,} for the {plural(held.splats, 'splat')} read before it" if before else ""
    raise FormatError(f"{holds}: up to {most * each:,} bytes in memory ({each} a "
                      f"splat{beside}), more than the "
                      f"{describe_bytes(ceiling)} a decompressed scene may take (raise it with --max-decompressed "
                      f"or {MAX_DECOMPRESSED_ENV})", path)


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats :func:`read` gives for ``path``, found without reading them (format by suffix).

    From the format's header or the file's size (each readable format's
    ``splat_count``); None when only reading tells: a ``.zst`` file (its header
    is compressed), or a file whose header the format cannot vouch for.
    """
    fmt = format_for(path, purpose="read")
    return None if is_compressed(path) else fmt.splat_count(path)


def read_texture(path: str | os.PathLike, *, progress=SILENT):
    """The viewer's texture as a file stores it, and the scene decoded from it, in one read.

    ``progress`` is told the bytes of a ``.zst`` file decompressed.

    Returns
    -------
    (padded, scene) or None
        None for a format that does not store the viewer's texture
        (no ``texture``): draw its attributes instead.
    """
    fmt = format_for(path, purpose="read")
    if not fmt.stores_texture:
        return None
    with plain_input(path, declared_size=fmt.declared_size, progress=progress) as plain:
        if is_compressed(path) or fmt.expands:
            check_memory(fmt, plain, path, TEXTURE_MEMORY_BYTES)
        padded, scene = fmt.texture.read(plain)
    _held(scene.count)
    if is_compressed(path):
        scene.meta["compressed_bytes"] = os.path.getsize(path)
    _check_undrawable(scene, path)
    return padded, scene


def refuse_empty(fmt, count: int, path, what: str = "no splats to write") -> None:
    """Raise :class:`UnsupportedError` (naming ``path``, saying ``what``) when ``count`` is 0 and
    its format ``fmt`` cannot hold an empty scene."""
    if count == 0 and not fmt.holds_empty:
        raise UnsupportedError(f"{what}; a {fmt.suffixes[0]} file cannot hold an empty scene", path)


def check_write_options(path, *, compat: str | None = None, sort: str | None = None, layout: str | None = None,
                        quality: str | None = None, also: tuple = ()):
    """Refuse options the output's format does not take; return that format.

    Parameters
    ----------
    path : path
    compat, sort, layout, quality
        As for :func:`write`.
    also : tuple
        Outputs the caller writes besides the formats (:data:`splatconv.publish.PAGE`, the
        player page), each declaring ``suffixes``, ``compat_modes``, ``layouts`` and
        ``qualities`` as a format does: a ``path`` with one of their suffixes is checked
        against it (and it is returned), and every message lists them beside the formats.

    Raises
    ------
    UsageError
    """
    fmt = next((other for other in also if _has_suffix(path, other.suffixes)), None)
    if fmt is None:
        fmt = format_for(path, purpose="write", also=tuple(s for other in also for s in other.suffixes))
    outputs = [(suffix, f) for suffix, f in REGISTRY.items() if f.can_write]
    outputs += [(suffix, other) for other in also for suffix in other.suffixes]
    _choice(compat, COMPAT_MODES, "compat mode")
    if compat is not None and compat not in fmt.compat_modes:
        takes = [suffix for suffix, f in outputs if compat in f.compat_modes]
        raise UsageError(f"--compat {compat} applies to {', '.join(takes)} output only", path)
    _choice(sort, SORT_MODES, "sort")
    if layout is not None and layout not in fmt.layouts:
        takes = [suffix for suffix, f in outputs if layout in f.layouts]
        if not takes:
            raise UsageError(f"unknown layout {layout!r}")
        raise UsageError(f"layout {layout} applies to {', '.join(takes)} output only", path)
    _choice(quality, QUALITIES, "quality")
    if quality is not None and quality not in fmt.qualities:
        takes = [suffix for suffix, f in outputs if quality in f.qualities]
        raise UsageError(f"--quality {quality} applies to {', '.join(takes)} output only", path)
    if quality is not None and compat is not None:
        raise UsageError("--compat and --quality exclude each other (--compat keeps the texture's bytes, "
                         "--quality embeds the scene quantized)", path)
    return fmt


def _has_suffix(path, suffixes) -> bool:
    """Whether ``path`` ends in one of ``suffixes`` (case-insensitive, after any ``.zst``)."""
    return inner_name(os.fspath(path)).lower().endswith(tuple(suffixes))


def write(scene: Scene, path: str | os.PathLike, *, compat: str | None = None, sort: str | None = None,
          force: bool = False, inputs=(), zstd_level: int | None = None, layout: str | None = None,
          quality: str | None = None, precision: int | None = None, tune: tuple = (), prepared=None,
          weights=None, progress=SILENT):
    """Write ``scene`` to ``path`` (format by suffix), atomically.

    Parameters
    ----------
    scene : Scene
    path : path
    compat : {None, "splatv-js"}
        A byte-identical mode the output format offers (``.splatv``: splaTV's
        own converter).
    sort : {None, "importance", "none"}
        Record order; None means the format's ``default_sort``.
    force : bool
        Replace an existing file (never an input).
    inputs : iterable of path
        Files the scene came from; writing onto them is refused.
    zstd_level : int, optional
        Level for a ``.zst`` output (default :data:`splatconv.zstd.DEFAULT_LEVEL`);
        the data is compressed as it is written, never held twice.
    layout : str, optional
        A record layout the output's format offers (``layouts``; ``.ply``:
        ``lite`` or ``3dgs``); None: the format's choice for the scene.
    quality : str, optional
        A quality setting the output's format offers (``qualities``; ``.splatvq``);
        None: the format's default.
    precision : int, optional
        A precision step beside the quality that the output's format offers
        (``precisions``); None: the quality as named.
    tune : tuple of str
        Quantizers coarsened a notch each beyond the step, of those the output's
        format offers (``tunings``; a name once a notch).
    prepared : optional
        What the format's ``prepare`` gave for this very scene (a proof writes it at several steps).
    weights : (N,) float ndarray, optional
        What each splat adds to the frames a user sees, for a format that spends its
        bits by it (``weighs``): :func:`splatconv.render.proof.frame_weights`.
    progress : splatconv.progress.Progress
        Told the splats written as they are written, and, for a ``.zst``
        output, the bytes compressed after the last write.

    Returns
    -------
    WriteReport
        Counts and ``notes`` describing every lossy step.
    """
    fmt = check_write_options(path, compat=compat, sort=sort, layout=layout, quality=quality)
    refuse_empty(fmt, scene.count, path)
    check_output(path, inputs, force)
    if precision is not None and precision not in fmt.precisions:
        raise UsageError(f"precision steps apply to {', '.join(s for s, f in REGISTRY.items() if f.precisions)} "
                         "output only", path)
    if any(name not in fmt.tunings for name in tune):
        raise UsageError(f"a .{fmt.name} writer tunes {', '.join(fmt.tunings) or 'no quantizer'}, "
                         f"not {', '.join(n for n in tune if n not in fmt.tunings)}", path)
    if prepared is not None and fmt.prepare is None:
        raise UsageError(f"a .{fmt.name} writer prepares nothing", path)
    if weights is not None and not fmt.weighs:
        raise UsageError(f"a .{fmt.name} writer weighs no splat", path)
    beside = _companions(fmt, path, inputs, force)
    with atomic_group(replace=force) as group, group.open(path) as stream, contextlib.ExitStack() as stack:
        streams = [stack.enter_context(group.open(other)) for other in beside]
        return _write_file(stream, fmt, scene, path, compat=compat, sort=sort, layout=layout, quality=quality,
                           precision=precision, tune=tuple(tune), prepared=prepared, weights=weights,
                           zstd_level=zstd_level, progress=progress, companions=streams)


def _companions(fmt, path, inputs, force: bool) -> tuple:
    """The files ``fmt`` writes beside ``path`` (:attr:`~splatconv.formats.base.Format.companions`), each
    checked as an output."""
    beside = fmt.companions(os.fspath(path)) if fmt.companions is not None else ()
    for other in beside:
        check_output(other, inputs, force)
    return beside


#: Bytes a splat in memory (the model's float32 columns): more than any format's file takes a splat
#: but the rare worst case of a ``.splatvq`` (a .splatv 64, a PLY 68 or 128).
_MODEL_BYTES_A_SPLAT = 4 * len(COLUMNS)
#: What a file holds besides its splats, about: header, cameras.
_HEADER_BYTES = 1 << 20


def _size_hint(scene: Scene) -> int:
    """About the bytes a file of ``scene`` takes, seldom fewer: sizes a ``.zst`` output's compressor."""
    return scene.count * _MODEL_BYTES_A_SPLAT + _HEADER_BYTES


def _write_file(stream, fmt, scene: Scene, path, *, compat: str | None = None, sort: str | None = None,
                layout: str | None = None, quality: str | None = None, precision: int | None = None,
                tune: tuple = (), prepared=None, weights=None, zstd_level: int | None = None, progress=SILENT,
                companions=()):
    """Write ``scene`` in format ``fmt`` to the binary ``stream`` that becomes ``path`` (``.zst``: compressed
    as it is written), and to the ``companions`` streams of the files beside it: what :func:`write` and
    :func:`write_each` do for each file. Errors name ``path``."""
    level = DEFAULT_LEVEL if zstd_level is None else zstd_level
    # Only the options given: a writer that offers none takes none.
    extra = {key: value for key, value in (("layout", layout), ("quality", quality), ("precision", precision),
                                           ("tune", tuple(tune) or None), ("prepared", prepared),
                                           ("weights", weights),
                                           ("companions", tuple(companions) or None)) if value is not None}
    try:
        with output_stream(stream, path, level, progress, size_hint=_size_hint(scene)) as out:
            report = fmt.write(scene, out, compat=compat, sort=sort or fmt.default_sort, progress=progress,
                               name=os.path.basename(path), **extra)
    except SplatconvError as e:
        if e.path is not None:
            raise
        raise type(e)(e.message, path, e.where) from None  # a writer does not know its file's name
    if not fmt.holds_sh:
        report.notes.extend(sh_dropped_note(scene.sh_degree, f"a .{fmt.name} file"))
    return report


def write_each(scenes, paths, *, sort: str | None = None, layout: str | None = None, quality: str | None = None,
               force: bool = False, inputs=(), zstd_level: int | None = None, progress=SILENT) -> list:
    """Write several scene files all or nothing: ``scenes[i]`` to ``paths[i]``.

    Every output is checked before the first scene is asked for; the scenes may
    come from a generator, made one at a time (a frame sequence need not be in
    memory at once). On any error no output is created or changed.

    Parameters
    ----------
    scenes : iterable of Scene
        As many as ``paths``.
    paths : sequence of path
    sort, layout, quality, force, inputs, zstd_level
        As for :func:`write`.
    progress : splatconv.progress.Progress
        Told each file written.

    Returns
    -------
    list of WriteReport
    """
    paths = [os.fspath(p) for p in paths]
    formats = [check_write_options(p, sort=sort, layout=layout, quality=quality) for p in paths]
    for path in paths:
        check_output(path, inputs, force)
    beside = [_companions(fmt, path, inputs, force) for fmt, path in zip(formats, paths)]
    reports = []
    with atomic_group(replace=force) as group, progress.stage("files", len(paths), "file") as advance:
        for fmt, path, others, scene in zip(formats, paths, beside, scenes):
            refuse_empty(fmt, scene.count, path)
            with group.open(path) as stream, contextlib.ExitStack() as stack:
                streams = [stack.enter_context(group.open(other)) for other in others]
                reports.append(_write_file(stream, fmt, scene, path, sort=sort, layout=layout, quality=quality,
                                           zstd_level=zstd_level, companions=streams))
            advance()
        if len(reports) != len(paths):
            raise ValueError(f"{len(reports)} scenes for {len(paths)} paths")
    return reports


def write_sequence(scenes, folder: str | os.PathLike, names, **options) -> list:
    """Write numbered files into ``folder`` all or nothing (see :func:`write_each`).

    ``folder`` is made when it does not exist (its parent must), and removed
    again when the writing fails.

    Parameters
    ----------
    scenes : iterable of Scene
    folder : path
    names : sequence of str
        File names inside ``folder``, one a scene.
    **options
        As for :func:`write_each`.
    """
    folder = os.fspath(folder)
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise OutputError("is not a folder", folder)
    made = not os.path.exists(folder)
    if made:
        parent = os.path.dirname(os.path.abspath(folder))
        if not os.path.isdir(parent):
            raise OutputError(f"folder {parent} does not exist", folder)
        os.mkdir(folder)
    try:
        return write_each(scenes, [os.path.join(folder, name) for name in names], **options)
    except BaseException:
        if made:
            with contextlib.suppress(OSError):
                os.rmdir(folder)
        raise

