"""Copying a scene's columns into a new row table, a cache-sized block of rows at a time.

Ops never change the columns they are given (they may be read-only views of a
memory-mapped input); they build new columns here and change those in place.
The new columns are views of one row-major table (:func:`splatconv.model.lite_rows`
or a row gather of the input's own table), so the writers keep their whole-row
fast paths (:func:`splatconv.model.row_fields`).

Columns of a row table are strided: a pass over one column touches every row's
cache line. Ops therefore work a block of :data:`CHUNK` rows at a time (about
1 MB of lite rows, which stays in cache across the column passes) rather than
column after column over the whole table.
"""

from __future__ import annotations

import numpy as np

from ..model import COLUMNS, Scene, lite_rows, row_fields

#: Rows a block: 8,192 lite rows are 1 MB.
CHUNK = 1 << 13


def blocks(columns: dict, names=COLUMNS, size: int = CHUNK):
    """Blocks of rows: ``(slice, {name: (k,) view})`` for each ``size`` rows of ``columns``."""
    n = len(columns["x"])
    # Plain ndarray views: slicing a memmap makes a memmap each time, at many times the cost.
    base = {name: columns[name].view(np.ndarray) for name in names}
    for start in range(0, n, size):
        part = slice(start, min(n, start + size))
        yield part, {name: base[name][part] for name in names}


def gather(columns: dict, index: np.ndarray | None = None, each=None) -> dict:
    """Rows ``index`` (all rows when None) of every column, as writeable views of one new table.

    Parameters
    ----------
    columns : dict of str to (N,) float32 ndarray
    index : (M,) integer ndarray, optional
    each : callable, optional
        ``each(block)`` is called with each block of new rows (a dict of
        writeable ``(k,) float32`` views) right after it is copied, while it is
        in cache: for changing the rows in place.

    Returns
    -------
    dict of str to (M,) float32 ndarray
    """
    m = len(columns["x"]) if index is None else len(index)
    found = row_fields([columns[name] for name in COLUMNS])
    if found is not None:
        matrix, fields = found
        # Whole rows (one pass over memory) instead of a pass per column.
        rows = np.empty((m, matrix.shape[1]), dtype=np.float32)
        out = {name: rows[:, f] for name, f in zip(COLUMNS, fields)}
    else:
        matrix = None
        _rows, out = lite_rows(m)
    for start in range(0, m, CHUNK):
        part = slice(start, min(m, start + CHUNK))
        source = part if index is None else index[part]
        if matrix is not None:
            rows[part] = matrix[source]
        else:
            for name in COLUMNS:
                out[name][part] = np.asarray(columns[name])[source]
        if each is not None:
            each({name: out[name][part] for name in COLUMNS})
    return out


def compact(columns: dict, index: np.ndarray, each=None) -> dict:
    """Rows ``index`` of columns made here (writeable views of one row table), moved up in place.

    Like :func:`gather`, without a second table: ``index`` is ascending, so row
    ``index[i] >= i`` and moving blocks forward never overwrites a row still to
    be moved. Falls back to :func:`gather` for columns that are not such views.
    """
    table = columns["x"].base
    if (not isinstance(table, np.ndarray) or table.ndim != 2 or table.dtype != np.float32
            or not table.flags.writeable or not table.flags.c_contiguous or len(table) != len(columns["x"])
            or any(columns[name].base is not table for name in COLUMNS)):
        return gather(columns, index, each)
    m = len(index)
    for start in range(0, m, CHUNK):
        part = slice(start, min(m, start + CHUNK))
        table[part] = table[index[part]]
        if each is not None:
            each({name: columns[name][part] for name in COLUMNS})
    return {name: columns[name][:m] for name in COLUMNS}


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


def blockwise(fn, columns: dict, names, dtype=bool) -> np.ndarray:
    """``fn(block)`` over blocks of rows, concatenated: an ``(N,)`` array of ``dtype``."""
    out = np.empty(len(columns["x"]), dtype=dtype)
    for part, block in blocks(columns, names):
        out[part] = fn(block)
    return out
