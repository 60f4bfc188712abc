"""How counts read in the sentences splatconv prints (notes, errors, reports)."""

from __future__ import annotations


def plural(count: int, noun: str, nouns: str | None = None) -> str:
    """``"1 splat"``, ``"2 splats"``, ``"1,000 splats"``: the count with thousands separators and the noun
    agreeing with it (``nouns``: an irregular plural)."""
    return f"{count:,} {noun if count == 1 else nouns or noun + 's'}"


def kind_words(kind: str) -> str:
    """An undrawable kind (:data:`splatconv.viewer.UNDRAWABLE_KINDS`) in words:
    ``"nan_position"`` -> ``"NaN position"``."""
    return kind.replace("_", " ").replace("nan", "NaN")


def kinds_text(counts: dict) -> str:
    """``{kind: count}`` as ``"zero rotation 240, NaN position 20"``: the kinds that occur, in the order given."""
    return ", ".join(f"{kind_words(kind)} {count:,}" for kind, count in counts.items() if count)
