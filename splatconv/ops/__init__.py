"""Operations on scenes, a module per family; no I/O, no printing.

Each returns the new :class:`splatconv.model.Scene` and a report of what it did.
"""
