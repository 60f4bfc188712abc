"""The ``splatconv`` command: a thin click layer over the library.

Library errors become one ``Error: ...`` line: exit 1 for bad input, 2 for
usage. Commands live a module per family and register on :data:`main` when
that module is loaded, which is when the command runs (``._group.COMMANDS``):
``splatconv --help`` imports none of them.
"""

from __future__ import annotations

from ._group import commands, main

__all__ = ["main", "commands"]
