"""A self-contained player page: ``.html`` holding the player and the scene.

Write-only. The scene is packed as ``.splatv`` (the same writer and options) and
embedded as base64 in the page built by :mod:`splatconv.web.page`, so the file
plays opened from disk or from any static host. base64 makes the page 4/3 the
size of the ``.splatv``; ``splatconv convert --external`` writes the scene beside
the page instead (:func:`splatconv.web.publish.publish`).
"""

from __future__ import annotations

import io
import os

from ..errors import UnsupportedError
from ..model import Scene
from ..zstd import inner_name
from ..web.page import SceneRef, build_page
from . import splatv

NAME = "html"
SUFFIXES = (".html",)
CAN_READ = False
CAN_WRITE = True
COMPAT_MODES = ("splatv-js",)
DEFAULT_SORT = "importance"
#: The viewer cannot show an empty texture.
HOLDS_EMPTY = False
#: Holds motion and a temporal basis (the embedded ``.splatv``).
DYNAMIC = True
#: Not the texture itself: a page around it, which nothing here reads back.
STORES_TEXTURE = False
#: Several scenes given for one page play as the segments of one clip
#: (:func:`splatconv.web.publish.publish`), not as a frame sequence.
PLAYS_SEGMENTS = True


def read(path, **options) -> Scene:
    """Not supported: a page is a player, not a scene format."""
    raise UnsupportedError("an .html player page cannot be read as a scene (convert its .splatv instead)", path)


def write(scene: Scene, stream, *, compat: str | None = None, sort: str | None = None, name: str | None = None,
          **options):
    """Write the player page with ``scene`` embedded.

    Parameters
    ----------
    scene : Scene
    stream : binary file object
    compat, sort
        As for ``.splatv`` (the embedded texture is exactly what a ``.splatv``
        write would give).
    name : str, optional
        The page's file name: its stem titles the page and names the scene.

    Returns
    -------
    splatv.WriteReport
    """
    buffer = io.BytesIO()
    report = splatv.write(scene, buffer, compat=compat, sort=sort or DEFAULT_SORT, **options)
    stem = os.path.splitext(inner_name(name))[0] if name else ""
    title = {"title": stem} if stem else {}
    stream.write(build_page([SceneRef(name=stem or "scene", data=buffer.getvalue())], **title))
    return report


#: What the embedded ``.splatv`` stores.
storage = splatv.storage


def info_fields(scene: Scene) -> dict:
    return {}
