"""The player page's one home: what bytes a page plays for a scene or a scene file, and every page written.

The page itself is built by :mod:`splatconv.web.page`, which knows no format:
this module asks the registry which formats the page plays as they are
(``check_playable``) and gives it every other scene as the viewer's texture
format (:func:`splatconv.formats.texture_format`), converted in memory. A page is
no scene format (it is written, never read): ``convert OUT.html``, ``bake``,
``merge`` and ``view`` all come here (:func:`write_page`, :func:`publish`,
:func:`page_bytes`), so every page chooses its bytes by one rule: a file's own bytes when the page
plays it as it is and nothing changes it, else :func:`scene_bytes`.

A page carries a poster unless told not to (``poster=False``): its first frame
(clip time 0, the first segment's camera 0), drawn by the headless renderer from
the very bytes the page plays (:func:`splatconv.render.poster.draw_poster`),
shown until WebGL draws and given to sharers where a file can hold it.
"""

from __future__ import annotations

import base64
import io
import os
import tempfile
from dataclasses import dataclass, field
from urllib.parse import quote

from .errors import SplatconvError, UnsupportedError, UsageError
from .files.inputs import open_input
from .files.output import atomic_group, atomic_writer, check_output
from .formats import format_for, playable_format, playable_formats, playable_qualities, texture_format
from .formats.base import WriteReport
from .io import check_write_options
from .io import read as read_scene
from .model import Scene
from .progress import SILENT
from .zstd import DEFAULT_LEVEL, inner_name, is_compressed, output_stream, plain_input
from .web.page import Picture, SceneRef, build_page, parse_durations

#: The suffix of a player page (``.zst`` after it: the same page, compressed).
PAGE_SUFFIX = ".html"
#: What a page's poster file is called beside it, after the page's name without ``.html``
#: (``--external``: ``OUT.poster.jpg``, which ``og:image`` names).
POSTER_SUFFIX = ".poster.jpg"


@dataclass(frozen=True)
class PageOutput:
    """What the player page takes as an output, in the words of a scene format's declaration
    (:class:`splatconv.formats.base.Format`), so that one check reads any output alike
    (:func:`splatconv.io.check_write_options` with ``also``, :func:`splatconv.io.refuse_empty`).
    A page is no format: nothing here reads, writes or describes a scene file.

    Attributes
    ----------
    suffixes : tuple of str
    compat_modes : tuple of str
        The texture format's: a page embeds its bytes.
    qualities : tuple of str
        Those of the formats the page plays as they are: a page at a quality embeds one.
    layouts, precisions : tuple
        Empty: a page has no record layout and proves no quality (``--min-psnr``).
    holds_empty : bool
        False: the viewer cannot show an empty scene.
    drawable_only : bool
        False: only a page at a quality may leave splats out (:func:`leaves_out_undrawable`).
    """

    suffixes: tuple
    compat_modes: tuple
    qualities: tuple
    layouts: tuple = ()
    precisions: tuple = ()
    holds_empty: bool = False
    drawable_only: bool = False


@dataclass(frozen=True)
class PageOptions:
    """What a page output takes beyond a scene file's options (``--fit``, ``--no-poster``).

    Attributes
    ----------
    fit : bool
        The page opens fitting the camera's whole view to the window.
    poster : bool
        The page carries its first frame as a poster (drawn: it costs a render).
    """

    fit: bool = False
    poster: bool = True

    def check(self, output) -> None:
        """Refuse options other than the defaults for an ``output`` that is no page.

        Raises
        ------
        UsageError
        """
        if self != PageOptions() and not is_page(output):
            raise UsageError(f"--fit and --no-poster apply to {PAGE_SUFFIX} output only", output)


#: The player page as an output.
PAGE = PageOutput(suffixes=(PAGE_SUFFIX,), compat_modes=texture_format().compat_modes,
                  qualities=playable_qualities())


