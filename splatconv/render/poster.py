"""A player page's poster: the page's first frame, drawn headlessly, as a JPEG.

The page opens at clip time 0 from its first segment's camera 0, at that
camera's focal lengths (:mod:`splatconv.publish` decides the rest). The poster
is that frame as ``render`` draws it at the camera's own size (scaled down to at
most :data:`POSTER_MAX_WIDTH` wide, fx and fy along), so the page can show it, at
the camera's size in CSS pixels, where the first WebGL frame will be.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass

from ..io import noting_undrawable
from . import camera as cam
from .frames import load, render_frames
from .preview import View

#: Widest poster, in pixels (a wider camera is scaled down, fx and fy along).
POSTER_MAX_WIDTH = 1280
#: JPEG quality of a poster: about 1 byte in 30 of a typical scene's page (a 1280x712 frame
#: of a 62,000-splat scene: 37 kB, its .splatv 4 MB).
POSTER_QUALITY = 80
#: The clip time the poster shows: where the page starts playing.
POSTER_TIME = 0.0


@dataclass(frozen=True)
class Poster:
    """A page's first frame.

    Attributes
    ----------
    jpeg : bytes
        The frame, RGB over black, baseline JPEG at :data:`POSTER_QUALITY`.
    width, height : int
        The JPEG's size in pixels.
    camera_width, camera_height : int
        The camera's own size, in the page's CSS pixels at its focal lengths.
    """

    jpeg: bytes
    width: int
    height: int
    camera_width: int
    camera_height: int


def draw_poster(path: str | os.PathLike) -> Poster | None:
    """The poster of a page whose first segment plays ``path`` (a scene file), or None when it has no camera.

    Without a camera the page's first view depends on the window, so no picture
    can stand in for it.

    Raises
    ------
    splatconv.render.gl.RenderUnavailable
        When no OpenGL context can be made.
    """
    with noting_undrawable(None):  # the page's own read already told of them
        source = load(path)
    if not source.cameras:
        return None
    camera = source.cameras[0]
    width, height, fx, fy = cam.fit(camera, None, POSTER_MAX_WIDTH)
    view = View(cam.view_matrix(camera), fx, fy, width, height)
    data = source.texture()
    del source
    (frame,) = list(render_frames(data, view, [POSTER_TIME]))
    from PIL import Image  # image files only: off convert's path

    out = io.BytesIO()
    Image.fromarray(frame[:, :, :3].copy(), "RGB").save(out, format="JPEG", quality=POSTER_QUALITY, optimize=True)
    return Poster(out.getvalue(), width, height, int(camera["width"]), int(camera["height"]))
