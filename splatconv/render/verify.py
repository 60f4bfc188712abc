"""``verify`` and ``diff``: prove a conversion by attributes and by pixels.

``verify`` checks that every attribute of CONVERTED differs from SOURCE only by
what quantization explains, then draws SOURCE through the float reference path
(its attributes as float32, no quantization) and CONVERTED as stored (a stored
texture as the viewer gets it; other files' attributes), with the same cameras,
times and splat order, and compares the frames. ``diff`` draws two scene files
the same way (both as the viewer would get them, or both unquantized) and
compares the frames. Both return an :class:`Outcome` (data; text and JSON are
:mod:`splatconv.text`'s).
"""

from __future__ import annotations

import contextlib
import math
import os
from dataclasses import dataclass, field

from ..compare import compare_scenes, pair
from ..errors import OutputError, UsageError
from ..files.output import atomic_group, check_output
from ..formats import format_for, texture_format
from ..io import holding
from ..progress import SILENT, Progress
from ..wording import plural
from . import camera as cam
from . import diff as imgdiff
from .frames import Frame, cameras_of, compare_frames, frame_views, load
from .layout import float_attributes
from . import proof as proving

#: Version of the JSON that :meth:`Outcome.as_dict` gives (``"schema": "splatconv.verify/1"``).
SCHEMA_VERSION = 1
DEFAULT_TIMES = (0.0, 0.25, 0.5, 0.75, 1.0)
DEFAULT_MIN_PSNR = 40.0
#: verify draws this many cameras (the first ones) unless ``--cameras`` says otherwise:
#: a header may list hundreds of thousands.
DEFAULT_CAMERAS = 8
#: verify's and diff's default image width: big enough to see damage, quick on a CPU.
VERIFY_MAX_WIDTH = 640
#: diff's frames for two scene files: one quick frame, t = 0.5 from camera 0.
DIFF_TIMES = (0.5,)
DIFF_CAMERAS = 1
#: Bytes a splat of either file takes at the peak of ``verify`` (both scenes, the pairing, the
#: float reference rows and the stored texture, the renderer's copies) and of ``diff`` of scene
#: files (both scenes and both textures, or with ``--reference`` both sets of float rows):
#: what the decompression ceiling counts (:func:`splatconv.io.holding`;
#: ``bench/bench_memory.py`` measures 222 and 329).
VERIFY_MEMORY_BYTES = 240
DIFF_MEMORY_BYTES = 352


def parse_times(text: str) -> list:
    """``--times`` value: comma-separated finite numbers."""
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


def parse_cameras(text: str | None) -> list | str | None:
    """``--cameras`` value checked for form before any file is read.

    Returns None (the default), ``"all"``, or a list of indices for
    :func:`pick_cameras` to check against the cameras there are.
    """
    if text is None or text == "all":
        return text
    try:
        return [int(c) for c in text.split(",")]
    except ValueError:
        raise UsageError(f"--cameras: expected 'all' or comma-separated indices, got {text!r}") from None


def pick_cameras(picked: list | str | None, available: int, first: int = DEFAULT_CAMERAS) -> list:
    """Indices of the cameras to draw: ``picked`` from :func:`parse_cameras`; None: the first ``first``."""
    if picked is None:
        return list(range(min(first, available)))
    if picked == "all":
        return list(range(available))
    bad = [c for c in picked if not 0 <= c < available]
    if bad:
        there = "there is 1 (0)" if available == 1 else f"there are {available:,} (0..{available - 1})"
        raise UsageError(f"--cameras: no camera {bad[0]}; {there}")
    return picked


def _times(times, default) -> list:
    if times is None:
        return list(default)
    if isinstance(times, str):
        return parse_times(times)
    return [float(t) for t in times]


