"""Files locked while in use (``flock``), so that those a killed run left behind can be told apart and removed.

The lock dies with its process: a matching file whose lock can be taken has no
live user. Part files of outputs (:mod:`splatconv.files.output`) and the
temporary files decompressed inputs go to (:func:`locked_temporary`) both work so.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import stat
import tempfile

from .signals import hold_signals, release_signals


def remove_unlocked(folder: str, pattern) -> list:
    """Remove this user's regular files in ``folder`` whose names match ``pattern`` and whose lock is free.

    Returns
    -------
    list of str
        The paths removed.
    """
    removed = []
    try:
        names = [n for n in os.listdir(folder) if pattern.fullmatch(n)]
    except OSError:
        return removed
    for name in names:
        path = os.path.join(folder, name)
        try:
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
        except OSError:
            continue
        try:
            info = os.fstat(fd)
            if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid():
                continue
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # raises while its writer holds it
            os.unlink(path)
            removed.append(path)
        except OSError:
            pass
        finally:
            os.close(fd)
    return removed


#: Names of the temporary files decompressed inputs go to (in the temporary folder).
TEMP_PREFIX = "splatconv-"
_TEMP_PATTERN = re.compile(re.escape(TEMP_PREFIX) + r"[a-z0-9_]{8}\.[A-Za-z0-9_]{1,16}")


@contextlib.contextmanager
def locked_temporary(suffix: str):
    """A locked temporary file for a decompressed input: yields ``(fd, path)``; removed on exit.

    Those that killed runs left (unlocked) in the temporary folder are removed
    first, as :func:`splatconv.files.output.remove_stale_parts` does for outputs. The lock is held
    until the file is removed; ``fd`` is the caller's to close.
    """
    held = hold_signals()  # a signal between creating a file and the try would leave it behind
    lock = None
    try:
        # Held here too: the first call probes the folder with a file of its own.
        folder = tempfile.gettempdir()
        remove_unlocked(folder, _TEMP_PATTERN)
        fd, tmp = tempfile.mkstemp(prefix=TEMP_PREFIX, suffix=suffix)
        lock = os.dup(fd)
        with contextlib.suppress(OSError):
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BaseException:
        if lock is not None:
            os.close(lock)
        release_signals(held)
        raise
    try:
        release_signals(held)
        yield fd, tmp
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        os.close(lock)
