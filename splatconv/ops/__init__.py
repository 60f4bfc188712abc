"""Operations on the scene model, a module per family; no I/O, no printing.

Each operation returns the new scene and a report of what it did.
"""
