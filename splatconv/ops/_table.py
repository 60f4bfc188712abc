"""Copying a scene's columns into a new row table, a cache-sized block of rows at a time.

Ops never change the columns they are given (they may be read-only views of a
memory-mapped input); they build new columns here and change those in place.
The new columns are views of one row-major table (:func:`splatconv.model.lite_rows`
or a row gather of the input's own table), so the writers keep their whole-row
fast paths (:func:`splatconv.model.row_fields`).

Columns of a row table are strided: a pass over one column touches every row's
cache line. Ops therefore work a block of :data:`CHUNK` rows at a time (about
1 MB of lite rows, which stays in cache across the column passes) rather than
column after column over the whole table, two threads taking blocks in turn
(:func:`run_blocks`).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..model import COLUMNS, Scene, lite_rows, row_fields, with_sh

#: Rows a block: 8,192 lite rows are 1 MB.
CHUNK = 1 << 13
#: Threads working on blocks: numpy lets go of the interpreter lock inside each
#: call, so two threads keep two cores busy; more only add hand-overs of the lock.
WORKERS = max(1, min(os.cpu_count() or 2, 2))


def run_blocks(n: int, job, size: int | None = None) -> list:
    """``job(part)`` for each block ``part`` (a slice) of ``n`` rows, by :data:`WORKERS` threads.

    Blocks are ``size`` rows (default :data:`CHUNK`). Jobs must touch only their
    own rows; their results come back in block order.
    """
    size = CHUNK if size is None else size
    parts = [slice(start, min(n, start + size)) for start in range(0, n, size)]

    def quiet(part):
        # NaN is handled explicitly everywhere; a signalling NaN (a hostile file may
        # hold them) would otherwise warn when widened or compared. The error state
        # belongs to a thread, so it is set in each job.
        with np.errstate(invalid="ignore"):
            return job(part)

    if len(parts) > 1 and WORKERS > 1:
        with ThreadPoolExecutor(max_workers=WORKERS) as pool:
            return list(pool.map(quiet, parts))
    return [quiet(part) for part in parts]


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
    return copy_rows(columns, index)[0]


def copy_rows(columns: dict, index: np.ndarray | None = None, each=None) -> tuple:
    """:func:`gather`, calling ``each(block)`` on each block of new rows as soon as it is copied.

    ``each`` gets a dict of writeable ``(k,) float32`` views of the block (in
    cache right after the copy), may change them in place and returns a number.

    Returns
    -------
    (dict, int or float)
        The new columns and the sum of what ``each`` returned (0 without it). SH bands
        (:data:`splatconv.model.SH_REST`) come along, gathered as they are.
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
        sources = {name: np.asarray(columns[name]) for name in COLUMNS}

    def job(part):
        source = part if index is None else index[part]
        if matrix is not None:
            rows[part] = matrix[source]
        else:
            for name in COLUMNS:
                out[name][part] = sources[name][source]
        return 0 if each is None else each({name: out[name][part] for name in COLUMNS})

    total = sum(run_blocks(m, job))
    # SH bands, when the scene has them, come along: no edit that keeps or moves rows drops them.
    return with_sh(out, columns, index), total


def compact(columns: dict, index: np.ndarray, each=None) -> tuple:
    """:func:`copy_rows` for columns made here (views of one writeable row table), in place.

    The rows ``index`` (ascending) move up within the same table: row
    ``index[i] >= i``, so moving blocks forward, in order, never overwrites a row
    still to be moved (hence one thread). Falls back to :func:`copy_rows` for
    other columns.
    """
    table = columns["x"].base
    if (not isinstance(table, np.ndarray) or table.ndim != 2 or table.dtype != np.float32
            or not table.flags.writeable or not table.flags.c_contiguous or len(table) != len(columns["x"])
            or any(columns[name].base is not table for name in COLUMNS)):
        return copy_rows(columns, index, each)
    m = len(index)
    total = 0
    for start in range(0, m, CHUNK):
        part = slice(start, min(m, start + CHUNK))
        table[part] = table[index[part]]
        if each is not None:
            total += each({name: columns[name][part] for name in COLUMNS})
    return with_sh({name: columns[name][:m] for name in COLUMNS}, columns, index), total


def _field_runs(columns: list):
    """``(start, end, fields)`` for runs of ``columns`` that are consecutive float32 fields of one row
    table: ``fields`` a ``(k, end - start)`` view of them; a column in no such run comes alone, with None."""
    start = 0
    while start < len(columns):
        first = columns[start]
        address = first.__array_interface__["data"][0]
        end = start + 1
        while (end < len(columns) and first.dtype == np.float32 and columns[end].dtype == np.float32
               and columns[end].base is first.base and columns[end].strides == first.strides
               and columns[end].__array_interface__["data"][0] == address + 4 * (end - start)):
            end += 1
        fields = None
        if end - start > 1 and first.strides[0] >= 4 * (end - start):
            fields = np.lib.stride_tricks.as_strided(first, shape=(len(first), end - start),
                                                     strides=(first.strides[0], 4), writeable=first.flags.writeable)
        else:
            end = start + 1
        yield start, end, fields
        start = end


def store_fields(block: dict, names, planes: np.ndarray) -> None:
    """Write ``planes[i]`` into column ``names[i]`` of ``block``, for each i.

    Where columns that follow each other in ``names`` are consecutive float32
    fields of one row table (as in the tables made here), each such run goes in
    by one transposed copy, about three times as fast as a strided pass per column.
    """
    columns = [block[name] for name in names]
    for start, end, fields in _field_runs(columns):
        if fields is None:
            columns[start][...] = planes[start]
        else:
            fields[...] = planes[start:end].T


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
    """``fn(block)`` over blocks of rows (by threads), concatenated: an ``(N,)`` array of ``dtype``."""
    out = np.empty(len(columns["x"]), dtype=dtype)
    base = {name: columns[name].view(np.ndarray) for name in names}

    def job(part):
        out[part] = fn({name: base[name][part] for name in names})

    run_blocks(len(out), job)
    return out
