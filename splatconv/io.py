"""Reading and writing scene files: the format by suffix, ``.zst`` transparently, atomically.

:func:`read`, :func:`write` and :func:`convert` are re-exported by
:mod:`splatconv`. Nothing here knows a format by name: each format module says
what it supports (see :mod:`splatconv.formats`).
"""

from __future__ import annotations

import os

from .cameras import load_cameras
from .errors import UnsupportedError, UsageError
from .formats import REGISTRY, compat_modes, format_for
from .fsutil import atomic_writer, check_output
from .model import Scene
from .progress import SILENT
from .transport import DEFAULT_LEVEL, is_compressed, output_stream, plain_input

#: Record orders a writer takes.
SORT_MODES = ("importance", "none")
#: How a PLY's ``f_dc_0..2`` are read.
COLOR_MODES = ("auto", "rgb", "sh")
#: Byte-identical modes some writer offers.
COMPAT_MODES = compat_modes()


def _choice(value, allowed, what: str):
    if value is not None and value not in allowed:
        raise UsageError(f"unknown {what} {value!r} (expected one of {', '.join(allowed)})")


def read(path: str | os.PathLike, *, color: str = "auto") -> Scene:
    """Read any supported scene file into a :class:`Scene` (format by suffix).

    Parameters
    ----------
    path : path
    color : {"auto", "rgb", "sh"}
        How a PLY's ``f_dc_0..2`` are read (see :func:`splatconv.formats.ply.read`).
    """
    _choice(color, COLOR_MODES, "colour mode")
    module = format_for(path, purpose="read")
    with plain_input(path) as plain:
        scene = module.read(plain, color=color)
    if is_compressed(path):
        scene.meta["compressed_bytes"] = os.path.getsize(path)
    return scene


def read_texture(path: str | os.PathLike):
    """The viewer's texture as a file stores it, and the scene decoded from it, in one read.

    Returns
    -------
    (padded, scene) or None
        None for a format that does not store the viewer's texture
        (``STORES_TEXTURE`` false): draw its attributes instead.
    """
    module = format_for(path, purpose="read")
    if not getattr(module, "STORES_TEXTURE", False):
        return None
    with plain_input(path) as plain:
        padded, scene = module.read_texture(plain)
    if is_compressed(path):
        scene.meta["compressed_bytes"] = os.path.getsize(path)
    return padded, scene


def check_write_options(path, *, compat: str | None = None, sort: str | None = None):
    """Refuse options the output's format does not take; the format module.

    Raises
    ------
    UsageError
    """
    module = format_for(path, purpose="write")
    _choice(compat, COMPAT_MODES, "compat mode")
    if compat is not None and compat not in module.COMPAT_MODES:
        suffixes = ", ".join(_suffixes_taking(compat))
        raise UsageError(f"--compat {compat} applies to {suffixes} output only", path)
    _choice(sort, SORT_MODES, "sort")
    return module


def _suffixes_taking(compat: str) -> list:
    """Suffixes of the formats whose writer takes ``compat``."""
    return [suffix for suffix, module in REGISTRY.items() if compat in module.COMPAT_MODES]


def write(scene: Scene, path: str | os.PathLike, *, compat: str | None = None, sort: str | None = None,
          force: bool = False, inputs=(), zstd_level: int | None = None, progress=SILENT):
    """Write ``scene`` to ``path`` (format by suffix), atomically.

    Parameters
    ----------
    scene : Scene
    path : path
    compat : {None, "splatv-js"}
        A byte-identical mode the output format offers (``.splatv``: splaTV's
        own converter).
    sort : {None, "importance", "none"}
        Record order; None means the format's ``DEFAULT_SORT``.
    force : bool
        Replace an existing file (never an input).
    inputs : iterable of path
        Files the scene came from; writing onto them is refused.
    zstd_level : int, optional
        Level for a ``.zst`` output (default :data:`splatconv.transport.DEFAULT_LEVEL`);
        the data is compressed as it is written, never held twice.
    progress : splatconv.progress.Progress
        Told the splats written as they are written.

    Returns
    -------
    WriteReport
        Counts and ``notes`` describing every lossy step.
    """
    module = check_write_options(path, compat=compat, sort=sort)
    if scene.count == 0 and not module.HOLDS_EMPTY:
        raise UnsupportedError(f"no splats to write; a {module.NAME} file cannot hold an empty scene", path)
    check_output(path, inputs, force)
    level = DEFAULT_LEVEL if zstd_level is None else zstd_level
    with atomic_writer(path) as stream, output_stream(stream, path, level) as out:
        return module.write(scene, out, compat=compat, sort=sort or module.DEFAULT_SORT, progress=progress)


def convert(source: str | os.PathLike, output: str | os.PathLike, *, compat: str | None = None,
            sort: str | None = None, cameras=None, color: str = "auto", force: bool = False,
            zstd_level: int | None = None, progress=SILENT):
    """Read ``source`` and write it to ``output``; formats by suffix.

    Parameters
    ----------
    cameras : path or list of dict, optional
        A ``cameras.json`` file (or its decoded list) replacing the source's cameras.

    Returns
    -------
    (Scene, WriteReport)
        The scene read (its ``notes`` say what reading dropped) and the write report.
    """
    format_for(source, purpose="read")
    module = check_write_options(output, compat=compat, sort=sort)
    # Check the output before the (possibly long) read: fail fast, touch nothing.
    check_output(output, [source], force)
    camera_list = load_cameras(cameras) if isinstance(cameras, (str, os.PathLike)) else cameras
    scene = read(source, color=color)
    if scene.count == 0 and not module.HOLDS_EMPTY:
        raise UnsupportedError(f"holds no splats; a {module.NAME} file cannot hold an empty scene", source)
    if camera_list is not None:
        scene.cameras = camera_list
    report = write(scene, output, compat=compat, sort=sort, force=force, inputs=[source], zstd_level=zstd_level,
                   progress=progress)
    return scene, report
