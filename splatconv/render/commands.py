"""Library entry points behind the ``render`` command."""

from __future__ import annotations

import math
import os

import numpy as np
from PIL import Image

from ..errors import UsageError
from ..fsutil import atomic_writer, check_output
from . import camera as cam
from . import diff as imgdiff
from . import images
from .frames import load, render_frames, resolve_view
from .verify import DEFAULT_MIN_PSNR, Frame, Outcome, check_min_psnr, diff_scenes, parse_times


#: ``diff``'s frames for two scene files: one quick frame (``verify`` draws more).
DIFF_TIMES = (0.5,)
DIFF_CAMERAS = "0"


def render_file(input_path, output_path, *, time=0.5, camera=None, view=None, size=None, fx=None, fy=None,
                frames=1, reference=False, color="auto", force=False) -> str:
    """Render a scene file to an image file; returns a one-line summary.

    Parameters mirror ``splatconv render``; ``view`` and ``size`` are the option
    strings (a JSON list, ``WxH``).
    """
    output_path = os.fspath(output_path)
    suffix = os.path.splitext(output_path)[1].lower()
    allowed = images.STILL + (images.ANIMATED if frames > 1 else ())
    if suffix not in allowed:
        raise UsageError(f"cannot write {suffix or 'a file without extension'}: use "
                         + ", ".join(allowed) + ("" if frames > 1 else " (or --frames N with .gif, .webp)"),
                         output_path)
    matrix = cam.parse_view(view) if view is not None else None
    dims = cam.parse_size(size) if size is not None else None
    if not math.isfinite(time):
        raise UsageError(f"--time: expected a finite number, got {time}")
    for name, value in (("--fx", fx), ("--fy", fy)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise UsageError(f"{name} must be a positive number")
    check_output(output_path, [input_path], force)
    source = load(input_path, color=color, keep_scene=reference)
    v = resolve_view(source, camera=camera, view=matrix, size=dims, fx=fx, fy=fy)
    times = [time] if frames == 1 else list(np.linspace(0.0, 1.0, frames))
    rendered, _stats = render_frames(source, v, times, reference=reference)
    with atomic_writer(output_path) as stream:
        images.save(rendered, times, stream, suffix)
    what = f"{len(times)} frames" if len(times) > 1 else f"t={time:g}"
    return f"wrote {output_path}: {v.width}x{v.height}, {what}"


def diff_files(a, b, *, size=None, cameras=None, times=None, min_psnr=40.0, color="auto", out=None,
               reference=False, force=False):
    """Compare two images, or two scene files drawn the same way; optionally write a heatmap.

    Scene files are drawn at ``times`` (default 0.5) from ``cameras`` (default
    ``"0"``): one frame, unlike ``verify``'s five times from every camera. Two
    images give one frame named by the two paths (no time or camera).

    Returns
    -------
    verify.Outcome
    """

    a, b = os.fspath(a), os.fspath(b)
    min_psnr = check_min_psnr(DEFAULT_MIN_PSNR if min_psnr is None else min_psnr)
    if out is not None:
        if not os.fspath(out).lower().endswith(".png"):
            raise UsageError("--out must be a .png file", out)
        check_output(out, [a, b], force)
    images = imgdiff.is_image(a), imgdiff.is_image(b)
    if images[0] != images[1]:
        raise UsageError("compare two images or two scene files, not one of each")
    if images[0]:
        if size or cameras or times or reference:
            raise UsageError("--size, --cameras, --times and --reference apply to scene files, not images")
        ia, ib = imgdiff.load_image(a), imgdiff.load_image(b)
        outcome = Outcome(min_psnr=min_psnr, paths=(a, b))
        outcome.frames.append(Frame(0.0, 0, imgdiff.compare(ia, ib), (ia, ib), names=(a, b)))
    else:
        outcome = diff_scenes(a, b, times=parse_times(times) if times else DIFF_TIMES,
                              cameras=cameras or DIFF_CAMERAS, size=cam.parse_size(size) if size else None,
                              min_psnr=min_psnr, color=color, reference=reference)
    if out is not None:
        worst = min(outcome.frames, key=lambda f: f.diff.psnr)
        with atomic_writer(out) as stream:

            Image.fromarray(imgdiff.heatmap(*worst.images), "RGB").save(stream, format="PNG")
    return outcome
