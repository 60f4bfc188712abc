"""Opening input files: regular files only, never one that blocks or never ends."""

from __future__ import annotations

import os
import stat

from ..errors import FormatError

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"))


def open_input(path: str, what: str | None = None):
    """Open the regular file ``path`` for reading, binary.

    Devices, FIFOs and sockets are refused: ``/dev/zero`` never ends and a FIFO
    blocks until someone writes. The file is opened non-blocking (which changes
    nothing for a regular file) so that checking a FIFO cannot hang.

    Parameters
    ----------
    path : str
    what : str, optional
        What the file is for (``"cameras"``), put in the message.

    Raises
    ------
    FormatError
        When it cannot be opened or is not a regular file.
    """
    label = f"cannot read {what}" if what else "cannot open"
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise FormatError(f"{label}: {e.strerror}", path) from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
            raise FormatError(f"{label}: is {kind}, not a regular file", path)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