@dataclass
class Outcome:
    """Everything ``verify`` or ``diff`` found, as data.

    Attributes
    ----------
    command : {"verify", "diff"}
    attributes : dict of str to compare.GroupError, or None
        verify's attribute check, by group; None for diff.
    count : int or None
        Splats compared (verify).
    notes : list of str
        What was drawn that a user may not expect (fewer cameras than the file has).
    """

    command: str
    paths: tuple = ()
    min_psnr: float = DEFAULT_MIN_PSNR
    frames: list = field(default_factory=list)
    attributes: dict | None = None
    count: int | None = None
    notes: list = field(default_factory=list)

    @property
    def failing_frames(self) -> list:
        return [f for f in self.frames if f.diff.psnr < self.min_psnr]

    @property
    def drifted(self) -> list:
        return [g for g in (self.attributes or {}).values() if g.unexplained]

    @property
    def passed(self) -> bool:
        return not self.failing_frames and not self.drifted

    @property
    def worst(self) -> Frame | None:
        """The frame of lowest PSNR (the first of equals)."""
        return min(self.frames, key=lambda f: f.diff.psnr) if self.frames else None

    def as_dict(self) -> dict:
        """The JSON form (``specs/json.md``): a ``schema`` key first, then the findings."""
        out = {"schema": f"splatconv.{self.command}/{SCHEMA_VERSION}", "paths": list(self.paths)}
        if self.count is not None:
            out["count"] = self.count
        out["min_psnr"] = self.min_psnr
        out["passed"] = self.passed
        if self.attributes is not None:
            out["attributes"] = {g.group: {
                "max_abs_error": g.max_abs_error, "max_rel_error": g.max_rel_error, "rmse": g.rmse,
                "unexplained": g.unexplained, "became_infinite": g.became_infinite,
                "nonfinite_changed": g.nonfinite_changed, "nan_stored": g.nan_stored,
                "compared": g.compared, "values": g.values, "storage": g.storage, "ok": not g.unexplained,
            } for g in self.attributes.values()}
        worst = self.worst
        out["frames"] = [{**f.where(), **f.diff.as_dict()} for f in self.frames]
        out["worst"] = None if worst is None else {**worst.where(), **worst.diff.as_dict()}
        out["notes"] = list(self.notes)
        return out


def _request(min_psnr, times, default_times, cameras, size) -> tuple:
    """The checked threshold, times, camera pick and image size of a comparison."""
    size = cam.parse_size(size) if isinstance(size, str) else size
    return check_min_psnr(min_psnr), _times(times, default_times), parse_cameras(cameras), size


def _load_pair(paths: tuple, color: str, progress: Progress, each: int) -> list:
    """Both files of a comparison, loaded for drawing, with a "reading" stage (``each``: the bytes a splat
    read takes at the command's peak, :func:`splatconv.io.holding`)."""
    loaded = []
    with progress.stage("reading", 2, "file") as advance, holding(each):
        for path in paths:
            loaded.append(load(path, color=color, progress=progress))
            advance()
    return loaded


def verify(source_path, converted_path, *, times=None, cameras: str | None = None, size=None,
           min_psnr: float = DEFAULT_MIN_PSNR, tolerance: int = imgdiff.TOLERANCE, color: str = "auto",
           report_dir=None, force: bool = False, proof: bool = False, progress: Progress = SILENT) -> Outcome:
    """Check CONVERTED against SOURCE by attributes and by rendered frames.

    Parameters
    ----------
    times : sequence of float or str, optional
        Scene times (default :data:`DEFAULT_TIMES`); a string is ``--times``.
    cameras : str, optional
        ``"all"`` or comma-separated indices; default the first
        :data:`DEFAULT_CAMERAS` (a note says so when the file has more).
    size : (int, int) or str, optional
        Image size; default each camera's, scaled down to :data:`VERIFY_MAX_WIDTH`.
    report_dir : path, optional
        Save each frame's images there as it is drawn (:func:`report_files`),
        all or nothing: on any error no report file is left, nor the folder if
        this run made it. Checked before anything is drawn: an existing report
        file is an error unless ``force``.
    proof : bool
        Draw the frames ``convert --min-psnr`` proves a compressed file by
        (:mod:`splatconv.render.proof`: its views, numbered in a note, and times),
        both files as the viewer draws them, instead of ``times``, ``cameras`` and
        ``size`` (refused with it): the worst frame is the one ``convert`` printed.
    progress : Progress
        Receives the stages "reading", "checking attributes" and "drawing".

    Returns
    -------
    Outcome
        ``passed`` is False when any frame is below ``min_psnr`` or any attribute
        drifted past what quantization explains. No image is kept: memory does
        not grow with the number of frames.
    """
    if proof and (times is not None or cameras is not None or size is not None):
        raise UsageError("--proof draws the views and times convert --min-psnr proves by: no --times, "
                         "--cameras or --size with it")
    min_psnr, times, picked, size = _request(min_psnr, times, DEFAULT_TIMES, cameras, size)
    paths = os.fspath(source_path), os.fspath(converted_path)
    source, converted = _load_pair(paths, color, progress, VERIFY_MEMORY_BYTES)
    with progress.stage("checking attributes", 2, "step") as advance:
        # Ties between a writer's orders are broken as the viewer's texture would store the values.
        storage = format_for(paths[1]).storage(converted.scene)
        order, paired = pair(source.scene, converted.scene, *paths,
                             storage=texture_format().storage(converted.scene),
                             colour_kept=storage["color"] != "quantized")
        advance()
        attributes = compare_scenes(source.scene, converted.scene, order, storage)
        advance()
    outcome = Outcome("verify", paths, min_psnr, attributes=attributes, count=len(order), notes=paired)
    if proof:
        named, times = proving.proof_plan(source.scene)
        views = [(i, view) for i, (_name, view) in enumerate(named)]
        times = list(times)
        outcome.notes.append("drew the views convert --min-psnr proves by, as the viewer draws both files: "
                             + "; ".join(f"camera {i}: {name}" for i, (name, _view) in enumerate(named)))
    else:
        available = cameras_of(source, converted)
        indices = pick_cameras(picked, len(available))
        if cameras is None and len(available) > len(indices):
            outcome.notes.append(f"drew the first {len(indices)} of {plural(len(available), 'camera')} "
                                 f"(--cameras all draws every one)")
        views = frame_views(available, indices, size, VERIFY_MAX_WIDTH)
    if report_dir is not None:
        check_report_dir(report_dir, [(i, t) for i, _ in views for t in times], paths, force)
    records = converted.records

    # Each callable drops its scene once the rows are built: nothing but the GL
    # textures is needed while drawing, so the scenes' memory goes back first.
    def source_data():
        nonlocal source
        rows = source.texture() if proof else float_attributes(source.scene, order, records)
        source = None
        return rows

    def converted_data():
        nonlocal converted
        data = (converted.texture() if proof else converted.stored if converted.stored is not None
                else float_attributes(converted.scene, None, records))
        converted = None
        return data

    with _report(report_dir, force) as group:
        def on_frame(frame, a, b):
            save_report_frame(report_dir, frame, a, b, paths, force, group=group)

        outcome.frames = compare_frames(source_data, converted_data, views, times, tolerance=tolerance,
                                        progress=progress, on_frame=on_frame if group is not None else None)
    return outcome


