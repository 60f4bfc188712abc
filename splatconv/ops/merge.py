"""Compose: several scenes in one, on the same timeline.

The viewer draws every splat of a file by the same rules at the same time, so
scenes are composed by putting their splats in one table, unchanged: each
input looks at every time exactly as it did alone, and where they overlap
they blend as splats of one scene do. A static input (a 3DGS PLY or a
``.splat``: read with the model's static temporal basis, temporal opacity
above 0.999999 over all of [0, 1]) stays at full opacity over the whole clip
beside a moving one. Move an input before composing it with the transforms of
:mod:`splatconv.ops.transform`.

Cameras: a file holds one list of cameras, which the viewer opens with; the
composition keeps the first input's that has any (they frame that input, as
moved), and says which were dropped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import model
from ..errors import UsageError
from ..model import Scene
from ..wording import plural
from .report import OpReport

@dataclass
class MergeReport(OpReport):
    """What composing did: an :class:`~splatconv.ops.report.OpReport` (``op`` ``"merge"``, no splat removed).

    ``counts``: ``inputs``, how many scenes; ``cameras_from``, the 1-based input
    whose cameras were kept (0: none had any). ``parts``: splats of each input,
    in order (the result's rows, input by input).
    """

    parts: list = field(default_factory=list)


def overlay(scenes: list) -> tuple[Scene, MergeReport]:
    """Put several scenes in one, all on the same timeline.

    Parameters
    ----------
    scenes : list of Scene
        At least one. Their splats are concatenated in order; values are not
        changed.

    Returns
    -------
    (Scene, MergeReport)
        The composed scene: variant plain 3DGS when every input is (a
        composition of static scenes stays static and writes as 3DGS), else
        Spacetime Gaussians lite; the first input's cameras that has any; the SH bands of
        the lowest degree any input holds (bands above it dropped, and said so).
    """
    if not scenes:
        raise UsageError("nothing to merge: no input scenes")
    parts = [s.count for s in scenes]
    total = sum(parts)
    _rows, out = model.lite_rows(total)
    start = 0
    for scene, n in zip(scenes, parts):
        for name in model.COLUMNS:
            out[name][start:start + n] = np.asarray(scene.columns[name])
        start += n
    # SH bands: the degree every input holds (the lowest), so that each splat keeps a colour of one basis.
    degrees = [s.sh_degree for s in scenes]
    degree = min(degrees)
    for name in model.sh_names(degree):
        out[name] = np.concatenate([np.asarray(s.columns[name], dtype=np.float32) for s in scenes])
    with_cameras = [i for i, s in enumerate(scenes) if s.cameras]
    cameras = list(scenes[with_cameras[0]].cameras) if with_cameras else None
    static = all(s.variant == model.VARIANT_3DGS for s in scenes)
    variant = model.VARIANT_3DGS if static else model.VARIANT_LITE
    notes = [f"merged {len(scenes)} scenes on one timeline: " + " + ".join(f"{n:,}" for n in parts)
             + f" = {plural(total, 'splat')}"]
    if max(degrees) > degree:
        cut = [i + 1 for i, d in enumerate(degrees) if d > degree]
        notes.append(f"SH bands: input{'s' if len(cut) > 1 else ''} {', '.join(map(str, cut))} cut to degree {degree}, "
                     f"the lowest of the inputs ({', '.join(map(str, degrees))})")
    if with_cameras:
        kept = with_cameras[0]
        dropped = [i + 1 for i in with_cameras[1:]]
        notes.append(f"cameras: input {kept + 1}'s {len(cameras)} kept"
                     + (f"; those of input{'s' if len(dropped) > 1 else ''} "
                        f"{', '.join(map(str, dropped))} dropped" if dropped else ""))
    counts = {"inputs": len(scenes), "cameras_from": with_cameras[0] + 1 if with_cameras else 0}
    report = MergeReport("merge", total, total, notes, counts, parts=parts)
    return Scene(columns=out, cameras=cameras, variant=variant, meta={}), report
