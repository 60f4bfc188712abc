"""Paging in a mapped input: every page of a file mapping in one call."""

from __future__ import annotations

import mmap
import sys

import numpy as np

#: madvise(2) MADV_POPULATE_READ (Linux 5.14+): map every page of a file mapping now.
_MADV_POPULATE_READ = getattr(mmap, "MADV_POPULATE_READ", 22 if sys.platform.startswith("linux") else None)


def _mapped(array):
    """The ``np.memmap`` ``array`` is a view of, or None."""
    while array is not None and getattr(array, "_mmap", None) is None:
        array = array.base if isinstance(array, np.ndarray) else None
    return array


def populate(array: np.ndarray) -> None:
    """Map every page of the file mapping behind ``array`` now, in one call.

    Readers go through every splat, and faulting a mapping's pages in one at a
    time as numpy first touches them costs two to three times as long (a new
    process sharing the mapping starts with none of them mapped). Does nothing
    for an array not backed by ``np.memmap``, or where the call is not supported.
    """
    array = _mapped(array)
    if array is None or _MADV_POPULATE_READ is None:
        return
    try:
        array._mmap.madvise(_MADV_POPULATE_READ)
    except (OSError, ValueError, AttributeError):
        pass


def release(array: np.ndarray) -> None:
    """Drop the pages of the file mapping that ``array`` (a view of it) spans from this process's memory.

    They stay in the page cache and are read again if touched: a reader that
    goes through a mapped file a piece at a time (``info``) holds a piece of
    it, not the file. Does nothing for an array not backed by ``np.memmap``,
    or where the call is not supported.
    """
    root = _mapped(array)
    if root is None or not len(array):
        return
    mapping = root._mmap
    try:
        start = array.__array_interface__["data"][0] - np.frombuffer(mapping, np.uint8).ctypes.data
        start -= start % mmap.PAGESIZE
        end = array.__array_interface__["data"][0] - np.frombuffer(mapping, np.uint8).ctypes.data \
            + len(array) * array.strides[0]
        mapping.madvise(mmap.MADV_DONTNEED, start, min(end, len(mapping)) - start)
    except (OSError, ValueError, AttributeError):
        pass


def hand_back(arrays) -> None:
    """Drop from this process's memory every page of the file mappings behind ``arrays``, each mapping
    once (a scene's columns: views of one mapped table): between two passes over a mapped input, hold
    none of it. The next pass reads the pages again from the page cache. Arrays not backed by a
    read-only ``np.memmap`` (every reader's mode) are left as they are.
    """
    roots = {}
    for array in arrays:
        root = _mapped(array)
        while root is not None and getattr(root.base, "_mmap", None) is not None:  # the mapping's own array
            root = root.base
        # Only a read-only mapping: the pages of a copy-on-write one ("c") may hold changes of this
        # process alone, which dropping them would undo.
        if root is not None and getattr(root, "mode", None) == "r":
            roots.setdefault(id(root._mmap), root)
    for root in roots.values():
        release(root)
