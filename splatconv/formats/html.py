"""A self-contained player page: ``.html`` holding the player and the scene.

Write-only. The scene is packed as ``.splatv`` (the same writer and options) and
embedded as base64 in the page built by :mod:`splatconv.web.page`, so the file
plays opened from disk or from any static host. base64 makes the page 4/3 the
size of the ``.splatv``; ``splatconv convert --external`` writes the scene beside
the page instead (:func:`splatconv.publish.publish`). A scene read from a
``.splatvq`` is embedded as ``.splatvq`` (encoded again with its setting: the
quantizers are projections, so its records come back unchanged), which the page
decodes itself: about half the bytes. A ``quality`` (a ``.splatvq`` setting) embeds
any scene as ``.splatvq`` at that setting: a compact page.
"""

from __future__ import annotations

import io
import os

from ..errors import UsageError
from ..model import Scene
from ..zstd import inner_name
from ..web.page import SceneRef, build_page
from . import splatv, splatvq
from .base import Format


def write(scene: Scene, stream, *, compat: str | None = None, sort: str | None = None, name: str | None = None,
          quality: str | None = None, **options):
    """Write the player page with ``scene`` embedded.

    Parameters
    ----------
    scene : Scene
    stream : binary file object
    compat, sort
        As for ``.splatv`` (the embedded texture is exactly what a ``.splatv``
        write would give). A scene read from a ``.splatvq`` (and no ``compat``)
        is embedded as ``.splatvq`` with the setting it was written with.
    quality : str, optional
        Embed the scene as ``.splatvq`` with this setting (:data:`splatvq.QUALITIES`),
        whatever it was read from; not with ``compat``.
    name : str, optional
        The page's file name: its stem titles the page and names the scene.

    Returns
    -------
    WriteReport
    """
    buffer = io.BytesIO()
    if quality is not None:
        if compat is not None:
            raise UsageError(f"compat {compat!r} and quality {quality!r} exclude each other: a quality embeds "
                             ".splatvq, compat the texture bytes")
        report = splatvq.write(scene, buffer, sort=sort or splatv.FORMAT.default_sort, quality=quality, **options)
    elif scene.variant == splatvq.FORMAT.name and compat is None:
        setting = scene.meta.get("setting")
        quality = setting if setting in splatvq.QUALITIES else None
        report = splatvq.write(scene, buffer, sort=sort or splatv.FORMAT.default_sort, quality=quality, **options)
        if setting != (quality or splatvq.codec.DEFAULT_SETTING):
            report.notes.append(f"the source's .splatvq setting {setting!r} is not one this version writes; "
                                f"embedded with the {splatvq.codec.DEFAULT_SETTING!r} setting")
    else:
        report = splatv.write(scene, buffer, compat=compat, sort=sort or splatv.FORMAT.default_sort, **options)
    stem = os.path.splitext(inner_name(name))[0] if name else ""
    title = {"title": stem} if stem else {}
    stream.write(build_page([SceneRef(name=stem or "scene", data=buffer.getvalue())], **title))
    return report


def info_fields(meta: dict) -> dict:
    """Nothing: a page is written, never read."""
    return {}


FORMAT = Format(
    name="html",
    suffixes=(".html",),
    default_sort=splatv.FORMAT.default_sort,
    holds_empty=False,  # the viewer cannot show an empty texture
    dynamic=True,  # the embedded .splatv holds motion and a temporal basis
    read=None,  # a page is a player, not a scene format
    write=write,
    compat_modes=splatv.FORMAT.compat_modes,
    qualities=splatvq.FORMAT.qualities,  # embeds the scene as .splatvq at that setting
    info_fields=info_fields,
    storage=splatv.storage,  # what the embedded .splatv stores
    # Several scenes given for one page play as the segments of one clip
    # (splatconv.publish.publish), not as a frame sequence.
    plays_segments=True,
)
