"""Operations on the scene model: no I/O, no printing; each returns the new scene and what it did.

* :mod:`~splatconv.ops.filters`: drop splats the viewer never draws, non-finite
  splats, faint splats, splats outside a box, all but the N most important;
* :mod:`~splatconv.ops.time`: linear time maps (:func:`remap_time`,
  :func:`place_in`) and :func:`trim`;
* :mod:`~splatconv.ops.transform`: p' = R (S p) + T for splats that move;
* :mod:`~splatconv.ops.edit`: all of them in ``convert``'s order;
* :mod:`~splatconv.ops.bake`: the scene at one time as a static scene;
* :mod:`~splatconv.ops.merge`: several scenes in one, on one timeline;
* :mod:`~splatconv.ops.prune`: rank splats by what they add to given frames, leave out the least.

Every operation returns ``(Scene, OpReport)``; the input scene is never changed.
"""

from __future__ import annotations

from .edit import ORDER, EditPlan, apply_edits
from .filters import crop, drop_nonfinite, drop_undrawable, max_splats, min_opacity
from .report import OpReport
from .time import place_in, remap_time, trim
from .transform import Transform, apply_transform, make_transform, parse_rotation

__all__ = ["OpReport", "EditPlan", "ORDER", "apply_edits", "drop_undrawable", "drop_nonfinite", "min_opacity", "crop",
           "max_splats", "remap_time", "place_in", "trim", "Transform", "make_transform", "parse_rotation",
           "apply_transform"]
