"""``merge``: several scene files in one, on the same timeline, each moved first by its own transform."""

from __future__ import annotations

from ..errors import UnsupportedError
from ..io import holding
from ..ops import apply_transform
from ..ops import drop_nonfinite as drop_nonfinite_splats
from ..ops.merge import overlay
from ..progress import SILENT
from ._steps import check_job, read_input, reading_for, silent, write_output

#: Bytes a splat read takes at the peak of ``merge`` (every input, the merged scene, the writer's):
#: what the decompression ceiling counts, over all the inputs together
#: (:func:`splatconv.io.holding`; ``bench/bench_memory.py`` measures 306).
MERGE_MEMORY_BYTES = 320


def merge(inputs, output, *, placements=None, sort=None, layout=None, quality=None, color: str = "auto",
          drop_nonfinite: bool = False, force: bool = False, page=None, progress=SILENT, tell=silent):
    """Read ``inputs``, place each (:func:`splatconv.ops.apply_transform`), overlay them
    (:func:`splatconv.ops.merge.overlay`) and write the result to ``output``.

    Parameters
    ----------
    inputs : sequence of path
    output : path
    placements : dict of int to Transform, optional
        Input number (1 for the first) -> the transform that moves it.
    drop_nonfinite : bool
        Remove every input's non-finite splats first (:func:`splatconv.ops.drop_nonfinite`).
    sort, layout, quality, force
        As for :func:`splatconv.io.write`.
    page : splatconv.publish.PageOptions, optional
        An ``.html`` output's options (fit, poster).
    tell : callable
        ``tell(lines)``: each input's notes once read and placed (``input N (PATH): ...``), the merge's, then
        the writer's once written.

    Returns
    -------
    (MergeReport, WriteReport)
    """
    inputs = list(inputs)
    placements = placements or {}
    check_job(inputs, output, force=force, sort=sort, layout=layout, quality=quality, page=page)
    scenes = []
    with holding(MERGE_MEMORY_BYTES):  # the inputs together
        for number, path in enumerate(inputs, 1):
            with reading_for(output, quality=quality):
                scene = read_input(path, color=color, progress=progress)
            if drop_nonfinite:
                scene, _report = drop_nonfinite_splats(scene)
            if number in placements:
                try:
                    scene, _report = apply_transform(scene, placements[number])
                except UnsupportedError as e:  # a camera it cannot move: say whose
                    raise UnsupportedError(e.message, path, e.where) from None
            tell(f"input {number} ({path}): {line}" for line in scene.notes)
            scenes.append(scene)
    merged, report = overlay(scenes)
    tell(report.notes)
    written = write_output(merged, output, sort=sort, layout=layout, quality=quality, force=force, inputs=inputs,
                           page=page, progress=progress)
    tell(written.notes)
    return report, written