@contextlib.contextmanager
def _report(directory, force: bool):
    """The group a report's files are written through (None: no report), all or nothing.

    A full disk part way once left the frames already saved: now every file waits
    beside its name until the last frame is drawn, and on any error all go, with
    the folder if this run made it.
    """
    if directory is None:
        yield None
        return
    directory = os.fspath(directory)
    made = not os.path.exists(directory)
    os.makedirs(directory, exist_ok=True)
    try:
        with atomic_group(replace=force) as group:
            yield group
    except BaseException:
        if made:
            with contextlib.suppress(OSError):
                os.rmdir(directory)  # only when empty: nothing but this run's files was there
        raise


def diff_scenes(path_a, path_b, *, times=None, cameras: str | None = None, size=None,
                min_psnr: float = DEFAULT_MIN_PSNR, tolerance: int = imgdiff.TOLERANCE, color: str = "auto",
                reference: bool = False, progress: Progress = SILENT, on_frame=None) -> Outcome:
    """Draw two scene files the same way and compare the frames (no attribute check).

    Each is drawn as the viewer would get it (a stored texture, or the scene
    packed as ``convert`` writes it) or, with ``reference``, unquantized; at
    ``times`` (default :data:`DIFF_TIMES`) from ``cameras`` (default camera 0).
    ``on_frame(frame, image_a, image_b)`` sees each pair as it is drawn.
    """
    min_psnr, times, picked, size = _request(min_psnr, times, DIFF_TIMES, cameras, size)
    paths = os.fspath(path_a), os.fspath(path_b)
    a, b = _load_pair(paths, color, progress, DIFF_MEMORY_BYTES)
    available = cameras_of(a, b)
    views = frame_views(available, pick_cameras(picked, len(available), DIFF_CAMERAS), size, VERIFY_MAX_WIDTH)
    outcome = Outcome("diff", paths, min_psnr)
    if reference:
        data_a, data_b = a.reference, b.reference
    else:
        data_a, data_b = a.texture, b.texture
    outcome.frames = compare_frames(data_a, data_b, views, times, tolerance=tolerance, progress=progress,
                                    on_frame=on_frame)
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


def save_report_frame(directory, frame: Frame, a, b, inputs=(), force: bool = False, *, group) -> list:
    """Save one frame's two images, heatmap and side-by-side picture through ``group``; returns the paths.

    ``group`` (:func:`splatconv.files.atomic_group`) puts them in place when it
    ends; an existing file is replaced only with ``force``.
    """
    heat = imgdiff.heatmap(a, b)
    written = []
    for path, img in zip(report_files(directory, frame.camera, frame.time),
                         (a, b, heat, imgdiff.side_by_side(a, b, heat))):
        check_output(path, inputs, force)
        with group.open(path) as stream:
            imgdiff.save_png(img, stream)
        written.append(path)
    return written
