"""How faithfully a merged clip shows its segments: each output frame drawn against its segment alone.

The float reference renderer (unquantized attributes, the viewer's shader
maths) draws both from one stored camera; the result is a PSNR per frame.
Used by ``merge --segments`` (:mod:`splatconv.jobs.segments`).
"""

from __future__ import annotations

import math

import numpy as np

from .. import viewer
from ..cameras import framing_camera
from ..errors import UsageError
from ..model import Scene
from ..ops.segments import SegmentReport
from ..progress import SILENT
from . import camera as cam
from .diff import compare
from .layout import float_attributes
from .preview import Renderer, View


#: Output frames the default check measures, spread evenly over the clip (its first and last
#: frame included), besides both sides of the hand-overs between segments (where merges go
#: wrong). Bounded so that the check costs about as much as the merge: each frame is two float
#: reference renders.
DEFAULT_SAMPLE = 5
#: Hand-overs the default check measures at most (both sides of each): all of them up to this
#: many, else this many spread evenly over the boundaries, the first and last included. The
#: sample is so at most DEFAULT_SAMPLE + 2 * SAMPLE_HAND_OVERS frames, however many segments.
SAMPLE_HAND_OVERS = 6
#: Stored camera the fidelity is measured from.
DEFAULT_CAMERA = 0
#: Width of the fidelity renders (the camera's size scaled down to it).
FIDELITY_WIDTH = 320
#: Splats drawn per frame are those at or above this temporal opacity (below the viewer's
#: 0.02 so that the shader, not this pre-selection, makes the cut).
_PRESELECT = 0.019


def _view(cameras, index: int, columns: dict, width: int) -> View:
    cams = cameras or [framing_camera(columns["x"], columns["y"], columns["z"])]
    if not 0 <= index < len(cams):
        plural = "" if len(cams) == 1 else "s"
        raise UsageError(f"--camera {index}: the segments have {len(cams)} camera{plural}, 0..{len(cams) - 1}")
    w, h, fx, fy = cam.fit(cams[index], None, width)
    return View(cam.view_matrix(cams[index]), fx, fy, w, h)


def _visible_rows(columns: dict, t: float) -> np.ndarray:
    return np.flatnonzero(~(viewer.temporal_opacity(columns, t, cut=False) < _PRESELECT))


def checked_frames(report: SegmentReport, every: int | None = None, sample: int = DEFAULT_SAMPLE) -> list:
    """The output frames a check measures, in order.

    Parameters
    ----------
    every : int, optional
        Every ``every``-th output frame from frame 0 (1: all). None: the sample.
    sample : int
        With ``every`` None: this many frames spread evenly over the clip (the
        first and the last included), and both sides of each hand-over (the
        last frame of a segment and the first of the next): every hand-over up to
        :data:`SAMPLE_HAND_OVERS`, else that many spread evenly.

    Returns
    -------
    list of int
        Output frame numbers, ascending, without repeats.
    """
    total = sum(p.frames for p in report.placements)
    if every is not None:
        return list(range(0, total, max(1, int(every))))
    spread = np.round(np.linspace(0, total - 1, min(max(1, int(sample)), total))).astype(np.int64)
    boundaries = report.placements[1:]
    if len(boundaries) > SAMPLE_HAND_OVERS:
        picks = np.round(np.linspace(0, len(boundaries) - 1, SAMPLE_HAND_OVERS)).astype(np.int64)
        boundaries = [boundaries[i] for i in picks]
    hand_overs = [f for p in boundaries for f in (p.first - 1, p.first)]
    return sorted(set(spread.tolist()) | set(hand_overs))


def fidelity(merged: Scene, segments: list, report: SegmentReport, *, camera: int = DEFAULT_CAMERA,
             frames=None, width: int = FIDELITY_WIDTH, progress=SILENT) -> list:
    """PSNR of the merged scene at each output frame time against its segment at the local time.

    Both are drawn with the float reference renderer (unquantized attributes,
    the viewer's shader maths) from the stored camera ``camera`` (the first
    segment's cameras; a framing camera when none has any), ``width`` pixels wide.
    Only splats that pass the temporal cut at the frame's time are uploaded
    (the others draw nothing).

    Parameters
    ----------
    frames : list of int, optional
        The output frames to measure (:func:`checked_frames`); None: every frame.

    Returns
    -------
    list of dict
        ``frame``, ``time``, ``segment``, ``local_time``, ``psnr`` (None when identical), one per frame measured.
    """
    times = report.frame_times()  # indexed by output frame: the segments' frames are consecutive
    frames = times if frames is None else [times[f] for f in frames]
    view = _view(merged.cameras or next((s.cameras for s in segments if s.cameras), None), camera,
                 merged.columns, width)
    a = Renderer(view.width, view.height)
    b = Renderer(view.width, view.height, ctx=a.ctx)
    out = []
    try:
        with progress.stage("checking frames", len(frames), "frame") as advance:
            for f, t, i, local in frames:
                images = []
                for r, scene, when in ((a, merged, t), (b, segments[i], local)):
                    rows = _visible_rows(scene.columns, when)
                    r.load_float(float_attributes(Scene(columns=scene.take(rows))))
                    images.append(r.draw(view, float(when)))
                psnr = compare(images[1], images[0]).psnr
                out.append({"frame": f, "time": round(t, 9), "segment": i, "local_time": round(local, 9),
                            "psnr": None if math.isinf(psnr) else round(psnr, 3)})
                advance()
    finally:
        b.release()
        a.release()
    return out


def fidelity_summary(rows: list) -> dict:
    """Median, minimum and frames below 30 and 40 dB of :func:`fidelity` rows (identical frames count as inf)."""
    v = np.array([math.inf if r["psnr"] is None else r["psnr"] for r in rows])
    if len(v) == 0:
        return {"frames": 0}
    return {"frames": len(v), "median_psnr": float(np.median(v)) if np.isfinite(np.median(v)) else None,
            "min_psnr": float(v.min()) if np.isfinite(v.min()) else None,
            "below_40": int((v < 40).sum()), "below_30": int((v < 30).sum())}
