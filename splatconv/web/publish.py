"""Write player pages: one scene or a list of segments, embedded or beside the page."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from urllib.parse import quote

from ..errors import UsageError
from ..files.output import atomic_group, check_output
from .page import SceneRef, build_page, parse_durations
from .scenes import check_splatv, is_plain_splatv, splatv_bytes


@dataclass
class PublishReport:
    """What :func:`publish` wrote: ``written`` as (path, bytes) pairs, and notes."""

    written: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def publish(inputs, output, *, external: bool = False, force: bool = False,
            durations: str | None = None) -> PublishReport:
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
        Write each scene as ``.splatv`` beside the page (``OUT.splatv``, or
        ``OUT.0.splatv``, ``OUT.1.splatv``, ... for segments) and have the page
        fetch it, instead of embedding it: for scenes too large to embed. Such a
        page must be served over HTTP (browsers refuse fetches from a page opened
        from disk). A plain ``.splatv`` input that already has that name (``convert
        scene.splatv scene.html --external``) is left as it is and played from there.
    force : bool
        Replace existing outputs (never an input).
    durations : str, optional
        ``"D0,D1,..."``: each segment's share of the timeline (any unit, e.g. frames).

    Returns
    -------
    PublishReport
    """
    inputs = [os.fspath(p) for p in inputs]
    output = os.fspath(output)
    if not output.lower().endswith(".html"):
        raise UsageError("a player page must be written to an .html file", output)
    if not inputs:
        raise UsageError("give at least one scene file")
    shares = parse_durations(durations, len(inputs))
    stem = output[: -len(".html")]
    names = [f"{stem}.splatv"] if len(inputs) == 1 else [f"{stem}.{i}.splatv" for i in range(len(inputs))]
    # An input that is already the .splatv the page would fetch stays where it is.
    kept = [external and is_plain_splatv(path) and _same_file(path, name) for path, name in zip(inputs, names)]
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
                check_splatv(path)
                report.notes.append(f"{name}: the page plays this input where it is")
                refs.append(SceneRef(name=os.path.basename(name), url=quote(os.path.basename(name)), duration=share))
                continue
            data, notes = splatv_bytes(path)
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
