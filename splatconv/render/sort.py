"""The viewer's per-frame depth order, vectorised.

splaTV sorts splats front to back with a 16-bit counting sort of a quantized depth
key. Reproducing it exactly (its quantization, its ties, its quirks) makes the
preview blend splats in the order the viewer does.
"""

from __future__ import annotations

import numpy as np

from ..viewer import js_int32

BUCKETS = 1 << 16


def depth_keys(positions: np.ndarray, view_proj: list) -> np.ndarray:
    """The viewer's depth key of each splat, ``(vp[2]*x + vp[6]*y + vp[10]*z) * 4096 | 0``: ``(N,) int64``.

    The splats whose key is the largest are never drawn (see :func:`viewer_order`).
    """
    with np.errstate(invalid="ignore"):  # a signalling NaN warns when widened; it stays NaN
        p = np.asarray(positions, dtype=np.float32).astype(np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        return js_int32((view_proj[2] * p[:, 0] + view_proj[6] * p[:, 1] + view_proj[10] * p[:, 2]) * 4096)


def viewer_order(positions: np.ndarray, view_proj: list) -> np.ndarray:
    """Front-to-back draw order of splats, as splaTV computes it.

    The key is ``(vp[2]*x + vp[6]*y + vp[10]*z) * 4096 | 0`` (row 2 of
    projection*view, no translation), rescaled to 65,536 buckets by
    ``(key - min) * 65536 / (max - min) | 0`` and counting-sorted (stable). The
    farthest splats land in bucket 65,536, which the viewer's typed arrays ignore:
    they are dropped and the tail of the index list stays 0 (splat 0 is drawn there
    again), exactly as in the viewer.

    Parameters
    ----------
    positions : (N, 3) float32 ndarray
    view_proj : list of 16 float
        projection * view, column-major.

    Returns
    -------
    (N,) int32 ndarray
        Splat indices in draw order.
    """
    depth = depth_keys(positions, view_proj)
    with np.errstate(invalid="ignore", over="ignore"):
        n = len(depth)
        out = np.zeros(n, dtype=np.int32)
        if n == 0:
            return out
        lo, hi = int(depth.min()), int(depth.max())
        inv = BUCKETS / (hi - lo) if hi != lo else np.inf
        bucket = js_int32((depth - lo) * inv)
    kept = np.flatnonzero(bucket < BUCKETS)
    # Buckets 0..65,535 as uint16: numpy's stable sort of 16-bit keys is a radix sort (a sixth of the
    # time of its merge sort of int64 at 1M splats), the same order.
    order = kept[np.argsort(bucket[kept].astype(np.uint16), kind="stable")]
    out[:len(order)] = order
    return out
