"""``merge --segments``: segment files laid end to end on one timeline, each output frame measured against
its segment; and the command's findings.

The merging is :mod:`splatconv.ops.segments` (no I/O), the measure
:mod:`splatconv.render.fidelity`.
"""

from __future__ import annotations

import os

from ..io import read
from ..ops.segments import (DEFAULT_BUDGET, DEFAULT_LEAK, check_budget, check_durations, check_segment_count,
                            merge_segments as merge_scenes)
from ..progress import SILENT
from ..render.fidelity import DEFAULT_CAMERA, checked_frames, fidelity, fidelity_summary
from ._steps import check_job, reading_for, silent, write_output

#: The first key of ``merge --segments --json`` (specs/json.md).
SEGMENTS_SCHEMA = "splatconv.merge-segments/3"


def merge_segments(inputs, output, *, durations=None, leak: int = DEFAULT_LEAK, budget: float = DEFAULT_BUDGET,
                   sort=None, layout=None, quality=None, color: str = "auto", force: bool = False, zstd_level=None,
                   check: bool = True, check_every: int | None = None, camera: int = DEFAULT_CAMERA,
                   page=None, progress=SILENT, tell=silent):
    """Read segment files, lay them end to end (:func:`splatconv.ops.segments.merge_segments`) and write.

    Parameters
    ----------
    check : bool
        Measure output frames against their segments (:func:`splatconv.render.fidelity.fidelity`).
    check_every : int, optional
        Measure every ``check_every``-th output frame (1: all). None: a sample of
        :data:`~splatconv.render.fidelity.DEFAULT_SAMPLE` frames spread evenly and the
        hand-overs (:func:`~splatconv.render.fidelity.checked_frames`).
    tell : callable
        ``tell(lines)``: the merged scene's notes, the merge's, then the writer's, once written.

    Returns
    -------
    (Scene, SegmentReport, WriteReport, dict)
        The merged scene, what merging did, what the writer did, and the check:
        ``rule`` ("sample", "every" or "none"), ``every`` (K or None), ``frames``
        (the output frames measured), ``of`` (output frames in all), ``rows`` (the
        per-frame fidelity, one per frame measured).
    """
    inputs = [os.fspath(p) for p in inputs]
    # Before any reading.
    check_budget(budget)
    if durations is not None:
        check_durations(durations)
    else:
        check_segment_count(len(inputs))
    check_job(inputs, output, force=force, sort=sort, layout=layout, quality=quality, page=page)
    with reading_for(output, quality=quality):
        scenes = [read(p, color=color) for p in inputs]
    merged, report = merge_scenes(scenes, durations, leak=leak, budget=budget, progress=progress)
    frames = checked_frames(report, check_every) if check else []
    rows = fidelity(merged, scenes, report, camera=camera, frames=frames, progress=progress) if check else []
    written = write_output(merged, output, sort=sort, force=force, inputs=inputs, zstd_level=zstd_level,
                           layout=layout, quality=quality, page=page, progress=progress)
    tell(merged.notes)
    tell(report.notes)
    tell(written.notes)
    checked = {"rule": "none" if not check else "sample" if check_every is None else "every",
               "every": check_every if check else None, "frames": frames,
               "of": sum(p.frames for p in report.placements), "rows": rows}
    return merged, report, written, checked


def segments_findings(report, written, output, checked: dict) -> dict:
    """``merge --segments``'s findings: data with the keys of specs/json.md in order.

    Parameters
    ----------
    report : splatconv.ops.segments.SegmentReport
    written : splatconv.formats.base.WriteReport
    output : path
    checked : dict
        The check :func:`merge_segments` returns: its rule, the frames measured, their fidelity.
    """
    data = {"schema": SEGMENTS_SCHEMA, **report.as_dict()}
    data["output"] = {"path": str(output), "splats": written.count, "bytes": os.path.getsize(output)}
    data["check"] = {"rule": checked["rule"], "every": checked["every"], "frames": list(checked["frames"]),
                     "of": checked["of"]}
    data["frames"] = list(checked["rows"])
    data["fidelity"] = fidelity_summary(checked["rows"])
    return data
