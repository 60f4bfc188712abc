"""Process-wide signal state: SIGTERM and SIGHUP end a run as Ctrl-C does, and can be held for an instant.

Ending by an exception runs every ``finally`` on the way out (part files,
decompressed temporaries); :func:`hold_signals` covers the instant between
creating such a file and entering the ``try`` that removes it.
"""

from __future__ import annotations

import contextlib
import signal

#: Signals that end a run the way Ctrl-C does: with the clean-up of every
#: ``finally`` (part files, decompressed temporaries). SIGKILL cannot be caught;
#: its part files are removed by the next run for the same output.
CLEANUP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


_held = 0
_pending = None


def hold_signals():
    """Hold back the exit that SIGINT, SIGTERM and SIGHUP cause until :func:`release_signals`.

    For the instant between creating a temporary file and entering the ``try``
    that removes it: a signal handled there would leave the file behind. Works
    through the handlers :func:`exit_on_signals` installs (the signal may arrive
    in any thread: blocking it in this one would not do).

    Returns
    -------
    object
        To pass to :func:`release_signals`.
    """
    global _held
    _held += 1
    return _held


def release_signals(_token=None) -> None:
    """Undo :func:`hold_signals`; a signal that came meanwhile takes effect now."""
    global _held, _pending
    _held = max(0, _held - 1)
    if _held == 0 and _pending is not None:
        signum, _pending = _pending, None
        _exit_for_signal(signum, None)


def _exit_for_signal(signum, _frame):
    # Raised in the main thread between two bytecodes; unwinding runs every
    # clean-up on the way. 128 + N is the status a shell gives a process killed by N.
    global _pending
    if _held:
        _pending = signum
        return
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise SystemExit(128 + signum)


def exit_on_signals() -> None:
    """Make SIGTERM and SIGHUP raise ``SystemExit(128 + signal)`` in the main thread, SIGINT ``KeyboardInterrupt``.

    Each can be held back for an instant by :func:`hold_signals`.

    Call once at program start (the CLI does); does nothing outside the main
    thread, where handlers cannot be set.
    """
    for signum in CLEANUP_SIGNALS + (signal.SIGINT,):
        with contextlib.suppress(ValueError, OSError):
            current = signal.getsignal(signum)
            if current is signal.SIG_IGN or (signum == signal.SIGINT and current is not signal.default_int_handler):
                continue  # started under nohup, or someone else handles Ctrl-C: leave it
            signal.signal(signum, _exit_for_signal)
