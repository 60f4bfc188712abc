"""One exception hierarchy for the library.

Every error carries *where* it happened so the CLI can print one line such as
``truncated.ply: element 'vertex': row 100: unexpected end of file``.
"""

from __future__ import annotations

import os


class SplatconvError(Exception):
    """Base class of every error the library raises on purpose.

    Parameters
    ----------
    message : str
        What is wrong, in words a user understands.
    path : str or os.PathLike, optional
        The file the problem is in; printed first.
    where : sequence of str, optional
        Locations inside the file, outermost first (``"element 'vertex'"``,
        ``"row 100"``, ``"property 'x'"``).
    """

    def __init__(self, message: str, path: str | os.PathLike | None = None, where=()):
        self.message = message
        self.path = os.fspath(path) if path is not None else None
        self.where = tuple(where)
        super().__init__(str(self))

    def __str__(self) -> str:
        parts = []
        if self.path is not None:
            parts.append(self.path)
        parts.extend(self.where)
        parts.append(self.message)
        return ": ".join(parts)


class FormatError(SplatconvError):
    """An input file is malformed or is not what its extension says."""


class UnsupportedError(SplatconvError):
    """An input is well formed but holds something splatconv cannot convert."""


class OutputError(SplatconvError):
    """The output cannot be written where asked (exists, same as input, ...)."""


class UsageError(SplatconvError):
    """An option value is invalid (bad cameras file, unknown format, ...)."""
