"""File-level entry points behind ``render`` and ``diff``: check the options, draw, write the output.

``verify`` needs no more than :func:`splatconv.render.verify.verify`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os

import numpy as np

from ..errors import UsageError
from ..files.output import atomic_writer, check_output
from ..io import holding
from ..progress import SILENT, Progress
from ..wording import plural
from . import camera as cam
from . import diff as imgdiff
from . import images
from . import paths
from . import video
from .frames import Frame, cameras_of, check_fit, load, render_frames, resolve_view
from .verify import DEFAULT_MIN_PSNR, Outcome, check_min_psnr, diff_scenes


#: Scene time ``render`` draws when not told: the middle of the viewer's clip.
DEFAULT_TIME = 0.5
#: Most frames one ``render`` sweeps over [0, 1].
MAX_FRAMES = 1000
#: Bytes a splat takes at the peak of ``render`` (the scene, the texture or float rows drawn, the
#: renderer's copies): what the decompression ceiling counts (:func:`splatconv.io.holding`;
#: ``bench/bench_memory.py`` measures 340, 397 with ``--reference``).
RENDER_MEMORY_BYTES = 416


def render_file(input_path, output_path, *, time: float = DEFAULT_TIME, camera: int | None = None,
                view: str | None = None, size: str | None = None, fx: float | None = None, fy: float | None = None,
                frames: int = 1, reference: bool = False, color: str = "auto", force: bool = False,
                fit: bool = False, fps: float | None = None, orbit: float | None = None, path: str | None = None,
                progress: Progress = SILENT) -> str:
    """Render a scene file to an image or video file; returns a one-line summary of what was written.

    Parameters mirror ``splatconv render``; ``view``, ``size`` and ``path`` are
    the option strings (a JSON list, ``WxH``, ``A,B``). ``size`` is each frame's
    size: a contact sheet of several frames is larger, and the summary gives its
    size. ``fit`` scales the camera's focal lengths with ``size`` so that its
    whole view shows (:func:`splatconv.render.frames.resolve_view`). Several
    ``frames`` sweep t over [0, 1] (frame k at k / (frames - 1)) and are drawn
    and written one at a time (a ``.gif`` or ``.webp`` keeps them all: its
    writer takes them at once), ``fps`` a second for an animation or video.
    ``orbit`` turns the camera by that many degrees over the sweep about the
    scene's centre (:func:`splatconv.render.paths.orbit_path`); ``path`` moves
    from one header camera to another (:func:`splatconv.render.paths.camera_path`).
    A video with no ``size`` loses a pixel row or column where the camera's size is odd.
    """
    output_path = os.fspath(output_path)
    if not 1 <= frames <= MAX_FRAMES:
        raise UsageError(f"--frames: expected 1 to {MAX_FRAMES}, got {frames}")
    suffix = os.path.splitext(output_path)[1].lower()
    moving = images.ANIMATED + video.VIDEO
    allowed = images.STILL + (moving if frames > 1 else ())
    if suffix not in allowed:
        raise UsageError(f"cannot write {suffix or 'a file without extension'}: use "
                         + ", ".join(allowed) + ("" if frames > 1 else f" (or --frames N with {', '.join(moving)})"),
                         output_path)
    matrix = cam.parse_view(view) if view is not None else None
    dims = cam.parse_size(size) if size is not None else None
    ends = _check_moves(orbit, path, camera, view, frames)
    if fps is not None and suffix not in moving:
        raise UsageError(f"--fps sets the rate of an animation or a video ({', '.join(moving)})", output_path)
    if suffix in video.VIDEO:  # before the read: a missing encoder or an odd --size fails at once
        codec = video.check_video(suffix, *(dims or (None, None)), fps=video.DEFAULT_FPS if fps is None else fps)
    if not math.isfinite(time):
        raise UsageError(f"--time: expected a finite number, got {time}")
    for name, value in (("--fx", fx), ("--fy", fy)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise UsageError(f"{name} must be a positive number")
    check_fit(fit, fx, fy)  # before the read
    check_output(output_path, [input_path], force)
    with progress.stage("reading", 1, "file") as advance, holding(RENDER_MEMORY_BYTES):
        source = load(input_path, color=color, progress=progress)
        advance()
    cameras = cameras_of(source)
    v = resolve_view(cameras, camera=camera, view=matrix, size=dims, fx=fx, fy=fy, fit=fit, path=source.path)
    times = [time] if frames == 1 else paths.shares(frames)
    views = v
    if orbit is not None or ends is not None:
        moved = (paths.orbit_path(cameras[camera or 0], paths.scene_centre(source.scene), orbit, frames)
                 if orbit is not None else paths.camera_path(*_path_cameras(cameras, ends, path, source.path), frames))
        views = [resolve_view([c], size=dims, fx=fx, fy=fy, fit=fit) for c in moved]
        v = views[0]
    rounded = ""
    if suffix in video.VIDEO and (v.width, v.height) != video.even_size(v.width, v.height):
        # Only a size taken from the camera can be odd here (an odd --size was refused).
        even = video.even_size(v.width, v.height)
        rounded = f" (the camera's {v.width}x{v.height} rounded down to even for {codec.name})"
        v = dataclasses.replace(v, width=even[0], height=even[1])
        views = [dataclasses.replace(x, width=even[0], height=even[1]) for x in views] if isinstance(views, list) else v
    if frames > 1 and suffix in images.STILL:
        cols, rows = images.sheet_grid(frames)
        if max(cols * v.width, rows * v.height) > cam.MAX_IMAGE_SIDE:
            raise UsageError(f"--frames {frames} of {v.width}x{v.height} make a {cols * v.width}x{rows * v.height} "
                             f"contact sheet, over {cam.MAX_IMAGE_SIDE:,} pixels a side: use fewer frames, a "
                             f"smaller --size, or .gif / .webp", output_path)
    data = source.reference() if reference else source.texture()
    del source
    with contextlib.closing(render_frames(data, views, times, progress=progress)) as drawn:
        del data
        with atomic_writer(output_path) as stream:
            if suffix in video.VIDEO:
                rate = video.DEFAULT_FPS if fps is None else fps
                count = video.write_video(drawn, stream, suffix, rate)
                return (f"wrote {output_path}: {v.width}x{v.height}{rounded} {codec.name}, {count} frames over "
                        f"t=0..1 at {rate:g} fps")
            width, height = images.save(drawn, times, stream, suffix,
                                        **({} if fps is None else {"fps": fps}))
    if len(times) == 1:
        return f"wrote {output_path}: {width}x{height}, t={time:g}"
    if suffix in images.STILL:
        return (f"wrote {output_path}: {width}x{height} contact sheet of {len(times)} frames "
                f"({v.width}x{v.height} each) over t=0..1")
    return f"wrote {output_path}: {width}x{height}, {len(times)} frames over t=0..1"


def _check_moves(orbit: float | None, path: str | None, camera: int | None, view: str | None,
                 frames: int) -> tuple | None:
    """Check ``--orbit`` and ``--path`` against the other options; ``path``'s two camera indices, or None."""
    if orbit is None and path is None:
        return None
    given = "--orbit" if path is None else "--path"
    if orbit is not None and path is not None:
        raise UsageError("--orbit and --path cannot be used together")
    if frames < 2:
        raise UsageError(f"{given} moves the camera over a sweep: give --frames N (2 or more)")
    if view is not None:
        raise UsageError(f"{given} moves a header camera: not with --view")
    if orbit is not None:
        if not math.isfinite(orbit):
            raise UsageError(f"--orbit: expected a finite number of degrees, got {orbit}")
        return None
    if camera is not None:
        raise UsageError("--path A,B names its cameras: not with --camera")
    parts = path.split(",")
    if len(parts) != 2 or not all(p.strip().isdigit() and len(p.strip()) < 10 for p in parts):
        raise UsageError(f"--path: expected two camera indices A,B, got {path!r}")
    return int(parts[0]), int(parts[1])


