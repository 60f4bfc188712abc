"""One module per format behind one registry keyed by file suffix.

A format module has ``NAME``, ``SUFFIXES``, ``read(path, **options) -> Scene``
and ``write(scene, stream, **options) -> WriteReport``. Adding a format is adding
a module and one line to ``_MODULES``. A ``.zst`` suffix after a format's suffix
means the same format, zstd-compressed (see :mod:`splatconv.transport`).
"""

from __future__ import annotations

import os

from ..errors import UsageError
from . import html, ply, splatv

_MODULES = (ply, splatv, html)
REGISTRY = {suffix: module for module in _MODULES for suffix in module.SUFFIXES}


def format_for(path: str | os.PathLike):
    """The format module for ``path``, chosen by its (case-insensitive) suffix.

    Raises
    ------
    UsageError
        For a suffix no format claims.
    """
    from ..transport import inner_name

    path = os.fspath(path)
    lower = inner_name(path).lower()
    for suffix, module in REGISTRY.items():
        if lower.endswith(suffix):
            return module
    known = ", ".join(sorted(REGISTRY))
    raise UsageError(f"unknown file type (expected one of {known}, optionally + .zst)", path)
