"""Files: safe output (never onto an input, never over a file unless asked, atomically), mapped input."""

from __future__ import annotations

import contextlib
import mmap
import os
import sys
import tempfile

import numpy as np

from .errors import FormatError, OutputError


def open_input(path: str):
    """Open ``path`` for reading, binary; a file that cannot be opened is a :class:`FormatError`."""
    try:
        return open(path, "rb")
    except OSError as e:
        raise FormatError(f"cannot open: {e.strerror}", path) from None


def check_output(output: str | os.PathLike, inputs=(), force: bool = False) -> None:
    """Refuse an output path that would clobber an input or an existing file.

    Parameters
    ----------
    output : path
    inputs : iterable of path
        Files read for this output; writing onto any of them (by any path, link or
        hard link) is refused even with ``force``.
    force : bool
        Allow replacing an existing file that is not an input.

    Raises
    ------
    OutputError
    """
    output = os.fspath(output)
    if os.path.isdir(output):
        raise OutputError("is a directory", output)
    parent = os.path.dirname(os.path.abspath(output))
    if not os.path.isdir(parent):
        raise OutputError(f"folder {parent} does not exist", output)
    if not os.path.exists(output):
        return
    for inp in inputs:
        with contextlib.suppress(OSError):
            if os.path.samefile(output, inp):
                raise OutputError("is the input file; refusing to write onto it", output)
    if not force:
        raise OutputError("already exists (use --force to replace it)", output)


@contextlib.contextmanager
def atomic_writer(output: str | os.PathLike):
    """Open a temporary file beside ``output``; rename it over ``output`` on success.

    On any exception the temporary file is removed and ``output`` is untouched.
    An ``OSError`` that names no file or only the temporary one (a full disk, a
    file size limit: ``write`` says "File too large" and nothing else) is made to
    name ``output``, so the user learns which write failed.

    Yields
    ------
    file
        A binary file object to write to.
    """
    output = os.fspath(output)
    parent = os.path.dirname(os.path.abspath(output))
    try:
        fd, tmp = tempfile.mkstemp(dir=parent, prefix="." + os.path.basename(output) + ".", suffix=".part")
    except OSError as e:
        e.filename, e.filename2 = output, None  # not the random temporary name
        raise
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, output)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError) and e.filename in (None, tmp):
            e.filename, e.filename2 = output, None
        raise


class AtomicGroup:
    """Several outputs written all or nothing; see :func:`atomic_group`."""

    def __init__(self):
        self._staged = []  # (temporary path, output path)

    @contextlib.contextmanager
    def open(self, output: str | os.PathLike):
        """A binary file to write ``output``'s content to: a temporary file beside it until the group ends."""
        output = os.fspath(output)
        parent = os.path.dirname(os.path.abspath(output))
        try:
            fd, tmp = tempfile.mkstemp(dir=parent, prefix="." + os.path.basename(output) + ".", suffix=".part")
        except OSError as e:
            e.filename, e.filename2 = output, None
            raise
        self._staged.append((tmp, output))
        try:
            with os.fdopen(fd, "wb") as f:
                yield f
        except OSError as e:
            if e.filename in (None, tmp):
                e.filename, e.filename2 = output, None
            raise


@contextlib.contextmanager
def atomic_group():
    """Write several files all or nothing (e.g. a numbered frame sequence).

    Each file is written to a temporary file beside it (:meth:`AtomicGroup.open`);
    when the block ends without an exception, every temporary file is renamed
    over its output, else all are removed and no output is touched. (The renames
    at the end are one system call each: only a failure between them, such as a
    power cut, could leave some outputs new and some old.)

    Yields
    ------
    AtomicGroup
    """
    group = AtomicGroup()
    try:
        yield group
        umask = os.umask(0)
        os.umask(umask)
        for tmp, output in group._staged:
            os.chmod(tmp, 0o666 & ~umask)
        for tmp, output in group._staged:
            os.replace(tmp, output)
    except BaseException:
        for tmp, _output in group._staged:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise


#: madvise(2) MADV_POPULATE_READ (Linux 5.14+): map every page of a file mapping now.
_MADV_POPULATE_READ = getattr(mmap, "MADV_POPULATE_READ", 22 if sys.platform.startswith("linux") else None)


def populate(array: np.ndarray) -> None:
    """Map every page of the file mapping behind ``array`` now, in one call.

    Readers go through every splat, and faulting a mapping's pages in one at a
    time as numpy first touches them costs two to three times as long (a new
    process sharing the mapping starts with none of them mapped). Does nothing
    for an array not backed by ``np.memmap``, or where the call is not supported.
    """
    while array is not None and getattr(array, "_mmap", None) is None:
        array = array.base if isinstance(array, np.ndarray) else None
    if array is None or _MADV_POPULATE_READ is None:
        return
    try:
        array._mmap.madvise(_MADV_POPULATE_READ)
    except (OSError, ValueError, AttributeError):
        pass
