"""From scenes to drawn frames: load a file, choose the views, draw, compare (no CLI, no printing).

``render``, ``verify`` and ``diff`` all go through here: :func:`load` reads a
scene file once (with its stored texture when the format keeps the viewer's
texture), :func:`cameras_of` gives the cameras to draw from (a framing camera
when no file has any), :func:`render_frames` draws one scene and
:func:`compare_frames` draws two the same way and compares them frame by frame.
:func:`render_scene` draws an in-memory :class:`~splatconv.model.Scene`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import viewer
from ..cameras import framing_camera
from ..errors import UnsupportedError, UsageError
from ..formats import texture_format
from ..io import read as read_scene
from ..io import read_texture
from ..model import Scene
from ..progress import SILENT, Progress
from ..wording import plural
from . import camera as cam
from . import diff as imgdiff
from .layout import float_attributes, texture_records
from .preview import Renderer, View


@dataclass
class Source:
    """A scene ready to draw.

    Attributes
    ----------
    path : str
        Where it was read from (for messages).
    scene : Scene
        Its attributes, in file order.
    stored : (R, 16) uint32 ndarray or None
        The viewer's texture as the file stores it (padding records included),
        for formats that store it; None for the others.
    """

    path: str
    scene: Scene
    stored: np.ndarray | None = None

    @property
    def cameras(self) -> list:
        return list(self.scene.cameras or [])

    @property
    def records(self) -> int:
        """Records the viewer draws: the stored texture's, or those a conversion would write."""
        return len(self.stored) if self.stored is not None else texture_records(self.scene.count)

    def draw_order(self) -> np.ndarray | None:
        """Scene rows in texture order: None (file order) when stored, else the importance order."""
        if self.stored is not None:
            return None
        return viewer.importance_order(viewer.importance(self.scene.columns))

    def texture(self) -> np.ndarray:
        """What the viewer gets: the stored records, or the scene packed as ``convert`` writes it.

        Returns
        -------
        (R, 16) uint32 ndarray
        """
        if self.stored is not None:
            return self.stored
        records, _report = texture_format().texture.encode(self.scene)
        return records

    def load_into(self, renderer) -> None:
        """Load :meth:`texture` into ``renderer`` (:class:`~splatconv.render.preview.Renderer`): where it is
        packed here, a block at a time, never held whole (the renderer's copy is all there is of it)."""
        if self.stored is not None:
            renderer.load_records(self.stored)
            return

        def fill(put):
            texture_format().texture.pieces(self.scene, put)

        renderer.load_pieces(self.scene.count, fill)

    def reference(self, order: np.ndarray | None = None, records: int | None = None) -> np.ndarray:
        """Float reference rows (:func:`~splatconv.render.layout.float_attributes`).

        ``order`` defaults to :meth:`draw_order` and ``records`` to :attr:`records`,
        so the float path draws the splats in the texture's order and count.
        """
        return float_attributes(self.scene, self.draw_order() if order is None else order,
                                self.records if records is None else records)


def load(path: str | os.PathLike, *, color: str = "auto", progress: Progress = SILENT) -> Source:
    """Read any scene file for drawing, in one read (``progress``: told a ``.zst`` file's decompression).

    Raises
    ------
    UnsupportedError
        When a file that does not store the viewer's texture holds no splats (exit 1: the
        input, not the command, is at fault).
    """
    path = os.fspath(path)
    stored = read_texture(path, progress=progress)
    if stored is not None:
        padded, scene = stored
        return Source(path, scene, padded)
    scene = read_scene(path, color=color, progress=progress)
    if scene.count == 0:
        raise UnsupportedError("holds no splats to draw", path)
    return Source(path, scene)


def cameras_of(*sources: Source) -> list:
    """The first source's cameras that has any; else one camera framing the first scene."""
    for source in sources:
        if source.cameras:
            return source.cameras
    c = sources[0].scene.columns
    return [framing_camera(c["x"], c["y"], c["z"])]


def check_fit(fit: bool, fx: float | None, fy: float | None) -> None:
    """Refuse ``fit`` with ``fx`` or ``fy``: it scales the camera's focal lengths, they set them."""
    if fit and (fx is not None or fy is not None):
        raise UsageError("--fit scales the camera's fx and fy with --size; --fx and --fy set them: give one or "
                         "the other")


def resolve_view(cameras: list, *, camera: int | None = None, view: list | None = None,
                 size: tuple | None = None, fx: float | None = None, fy: float | None = None,
                 fit: bool = False, path: str | None = None) -> View:
    """``render``'s options as a :class:`View`.

    The camera (``camera``, default 0) gives the view matrix unless ``view`` is
    given, and the intrinsics. With no ``size``, the image is the camera's size
    scaled down to at most 1280 wide and fx, fy scale with it (see
    :func:`camera.fit`), so the preview frames what the camera saw. With an
    explicit ``size``, fx and fy stay the camera's, as in the viewer's window of
    that size (so a render at the viewer's window size draws what the viewer
    draws), unless ``fit``: then they scale by min(W / width, H / height), so the
    camera's whole view shows at ``size`` (letterboxed along the other side when
    the aspect ratios differ), as :func:`camera.fit` draws it for ``verify``.
    ``fx`` and ``fy`` replace either (not with ``fit``).

    Raises
    ------
    UsageError
        For a camera the file does not have, or ``fit`` with ``fx`` or ``fy``.
    """
    check_fit(fit, fx, fy)
    index = 0 if camera is None else camera
    if not 0 <= index < len(cameras):
        raise UsageError(f"--camera {index}: the file has {plural(len(cameras), 'camera')}, "
                         f"0..{len(cameras) - 1}", path)
    c = cameras[index]
    if size is None or fit:
        width, height, cfx, cfy = cam.fit(c, size)
    else:
        (width, height), cfx, cfy = size, float(c["fx"]), float(c["fy"])
    matrix = view if view is not None else cam.view_matrix(c)
    return View(matrix, fx if fx is not None else cfx, fy if fy is not None else cfy, width, height)


