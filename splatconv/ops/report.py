"""What an operation on a scene did: counts and sentences, no printing."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class OpReport:
    """The outcome of one operation on a scene.

    Attributes
    ----------
    op : str
        The operation, named as its command-line option (``"drop-nonfinite"``,
        ``"trim"``, ``"transform"``, ...).
    count_in, count_out : int
        Splats before and after.
    notes : list of str
        What was removed or changed, in words, each figure true; shown to the
        user as ``note:`` lines.
    counts : dict of str to int
        Figures behind the notes, by name (e.g. splats removed per attribute group).
    """

    op: str
    count_in: int
    count_out: int
    notes: list = field(default_factory=list)
    counts: dict = field(default_factory=dict)

    @property
    def removed(self) -> int:
        """Splats the operation removed."""
        return self.count_in - self.count_out
