"""A one-line progress bar on stderr for :class:`splatconv.progress.Progress` stages.

Shown only when stderr is a terminal (never in pipes, logs or ``--json`` runs)
and cleared when the stage ends, so what stays on screen is the command's output.
A stage begun inside another (decompressing while reading) takes the line
while it lasts; the outer stage's bar comes back when it ends.
"""

from __future__ import annotations

import contextlib
import shutil
import sys
import time

from ..progress import SILENT, Progress

#: Seconds between redraws.
_INTERVAL = 0.2
_WIDTH = 24


class _Bar(Progress):
    def __init__(self, stream):
        self.stream = stream
        self._open = []  # redraw functions of the stages begun and not yet ended, innermost last

    @contextlib.contextmanager
    def stage(self, label: str, total: int | None = None, unit: str = "it"):
        start = time.monotonic()
        state = {"done": 0, "drawn": 0.0, "shown": False}

        def draw(now: float) -> None:
            done = state["done"]
            rate = done / max(now - start, 1e-9)
            if total:
                filled = int(_WIDTH * min(done, total) / total)
                text = (f"{label}: {100 * done / total:3.0f}% [{'#' * filled}{'.' * (_WIDTH - filled)}] "
                        f"{done:,}/{total:,} {unit}s, {rate:,.0f} {unit}/s")
            else:
                text = f"{label}: {done:,} {unit}s, {rate:,.0f} {unit}/s"
            columns = shutil.get_terminal_size((80, 24)).columns
            self.stream.write("\r" + text[:max(columns - 1, 0)] + "\x1b[K")
            self.stream.flush()
            state["drawn"], state["shown"] = now, True

        def advance(n: int = 1) -> None:
            state["done"] += n
            now = time.monotonic()
            if now - state["drawn"] >= _INTERVAL:
                draw(now)

        self._open.append(draw)
        draw(start)
        try:
            yield advance
        finally:
            self._open.pop()
            if self._open:
                self._open[-1](time.monotonic())
            elif state["shown"]:
                self.stream.write("\r\x1b[K")
                self.stream.flush()


def progress_for(quiet: bool, stream=None) -> Progress:
    """A bar on ``stream`` (default stderr) when it is a terminal and not ``quiet``; otherwise silent."""
    stream = sys.stderr if stream is None else stream
    if quiet or not (hasattr(stream, "isatty") and stream.isatty()):
        return SILENT
    return _Bar(stream)
