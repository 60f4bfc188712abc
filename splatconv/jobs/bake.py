"""``bake``: the scene as the viewer shows it at one moment, as a static scene file; or a folder of moments."""

from __future__ import annotations

import os

from ..formats import FRAME_SUFFIX
from ..io import check_write_options, holding, write_sequence
from ..ops import bake as bake_ops
from ..progress import SILENT
from ._steps import check_job, read_input, silent, write_output

#: Bytes a splat takes at the peak of ``bake`` (the scene, the baked scene and the float64 work of
#: the bake, the writer's): what the decompression ceiling counts (:func:`splatconv.io.holding`;
#: ``bench/bench_memory.py`` measures 507).
BAKE_MEMORY_BYTES = 528


def bake(source, output, *, time: float, sort=None, layout=None, quality=None, color: str = "auto",
         drop_nonfinite: bool = False, force: bool = False, page=None, progress=SILENT, tell=silent):
    """Bake ``source`` at ``time`` (:func:`splatconv.ops.bake.bake`) and write it to ``output``.

    Parameters
    ----------
    source, output : path
    time : float
        In the viewer's [0, 1].
    sort, layout, quality, force
        As for :func:`splatconv.io.write`.
    page : splatconv.publish.PageOptions, optional
        An ``.html`` output's options (fit, poster).
    drop_nonfinite : bool
        Also remove baked splats left with a non-finite value.
    tell : callable
        ``tell(lines)``: the scene's notes once read, the bake's once baked, the writer's once written.

    Returns
    -------
    (BakeReport, WriteReport)
    """
    check_job([source], output, force=force, sort=sort, layout=layout, quality=quality, page=page)
    with holding(BAKE_MEMORY_BYTES):
        scene = read_input(source, color=color, progress=progress)
    tell(scene.notes)
    baked, report = bake_ops.bake(scene, time, drop_nonfinite=drop_nonfinite)
    tell(report.notes)
    written = write_output(baked, output, sort=sort, layout=layout, quality=quality, force=force, inputs=[source],
                           page=page, progress=progress)
    tell(written.notes)
    return report, written


def bake_frames(source, folder, *, frames: int, suffix: str = FRAME_SUFFIX, sort=None, layout=None,
                quality=None, color: str = "auto", drop_nonfinite: bool = False, force: bool = False, progress=SILENT,
                tell=silent):
    """Bake ``frames`` moments of ``source`` into ``folder`` (made if missing), all or nothing.

    Frame k, at time k / (frames - 1), is ``folder/frame_KKKK`` + ``suffix``
    (:func:`splatconv.ops.bake.frame_names`); each is baked as it is written, so
    the frames are never in memory at once.

    Parameters
    ----------
    tell : callable
        ``tell(lines)``: the scene's notes once read, each frame's bake notes as
        it is baked and its writer's once all are written (``NAME: ...``), and a
        note when ``folder`` holds other frame files from before.

    Returns
    -------
    (list of str, list of float, list of WriteReport)
        The frame names, their times, what the writer did for each.
    """
    names = bake_ops.frame_names(frames, suffix)
    # The frames' options are checked before the (possibly long) read, as a file's are.
    if names:
        check_write_options(os.path.join(folder, names[0]), sort=sort, layout=layout, quality=quality)
    with holding(BAKE_MEMORY_BYTES):
        scene = read_input(source, color=color, progress=progress)
    tell(scene.notes)
    moments = list(bake_ops.frame_times(frames))

    made = bake_ops.bake_frames(scene, frames, drop_nonfinite=drop_nonfinite)  # checks the count at once

    def baked():
        for name, (_t, frame, report) in zip(names, made):
            tell(f"{name}: {line}" for line in report.notes)
            yield frame

    reports = write_sequence(baked(), folder, names, sort=sort, layout=layout, quality=quality, force=force,
                             inputs=[source], progress=progress)
    for name, report in zip(names, reports):
        tell(f"{name}: {line}" for line in report.notes)
    stale = bake_ops.other_frames(os.listdir(folder), names, suffix)
    if stale:
        tell([f"{folder} also holds {len(stale)} other frame files from before ({stale[0]}, ...): "
              "a flipbook player would show them too"])
    return names, moments, reports
