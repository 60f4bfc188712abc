"""The steps every job takes: check before reading, read with progress, write, tell notes.

An output is a scene file (a format, :mod:`splatconv.io`) or the player page
(:mod:`splatconv.publish`, which alone writes pages); the steps here tell them
apart, so that no job does.
"""

from __future__ import annotations

import contextlib
import os

from ..files.output import check_output
from ..formats import format_for
from ..io import check_write_options, noting_undrawable, read, write
from ..progress import SILENT
from ..publish import PAGE, PageOptions, is_page, leaves_out_undrawable, write_page


def silent(lines) -> None:
    """The default ``tell``: notes are in what the job returns, and go nowhere else."""


def check_job(inputs, output, *, force: bool, compat: str | None = None, sort: str | None = None,
              layout: str | None = None, quality: str | None = None, page: PageOptions | None = None):
    """Refuse a job before anything is read: an input of no readable format, an option the output's format
    does not take, an output that would clobber an input or (without ``force``) an existing file.

    Parameters
    ----------
    inputs : sequence of path
    output : path
    force : bool
    compat, sort, layout, quality
        As for :func:`splatconv.io.write`.
    page : PageOptions, optional
        A page output's options (refused, but for the defaults, for a scene file).

    Returns
    -------
    splatconv.formats.base.Format or splatconv.publish.PageOutput
        The output's format, or :data:`splatconv.publish.PAGE` for a player page.

    Raises
    ------
    SplatconvError
    """
    inputs = [os.fspath(p) for p in inputs]
    for path in inputs:
        format_for(path, purpose="read")
    fmt = check_write_options(output, compat=compat, sort=sort, layout=layout, quality=quality, also=(PAGE,))
    (page or PageOptions()).check(output)
    check_output(output, inputs, force)
    return fmt


@contextlib.contextmanager
def reading_for(output, *, quality: str | None = None):
    """While the block runs, scenes read for writing ``output`` are noted as
    :func:`splatconv.io.noting_undrawable` says, but not when the output leaves their undrawable
    splats out itself (``drawable_only``; a page at a quality whose format does): advice to remove
    them would be moot, and the writer's note counts what it left out."""
    leaves = leaves_out_undrawable(quality) if is_page(output) else format_for(output, purpose="write").drawable_only
    with noting_undrawable(None) if leaves else contextlib.nullcontext():
        yield


def write_output(scene, output, *, source=None, compat: str | None = None, sort: str | None = None,
                 layout: str | None = None, quality: str | None = None, force: bool = False, inputs=(),
                 zstd_level: int | None = None, page: PageOptions | None = None, progress=SILENT):
    """Write ``scene`` to ``output``: a scene file (:func:`splatconv.io.write`) or a player page
    (:func:`splatconv.publish.write_page`, which may embed ``source``, the file the scene was read from
    unchanged, as it is, and takes ``page``'s options: fit, poster). The options are
    :func:`splatconv.io.write`'s.

    Returns
    -------
    WriteReport
    """
    if is_page(output):
        page = page or PageOptions()
        return write_page(scene, output, source=source, compat=compat, sort=sort, quality=quality, force=force,
                          inputs=inputs, zstd_level=zstd_level, fit=page.fit, poster=page.poster, progress=progress)
    return write(scene, output, compat=compat, sort=sort, layout=layout, quality=quality, force=force,
                 inputs=inputs, zstd_level=zstd_level, progress=progress)


def read_input(path, *, color: str, progress=SILENT):
    """Read one input file as a "reading" stage of ``progress`` (and the bytes of a ``.zst`` decompressed)."""
    with progress.stage("reading", 1, "file") as advance:
        scene = read(path, color=color, progress=progress)
        advance()
    return scene
