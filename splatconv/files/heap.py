"""The process's heap: one malloc arena for every thread.

glibc's malloc gives each thread that allocates while another does an arena of
its own, and keeps what is freed there for that arena. The helper threads that
pack and unpack blocks (``.splatv``, ``.splatvq``) then leave their freed working
arrays resident in arenas no other thread takes from: a proved 1M-splat
``convert`` held some 85 MB so between a candidate's encode and its decode into
the renderer, on top of what either needs. With one arena, what one phase frees
the next allocates; the helpers work on whole blocks, so they seldom wait on its
lock (a ``.splatv`` conversion runs as fast).
"""

from __future__ import annotations

import ctypes
import os
import sys

#: mallopt(3) parameter: the most arenas malloc makes (glibc).
_M_ARENA_MAX = -8


def _glibc(name: str, argtypes: tuple):
    """The C library's function ``name`` (argument and int result types set), or None off Linux or where
    the library has none."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        function = getattr(ctypes.CDLL(None), name)
    except (OSError, AttributeError):
        return None
    function.argtypes, function.restype = argtypes, ctypes.c_int
    return function


def one_arena() -> bool:
    """Have every thread's malloc take from the main arena (glibc), unless ``MALLOC_ARENA_MAX`` says
    otherwise; call it before any helper thread starts. Whether it was set (False off glibc)."""
    mallopt = None if "MALLOC_ARENA_MAX" in os.environ else _glibc("mallopt", (ctypes.c_int, ctypes.c_int))
    return mallopt is not None and mallopt(_M_ARENA_MAX, 1) == 1


def trim() -> None:
    """Give the heap's free pages back to the system (glibc's ``malloc_trim``; nothing elsewhere): between a
    proof's passes, what one pass freed is not resident through the next (a candidate's decode and draws
    free some 100 MB at 1M splats, whose pages its next encode would only partly reuse)."""
    malloc_trim = _glibc("malloc_trim", (ctypes.c_size_t,))
    if malloc_trim is not None:
        malloc_trim(0)
