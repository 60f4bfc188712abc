"""One module per format behind one registry keyed by file suffix.

Every format module declares what it supports (see :mod:`splatconv.formats.base`):
``NAME``, ``SUFFIXES``, ``CAN_READ``, ``CAN_WRITE``, ``COMPAT_MODES``,
``DEFAULT_SORT``, ``HOLDS_EMPTY``, ``DYNAMIC``, ``STORES_TEXTURE``, ``PLAYS_SEGMENTS``
(a player page), and provides ``read``, ``write``, ``info_fields``,
``storage`` (how it stores each attribute group, which ``verify`` and ``stats``
judge errors by) and, when it can be read, ``splat_count`` (the splats ``read``
would give, from the header or the file size without reading them, or None when
only reading tells) and ``most_splats`` (at most that many, always known).
Callers look a module up with :func:`format_for` and ask it those questions;
none of them names a format. Adding a format is adding a module and one line to
``_MODULES``. A ``.zst`` suffix after a format's suffix means the
same format, zstd-compressed (see :mod:`splatconv.zstd`).
"""

from __future__ import annotations

import os

from ..errors import UsageError
from ..zstd import inner_name
from . import html, ply, splat, splatv

_MODULES = (ply, splatv, splat, html)
REGISTRY = {suffix: module for module in _MODULES for suffix in module.SUFFIXES}


def _lookup(path: str):
    """The module whose suffix ``path`` ends in (case-insensitive, after any ``.zst``), or None."""
    lower = inner_name(path).lower()
    for suffix, module in REGISTRY.items():
        if lower.endswith(suffix):
            return module
    return None


def format_for(path: str | os.PathLike, *, purpose: str | None = None):
    """The format module for ``path``, chosen by its (case-insensitive) suffix.

    Parameters
    ----------
    path : path
    purpose : {None, "read", "write"}
        Refuse a format that cannot be read (or written).

    Raises
    ------
    UsageError
        For a suffix no format claims, or one that cannot serve ``purpose``.
    """
    path = os.fspath(path)
    module = _lookup(path)
    if module is None:
        known = ", ".join(sorted(REGISTRY))
        raise UsageError(f"unknown file type (expected one of {known}, optionally + .zst)", path)
    if purpose == "read" and not module.CAN_READ:
        raise UsageError(f"{module.NAME} files can be written, not read", path)
    if purpose == "write" and not module.CAN_WRITE:
        raise UsageError(f"{module.NAME} files can be read, not written", path)
    return module


def plays_segments(path: str | os.PathLike) -> bool:
    """Whether ``path``'s format plays several scenes as the segments of one clip (``PLAYS_SEGMENTS``);
    False for a suffix no format claims."""
    module = _lookup(os.fspath(path))
    return module is not None and module.PLAYS_SEGMENTS


def compat_modes() -> tuple:
    """Every compat mode some format accepts, for option choices."""
    return tuple(sorted({mode for module in _MODULES for mode in module.COMPAT_MODES}))
