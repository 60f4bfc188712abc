"""Progress of long work, reported through a callback the caller chooses.

Library functions that can take more than a couple of seconds accept a
``progress`` argument: a :class:`Progress` (default :data:`SILENT`). They call
``progress.stage(label, total)`` and advance the returned counter; they never
print. The CLI passes a one-line bar on stderr (``splatconv/cli/_progress.py``) when stderr is a
terminal and ``--quiet`` is not given.
"""

from __future__ import annotations

import contextlib


class Progress:
    """Receives progress; this base class ignores it (:data:`SILENT`)."""

    @contextlib.contextmanager
    def stage(self, label: str, total: int | None = None, unit: str = "it"):
        """A named stage of ``total`` units (None: unknown); yields ``advance(n=1)``."""
        yield _ignore


def _ignore(n: int = 1) -> None:
    return None


#: The default: no progress reported.
SILENT = Progress()