def frame_views(cameras: list, indices, size: tuple | None = None, max_width: int = cam.MAX_DEFAULT_WIDTH) -> list:
    """(camera index, View) for each chosen camera, as ``verify`` and ``diff`` draw them.

    The default size is the camera's scaled down to ``max_width``; fx and fy
    scale with the size (see :func:`camera.fit`): these compare what the camera saw.
    """
    views = []
    for i in indices:
        w, h, fx, fy = cam.fit(cameras[i], size, max_width)
        views.append((i, View(cam.view_matrix(cameras[i]), fx, fy, w, h)))
    return views


def render_frames(data: np.ndarray, view, times, *, progress: Progress = SILENT):
    """Draw ``data`` from ``view`` at each time, one frame at a time.

    Parameters
    ----------
    data : ndarray
        ``(R, 16) uint32`` texture records (:meth:`Source.texture`) or float
        reference rows (:meth:`Source.reference`).
    view : View or sequence of View
        One view for every frame, or one per time (a camera path), all one size.
    times : sequence of float

    Yields
    ------
    (H, W, 4) uint8 ndarray
        The framebuffer, top row first: premultiplied RGB and alpha. Close the
        generator (``contextlib.closing``) when not exhausting it, to free GL.
    """
    views = [view] * len(times) if isinstance(view, View) else list(view)
    if len(views) != len(times) or len({(v.width, v.height) for v in views}) > 1:
        raise ValueError("render_frames: one view, or one view per time, all one size")
    r = Renderer(views[0].width, views[0].height)
    try:
        r.load(data)
        del data
        with progress.stage("drawing", len(times), "frame") as advance:
            for v, t in zip(views, times):
                yield r.draw(v, float(t))
                advance()
    finally:
        r.release()


def render_scene(scene: Scene, view: View | dict, times, *, reference: bool = True,
                 size: tuple | None = None) -> np.ndarray:
    """Draw an in-memory scene with the viewer's shader maths.

    The splats are drawn in the order and number a ``.splatv`` conversion would
    hold (importance order, zero padding to whole texture rows), so the frames
    are those ``verify`` draws of a source file.

    Parameters
    ----------
    scene : Scene
        Any number of splats (none draws black frames).
    view : View or dict
        A :class:`View`, or a ``cameras.json`` camera drawn at its own size
        scaled down to at most 1280 wide (``size`` = (W, H) to choose; fx, fy
        scale with it, see :func:`camera.fit`).
    times : float or sequence of float
        Scene times (the viewer plays [0, 1]).
    reference : bool
        True (default): the float reference path, the attributes unquantized;
        False: the scene packed as the ``.splatv`` writer would (what the viewer
        shows of a conversion).

    Returns
    -------
    (T, H, W, 4) uint8 ndarray
        One frame per time: premultiplied RGB and alpha over black.
    """
    if isinstance(view, dict):
        width, height, fx, fy = cam.fit(view, size)
        view = View(cam.view_matrix(view), fx, fy, width, height)
    times = [float(times)] if np.ndim(times) == 0 else [float(t) for t in times]
    source = Source("<scene>", scene)
    data = source.reference() if reference or scene.count == 0 else source.texture()
    out = np.empty((len(times), view.height, view.width, 4), np.uint8)
    for i, image in enumerate(render_frames(data, view, times)):
        out[i] = image
    return out


@dataclass
class Frame:
    """One compared pair: a scene frame (time, camera) or, with ``names``, two image files."""

    time: float
    camera: int
    diff: imgdiff.ImageDiff
    names: tuple = ()

    def where(self) -> dict:
        """What was compared: ``{"a", "b"}`` image paths, or ``{"time", "camera"}``."""
        if self.names:
            return {"a": self.names[0], "b": self.names[1]}
        return {"time": self.time, "camera": self.camera}


def compare_frames(a, b, views: list, times, *, tolerance: int = imgdiff.TOLERANCE,
                   progress: Progress = SILENT, on_frame=None) -> list:
    """Draw two scenes from the same views at the same times and compare each pair.

    Parameters
    ----------
    a, b : callable
        Each returns what to draw (as for :func:`render_frames`); called once,
        and the array is dropped after upload, so it need not outlive it.
    views : list of (int, View)
        From :func:`frame_views`.
    times : sequence of float
    on_frame : callable, optional
        ``on_frame(frame, image_a, image_b)`` for each pair as it is drawn (to
        save it); no image is kept here, so memory does not grow with the
        number of frames.

    Returns
    -------
    list of Frame
        Camera-major: every time of the first view, then the next view.
    """
    if not views:
        return []
    first = views[0][1]
    ra = Renderer(first.width, first.height)
    rb = Renderer(first.width, first.height, ctx=ra.ctx)
    frames = []
    try:
        ra.load(a())
        rb.load(b())
        # The depth order depends only on the positions and the view: with the same
        # position bits (a faithful conversion) one sort serves both frames.
        shared = np.array_equal(ra.positions.view(np.uint32), rb.positions.view(np.uint32))
        with progress.stage("drawing", len(views) * len(times), "frame") as advance:
            for index, view in views:
                for t in times:
                    ia = ra.draw(view, float(t))
                    ib = rb.draw(view, float(t), order=ra.last_order if shared else None)
                    frame = Frame(float(t), index, imgdiff.compare(ia, ib, tolerance))
                    frames.append(frame)
                    if on_frame is not None:
                        on_frame(frame, ia, ib)
                    advance()
    finally:
        rb.release()
        ra.release()
    return frames
