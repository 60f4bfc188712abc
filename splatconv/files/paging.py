"""Paging in a mapped input: every page of a file mapping in one call."""

from __future__ import annotations

import mmap
import sys

import numpy as np

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
