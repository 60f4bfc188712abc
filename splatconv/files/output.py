"""Safe output: never onto an input, never over a file unless asked, atomically; one file or a group.

Output goes to a ``.NAME.XXXXXXXX.part`` file beside ``NAME`` that is renamed into
place at the end. While it is written the part file is locked (``flock``), so a
later run can tell the leftovers of a killed one (unlocked: the lock dies with its
process) from a run still writing, and removes them. One writer does this work
(:class:`AtomicGroup`): :func:`atomic_writer` is a group of one file.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import tempfile

from ..errors import OutputError
from .signals import check_signals, hold_signals, release_signals
from .stale import remove_unlocked


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
    return remove_unlocked(os.path.dirname(os.path.abspath(output)), _part_pattern(output))


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


def _name_output(error: OSError, tmp: str, output: str) -> None:
    """Make an ``OSError`` that names no file or only the part file name ``output`` instead.

    A full disk or a file size limit (``write`` says "File too large" and
    nothing else) would otherwise not say which write failed, or name a random
    temporary file.
    """
    if error.filename in (None, tmp):
        error.filename, error.filename2 = output, None


class AtomicGroup:
    """Outputs written all or nothing: each to a locked part file beside it, put in place when the group ends.

    Made by :func:`atomic_group` (several files) and :func:`atomic_writer` (one).
    """

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
        release_signals(held)  # a signal that came meanwhile is handled here: the part is staged, so removed
        try:
            with os.fdopen(fd, "wb") as f:
                yield f
        except OSError as e:
            _name_output(e, tmp, output)
            raise

    def _commit(self) -> None:
        """Rename every part file over its output (with ``replace`` false: only onto a name still free).

        Not after a signal that asked the run to end, even one whose exception
        was lost (:func:`check_signals`); one that comes during the renames ends
        the run once they are done (the outputs are then whole).
        """
        held = hold_signals()
        try:
            check_signals()
            self._rename_all()
        finally:
            release_signals(held)

    def _rename_all(self) -> None:
        umask = os.umask(0)
        os.umask(umask)
        linked = []
        try:
            for tmp, output in self._staged:
                try:
                    os.chmod(tmp, 0o666 & ~umask)
                except OSError as e:
                    _name_output(e, tmp, output)
                    raise
            for tmp, output in self._staged:
                try:
                    if self.replace:
                        os.replace(tmp, output)
                    else:
                        _link_into_place(tmp, output)
                        linked.append(output)
                except OSError as e:
                    _name_output(e, tmp, output)
                    raise
        except BaseException:
            for output in linked:  # new names this group made a moment ago: none may stay
                with contextlib.suppress(OSError):
                    os.unlink(output)
            raise

    def _discard(self) -> None:
        for tmp, _output in self._staged:
            with contextlib.suppress(OSError):
                os.unlink(tmp)

    def _unlock(self) -> None:
        for lock in self._locks:
            os.close(lock)


@contextlib.contextmanager
def atomic_group(replace: bool = True):
    """Write several files all or nothing (e.g. a numbered frame sequence).

    Each file is written to a temporary file beside it (:meth:`AtomicGroup.open`);
    when the block ends without an exception, every temporary file is renamed
    over its output, else all are removed and no output is touched. (The renames
    at the end are one system call each: only a failure between them, such as a
    power cut, could leave some outputs new and some old.) Part files a killed
    run left for the same outputs are removed first (see :func:`remove_stale_parts`).

    Parameters
    ----------
    replace : bool
        Replace existing outputs. When False, an output that appeared since it
        was checked (another run) is kept, the group fails there, and
        :class:`OutputError` is raised.

    Yields
    ------
    AtomicGroup
    """
    group = AtomicGroup(replace)
    try:
        yield group
        group._commit()
    except BaseException:
        group._discard()
        raise
    finally:
        group._unlock()


@contextlib.contextmanager
def atomic_writer(output: str | os.PathLike, replace: bool = True):
    """Open a temporary file beside ``output``; rename it to ``output`` on success (a group of one).

    On any exception (``KeyboardInterrupt`` and the ``SystemExit`` of
    :func:`splatconv.files.signals.exit_on_signals` included) the temporary file
    is removed and ``output`` is untouched. An ``OSError`` that names no file or
    only the temporary one is made to name ``output``.

    Parameters
    ----------
    output : path
    replace : bool
        As for :func:`atomic_group`.

    Yields
    ------
    file
        A binary file object to write to.
    """
    with atomic_group(replace) as group, group.open(output) as f:
        yield f
