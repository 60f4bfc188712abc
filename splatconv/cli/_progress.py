"""A tqdm bar on stderr for :class:`splatconv.progress.Progress` stages."""

from __future__ import annotations

import contextlib
import sys

from tqdm import tqdm

from ..progress import SILENT, Progress


class _Bar(Progress):
    @contextlib.contextmanager
    def stage(self, label: str, total: int | None = None, unit: str = "it"):
        with tqdm(total=total, desc=label, unit=unit, unit_scale=True, leave=False, file=sys.stderr,
                  dynamic_ncols=True, mininterval=0.2) as bar:
            yield bar.update


def progress_for(quiet: bool) -> Progress:
    """A bar on stderr when it is a terminal and not ``quiet``; otherwise silent."""
    stream = sys.stderr
    if quiet or not (hasattr(stream, "isatty") and stream.isatty()):
        return SILENT
    return _Bar()
