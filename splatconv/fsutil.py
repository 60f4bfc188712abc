"""Files: safe output (never onto an input, never over a file unless asked, atomically), mapped input.

Output goes to a ``.NAME.XXXXXXXX.part`` file beside ``NAME`` that is renamed into
place at the end. While it is written the part file is locked (``flock``), so a
later run can tell the leftovers of a killed one (unlocked: the lock dies with its
process) from a run still writing, and removes them.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import mmap
import os
import re
import signal
import stat
import sys
import tempfile

import numpy as np

from .errors import FormatError, OutputError


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


def _part_pattern(output: str):
    """The names ``tempfile.mkstemp`` gives the part files of ``output`` (8 random characters)."""
    return re.compile(re.escape("." + os.path.basename(output) + ".") + r"[a-z0-9_]{8}" + re.escape(".part"))


def remove_stale_parts(output: str | os.PathLike) -> list:
    """Remove part files of ``output`` left by runs that were killed (``SIGKILL``, power loss).

    A part file whose lock can be taken has no live writer. Only names of the
    form ``.NAME.XXXXXXXX.part`` beside ``output`` are considered.

    Returns
    -------
    list of str
        The paths removed.
    """
    output = os.fspath(output)
    return _remove_unlocked(os.path.dirname(os.path.abspath(output)), _part_pattern(output))


def _remove_unlocked(folder: str, pattern) -> list:
    """Remove this user's regular files in ``folder`` whose names match ``pattern`` and whose lock is free."""
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
    first, as :func:`remove_stale_parts` does for outputs. The lock is held
    until the file is removed; ``fd`` is the caller's to close.
    """
    held = hold_signals()  # a signal between creating a file and the try would leave it behind
    lock = None
    try:
        # Held here too: the first call probes the folder with a file of its own.
        folder = tempfile.gettempdir()
        _remove_unlocked(folder, _TEMP_PATTERN)
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


def _link_into_place(tmp: str, output: str) -> None:
    """Give ``tmp`` the name ``output`` only if no file has that name, checked at that instant.

    ``link`` fails when the name exists, unlike ``rename``: of two runs racing
    for one new name, exactly one wins. Where hard links are not supported the
    check falls back to ``exists`` just before the rename.
    """
    try:
        os.link(tmp, output)
    except FileExistsError:
        raise OutputError("already exists (use --force to replace it)", output) from None
    except OSError as e:
        if e.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK, errno.EXDEV):
            raise
        if os.path.lexists(output):
            raise OutputError("already exists (use --force to replace it)", output) from None
        os.replace(tmp, output)
        return
    os.unlink(tmp)


def _locked_part(output: str, parent: str):
    """Create and lock a part file for ``output``: ``(fd, path)``.

    Another run's :func:`remove_stale_parts` may take a new part for a dead one's
    in the instant between its creation and its lock: then it is gone by the
    time the lock is held, and a new one is made.
    """
    for _ in range(8):
        try:
            fd, tmp = tempfile.mkstemp(dir=parent, prefix="." + os.path.basename(output) + ".", suffix=".part")
        except OSError as e:
            e.filename, e.filename2 = output, None  # not the random temporary name
            raise
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)  # another run holds it to remove it
            continue
        except OSError:
            return fd, tmp  # no locks on this file system: nothing removes it either
        with contextlib.suppress(FileNotFoundError):
            if os.path.samestat(os.fstat(fd), os.stat(tmp)):
                return fd, tmp
        os.close(fd)
    raise OutputError("cannot create a temporary file beside it (removed as soon as made)", output)


def _start_part(output: str) -> tuple:
    """Remove ``output``'s stale parts and create its locked part file, with signals held.

    Returns ``(fd, tmp, lock, held)``: the part's writing descriptor and path, a second
    descriptor that keeps the part locked after the writing one is closed (an unlocked
    part is a dead run's), and the signal hold. The caller records what it must clean
    up and then calls :func:`release_signals` with ``held``: a signal between creating
    the part and recording it would leave the part behind.
    """
    parent = os.path.dirname(os.path.abspath(output))
    remove_stale_parts(output)
    held = hold_signals()
    try:
        fd, tmp = _locked_part(output, parent)
        return fd, tmp, os.dup(fd), held
    except BaseException:
        release_signals(held)
        raise


@contextlib.contextmanager
def atomic_writer(output: str | os.PathLike, replace: bool = True):
    """Open a temporary file beside ``output``; rename it to ``output`` on success.

    On any exception (``KeyboardInterrupt`` and the ``SystemExit`` of
    :func:`exit_on_signals` included) the temporary file is removed and
    ``output`` is untouched. Part files a killed run left for the same
    ``output`` are removed first (see :func:`remove_stale_parts`). An ``OSError``
    that names no file or only the temporary one (a full disk, a file size
    limit: ``write`` says "File too large" and nothing else) is made to name
    ``output``, so the user learns which write failed.

    Parameters
    ----------
    output : path
    replace : bool
        Replace an existing ``output``. When False, a file that appears under
        that name while this one is written (another run) is kept, and
        :class:`OutputError` is raised.

    Yields
    ------
    file
        A binary file object to write to.
    """
    output = os.fspath(output)
    fd, tmp, lock, held = _start_part(output)
    try:
        release_signals(held)  # a signal that came meanwhile is handled here, inside the try
        with os.fdopen(fd, "wb") as f:
            yield f
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        if replace:
            os.replace(tmp, output)
        else:
            _link_into_place(tmp, output)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError) and e.filename in (None, tmp):
            e.filename, e.filename2 = output, None
        raise
    finally:
        os.close(lock)


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


class AtomicGroup:
    """Several outputs written all or nothing; see :func:`atomic_group`."""

    def __init__(self, replace: bool = True):
        self.replace = replace
        self._staged = []  # (temporary path, output path)
        self._locks = []  # descriptors holding the part files' locks

    @contextlib.contextmanager
    def open(self, output: str | os.PathLike):
        """A binary file to write ``output``'s content to: a temporary file beside it until the group ends."""
        output = os.fspath(output)
        fd, tmp, lock, held = _start_part(output)
        self._locks.append(lock)  # held until the group ends, so no other run takes it for a dead one's
        self._staged.append((tmp, output))
        release_signals(held)
        try:
            with os.fdopen(fd, "wb") as f:
                yield f
        except OSError as e:
            if e.filename in (None, tmp):
                e.filename, e.filename2 = output, None
            raise


@contextlib.contextmanager
def atomic_group(replace: bool = True):
    """Write several files all or nothing (e.g. a numbered frame sequence).

    Each file is written to a temporary file beside it (:meth:`AtomicGroup.open`);
    when the block ends without an exception, every temporary file is renamed
    over its output, else all are removed and no output is touched. (The renames
    at the end are one system call each: only a failure between them, such as a
    power cut, could leave some outputs new and some old.)

    With ``replace`` false, an output that appeared since it was checked is not
    replaced: the group fails there (as :func:`atomic_writer` does).

    Yields
    ------
    AtomicGroup
    """
    group = AtomicGroup(replace)
    try:
        yield group
        umask = os.umask(0)
        os.umask(umask)
        for tmp, output in group._staged:
            os.chmod(tmp, 0o666 & ~umask)
        linked = []
        try:
            for tmp, output in group._staged:
                if replace:
                    os.replace(tmp, output)
                else:
                    _link_into_place(tmp, output)
                    linked.append(output)
        except BaseException:
            for output in linked:  # new names this group made a moment ago: none may stay
                with contextlib.suppress(OSError):
                    os.unlink(output)
            raise
    except BaseException:
        for tmp, _output in group._staged:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise
    finally:
        for lock in group._locks:
            os.close(lock)


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
