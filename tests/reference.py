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


def splat_rotation_bytes(q: np.ndarray) -> tuple[np.ndarray, int, int]:
    """``.splat`` rotation bytes of quaternions ``(M, 4) float32``, the plain float64 way: bytes, splats
    normalised and rounded, non-finite ones (what :func:`splatconv.formats.splat._rotation_bytes` gives)."""
    q = q.astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        steps = q * 128.0 + 128.0
        on_grid = np.all((steps == np.rint(steps)) & (steps >= 0) & (steps <= 255), axis=1)
        length = np.sqrt((q * q).sum(axis=1, keepdims=True))
        kept = on_grid & ((np.abs(length[:, 0] - 1.0) <= 2.0 / 128.0) | (length[:, 0] == 0.0))
        unit = q / length
        nonfinite = ~np.all(np.isfinite(unit), axis=1) & ~kept
        unit[nonfinite] = 0.0
        scaled = np.where(kept[:, None], steps, unit * 128.0 + 128.0)
    out = np.rint(np.clip(scaled, 0.0, 255.0)).astype(np.uint8)
    return out, int(np.count_nonzero(~kept & ~nonfinite)), int(np.count_nonzero(nonfinite))


def spz_sh_bytes(values: np.ndarray, bits: int) -> np.ndarray:
    """``.spz`` SH coefficient bytes of float32 ``values`` rounded to ``bits``, in float64 as the reference
    library's quantizeSH computes them (NaN as 0)."""
    with np.errstate(over="ignore"):
        q = np.rint(np.nan_to_num(values.astype(np.float64), nan=0.0) * 128.0 + 128.0)
    bucket = 1 << (8 - bits)
    q = np.floor((q + bucket / 2) / bucket) * bucket
    return np.clip(q, 0, 255).astype(np.uint8)
