"""How counts read in the sentences splatconv prints (notes, errors, reports)."""

from __future__ import annotations


def plural(count: int, noun: str, nouns: str | None = None) -> str:
    """``"1 splat"``, ``"2 splats"``, ``"1,000 splats"``: the count with thousands separators and the noun
    agreeing with it (``nouns``: an irregular plural)."""
    return f"{count:,} {noun if count == 1 else nouns or noun + 's'}"
