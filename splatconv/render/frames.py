"""From a scene file and camera options to rendered frames (no CLI, no printing)."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import viewer
from ..cameras import framing_camera
from ..errors import UsageError
from ..formats import splatv
from ..io import read as read_scene
from ..io import read_texture
from . import camera as cam
from .preview import FrameTimes, Renderer, View, float_attributes


@dataclass
class Source:
    """A scene ready to draw: its texture records, cameras and (lazily) float attributes."""

    path: str
    records: np.ndarray
    cameras: list
    scene: object = None
    order: np.ndarray = None

    def float_texels(self) -> np.ndarray:
        """Float reference attributes in the same splat order as ``records``."""
        if self.scene is None:
            raise UsageError("the float reference path needs a scene read from its attributes", self.path)
        return float_attributes(self.scene, self.order)


def load(path: str | os.PathLike, *, color: str = "auto", keep_scene: bool = False) -> Source:
    """Read any scene file for drawing.

    A ``.splatv`` is drawn from its stored records; a PLY is packed in memory the
    way ``convert`` would write it (default writer, importance order).
    """
    path = os.fspath(path)
    stored = read_texture(path)
    if stored is not None:
        padded, scene = stored
        return Source(path, padded, list(scene.cameras), scene if keep_scene else None, None)
    scene = read_scene(path, color=color)
    if scene.count == 0:
        raise UsageError("holds no splats to draw", path)
    order = viewer.importance_order(viewer.importance(scene.columns))
    records, _report = splatv.encode(scene)
    return Source(path, records, list(scene.cameras or []), scene if keep_scene else None, order)


def resolve_view(source: Source, *, camera: int | None = None, view: list | None = None,
                 size: tuple | None = None, fx: float | None = None, fy: float | None = None) -> View:
    """Turn the render options into a :class:`View`.

    The camera (``--camera I``, default 0; a framing camera when the file has none)
    gives the view matrix unless ``view`` is given, and the intrinsics. With no
    ``size``, the image is the camera's size scaled down to at most 1280 wide and
    fx, fy scale with it (see :func:`camera.fit`), so the preview frames what the
    camera saw. With an explicit ``size``, fx and fy stay the camera's, as in the
    viewer's window of that size (so a render at the viewer's window size draws
    what the viewer draws). ``fx`` and ``fy`` replace either.
    """
    cameras = source.cameras
    if not cameras:
        x, y, z = (source.records[:, i].view(np.float32) for i in range(3))
        cameras = [framing_camera(x, y, z)]
    index = 0 if camera is None else camera
    if not 0 <= index < len(cameras):
        raise UsageError(f"--camera {index}: the file has {len(cameras)} camera(s), 0..{len(cameras) - 1}",
                         source.path)
    c = cameras[index]
    if size is None:
        width, height, cfx, cfy = cam.fit(c)
    else:
        (width, height), cfx, cfy = size, float(c["fx"]), float(c["fy"])
    matrix = view if view is not None else cam.view_matrix(c)
    return View(matrix, fx if fx is not None else cfx, fy if fy is not None else cfy, width, height)


def render_frames(source: Source, view: View, times, *, reference: bool = False,
                  renderer: Renderer | None = None):
    """Draw ``source`` at each time.

    Parameters
    ----------
    reference : bool
        Use the float reference path (unquantized attributes) instead of the texture.

    Returns
    -------
    frames : list of (H, W, 4) uint8 ndarray
    times : list of FrameTimes
    """
    own = renderer is None
    r = renderer or Renderer(view.width, view.height)
    try:
        if reference:
            r.load_float(source.float_texels())
        else:
            r.load_records(source.records)
        frames, stats = [], []
        for t in times:
            ft = FrameTimes()
            frames.append(r.draw(view, float(t), ft))
            stats.append(ft)
        return frames, stats
    finally:
        if own:
            r.release()
