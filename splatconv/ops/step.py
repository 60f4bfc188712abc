"""One edit step, as :func:`splatconv.ops.edit.apply_edits` runs it: the interface every filter fills.

The planner reads the rows in passes over blocks (a block stays in cache while
every step reads it), then lets each step, in order, decide which rows it keeps
from what it read, and report. A step that re-times the rows (the trim) copies
them with a new time map; the steps after it read the copy, in a second pass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .report import OpReport


@dataclass
class Rows:
    """The splats as a plan goes: the columns, which of their rows are still kept, and
    whether the columns are a copy made by the plan (which may then be changed in place).

    Attributes
    ----------
    columns : dict of str -> (N,) float32
    alive : (N,) bool or None
        Rows still kept; None: all of them.
    owned : bool
    """

    columns: dict
    alive: np.ndarray | None = None
    owned: bool = False

    @property
    def count(self) -> int:
        """Rows still kept."""
        return len(self.columns["x"]) if self.alive is None else int(self.alive.sum())

    def keep(self, mask: np.ndarray | None) -> None:
        """Keep only the rows of ``mask`` (``(N,) bool``; None: keep all) among those kept so far."""
        if mask is not None:
            self.alive = mask if self.alive is None else self.alive & mask


class Step:
    """One edit of a plan.

    Attributes
    ----------
    name : str
        As the option is named (:data:`splatconv.ops.edit.ORDER`).
    dtype : numpy dtype
        Of the value :meth:`tester` gives each row (a mask, a kind, a key).
    retimes : bool
        Whether :meth:`apply` copies the rows with a new time map (the steps after it
        are read from the copy, in another pass).
    """

    name: str = ""
    dtype = bool
    retimes = False

    def tester(self, columns: dict):
        """``test(part, block)``: this step's values of the rows ``part`` (a slice) of
        ``columns``, ``block`` their columns: ``(len(part),) dtype``."""
        raise NotImplementedError

    def apply(self, rows: Rows, values: np.ndarray) -> OpReport:
        """Keep the rows this step keeps, given its ``values`` of every row of ``rows.columns``;
        the report of what it did (over the rows kept before it)."""
        raise NotImplementedError


__all__ = ["Rows", "Step"]
