"""The steps every job takes: check before reading, read with progress, tell notes."""

from __future__ import annotations

import os

from ..files.output import check_output
from ..formats import format_for
from ..io import check_write_options, read
from ..progress import SILENT


def silent(lines) -> None:
    """The default ``tell``: notes are in what the job returns, and go nowhere else."""


def check_job(inputs, output, *, force: bool, compat: str | None = None, sort: str | None = None,
              layout: str | None = None, quality: str | None = None):
    """Refuse a job before anything is read: an input of no readable format, an option the output's format
    does not take, an output that would clobber an input or (without ``force``) an existing file.

    Parameters
    ----------
    inputs : sequence of path
    output : path
    force : bool
    compat, sort, layout, quality
        As for :func:`splatconv.io.write`.

    Returns
    -------
    splatconv.formats.base.Format
        The output's format.

    Raises
    ------
    SplatconvError
    """
    inputs = [os.fspath(p) for p in inputs]
    for path in inputs:
        format_for(path, purpose="read")
    fmt = check_write_options(output, compat=compat, sort=sort, layout=layout, quality=quality)
    check_output(output, inputs, force)
    return fmt


def read_input(path, *, color: str, progress=SILENT):
    """Read one input file as a "reading" stage of ``progress`` (and the bytes of a ``.zst`` decompressed)."""
    with progress.stage("reading", 1, "file") as advance:
        scene = read(path, color=color, progress=progress)
        advance()
    return scene
