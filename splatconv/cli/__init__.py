"""The ``splatconv`` command: a thin click layer over the library.

Library errors become one ``Error: ...`` line: exit 1 for bad input, 2 for
usage. Commands live a module per family and register on :data:`main`.
"""

from __future__ import annotations

from . import drawing, edit, scenes, web  # noqa: F401  (registers the commands)
from ._base import main

__all__ = ["main"]
