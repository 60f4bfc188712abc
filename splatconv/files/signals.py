"""Process-wide signal state: SIGTERM and SIGHUP end a run as Ctrl-C does, and can be held for an instant.

Ending by an exception runs every ``finally`` on the way out (part files,
decompressed temporaries); :func:`hold_signals` covers the instant between
creating such a file and entering the ``try`` that removes it.

An exception raised by a signal handler is not certain to end the run: the
handler runs between two bytecodes of whatever Python code the main thread is
in, and C code that calls Python and then clears the error it got back (numpy's
``np.dtype((np.void, n))``, called as the ``.splatv`` writer starts, did so)
swallows it, and the run went on to write its output and exit 0. So a signal is
also remembered: :func:`check_signals` raises its exception again, and every
output is put in place only after that check (``files.output``), and the
command line checks once more before it exits, whatever error the exception
became. A run a signal ended then leaves at once (:func:`exit_at_once`): the
threading module's own locks are not safe against it.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys

#: Signals that end a run the way Ctrl-C does: with the clean-up of every
#: ``finally`` (part files, decompressed temporaries). SIGKILL cannot be caught;
#: its part files are removed by the next run for the same output.
CLEANUP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


_held = 0
_pending = None
#: The first signal that asked this run to end (None: none yet). Never cleared:
#: once asked to end, the run ends, even if the exception raised for it was lost.
_received = None


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
    # clean-up on the way.
    global _pending, _received
    if _received is None:
        _received = signum
    if _held:
        _pending = signum
        return
    _raise_for(signum)


def _raise_for(signum):
    if signum == signal.SIGINT:
        raise KeyboardInterrupt  # click's "Aborted!", status 1
    raise SystemExit(_status(signum))


def _status(signum) -> int:
    # 128 + N is the status a shell gives a process killed by N; Ctrl-C is click's 1.
    return 1 if signum == signal.SIGINT else 128 + signum


def check_signals() -> None:
    """Raise the exception of a signal that asked this run to end, if one did.

    For the points past which a run would make its work visible (an output put
    in place, a zero exit status): the exception the handler raised may have
    been swallowed by C code wherever the signal landed (see the module's docstring).

    Raises
    ------
    KeyboardInterrupt or SystemExit
        ``KeyboardInterrupt`` for SIGINT, ``SystemExit(128 + N)`` for signal N.
    """
    if _received is not None:
        _raise_for(_received)


def asked_to_end() -> bool:
    """Whether a signal asked this run to end (and was not consumed on purpose)."""
    return _received is not None


def status_for_signal() -> int:
    """The exit status of a run the signal :func:`asked_to_end`: 128 + N, or 1 for Ctrl-C (click's)."""
    return _status(_received)


def exit_at_once(code: int) -> None:
    """End the process with ``code`` without waiting for its threads: for a run a signal ended.

    Call it once the exception has unwound every ``finally`` (the clean-ups are
    done). A signal can land inside the threading module's own ``with`` blocks
    (``Thread.start`` waiting for the new thread to start, as a thread pool grows),
    where Python cannot promise to release the lock it just took; the new thread
    then waits for that lock forever, and so would the interpreter's exit, which
    joins every thread. Standard output and error are flushed first.
    """
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


def consume_signals() -> None:
    """Forget the signals that asked the run to end: for a command whose normal end a Ctrl-C is (``view``).

    Call it only where the exception the signal raised has been caught on purpose.
    """
    global _received, _pending
    _received = _pending = None


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