def is_page(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a player page (its suffix, case-insensitive, after any ``.zst``)."""
    return inner_name(os.fspath(path)).lower().endswith(PAGE_SUFFIX)


def leaves_out_undrawable(quality: str | None = None) -> bool:
    """Whether a page at ``quality`` leaves out the splats the viewer can never draw: when the format it
    then embeds does (``drawable_only``)."""
    return quality is not None and playable_format(quality).drawable_only


def _plays_as_is(path, quality: str | None = None) -> bool:
    """Whether the page is given ``path``'s own bytes: a format the page plays as it is, no quality asked."""
    return quality is None and format_for(path, purpose="read").check_playable is not None


def _played_as(path, quality: str | None = None):
    """The format whose bytes the page is given for ``path``: its own when the page plays it as it is;
    with a ``quality``, the format the page plays that offers it."""
    if quality is not None:
        format_for(path, purpose="read")
        return playable_format(quality)
    return format_for(path, purpose="read") if _plays_as_is(path) else texture_format()


def page_suffix(path: str | os.PathLike, quality: str | None = None) -> str:
    """The suffix of the file the page is given for ``path`` (what ``view`` serves, ``--external`` writes),
    at ``quality`` when given."""
    return _played_as(path, quality).suffixes[0]


def check_playable(path: str | os.PathLike) -> None:
    """Check a plain file the page plays as it is, as every command reads it (a header, the splats).

    Raises
    ------
    FormatError
        For a file the page could not play: a damaged header, no splats.
    """
    format_for(path, purpose="read").check_playable(path)


def is_plain_playable(path: str | os.PathLike) -> bool:
    """True for an uncompressed file the player plays as it is, which it can fetch from disk."""
    return format_for(path, purpose="read").check_playable is not None and not is_compressed(path)


def scene_bytes(scene: Scene, *, compat: str | None = None, sort: str | None = None, quality: str | None = None,
             progress=SILENT) -> tuple[bytes, WriteReport]:
    """The bytes a page plays for ``scene``, packed in memory: the one rule every page follows for a scene
    that is not a file's own bytes (:func:`page_bytes` passes those through).

    * With a ``quality``: the format the page plays that offers it
      (:func:`splatconv.formats.playable_format`, a ``.splatvq``), at that setting.
    * A scene read from a format the page plays that has quality settings (a
      ``.splatvq``), without ``compat``: that format again, at the setting it was
      read at (its ``meta["setting"]``; the quantizers are projections, so its
      records come back unchanged): about half the texture's bytes.
    * Otherwise the viewer's texture format (:func:`splatconv.formats.texture_format`),
      with ``compat`` and ``sort``: exactly what ``convert`` writes to a ``.splatv``.

    Returns
    -------
    data : bytes
    report : WriteReport
        What the write did (its count and notes).

    Raises
    ------
    UsageError
        For ``compat`` with ``quality``.
    """
    if quality is not None and compat is not None:
        raise UsageError(f"compat {compat!r} and quality {quality!r} exclude each other: a quality embeds "
                         "a quantized scene, compat the texture's bytes")
    played = _scene_format(scene, compat, quality)
    buffer = io.BytesIO()
    if played is None:
        texture = texture_format()
        report = texture.write(scene, buffer, compat=compat, sort=sort or texture.default_sort, progress=progress)
        return buffer.getvalue(), report
    setting = quality or scene.meta.get("setting")
    kept = setting if setting in played.qualities else None
    report = played.write(scene, buffer, sort=sort or played.default_sort, quality=kept, progress=progress)
    if kept != setting:
        report.notes.append(f"the source's {played.suffixes[0]} setting {setting!r} is not one this version "
                            f"writes; embedded with the {played.qualities[0]!r} setting")
    return buffer.getvalue(), report


def _scene_format(scene: Scene, compat: str | None, quality: str | None):
    """The format :func:`scene_bytes` packs ``scene`` as, or None for the texture format."""
    return playable_format(quality) if quality is not None else _kept_format(scene, compat)


def _kept_format(scene: Scene, compat: str | None):
    """The format the page plays with quality settings that ``scene`` was read from (kept without
    ``compat``), or None."""
    if compat is not None:
        return None
    return next((fmt for fmt in playable_formats() if fmt.name == scene.variant and fmt.qualities), None)


def page_bytes(path: str | os.PathLike, quality: str | None = None) -> tuple[bytes, list]:
    """The bytes the page plays for any scene file, and notes on what converting it lost.

    A file the page plays as it is (the viewer's texture, ``.splatv``, or a
    ``.splatvq``; maybe ``.zst``) is passed through unchanged, once checked as
    every command reads it; any other file, or any file with a ``quality``, is
    read and packed in memory by :func:`scene_bytes`.

    Returns
    -------
    data : bytes
    notes : list of str
    """
    path = os.fspath(path)
    if _plays_as_is(path, quality):
        fmt = format_for(path, purpose="read")
        with plain_input(path, declared_size=fmt.declared_size) as plain:
            fmt.check_playable(plain)
            with open_input(plain) as f:
                return f.read(), []
    scene = read_scene(path)
    if scene.count == 0:
        raise UnsupportedError("holds no splats to show", path)
    data, report = scene_bytes(scene, quality=quality)
    return data, list(scene.notes) + list(report.notes)


def write_page(scene: Scene, output: str | os.PathLike, *, source=None, compat: str | None = None,
               sort: str | None = None, quality: str | None = None, force: bool = False, inputs=(),
               zstd_level: int | None = None, fit: bool = False, poster: bool = True,
               progress=SILENT) -> WriteReport:
    """Write ``output``, the player page with ``scene`` embedded, atomically (``.html.zst``: compressed).

    Parameters
    ----------
    scene : Scene
        Not empty (the caller refuses an empty scene as it reads it, naming its file).
    source : path, optional
        The file ``scene`` was read from, given when nothing changed it since: without
        ``compat``, ``sort`` and ``quality``, a file the page plays as it is is then
        embedded as its own bytes (:func:`page_bytes`), as :func:`publish` and ``view``
        give it. Otherwise the scene is packed by :func:`scene_bytes`.
    compat, sort, quality
        As for :func:`scene_bytes`.
    force, inputs, zstd_level, progress
        As for :func:`splatconv.io.write`.
    fit : bool
        The page opens fitting the camera's whole view to the window (:func:`splatconv.web.page.build_page`).
    poster : bool
        Draw the page's first frame and embed it as a ``data:`` JPEG, shown until WebGL draws
        (:func:`_poster`; a single file gives sharers no picture: ``og:image`` needs a file).

    Returns
    -------
    WriteReport
        The splats embedded and the notes of packing them (and of a poster that could not be drawn).
    """
    output = os.fspath(output)
    check_output(output, inputs, force)
    try:
        if source is not None and compat is None and sort is None and _plays_as_is(source, quality):
            data, _ = page_bytes(source)
            suffix = page_suffix(source)
            report = WriteReport(count=scene.count)
        else:
            data, report = scene_bytes(scene, compat=compat, sort=sort, quality=quality, progress=progress)
            suffix = (_scene_format(scene, compat, quality) or texture_format()).suffixes[0]
    except SplatconvError as e:
        if e.path is not None:
            raise
        raise type(e)(e.message, output, e.where) from None  # a writer does not know the page's name
    picture = None
    if poster:
        drawn, notes = _poster(data, suffix)
        report.notes.extend(notes)
        picture = None if drawn is None else _picture(drawn, _data_uri(drawn.jpeg))
    stem = _stem(output)
    page = _page([SceneRef(name=stem or "scene", data=data)], stem, fit=fit, picture=picture)
    level = DEFAULT_LEVEL if zstd_level is None else zstd_level
    with atomic_writer(output, replace=force) as stream, \
            output_stream(stream, output, level, progress, size_hint=len(page)) as out:
        out.write(page)
    return report


def _stem(output: str) -> str:
    """A page's file name without its suffixes: its title, and the name of a scene made for it."""
    return os.path.basename(inner_name(output))[: -len(PAGE_SUFFIX)]


def _page(refs: list, stem: str, **options) -> bytes:
    """The page playing ``refs``, titled ``stem`` (when its name has one); ``options``: :func:`build_page`'s."""
    return build_page(refs, title=stem, **options) if stem else build_page(refs, **options)


def _poster(data: bytes, suffix: str):
    """The page's poster, drawn from ``data``, the bytes its first segment plays (a ``suffix`` file).

    Returns
    -------
    (Poster or None, list of str)
        None, with a note saying why, when the scene has no camera (the page's first view then
        depends on the window) or no OpenGL context can be made.
    """
    with tempfile.TemporaryDirectory(prefix="splatconv-poster-") as folder:
        path = os.path.join(folder, "page" + suffix)
        with open(path, "wb") as f:
            f.write(data)
        return _file_poster(path)


def _file_poster(path: str):
    """:func:`_poster` of a file the page plays as it is."""
    # Declared lazy (tests/test_architecture.py): the renderer loads only when a page is written.
    from .render.gl import RenderUnavailable
    from .render.poster import draw_poster

    try:
        drawn = draw_poster(path)
    except RenderUnavailable as e:
        return None, [f"no poster: {e.message}"]
    if drawn is None:
        return None, ["no poster: the scene has no camera, so the page's first view depends on the window"]
    return drawn, []


def _picture(drawn, src: str, share: str | None = None) -> Picture:
    return Picture(src=src, width=drawn.camera_width, height=drawn.camera_height,
                   pixels=(drawn.width, drawn.height), share=share)


def _data_uri(jpeg: bytes) -> str:
    return "data:image/jpeg;base64," + base64.b64encode(jpeg).decode("ascii")


@dataclass
class PublishReport:
    """What :func:`publish` wrote: ``written`` as (path, bytes) pairs, and notes."""

    written: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def publish(inputs, output, *, external: bool = False, force: bool = False,
            durations: str | None = None, quality: str | None = None, fit: bool = False,
            poster: bool = True) -> PublishReport:
    """Write ``output`` (``.html``): the player with ``inputs`` as one clip.

    Parameters
    ----------
    inputs : list of path
        Scene files (any format ``convert`` reads); several are the segments of one
        clip, played in this order, each an equal share of the timeline unless
        ``durations`` says otherwise.
    output : path
        The page; must end in ``.html``.
    external : bool
        Write each scene beside the page as the file the page plays
        (:func:`page_suffix`: ``OUT.splatv``, or ``OUT.0.splatv``, ``OUT.1.splatv``,
        ... for segments; ``.splatvq`` for a ``.splatvq`` input, played as it is)
        and have the page fetch it, instead of embedding it: for scenes too large
        to embed. Such a page must be served over HTTP (browsers refuse fetches
        from a page opened from disk). A plain input the page plays as it is that
        already has that name (``convert scene.splatv scene.html --external``) is
        left as it is and played from there.
    force : bool
        Replace existing outputs (never an input).
    durations : str, optional
        ``"D0,D1,..."``: each segment's share of the timeline (any unit, e.g. frames).
    quality : str, optional
        Give the page every scene as a ``.splatvq`` at this setting (:func:`page_bytes`),
        embedded or, with ``external``, written beside it (``OUT.splatvq``); an input
        is then never played where it is.
    fit : bool
        The page opens fitting the camera's whole view to the window.
    poster : bool
        Draw the clip's first frame (the first input's camera 0 at time 0) as the page's
        poster: with ``external`` written beside the page (``OUT.poster.jpg``, named by its
        ``og:image`` and ``twitter:image`` for sharers), else embedded as a ``data:`` JPEG.

    Returns
    -------
    PublishReport
    """
    inputs = [os.fspath(p) for p in inputs]
    output = os.fspath(output)
    if not is_page(output) or is_compressed(output):
        raise UsageError(f"a player page must be written to an {PAGE_SUFFIX} file", output)
    if not inputs:
        raise UsageError("give at least one scene file")
    check_write_options(output, quality=quality, also=(PAGE,))
    shares = parse_durations(durations, len(inputs))
    stem = output[: -len(PAGE_SUFFIX)]
    suffixes = [page_suffix(path, quality) for path in inputs]
    names = [f"{stem}{suffixes[0]}"] if len(inputs) == 1 else [f"{stem}.{i}{s}" for i, s in enumerate(suffixes)]
    # An input that is already the file the page would fetch stays where it is.
    kept = [external and quality is None and is_plain_playable(path) and _same_file(path, name)
            for path, name in zip(inputs, names)]
    poster_name = f"{stem}{POSTER_SUFFIX}"
    outputs = [output] + ([name for name, keep in zip(names, kept) if not keep] if external else [])
    outputs += [poster_name] if external and poster else []
    for path in outputs:
        check_output(path, inputs, force)
    if len(set(map(os.path.abspath, outputs))) != len(outputs):  # pragma: no cover (names are distinct)
        raise UsageError("output names collide", output)
    report = PublishReport()
    refs = []
    picture = None
    # All files or none: a page never points at a scene file that was not written.
    with atomic_group(replace=force) as group:
        for path, name, share, keep in zip(inputs, names, shares, kept):
            if keep:
                check_playable(path)
                if poster and not refs:
                    made = _file_poster(path)
                report.notes.append(f"{name}: the page plays this input where it is")
                refs.append(SceneRef(name=os.path.basename(name), url=quote(os.path.basename(name)), duration=share))
                continue
            data, notes = page_bytes(path, quality)
            report.notes.extend(f"{path}: {n}" for n in notes)
            if poster and not refs:  # the clip's first frame: the first segment's
                made = _poster(data, page_suffix(path, quality))
            if external:
                with group.open(name) as stream:
                    stream.write(data)
                report.written.append((name, len(data)))
                # Named as the file the page fetches: a message about it names what is missing.
                refs.append(SceneRef(name=os.path.basename(name), url=quote(os.path.basename(name)), duration=share))
            else:
                refs.append(SceneRef(name=os.path.basename(path), data=data, duration=share))
        if poster:
            picture = _published_picture(group, report, made, external, poster_name)
        page = _page(refs, _stem(output), fit=fit, picture=picture)
        with group.open(output) as stream:
            stream.write(page)
    report.written.insert(0, (output, len(page)))
    return report


def _published_picture(group, report: PublishReport, made: tuple, external: bool, name: str):
    """A published page's picture of the poster ``made`` (:func:`_poster`'s answer): a file ``name``
    beside an ``external`` page (written in ``group``, named for sharers), else a ``data:`` URI."""
    drawn, notes = made
    report.notes.extend(notes)
    if drawn is None:
        return None
    if not external:
        return _picture(drawn, _data_uri(drawn.jpeg))
    with group.open(name) as stream:
        stream.write(drawn.jpeg)
    report.written.append((name, len(drawn.jpeg)))
    url = quote(os.path.basename(name))
    return _picture(drawn, url, share=url)


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # b not there yet
        return False
