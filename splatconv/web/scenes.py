"""Scene files as the ``.splatv`` bytes the player plays."""

from __future__ import annotations

import io
import os

from ..errors import UnsupportedError
from ..formats import format_for, splatv
from ..io import read as read_scene
from ..files.inputs import open_input
from ..zstd import is_compressed, plain_input


def check_splatv(path: str | os.PathLike) -> None:
    """Check a plain ``.splatv`` file as every command reads it (header, splat chunk, cameras).

    Raises
    ------
    FormatError
        For a file the page could not play: not .splatv, a damaged header, no splat chunk.
    """
    splatv.read_records(path)


def stores_texture(path: str | os.PathLike) -> bool:
    """True for a file that holds the viewer's texture itself (``.splatv``, maybe ``.zst``): the page plays its bytes."""
    return bool(getattr(format_for(path, purpose="read"), "STORES_TEXTURE", False))


def is_plain_splatv(path: str | os.PathLike) -> bool:
    """True for an uncompressed file holding the viewer's texture, which the player can fetch as it is."""
    return stores_texture(path) and not is_compressed(path)


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
    module = format_for(path, purpose="read")
    if getattr(module, "STORES_TEXTURE", False):
        with plain_input(path, declared_size=getattr(module, "declared_size", None)) as plain:
            check_splatv(plain)
            with open_input(plain) as f:
                return f.read(), []
    scene = read_scene(path)
    if scene.count == 0:
        raise UnsupportedError("holds no splats to show", path)
    buffer = io.BytesIO()
    report = splatv.write(scene, buffer, sort=splatv.DEFAULT_SORT)
    return buffer.getvalue(), list(scene.notes) + list(report.notes)
