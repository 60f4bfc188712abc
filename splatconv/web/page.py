"""Build the player page: one HTML file holding the player, its shaders and its scenes.

The page is the same whether ``splatconv view`` serves it or ``convert OUT.html``
writes it: the CSS, the player, the sort worker, the ``.splatvq`` decode worker, the shader sources of
:mod:`splatconv.render` and a JSON configuration are inlined, so the page makes no
request except for a scene that is not embedded.
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
import sys
from dataclasses import dataclass
from importlib import resources

from ..errors import UsageError
from ..wording import plural

#: The vertex shader is the first four files joined: ``render.preview.vertex_source("texture")``'s
#: program with the viewer's instanced inputs.
SHADERS = ("splat_head.glsl", "splat_instanced.glsl", "fetch_splatv.glsl", "splat_main.glsl", "splat.frag")
_TEMPLATE_FIELD = re.compile(r"\{\{([A-Z]+)\}\}")


@dataclass
class SceneRef:
    """One segment of the clip the page plays.

    Exactly one of ``url`` (fetched, relative to the page) and ``data`` (the
    ``.splatv`` or ``.splatvq`` bytes, embedded as base64; the page tells them
    apart by their first bytes) is set. ``duration`` (optional, any
    positive unit, e.g. frames) sets the segment's share of the timeline: its
    duration over the sum of all. Without durations every segment gets an equal share.
    """

    name: str
    url: str | None = None
    data: bytes | None = None
    duration: float | None = None


@dataclass(frozen=True)
class Picture:
    """The page's poster: shown under the canvas until the first WebGL frame is drawn.

    ``src`` is its URL in the page (a ``data:`` URI, or a file relative to the
    page); ``share``, when given, the URL sharers are pointed at
    (``og:image``, ``twitter:image``: a file beside the page, since most refuse a
    ``data:`` URI). ``width`` and ``height`` are the camera's size: the picture is
    laid out at that many CSS pixels, where the camera's focal lengths put the
    first frame (or scaled to the window, when the page fits the view);
    ``pixels`` the image's own (width, height), told to sharers.
    """

    src: str
    width: int
    height: int
    pixels: tuple
    share: str | None = None


def parse_durations(text: str | None, count: int) -> list:
    """``--durations D0,D1,...``: one positive finite number per segment; None gives ``[None] * count``.

    Raises
    ------
    UsageError
    """
    if text is None:
        return [None] * count
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        raise UsageError(f"--durations: expected comma-separated numbers, got {text!r}") from None
    if len(values) != count:
        raise UsageError(f"--durations gives {plural(len(values), 'value')} for {plural(count, 'segment')}")
    if not all(math.isfinite(v) and v > 0 for v in values):
        raise UsageError("--durations: every duration must be a positive finite number")
    # The player adds them left to right in doubles and divides each running sum
    # by the total: an infinite total, or a share that rounds to nothing, breaks it.
    total, bounds = 0.0, []
    for v in values:
        total += v
        bounds.append(total)
    if not math.isfinite(total):
        raise UsageError(f"--durations: they add up to more than the largest double ({sys.float_info.max:.3g}), "
                         "the page's arithmetic: give smaller numbers")
    shares = [b / total for b in bounds]
    for i, (before, after) in enumerate(zip([0.0] + shares, shares)):
        if not after > before:
            raise UsageError(f"--durations: segment {i}'s share of the timeline ({values[i]:g} of {total:g}) "
                             "rounds to nothing")
    return values


def _asset(name: str) -> str:
    return resources.files(__package__).joinpath("assets", name).read_text(encoding="utf-8")


def _shader(name: str) -> str:
    return resources.files("splatconv.render").joinpath("shaders", name).read_text(encoding="utf-8")


def _json_text(text: str) -> str:
    """JSON safe inside a <script> element: every ``<`` (only ever inside a string) as ``\\u003c``."""
    return text.replace("<", "\\u003c")


def _checked(name: str, text: str) -> str:
    """Package source that goes into a <script> element as it is: refuse what would end it early."""
    lower = text.lower()
    if "</script" in lower or "<!--" in lower:  # our sources never hold these; refuse rather than mangle
        raise ValueError(f"{name} contains '</script' or '<!--'")
    return text


def _text_block(name: str, text: str, kind: str = "text/plain") -> str:
    return f'<script type="{kind}" data-asset="{html.escape(name)}">{_checked(name, text)}</script>'


def build_page(scenes: list, title: str = "splatconv player", *, fit: bool = False,
               picture: Picture | None = None) -> bytes:
    """The player page for ``scenes``, as UTF-8 HTML bytes.

    Parameters
    ----------
    scenes : list of SceneRef
        The clip's segments in playing order (one for a single scene).
    title : str
        Shown in the page's title and panel.
    fit : bool
        Open fitting the camera's whole view to the window (its focal lengths
        scaled by the smaller of the window's and the camera's size ratios), instead
        of keeping the camera's focal lengths at any window size (splaTV's way).
    picture : Picture, optional
        The poster shown until the first frame is drawn (and given to sharers).

    Returns
    -------
    bytes
    """
    blocks = [_text_block(name, _shader(name)) for name in SHADERS]
    blocks.append(_text_block("sort_worker.js", _asset("sort_worker.js")))
    blocks.append(_text_block("splatvq_decode.js", _asset("splatvq_decode.js")))
    entries = []
    for i, scene in enumerate(scenes):
        entry = {"name": scene.name}
        if scene.duration is not None:
            entry["duration"] = scene.duration
        if scene.data is not None:
            entry["embedded"] = f"scene-{i}"
            encoded = base64.b64encode(scene.data).decode("ascii")
            # Lines of 76 characters keep editors and diff tools responsive.
            lines = "\n".join(encoded[k:k + 76] for k in range(0, len(encoded), 76))
            blocks.append(f'<script type="application/octet-stream" data-asset="scene-{i}">\n{lines}\n</script>')
        else:
            entry["url"] = scene.url
        entries.append(entry)
    settings = {"scenes": entries, **({"fit": True} if fit else {})}
    config = json.dumps(settings, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    fields = {
        "TITLE": html.escape(title),
        "CSS": _asset("player.css"),
        "CONFIG": _json_text(config),
        "ASSETS": "\n".join(blocks),
        "PLAYER": _checked("player.js", _asset("player.js")),
        "BODY": ' class="fit"' if fit else "",
        "META": _share_meta(title, picture),
        "POSTER": _poster_element(picture),
    }
    page = _TEMPLATE_FIELD.sub(lambda m: fields[m.group(1)], _asset("player.html"))
    return page.encode("utf-8")


def _share_meta(title: str, picture: Picture | None) -> str:
    """Open Graph and Twitter card tags: the title, and the poster where sharers can fetch it."""
    tags = [f'<meta property="og:title" content="{html.escape(title)}">']
    if picture is not None and picture.share is not None:
        url = html.escape(picture.share)
        tags += [f'<meta property="og:image" content="{url}">',
                 f'<meta property="og:image:width" content="{picture.pixels[0]}">',
                 f'<meta property="og:image:height" content="{picture.pixels[1]}">',
                 '<meta name="twitter:card" content="summary_large_image">',
                 f'<meta name="twitter:image" content="{url}">']
    return "\n".join(tags)


def _poster_element(picture: Picture | None) -> str:
    if picture is None:
        return ""
    return (f'<img id="poster" alt="" src="{html.escape(picture.src)}" '
            f'style="width: {picture.width}px; height: {picture.height}px">')
