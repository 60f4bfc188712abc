"""splatconv: move 4D Gaussian-splatting scenes between training and viewing formats.

The library API::

    scene = splatconv.read("scene.ply")          # -> Scene (columnar model)
    report = splatconv.write(scene, "scene.splatv")
    scene, report = splatconv.convert("scene.ply", "scene.splatv", compat="splatv-js")
    print(report.notes)                          # every lossy step, in words
"""

from __future__ import annotations

import os

from .errors import FormatError, OutputError, SplatconvError, UnsupportedError, UsageError
from .model import Scene

__version__ = "0.1.0"

__all__ = ["read", "write", "convert", "Scene", "SplatconvError", "FormatError", "UnsupportedError",
           "OutputError", "UsageError", "__version__"]

COMPAT_MODES = ("splatv-js",)
SORT_MODES = ("importance", "none")
COLOR_MODES = ("auto", "rgb", "sh")


def read(path: str | os.PathLike, *, color: str = "auto") -> Scene:
    """Read any supported scene file into a :class:`Scene` (format by suffix).

    Parameters
    ----------
    path : path
    color : {"auto", "rgb", "sh"}
        How a PLY's ``f_dc_0..2`` are read (see :func:`splatconv.formats.ply.read`).
    """
    from .formats import format_for
    from .transport import is_compressed, plain_input

    if color not in COLOR_MODES:
        raise UsageError(f"unknown colour mode {color!r} (expected one of {', '.join(COLOR_MODES)})")
    module = format_for(path)
    with plain_input(path, declared_size=getattr(module, "declared_size", None)) as plain:
        scene = module.read(plain, color=color)
    if is_compressed(path):
        scene.meta["compressed_bytes"] = os.path.getsize(path)
    return scene


def write(scene: Scene, path: str | os.PathLike, *, compat: str | None = None, sort: str | None = None,
          force: bool = False, inputs=(), zstd_level: int | None = None):
    """Write ``scene`` to ``path`` (format by suffix), atomically.

    Parameters
    ----------
    scene : Scene
    path : path
    compat : {None, "splatv-js"}
        Only for ``.splatv``: byte-identical texture to splaTV's own converter.
    sort : {None, "importance", "none"}
        Record order; None means the format's default (importance for splatv,
        input order for PLY).
    force : bool
        Replace an existing file (never an input).
    inputs : iterable of path
        Files the scene came from; writing onto them is refused.
    zstd_level : int, optional
        Level for a ``.zst`` output (default 19); the data is compressed as it
        is written, never held twice.

    Returns
    -------
    WriteReport
        Counts and ``notes`` describing every lossy step.
    """
    from .formats import format_for, splatv
    from .fsutil import atomic_writer, check_output
    from .transport import DEFAULT_LEVEL, output_stream

    module = format_for(path)
    if compat is not None and compat not in COMPAT_MODES:
        raise UsageError(f"unknown compat mode {compat!r} (expected one of {', '.join(COMPAT_MODES)})")
    if compat is not None and module is not splatv:
        raise UsageError(f"--compat {compat} applies to .splatv output only", path)
    if sort is not None and sort not in SORT_MODES:
        raise UsageError(f"unknown sort {sort!r} (expected one of {', '.join(SORT_MODES)})")
    check_output(path, inputs, force)
    level = DEFAULT_LEVEL if zstd_level is None else zstd_level
    with atomic_writer(path, replace=force) as stream, output_stream(stream, path, level) as out:
        return module.write(scene, out, compat=compat, sort=sort)


def convert(source: str | os.PathLike, output: str | os.PathLike, *, compat: str | None = None,
            sort: str | None = None, cameras=None, color: str = "auto", force: bool = False,
            zstd_level: int | None = None):
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
    from .cameras import load_cameras
    from .formats import format_for
    from .fsutil import check_output

    format_for(source)
    format_for(output)
    # Check the output before the (possibly long) read: fail fast, touch nothing.
    check_output(output, [source], force)
    camera_list = load_cameras(cameras) if isinstance(cameras, (str, os.PathLike)) else cameras
    scene = read(source, color=color)
    if scene.count == 0 and format_for(output).NAME == "splatv":
        raise UnsupportedError("holds no splats; the viewer cannot show an empty texture", source)
    if camera_list is not None:
        scene.cameras = camera_list
    report = write(scene, output, compat=compat, sort=sort, force=force, inputs=[source], zstd_level=zstd_level)
    return scene, report
