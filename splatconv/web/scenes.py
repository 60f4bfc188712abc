"""Scene files as the ``.splatv`` bytes the player plays."""

from __future__ import annotations

import io
import os

from .. import read as read_scene
from ..errors import UnsupportedError
from ..formats import format_for, splatv
from ..fsutil import open_input
from ..transport import is_compressed, plain_input


def check_splatv(path: str | os.PathLike) -> int:
    """Check a plain ``.splatv`` file's header the way the player will; returns its size in bytes.

    Raises
    ------
    FormatError
        For a file the page could not read (not .splatv, damaged header, no splat chunk).
    """
    path = os.fspath(path)
    with open_input(path) as f:
        size = os.fstat(f.fileno()).st_size
        chunks, _offset = splatv.read_header(f, path, size)
    if not any(c["type"] == "splat" for c in chunks):
        from ..errors import FormatError

        raise FormatError("header has no 'splat' chunk", path)
    return size


def is_plain_splatv(path: str | os.PathLike) -> bool:
    """True for an uncompressed ``.splatv`` file, which the player can fetch as it is."""
    return format_for(path) is splatv and not is_compressed(path)


def splatv_bytes(path: str | os.PathLike) -> tuple[bytes, list]:
    """The ``.splatv`` bytes of any scene file, and notes on what converting it lost.

    A ``.splatv`` (or ``.splatv.zst``) is passed through unchanged; any other
    format is read and packed in memory exactly as ``convert`` would write it.

    Returns
    -------
    data : bytes
    notes : list of str
    """
    path = os.fspath(path)
    if format_for(path) is splatv:
        with plain_input(path) as plain:
            check_splatv(plain)
            with open_input(plain) as f:
                return f.read(), []
    scene = read_scene(path)
    if scene.count == 0:
        raise UnsupportedError("holds no splats to show", path)
    buffer = io.BytesIO()
    report = splatv.write(scene, buffer)
    return buffer.getvalue(), list(scene.notes) + list(report.notes)
