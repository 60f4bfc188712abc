"""Reference implementations that exist only to check the library's fast paths.

Not used by the pipeline (the ``.splatv`` writer packs whole records in
:mod:`splatconv.formats.splatv_engine`); kept here as independent oracles for
the tests, written the plain way.
"""

from __future__ import annotations

import numpy as np

from splatconv.formats import splatv_engine as engine
from splatconv.formats.base import WriteReport
from splatconv.formats.splatv_layout import WORDS_PER_SPLAT


def pack_half2(low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Two ``(N,) uint16`` arrays -> ``(N,) uint32``, ``low`` in bits 0-15 (packHalf2x16)."""
    return low.astype(np.uint32) | (high.astype(np.uint32) << 16)


def unorm8_nearest(v: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Scaled values (already x255, float64) -> uint8, clamped then rounded to nearest even.

    Returns
    -------
    bytes : (N,) uint8 ndarray
    clamped : int
        Values whose byte the clamp changes: those whose nearest integer is
        outside [0, 255] (-0.4 rounds to 0 anyway; NaN excluded).
    nan : int
        NaN values (written as 0).
    """
    v = np.asarray(v, dtype=np.float64)
    nan = np.isnan(v)
    clamped = int(np.count_nonzero((np.rint(v) < 0) | (np.rint(v) > 255)))
    out = np.rint(np.clip(np.where(nan, 0.0, v), 0.0, 255.0)).astype(np.uint8)
    return out, clamped, int(np.count_nonzero(nan))


def unorm8_truncate(v: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Scaled values (x255, float64) -> uint8 the way splaTV's JS stores them.

    ``Math.max(0, Math.min(255, v))`` then a Uint8Array store: truncation toward
    zero; NaN gives 0. Returns the bytes and the clamped and NaN counts, as
    :func:`unorm8_nearest` does (clamped: values whose truncation is outside [0, 255]).
    """
    v = np.asarray(v, dtype=np.float64)
    nan = np.isnan(v)
    clamped = int(np.count_nonzero((np.trunc(v) < 0) | (np.trunc(v) > 255)))
    out = np.trunc(np.clip(np.where(nan, 0.0, v), 0.0, 255.0)).astype(np.uint8)
    return out, clamped, int(np.count_nonzero(nan))


def pack_rgba8(r, g, b, a) -> np.ndarray:
    """Four ``(N,) uint8`` -> ``(N,) uint32`` with R in the low byte."""
    return (r.astype(np.uint32) | (g.astype(np.uint32) << 8)
            | (b.astype(np.uint32) << 16) | (a.astype(np.uint32) << 24))


def pack_block(cols: dict, compat: bool, report: WriteReport) -> np.ndarray:
    """Pack a block of rows into texture records, in the given order, with the engine.

    Parameters
    ----------
    cols : dict of str to (M,) float32 ndarray
    compat : bool
        Model splaTV's JavaScript converter bit for bit instead of rounding.
    report : WriteReport
        Counts are added to it.

    Returns
    -------
    (M, 16) uint32 ndarray
    """
    m = len(cols["x"])
    out = np.empty((m, WORDS_PER_SPLAT), dtype="<u4")
    counts = engine.new_counts()
    engine.pack_rows(engine.RowSource(cols), slice(0, m), out, compat, counts, engine.Scratch())
    engine.merge_counts(report, counts)
    return out
