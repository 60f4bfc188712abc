"""``verify`` and ``diff``: prove a conversion by structure and by pixels.

``verify`` draws SOURCE through the float reference path (its attributes as float32,
no quantization) and CONVERTED as stored (a .splatv texture; a PLY's attributes),
with the same cameras, times and splat order, and compares the frames. Before
drawing it checks that every attribute differs only by what quantization explains.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..cameras import framing_camera
from ..compare import align, compare_scenes
from ..errors import OutputError, UsageError
from ..formats.splatv_layout import SPLATS_PER_ROW, texture_height
from ..io import read as read_scene
from ..io import read_texture
from ..fsutil import atomic_writer, check_output
from . import camera as cam
from . import diff as imgdiff
from .frames import load
from .preview import FLOAT_SPLATS_PER_ROW, Renderer, View, float_attributes

DEFAULT_TIMES = (0.0, 0.25, 0.5, 0.75, 1.0)
DEFAULT_MIN_PSNR = 40.0
#: verify's default image width: big enough to see damage, quick on a CPU.
VERIFY_MAX_WIDTH = 640


def parse_times(text: str) -> list:
    """``--times`` value: comma-separated numbers."""
    try:
        times = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise UsageError(f"--times: expected comma-separated numbers, got {text!r}") from None
    if not times or not all(math.isfinite(t) for t in times):
        raise UsageError(f"--times: expected comma-separated numbers, got {text!r}")
    return times


def check_min_psnr(min_psnr: float) -> float:
    """A finite threshold: NaN compares false with every PSNR, so it would pass everything."""
    if not math.isfinite(min_psnr):
        raise UsageError(f"--min-psnr: expected a finite number of dB, got {min_psnr}")
    return float(min_psnr)


def parse_cameras(text: str, available: int) -> list:
    """``--cameras`` value: ``all`` or comma-separated indices."""
    if text == "all":
        return list(range(available))
    try:
        picked = [int(c) for c in text.split(",")]
    except ValueError:
        raise UsageError(f"--cameras: expected 'all' or comma-separated indices, got {text!r}") from None
    bad = [c for c in picked if not 0 <= c < available]
    if bad:
        raise UsageError(f"--cameras: no camera {bad[0]}; there are {available} (0..{available - 1})")
    return picked


def frame_views(cameras: list, indices: list, size, max_width: int = VERIFY_MAX_WIDTH) -> list:
    """(camera index, View) for each chosen camera; default size scaled to max_width.

    fx and fy scale with the size, as in ``render`` (see :func:`camera.fit`).
    """
    views = []
    for i in indices:
        w, h, fx, fy = cam.fit(cameras[i], size, max_width)
        views.append((i, View(cam.view_matrix(cameras[i]), fx, fy, w, h)))
    return views


def _float_texels_padded(scene, order, records: int) -> np.ndarray:
    """Float reference rows in the given order, padded with zero rows to ``records``.

    Zero rows stand for the texture's zero padding, which the viewer also sorts, so
    both paths see the same depth range and draw in the same order.
    """
    rows = float_attributes(scene, order)
    if records > len(rows):
        rows = np.concatenate([rows, np.zeros((records - len(rows), rows.shape[1]), np.float32)])
    return rows


@dataclass
class Frame:
    """One compared pair: a scene frame (time, camera) or, with ``names``, two image files."""

    time: float
    camera: int
    diff: imgdiff.ImageDiff
    images: tuple = ()
    names: tuple = ()

    def where(self) -> dict:
        """What was compared: ``{"a", "b"}`` image paths, or ``{"time", "camera"}``."""
        if self.names:
            return {"a": self.names[0], "b": self.names[1]}
        return {"time": self.time, "camera": self.camera}


@dataclass
class Outcome:
    """Everything ``verify`` or ``diff`` found, as data."""

    frames: list = field(default_factory=list)
    structure: dict = field(default_factory=dict)
    min_psnr: float = DEFAULT_MIN_PSNR
    count: int = 0
    paths: tuple = ()

    @property
    def failing_frames(self) -> list:
        return [f for f in self.frames if f.diff.psnr < self.min_psnr]

    @property
    def drifted(self) -> list:
        return [g for g in self.structure.values() if g.unexplained]

    @property
    def passed(self) -> bool:
        return not self.failing_frames and not self.drifted

    def as_dict(self) -> dict:
        worst = min(self.frames, key=lambda f: f.diff.psnr) if self.frames else None
        return {
            "paths": list(self.paths),
            "count": self.count,
            "min_psnr": self.min_psnr,
            "passed": self.passed,
            "structure": {g.group: {"max_abs_error": g.max_abs_error, "max_rel_error": g.max_rel_error,
                                    "rmse": g.rmse, "unexplained": g.unexplained, "compared": g.compared,
                                    "ok": not g.unexplained} for g in self.structure.values()},
            "frames": [{**f.where(), **f.diff.as_dict()} for f in self.frames],
            "worst": None if worst is None else {**worst.where(), **worst.diff.as_dict()},
        }


def _read(path: str, color: str):
    """A scene, plus its texture when it is a .splatv (drawn as stored); one read."""
    stored = read_texture(path)
    if stored is not None:
        padded, scene = stored
        return scene, padded
    return read_scene(path, color=color), None


def verify(source_path, converted_path, *, times=None, cameras=None, size=None,
           min_psnr=DEFAULT_MIN_PSNR, tolerance=imgdiff.TOLERANCE, color="auto", keep_images=False,
           report_dir=None, force=False) -> Outcome:
    """Check CONVERTED against SOURCE by attributes and by rendered frames.

    Parameters
    ----------
    report_dir : path, optional
        Write each frame's images there (:func:`write_report_dir`). Checked before
        anything is drawn: an existing report file is an error unless ``force``.

    Returns
    -------
    Outcome
        ``passed`` is False when any frame is below ``min_psnr`` or any attribute
        drifted past what quantization explains.
    """
    min_psnr = check_min_psnr(min_psnr)
    times = DEFAULT_TIMES if times is None else parse_times(times) if isinstance(times, str) else times
    cameras = "all" if cameras is None else cameras
    size = cam.parse_size(size) if isinstance(size, str) else size
    source_path, converted_path = os.fspath(source_path), os.fspath(converted_path)
    source, _ = _read(source_path, color)
    converted, records = _read(converted_path, color)
    order = align(source, converted, source_path, converted_path)
    outcome = Outcome(min_psnr=min_psnr, count=source.count, paths=(source_path, converted_path))
    outcome.structure = compare_scenes(source, converted, order)

    cams = source.cameras or converted.cameras or [framing_camera(source.columns["x"], source.columns["y"],
                                                                  source.columns["z"])]
    views = frame_views(cams, parse_cameras(cameras, len(cams)) if isinstance(cameras, str) else cameras, size)
    if report_dir is not None:
        check_report_dir(report_dir, [(i, float(t)) for i, _ in views for t in times],
                         (source_path, converted_path), force)
        keep_images = True
    n_records = len(records) if records is not None else texture_height(source.count) * SPLATS_PER_ROW
    src_rows = _float_texels_padded(source, order, n_records)
    conv_rows = None if records is not None else _float_texels_padded(converted, None, n_records)
    for index, view in views:
        a = Renderer(view.width, view.height)
        b = Renderer(view.width, view.height, ctx=a.ctx)
        try:
            a.load_float(src_rows)
            b.load_records(records) if records is not None else b.load_float(conv_rows)
            for t in times:
                ia, ib = a.draw(view, float(t)), b.draw(view, float(t))
                d = imgdiff.compare(ia, ib, tolerance)
                outcome.frames.append(Frame(float(t), index, d, (ia, ib) if keep_images else ()))
        finally:
            b.release()
            a.release()
    if report_dir is not None:
        write_report_dir(outcome, report_dir, force)
    return outcome


def diff_scenes(path_a, path_b, *, times=(0.5,), cameras="0", size=None, min_psnr=DEFAULT_MIN_PSNR,
                tolerance=imgdiff.TOLERANCE, color="auto", reference=False) -> Outcome:
    """Draw two scene files the same way and compare the frames (no structure check)."""

    min_psnr = check_min_psnr(min_psnr)

    a_src = load(path_a, color=color, keep_scene=reference)
    b_src = load(path_b, color=color, keep_scene=reference)
    cams = a_src.cameras or b_src.cameras
    if not cams:
        x, y, z = (a_src.records[:, i].view(np.float32) for i in range(3))
        cams = [framing_camera(x, y, z)]
    views = frame_views(cams, parse_cameras(cameras, len(cams)), size)
    outcome = Outcome(min_psnr=min_psnr, paths=(os.fspath(path_a), os.fspath(path_b)))
    for index, view in views:
        ra = Renderer(view.width, view.height)
        rb = Renderer(view.width, view.height, ctx=ra.ctx)
        try:
            for r, s in ((ra, a_src), (rb, b_src)):
                if reference:
                    r.load_float(_float_texels_padded(s.scene, s.order, len(s.records)))
                else:
                    r.load_records(s.records)
            for t in times:
                ia, ib = ra.draw(view, float(t)), rb.draw(view, float(t))
                outcome.frames.append(Frame(float(t), index, imgdiff.compare(ia, ib, tolerance), (ia, ib)))
        finally:
            rb.release()
            ra.release()
    return outcome


#: The images saved per frame by ``--report-dir``, in file-name order of kinds.
REPORT_KINDS = ("source", "converted", "diff", "side_by_side")


def report_files(directory, camera: int, time: float) -> list:
    """The paths ``--report-dir`` writes for one frame."""
    stem = os.path.join(os.fspath(directory), f"cam{camera}_t{time:.3f}")
    return [f"{stem}_{kind}.png" for kind in REPORT_KINDS]


def check_report_dir(directory, frames, inputs=(), force: bool = False) -> None:
    """Refuse a report that would overwrite files, before anything is drawn or written.

    Parameters
    ----------
    frames : iterable of (int, float)
        (camera, time) of each frame to be saved.
    inputs : iterable of path
        Never written onto, even with ``force``.

    Raises
    ------
    OutputError
        The folder is a file, or a report file exists and ``force`` is False.
    UsageError
        Two frames would be saved under the same names (times equal to 3 decimals).
    """
    directory = os.fspath(directory)
    if os.path.exists(directory) and not os.path.isdir(directory):
        raise OutputError("is not a folder", directory)
    seen = {}
    for camera, t in frames:
        paths = report_files(directory, camera, t)
        if paths[0] in seen:
            raise UsageError(f"--report-dir: camera {camera} at t={seen[paths[0]]:g} and at t={t:g} would both be "
                             f"saved as {os.path.basename(paths[0])}; give cameras and times that differ "
                             f"(times in the first 3 decimals)")
        seen[paths[0]] = t
        if os.path.isdir(directory):
            for path in paths:
                check_output(path, inputs, force)


def write_report_dir(outcome: Outcome, directory, force: bool = False) -> list:
    """Save each frame's two images, heatmap and side-by-side; returns the paths.

    Each file is written atomically. Existing files are replaced only with
    ``force``; none is written when any would be refused.
    """
    directory = os.fspath(directory)
    frames = [f for f in outcome.frames if f.images]
    check_report_dir(directory, [(f.camera, f.time) for f in frames], outcome.paths, force)
    os.makedirs(directory, exist_ok=True)
    written = []
    for f in frames:
        a, b = f.images
        heat = imgdiff.heatmap(a, b)
        images = (a, b, heat, imgdiff.side_by_side(a, b, heat))
        for path, img in zip(report_files(directory, f.camera, f.time), images):
            with atomic_writer(path) as stream:
                imgdiff.save_png(img, stream)
            written.append(path)
    return written


__all__ = ["verify", "diff_scenes", "write_report_dir", "check_report_dir", "report_files", "parse_times",
           "parse_cameras", "check_min_psnr", "FLOAT_SPLATS_PER_ROW"]