def _path_cameras(cameras: list, ends: tuple, path: str, where: str) -> tuple:
    """The two cameras ``--path`` names, refusing an index the file does not have."""
    for index in ends:
        if index >= len(cameras):
            raise UsageError(f"--path {path}: the file has {plural(len(cameras), 'camera')}, "
                             f"0..{len(cameras) - 1}", where)
    return cameras[ends[0]], cameras[ends[1]]


def diff_files(a, b, *, size: str | None = None, cameras: str | None = None, times: str | None = None,
               min_psnr: float = DEFAULT_MIN_PSNR, color: str = "auto", out=None, reference: bool = False,
               force: bool = False, progress: Progress = SILENT) -> Outcome:
    """Compare two images, or two scene files drawn the same way; optionally write a heatmap.

    Scene files are drawn at ``times`` (default 0.5) from ``cameras`` (default
    camera 0): one frame, unlike ``verify``'s five times from several cameras
    (see :func:`splatconv.render.verify.diff_scenes`). Two images give one frame
    named by the two paths (no time or camera). ``out`` receives a heatmap of
    the worst frame; only that frame's images are kept while drawing.

    Returns
    -------
    Outcome
    """
    a, b = os.fspath(a), os.fspath(b)
    min_psnr = check_min_psnr(DEFAULT_MIN_PSNR if min_psnr is None else min_psnr)
    if out is not None:
        if not os.fspath(out).lower().endswith(".png"):
            raise UsageError("--out must be a .png file", out)
        check_output(out, [a, b], force)
    kinds = imgdiff.is_image(a), imgdiff.is_image(b)
    if kinds[0] != kinds[1]:
        raise UsageError("compare two images or two scene files, not one of each")
    worst = []
    if kinds[0]:
        if size or cameras or times or reference:
            raise UsageError("--size, --cameras, --times and --reference apply to scene files, not images")
        ia, ib = imgdiff.load_image(a), imgdiff.load_image(b)
        outcome = Outcome("diff", (a, b), min_psnr)
        outcome.frames.append(Frame(0.0, 0, imgdiff.compare(ia, ib), names=(a, b)))
        worst.append((outcome.frames[0], (ia, ib)))
    else:
        def keep_worst(frame, ia, ib):
            if not worst or frame.diff.psnr < worst[0][0].diff.psnr:
                worst[:] = [(frame, (ia, ib))]

        outcome = diff_scenes(a, b, times=times, cameras=cameras, size=size, min_psnr=min_psnr, color=color,
                              reference=reference, progress=progress, on_frame=keep_worst if out else None)
    if out is not None:
        frame, pair = worst[0]
        heat = imgdiff.heatmap(*pair)
        with atomic_writer(out) as stream:
            imgdiff.save_png(heat, stream)
        of = "" if frame.names else f" (t={frame.time:g}, camera {frame.camera}, the worst frame)"
        outcome.notes.append(f"wrote {os.fspath(out)}: difference heatmap{of}, {heat.shape[1]}x{heat.shape[0]}, "
                             f"{os.path.getsize(out):,} bytes")
    return outcome
