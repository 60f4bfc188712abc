"""``convert`` of one scene file: read, optionally edit, write in another format or as a player page."""

from __future__ import annotations

import os

from ..cameras import load_cameras
from ..errors import UnsupportedError
from ..io import holding, refuse_empty
from ..progress import SILENT
from ._steps import check_job, read_input, reading_for, silent, write_output

#: Bytes a splat takes at the peak of ``convert`` (the scene and what the writer builds: 128 to
#: ``.ply``, 145 to ``.splatv``, 177 to ``.splatvq``, ``bench/bench_memory.py``): what the
#: decompression ceiling counts (:func:`splatconv.io.holding`).
CONVERT_MEMORY_BYTES = 192
#: The same with the proof of a compressed output (:mod:`splatconv.jobs.prove`): the source as a
#: scene, a candidate being encoded, and the renderer's textures and depth keys (it was measured when
#: a candidate was read back as a scene too: a bound, not a tight one)
#: (some 830 bytes a splat over a fixed 250 MB between generated scenes of 100,000 and 300,000
#: splats; 1.4 kB a splat over a scene of 65,536 in ``tests/test_memory.py``).
PROVE_MEMORY_BYTES = 1536


def convert(source: str | os.PathLike, output: str | os.PathLike, *, compat: str | None = None,
            sort: str | None = None, cameras=None, color: str = "auto", force: bool = False,
            zstd_level: int | None = None, layout: str | None = None, quality: str | None = None, progress=SILENT,
            edit=None, tell=silent, writer=None, memory: int = CONVERT_MEMORY_BYTES, page=None):
    """Read ``source`` and write it to ``output``; formats by suffix, ``.html`` a player page
    (:func:`splatconv.publish.write_page`: a file the page plays as it is, given no option that changes it,
    is embedded as its own bytes, as ``publish`` and ``view`` give it).

    Parameters
    ----------
    cameras : path or list of dict, optional
        A ``cameras.json`` file (or its decoded list) replacing the source's cameras.
    edit : callable, optional
        ``edit(scene) -> scene``, applied after reading (and after ``cameras``)
        and before writing, e.g. :func:`splatconv.ops.apply_edits` with a plan.
    compat, sort, force, zstd_level, layout, quality
        As for :func:`splatconv.io.write`.
    writer : callable, optional
        ``writer(scene, output, *, quality, sort, zstd_level, force, progress) -> (WriteReport, notes)``
        instead of writing the output, e.g. one that proves the output's
        quality (:func:`splatconv.jobs.prove.convert_proven`); its notes are told
        after the write report's.
    page : splatconv.publish.PageOptions, optional
        An ``.html`` output's options (fit, poster).
    memory : int
        Bytes a splat takes at the command's peak, which the decompression
        ceiling counts (:data:`PROVE_MEMORY_BYTES` with a proving writer).
    progress : splatconv.progress.Progress
        Told the reading (a "reading" stage, and the bytes of a ``.zst`` input
        decompressed) and the writing (as :func:`splatconv.io.write`).
    tell : callable
        ``tell(lines)``: the scene's notes, then the writer's, once written.

    Returns
    -------
    (Scene, WriteReport)
        The scene written (its ``notes`` say what reading dropped, and what
        ``edit`` did when it says so) and the write report.
    """
    # The output is checked before the (possibly long) read: fail fast, touch nothing.
    fmt = check_job([source], output, force=force, compat=compat, sort=sort, layout=layout, quality=quality,
                    page=page)
    camera_list = load_cameras(cameras) if isinstance(cameras, (str, os.PathLike)) else cameras
    with reading_for(output, quality=quality), holding(memory):
        scene = read_input(source, color=color, progress=progress)
    refuse_empty(fmt, scene.count, source, "holds no splats")
    changed = camera_list is not None or edit is not None
    if camera_list is not None:
        scene.cameras = camera_list
    if edit is not None:
        try:
            scene = edit(scene)
        except UnsupportedError as e:  # a camera the transform cannot move: say whose
            given = isinstance(cameras, (str, os.PathLike))
            if e.path is not None or (camera_list is not None and not given):
                raise
            raise UnsupportedError(e.message, cameras if given else source, e.where) from None
    proved = []
    if writer is None:
        report = write_output(scene, output, source=None if changed else source, compat=compat, sort=sort,
                              force=force, inputs=[source], zstd_level=zstd_level, layout=layout, quality=quality,
                              page=page, progress=progress)
    else:
        report, proved = writer(scene, output, quality=quality, sort=sort, zstd_level=zstd_level, force=force,
                                progress=progress)
    tell(scene.notes)
    tell(report.notes)
    tell(proved)
    return scene, report
