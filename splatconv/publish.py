"""Publish scenes in the player page: the bytes the page plays for any scene file, and pages written.

The page itself is built by :mod:`splatconv.web.page`, which knows no format:
this module asks the registry which formats the page plays as they are
(``check_playable``) and gives it every other scene as the viewer's texture
format (:func:`splatconv.formats.texture_format`), converted in memory.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass, field
from urllib.parse import quote

from .errors import UnsupportedError, UsageError
from .formats import format_for, page_format, playable_format, texture_format
from .files.inputs import open_input
from .files.output import atomic_group, check_output
from .io import check_write_options
from .io import read as read_scene
from .zstd import is_compressed, plain_input
from .web.page import SceneRef, build_page, parse_durations


def _played_as(path, quality: str | None = None):
    """The format whose bytes the page is given for ``path``: its own when the page plays it as it is;
    with a ``quality``, the format the page plays that offers it."""
    fmt = format_for(path, purpose="read")
    if quality is not None:
        return playable_format(quality)
    return fmt if fmt.check_playable is not None else texture_format()


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


def page_bytes(path: str | os.PathLike, quality: str | None = None) -> tuple[bytes, list]:
    """The bytes the page plays for any scene file, and notes on what converting it lost.

    A file the page plays as it is (the viewer's texture, ``.splatv``; maybe
    ``.zst``) is passed through unchanged; any other format is read and packed
    in memory as the texture format, exactly as ``convert`` would write it. With
    a ``quality``, every file is read and written in memory as the format the page
    plays that offers it (:func:`splatconv.formats.playable_format`: a ``.splatvq``
    at that setting).

    Returns
    -------
    data : bytes
    notes : list of str
    """
    path = os.fspath(path)
    fmt = format_for(path, purpose="read")
    if fmt.check_playable is not None and quality is None:
        with plain_input(path, declared_size=fmt.declared_size) as plain:
            fmt.check_playable(plain)
            with open_input(plain) as f:
                return f.read(), []
    scene = read_scene(path)
    if scene.count == 0:
        raise UnsupportedError("holds no splats to show", path)
    buffer = io.BytesIO()
    if quality is not None:
        played = playable_format(quality)
        report = played.write(scene, buffer, sort=played.default_sort, quality=quality)
    else:
        texture = texture_format()
        report = texture.write(scene, buffer, sort=texture.default_sort)
    return buffer.getvalue(), list(scene.notes) + list(report.notes)


@dataclass
class PublishReport:
    """What :func:`publish` wrote: ``written`` as (path, bytes) pairs, and notes."""

    written: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def publish(inputs, output, *, external: bool = False, force: bool = False,
            durations: str | None = None, quality: str | None = None) -> PublishReport:
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

    Returns
    -------
    PublishReport
    """
    inputs = [os.fspath(p) for p in inputs]
    output = os.fspath(output)
    page_ending = page_format().suffixes[0]
    if not output.lower().endswith(page_ending):
        raise UsageError(f"a player page must be written to an {page_ending} file", output)
    if not inputs:
        raise UsageError("give at least one scene file")
    check_write_options(output, quality=quality)
    shares = parse_durations(durations, len(inputs))
    stem = output[: -len(page_ending)]
    suffixes = [page_suffix(path, quality) for path in inputs]
    names = [f"{stem}{suffixes[0]}"] if len(inputs) == 1 else [f"{stem}.{i}{s}" for i, s in enumerate(suffixes)]
    # An input that is already the file the page would fetch stays where it is.
    kept = [external and quality is None and is_plain_playable(path) and _same_file(path, name)
            for path, name in zip(inputs, names)]
    outputs = [output] + ([name for name, keep in zip(names, kept) if not keep] if external else [])
    for path in outputs:
        check_output(path, inputs, force)
    if len(set(map(os.path.abspath, outputs))) != len(outputs):  # pragma: no cover (names are distinct)
        raise UsageError("output names collide", output)
    report = PublishReport()
    refs = []
    # All files or none: a page never points at a scene file that was not written.
    with atomic_group(replace=force) as group:
        for path, name, share, keep in zip(inputs, names, shares, kept):
            if keep:
                check_playable(path)
                report.notes.append(f"{name}: the page plays this input where it is")
                refs.append(SceneRef(name=os.path.basename(name), url=quote(os.path.basename(name)), duration=share))
                continue
            data, notes = page_bytes(path, quality)
            report.notes.extend(f"{path}: {n}" for n in notes)
            if external:
                with group.open(name) as stream:
                    stream.write(data)
                report.written.append((name, len(data)))
                # Named as the file the page fetches: a message about it names what is missing.
                refs.append(SceneRef(name=os.path.basename(name), url=quote(os.path.basename(name)), duration=share))
            else:
                refs.append(SceneRef(name=os.path.basename(path), data=data, duration=share))
        page = build_page(refs, title=os.path.basename(stem))
        with group.open(output) as stream:
            stream.write(page)
    report.written.insert(0, (output, len(page)))
    return report


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # b not there yet
        return False
