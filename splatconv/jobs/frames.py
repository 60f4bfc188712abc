"""``convert`` of a frame sequence: a directory, a glob or a list of files fitted into one 4D scene.

The fitting is :mod:`splatconv.ops.sequence` (no I/O); this module resolves the
inputs into frame paths and feeds the frames to the fit one at a time through
:func:`splatconv.io.read`, so any format that can be read can be a frame.
"""

from __future__ import annotations

import glob
import os
import re

import numpy as np

from ..cameras import load_cameras
from ..errors import UsageError
from ..formats import REGISTRY, texture_format
from ..io import read, refuse_empty, splat_count
from ..model import COLUMNS, Scene
from ..ops.sequence import fit_sequence
from ..progress import SILENT
from ..zstd import inner_name
from ..publish import is_page
from ._steps import check_job, reading_for, silent, write_output

_GLOB_CHARS = re.compile(r"[*?[]")


def natural_key(path: str):
    """Sort key that orders digit runs by value: frame_2 before frame_10."""
    name = os.fspath(path)
    return [(0, int(part), part) if part.isdigit() else (1, 0, part) for part in re.split(r"(\d+)", name)]


def is_sequence(inputs) -> bool:
    """Whether convert's inputs name a frame sequence rather than one scene file.

    Several paths, a directory, or a pattern that is not itself an existing file.
    """
    inputs = [os.fspath(p) for p in inputs]
    if len(inputs) != 1:
        return True
    only = inputs[0]
    return os.path.isdir(only) or (not os.path.exists(only) and bool(_GLOB_CHARS.search(only)))


def _readable(name: str) -> bool:
    lower = inner_name(name).lower()
    return any(lower.endswith(suffix) and fmt.can_read for suffix, fmt in REGISTRY.items())


def frame_paths(inputs) -> list:
    """Resolve a directory, glob patterns or file paths into frame files, in natural order.

    A directory gives its files of readable formats (not recursing); a pattern
    gives its matches; a file gives itself. The result is sorted by
    :func:`natural_key` (shells sort ``frame_10`` before ``frame_2``), with
    duplicates removed.

    Raises
    ------
    UsageError
        When nothing matches, or a named file does not exist.
    """
    found = []
    for item in (os.fspath(p) for p in inputs):
        if os.path.isdir(item):
            names = [os.path.join(item, n) for n in os.listdir(item)]
            hits = [n for n in names if os.path.isfile(n) and _readable(n)]
            if not hits:
                raise UsageError("directory holds no scene files", item)
            found += hits
        elif not os.path.exists(item) and _GLOB_CHARS.search(item):
            hits = [n for n in glob.glob(item) if os.path.isfile(n)]
            if not hits:
                raise UsageError("no files match", item)
            found += hits
        elif not os.path.isfile(item):
            raise UsageError("no such file", item)
        else:
            found.append(item)
    return sorted(set(found), key=natural_key)


def convert_frames(inputs, output, *, frame_times=None, same_splats: str = "auto", max_error=None,
                   compat=None, sort=None, cameras=None, color: str = "auto", force: bool = False,
                   zstd_level=None, layout=None, quality=None, page=None, progress=SILENT, tell=silent):
    """Read a frame sequence and write it as one 4D scene (see :func:`splatconv.ops.sequence.fit_sequence`).

    Parameters
    ----------
    inputs : list of path
        A directory, glob patterns or files (see :func:`frame_paths`).
    frame_times : sequence of float, optional
        One time per frame (default frame k of N at k / (N - 1)).
    cameras : path or list of dict, optional
        Replaces the cameras of the first frame that has some.
    tell : callable
        ``tell(lines)``: the scene's notes, the fit's, then the writer's, once written.

    Returns
    -------
    (Scene, SequenceReport, WriteReport, list of str)
        The scene written, what the fit did, what the writer did, the frame paths in order.
    """
    paths = frame_paths(inputs)
    fmt = check_job(paths, output, force=force, compat=compat, sort=sort, layout=layout, quality=quality, page=page)
    camera_list = load_cameras(cameras) if isinstance(cameras, (str, os.PathLike)) else cameras
    found = {}

    def read_frame(k):
        with reading_for(output, quality=quality):
            scene = read(paths[k], color=color)
        if "cameras" not in found and scene.cameras:
            found["cameras"] = scene.cameras
        return scene

    # Counted from headers, not by reading: only the fit's own passes read the frames.
    # Frame times must stay apart as the output stores them (halves in the viewer's texture).
    empty = Scene(columns={name: np.empty(0, np.float32) for name in COLUMNS})
    stored = texture_format() if is_page(output) else fmt  # a page plays the viewer's texture
    time_type = np.float16 if stored.storage(empty).get("trbf") == "half" else np.float32
    scene, fit = fit_sequence(read_frame, len(paths), times=frame_times, same_splats=same_splats,
                              max_error=max_error, counts=[splat_count(p) for p in paths], time_type=time_type,
                              progress=progress)
    refuse_empty(fmt, scene.count, paths[0], "the frames hold no splats")
    scene.cameras = camera_list if camera_list is not None else found.get("cameras")
    report = write_output(scene, output, compat=compat, sort=sort, force=force, inputs=paths, zstd_level=zstd_level,
                          layout=layout, quality=quality, page=page, progress=progress)
    tell(scene.notes)
    tell(fit.notes)
    tell(report.notes)
    return scene, fit, report, paths
