"""Copying a scene's columns into a new row table, the form the writers read fastest.

Ops never change the columns they are given (they may be read-only views of a
memory-mapped input); they build new columns here and change those in place.
The new columns are views of one row-major table (:func:`splatconv.model.lite_rows`
or a row gather of the input's own table), so the writers keep their whole-row
fast paths (:func:`splatconv.model.row_fields`).
"""

from __future__ import annotations

import numpy as np

from ..model import COLUMNS, Scene, lite_rows, row_fields


def gather(columns: dict, index: np.ndarray | None = None) -> dict:
    """Rows ``index`` (all rows when None) of every column, as writeable views of one new table.

    Parameters
    ----------
    columns : dict of str to (N,) float32 ndarray
    index : (M,) integer ndarray, optional

    Returns
    -------
    dict of str to (M,) float32 ndarray
    """
    found = row_fields([columns[name] for name in COLUMNS])
    if found is not None:
        matrix, fields = found
        # One gather of whole rows (one pass over memory) instead of a pass per column.
        rows = matrix.copy() if index is None else matrix[index]
        return {name: rows[:, f] for name, f in zip(COLUMNS, fields)}
    n = len(columns["x"]) if index is None else len(index)
    _rows, out = lite_rows(n)
    for name in COLUMNS:
        column = np.asarray(columns[name])
        out[name][:] = column if index is None else column[index]
    return out


def derive(scene: Scene, columns: dict, notes=(), cameras=...) -> Scene:
    """A new scene with ``columns`` (and ``cameras`` when given), ``scene``'s facts,
    and its notes followed by ``notes``."""
    return Scene(columns=columns, cameras=scene.cameras if cameras is ... else cameras, variant=scene.variant,
                 meta=dict(scene.meta), notes=list(scene.notes) + list(notes))


def keep_rows(scene: Scene, keep: np.ndarray) -> dict:
    """The columns of the rows where ``keep`` (``(N,) bool``) is true; the same dict when all are."""
    if keep.all():
        return scene.columns
    return gather(scene.columns, np.flatnonzero(keep))
