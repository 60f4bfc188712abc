"""Compare two scenes attribute by attribute, in the units the viewer uses.

Used by ``verify`` (is every error explained by quantization?) and by ``stats``
(how large are the errors?). Pure numpy: no I/O, no printing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import packing, viewer
from .errors import UnsupportedError
from .model import GROUPS, Scene
from .wording import plural

HALF_MAX = packing.HALF_MAX
#: One half-float ulp relative to the value (10 mantissa bits), the largest error
#: of either writer (rounding gives half of it, splaTV's truncation all of it).
HALF_REL = 2.0**-10
#: Smallest half subnormal step.
HALF_ABS = 2.0**-24
#: One 8-bit step.
BYTE = 1.0 / 255.0
#: Groups stored as bytes (the rest of the attributes are halves, positions float32).
BYTE_GROUPS = ("color", "opacity")


def quantization_bound(group: str, values: np.ndarray) -> np.ndarray:
    """Largest error a faithful .splatv conversion may introduce, per value."""
    if group == "position":
        return np.zeros_like(values)
    if group in BYTE_GROUPS:
        return np.full_like(values, BYTE * (1 + 1e-6))
    with np.errstate(invalid="ignore"):
        return np.maximum(np.abs(values) * HALF_REL, HALF_ABS)


def _position_key(cols: dict) -> np.ndarray:
    """Position bits with every NaN made alike (a browser may quiet them)."""
    bits = np.stack([np.asarray(cols[c], dtype=np.float32).view(np.uint32) for c in ("x", "y", "z")], axis=1)
    nan = (bits & packing.F32_EXP_MASK) == packing.F32_EXP_MASK
    nan &= (bits & packing.F32_MANT_MASK) != 0
    return np.where(nan, np.uint32(packing.F32_QUIET_NAN), bits)


def _byte_key(cols: dict) -> np.ndarray:
    """Opacity and colour as the bytes a writer stores, ``(N, 4) uint8`` (NaN as 0)."""
    v = np.concatenate([viewer.opacity(cols)[:, None], viewer.colors(cols)], axis=1)
    return np.nan_to_num(np.round(v * 255.0), nan=0.0).astype(np.uint8)


def align(source: Scene, converted: Scene, source_name: str = "SOURCE", converted_name: str = "CONVERTED"):
    """Row order of ``source`` matching ``converted`` row by row.

    Tries the orders a writer produces (input order; importance, double or
    float32 key). Conversion keeps positions exact, so an order whose positions
    match is the writer's, unless splats share positions (or all are NaN): then
    several orders match, and the one whose other attributes agree wins (fewest
    values off by more than quantization explains; the first listed on a tie).
    When none matches, rows are matched by sorting both sides by position, ties
    broken by opacity and colour bytes.

    Returns
    -------
    (N,) int64 ndarray
        ``source`` row for each ``converted`` row.

    Raises
    ------
    UnsupportedError
        When the splat counts differ.
    """
    n, m = source.count, converted.count
    if n != m:
        raise UnsupportedError(f"{source_name} has {plural(n, 'splat')} but {converted_name} has {m:,}")
    a, b = _position_key(source.columns), _position_key(converted.columns)
    key = viewer.importance(source.columns)
    with np.errstate(invalid="ignore", over="ignore"):
        candidates = (np.arange(n), viewer.importance_order(key), viewer.importance_order(key.astype(np.float32)))
    matching = []
    for order in candidates:
        if np.array_equal(a[order], b) and not any(np.array_equal(order, other) for other in matching):
            matching.append(order)
    if len(matching) == 1:
        return matching[0]
    if matching:
        return min(matching, key=lambda order: sum(
            g.unexplained for g in compare_scenes(source, converted, order).values()))
    sa = np.lexsort(np.concatenate([a, _byte_key(source.columns)], axis=1).T[::-1])
    sb = np.lexsort(np.concatenate([b, _byte_key(converted.columns)], axis=1).T[::-1])
    order = np.empty(n, dtype=np.int64)
    order[sb] = sa
    return order


@dataclass
class GroupError:
    """Errors of one attribute group, converted against source, in viewer units."""

    group: str
    max_abs_error: float  # over pairs finite on both sides
    max_rel_error: float
    rmse: float
    unexplained: int  # values whose error exceeds what quantization explains
    worst_bound: float  # the bound at the worst unexplained value (or 0)
    compared: int  # pairs finite on both sides
    values: int = 0  # values in the group: splats x components
    became_infinite: int = 0  # finite source values stored as infinity (part of unexplained)
    nonfinite_changed: int = 0  # NaN or infinite source values stored as something else (part of unexplained)
    nan_stored: int = 0  # NaN source values stored as numbers by a byte that cannot hold NaN (explained)

    def merge(self, other: "GroupError") -> "GroupError":
        """The errors of both sets of rows together (``other`` another block of the same group)."""
        n = self.compared + other.compared
        top = max(self.rmse, other.rmse)
        # Scaled by the larger: a saturated value's error (up to 1e308) squared would overflow.
        rmse = 0.0
        if n and top:
            rmse = top if math.isinf(top) else top * math.sqrt(
                ((self.rmse / top) ** 2 * self.compared + (other.rmse / top) ** 2 * other.compared) / n)
        return GroupError(self.group, max(self.max_abs_error, other.max_abs_error),
                          max(self.max_rel_error, other.max_rel_error), rmse,
                          self.unexplained + other.unexplained, max(self.worst_bound, other.worst_bound), n,
                          values=self.values + other.values,
                          became_infinite=self.became_infinite + other.became_infinite,
                          nonfinite_changed=self.nonfinite_changed + other.nonfinite_changed,
                          nan_stored=self.nan_stored + other.nan_stored)


def group_errors(source_cols: dict, converted_cols: dict, group: str) -> GroupError:
    """Error statistics of one group over finite pairs; NaN must stay NaN.

    Colour and opacity are stored as bytes, which cannot hold NaN: a NaN there
    stored as a number is explained (and counted in ``nan_stored``).

    Parameters
    ----------
    source_cols, converted_cols : dict of str to (N,) ndarray
        Model columns, row i of one matching row i of the other.
    group : str
        A key of :data:`splatconv.model.GROUPS`.
    """
    return value_errors(viewer.group_values(source_cols, group), viewer.group_values(converted_cols, group), group)


def value_errors(a: np.ndarray, b: np.ndarray, group: str) -> GroupError:
    """:func:`group_errors` of values already in viewer units.

    Parameters
    ----------
    a, b : (N, k) float64 ndarray
        ``viewer.group_values`` of source and converted rows.
    group : str

    Notes
    -----
    Differences and ratios are taken only where both values are finite (``where=``
    masks): computing inf - inf and masking it afterwards would warn.
    """
    both = np.isfinite(a) & np.isfinite(b)
    err = np.zeros(a.shape, dtype=np.float64)
    with np.errstate(over="ignore"):  # a difference past 1.8e308 is infinite, which is the truth
        np.subtract(a, b, out=err, where=both)
    np.abs(err, out=err)
    rel = np.zeros(a.shape, dtype=np.float64)
    with np.errstate(over="ignore"):  # an error over a float64-subnormal value may pass 1.8e308: inf is the truth
        np.divide(err, np.abs(a), out=rel, where=both & (a != 0))
    bound = quantization_bound(group, np.where(both, a, 0.0))
    # Finite values past the half range saturate (or become infinite in splaTV's
    # converter), keeping their sign; NaN stays NaN. Both are lossy but expected, counted elsewhere.
    over = False
    if group != "position":
        over = np.isfinite(a) & (np.abs(a) > HALF_MAX) & (np.abs(b) >= HALF_MAX) & (np.signbit(a) == np.signbit(b))
    same_special = (np.isnan(a) & np.isnan(b)) | (np.isinf(a) & (a == b))
    nan_stored = np.isnan(a) & np.isfinite(b) if group in BYTE_GROUPS else np.zeros(a.shape, bool)
    bad = ~(both & (err <= bound)) & ~over & ~same_special & ~nan_stored
    n = int(both.sum())
    worst = float(bound[bad].max()) if bad.any() else 0.0
    top = float(err.max()) if err.size else 0.0
    # Scaled by the largest error: a saturated value's error (up to 1e308) squared would overflow.
    rmse = 0.0
    if n and top:
        rmse = top if math.isinf(top) else top * math.sqrt(float(np.square(err[both] / top).mean()))
    return GroupError(group, top, float(rel.max()) if rel.size else 0.0, rmse, int(bad.sum()), worst, n,
                      values=int(a.size), became_infinite=int((bad & np.isfinite(a) & np.isinf(b)).sum()),
                      nonfinite_changed=int((bad & ~np.isfinite(a)).sum()), nan_stored=int(nan_stored.sum()))


#: Rows compared per step: bounds the float64 temporaries of group_errors (a few MB a column).
_ROWS = 1 << 17


def compare_scenes(source: Scene, converted: Scene, order: np.ndarray | None = None) -> dict:
    """Per-group errors of ``converted`` against ``source``; rows aligned by ``order``.

    Computed :data:`_ROWS` rows at a time and merged, so that memory stays
    bounded whatever the scene's size.
    """
    n = converted.count
    parts = {g: [] for g in GROUPS}
    for start in range(0, max(n, 1), _ROWS):
        rows = slice(start, min(start + _ROWS, n))
        pick = rows if order is None else order[rows]
        src = {k: v[pick] for k, v in source.columns.items()}
        conv = {k: v[rows] for k, v in converted.columns.items()}
        for g in GROUPS:
            parts[g].append(group_errors(src, conv, g))
    return {g: _merge(parts[g]) for g in GROUPS}


def _merge(parts: list) -> GroupError:
    """One GroupError from those of consecutive row ranges."""
    merged = parts[0]
    for part in parts[1:]:
        merged = merged.merge(part)
    return merged
