"""Compare two scenes attribute by attribute, in the units the viewer uses.

The one comparison behind ``verify`` (is every error explained by quantization?)
and ``stats`` (how large are the errors?): both pair rows with :func:`pair` and
measure them with :class:`Comparison`, so they report the same figures. Values
are compared as each file reads (the model's columns): a ``.splatv``'s halves and
bytes as the float32 logarithms and logits its reader gives, which write back to
the same texture, so a pair whose records are identical differs by nothing.
Pure numpy: no I/O, no printing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import packing, viewer
from .errors import UnsupportedError
from .model import GROUPS, Scene
from .wording import kinds_text, plural

HALF_MAX = packing.HALF_MAX
#: One half-float ulp relative to the value (10 mantissa bits), the largest error
#: of either writer (rounding gives half of it, splaTV's truncation all of it).
HALF_REL = 2.0**-10
#: Smallest half subnormal step.
HALF_ABS = 2.0**-24
#: One 8-bit step.
BYTE = 1.0 / 255.0
#: A linear value stored as float32 while the model keeps its logarithm (a .splat's
#: scales): two float32 roundings, of the value and of its logarithm, relative.
FLOAT32_REL = 2.0**-16
#: A quaternion component stored as a byte in steps of this (a .splat's rotation).
QUATERNION_STEP = 1.0 / 128.0
F32_MAX = float(np.finfo(np.float32).max)
#: Below these magnitudes a storage kind's step no longer shrinks with the value
#: (half subnormals, byte steps, float32 subnormals), so an error there is
#: measured against the step: relative error = |error| / max(|source|, floor).
#: ``exact``, ``none`` and ``quantized`` keep no floor (any error there is real; a source 0 is left out).
RESOLUTION_FLOOR = {"exact": 0.0, "half": 2.0**-14, "float32": float(np.finfo(np.float32).tiny), "byte": BYTE,
                    "unit_quaternion_byte": QUATERNION_STEP, "unit_quaternion": float(np.finfo(np.float32).tiny),
                    "none": 0.0, "quantized": 0.0}

#: How a format stores an attribute group (each format module's ``STORAGE`` maps every
#: group to one), and so the error a faithful conversion may bring:
#:
#: ``exact``: as the model holds it; ``half``: a half float (one ulp; a value past the
#: half range may saturate or become the infinity of its sign); ``float32``: see
#: :data:`FLOAT32_REL` (past the float32 range: infinity); ``byte``: value * 255 as a byte
#: (one step; NaN cannot be held and is stored as a number); ``unit_quaternion_byte``:
#: normalised, each component in :data:`QUATERNION_STEP` steps, compared normalised
#: (the viewer normalises) with two steps of room (rounding, then the length's change);
#: ``unit_quaternion``: normalised, then float32, compared normalised (a glTF's rotation);
#: ``none``: not stored at all (a static format's time and motion); ``quantized``: stored, but
#: quantized past a value-by-value check (a ``.splatvq``'s positions, rotations, scales, motion,
#: omega and time). Neither is checked value by value (:data:`UNCHECKED`): the frames drawn at
#: several times check what the viewer shows.
STORAGE_KINDS = ("exact", "half", "float32", "byte", "unit_quaternion_byte", "unit_quaternion", "none",
                 "quantized")
#: Storage kinds whose values are never ``unexplained``.
UNCHECKED = ("none", "quantized")


def quantization_bound(group: str, values: np.ndarray, kind: str) -> np.ndarray:
    """Largest error a faithful conversion may introduce, per value, for storage ``kind`` (:data:`STORAGE_KINDS`)."""
    if kind == "exact":
        return np.zeros_like(values)
    if kind == "byte":
        return np.full_like(values, BYTE * (1 + 1e-6))
    if kind == "unit_quaternion_byte":
        return np.full_like(values, 2 * QUATERNION_STEP * (1 + 1e-6))
    if kind in UNCHECKED:
        return np.full_like(values, np.inf)
    with np.errstate(invalid="ignore"):
        if kind in ("float32", "unit_quaternion"):
            return np.maximum(np.abs(values) * FLOAT32_REL, np.finfo(np.float32).smallest_subnormal)
        return np.maximum(np.abs(values) * HALF_REL, HALF_ABS)


def _unit_rows(q: np.ndarray) -> np.ndarray:
    """Quaternion rows normalised (float64); rows with no direction (zero, NaN, infinite) all NaN."""
    u = viewer.unit_quaternions(q)
    u[~np.isfinite(u).all(axis=1)] = np.nan
    return u


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


def _colour_words(cols: dict) -> np.ndarray:
    """The RGBA8 word a writer stores (R in the low byte, alpha in the high): ``(N,) uint32``."""
    b = _byte_key(cols).astype(np.uint32)
    return b[:, 1] | b[:, 2] << 8 | b[:, 3] << 16 | b[:, 0] << 24


def _ordered_bits(bits: np.ndarray) -> np.ndarray:
    """float32 bit patterns ``uint32`` as unsigned integers in the floats' order (NaN bits as they come)."""
    negative = (bits >> 31).astype(bool)
    return np.where(negative, ~bits, bits | np.uint32(0x80000000))


#: Neighbours each side looked at in each sorted order when candidates are gathered (:func:`_candidates`).
_WINDOW = 3
#: Offsets of the grids whose Morton orders give the candidates, in units of the finest cell: a splat's
#: partner sits just across a cell boundary of one grid and rarely of all four.
_GRID_SHIFTS = ((0, 0, 0), (0x0AAAAA, 0x155555, 0x0CCCCC), (0x155555, 0x0CCCCC, 0x0AAAAA),
                (0x0CCCCC, 0x0AAAAA, 0x155555))


def _candidates(word: np.ndarray, side: np.ndarray, orders: list) -> tuple:
    """Distinct pairs (source element, converted element) of one colour word that sit within :data:`_WINDOW`
    places of each other in any of ``orders`` (each an ``(K,) uint64`` key; elements sorted by word, then key)."""
    found = []
    for key in orders:
        s = np.argsort(key, kind="stable")
        s = s[np.argsort(word[s], kind="stable")]
        ws, ss = word[s], side[s]
        for k in range(1, _WINDOW + 1):
            hit = np.flatnonzero((ws[:-k] == ws[k:]) & (ss[:-k] != ss[k:]))
            left, right = s[hit], s[hit + k]
            source_left = ss[hit] == 0
            found.append(np.where(source_left, left, right).astype(np.int64) << 32
                         | np.where(source_left, right, left).astype(np.int64))
    both = np.concatenate(found) if found else np.zeros(0, np.int64)
    if not len(both):
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    both.sort()
    both = both[np.concatenate([[True], both[1:] != both[:-1]])]
    return (both >> 32).astype(np.intp), (both & 0xFFFFFFFF).astype(np.intp)


def _nearness(pos: list, keys: list, centre: list, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """How near each candidate pair (rows ``i`` of the first side, ``j`` of the second) is, as one
    float64 key to sort by, nearest first: the squared distance of their positions (infinite where
    it is not finite); a pair whose positions are alike bit for bit (NaN too) comes before every
    other, ordered by the gap between their temporal centres, so a copy of a splat at another time
    pairs with its own time."""
    d = np.zeros(len(i), dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        for a, b in zip(*pos):
            d += np.square(a[i] - b[j])
        d[~np.isfinite(d)] = np.inf
        same = (keys[0][i] == keys[1][j]).all(axis=1)
        gap = np.abs(centre[0][i[same]] - centre[1][j[same]])
    gap[~(gap >= 0)] = np.inf  # NaN: as far as can be
    d[same] = -1.0 / (1.0 + gap)  # in [-1, 0): before any distance, smaller gaps first
    return d


def _greedy(i: np.ndarray, j: np.ndarray, near: np.ndarray, na: int, nb: int) -> tuple:
    """Pairs taken from candidates (i, j) nearest first, each element in one pair at most.

    ``near`` orders the candidates (:func:`_nearness`); ties keep the candidates' order (:func:`_candidates` gives them by row numbers). Each round takes every
    candidate that is the best left for both its elements, which takes the same pairs as going
    down the sorted list one by one.
    """
    o = np.argsort(near, kind="stable")
    i, j = i[o], j[o]
    took_a, took_b = np.zeros(na, bool), np.zeros(nb, bool)
    first_a, first_b = np.empty(na, np.int64), np.empty(nb, np.int64)
    pairs_a, pairs_b = [], []
    while len(i):
        rank = np.arange(len(i))
        first_a[i] = len(i)
        first_b[j] = len(i)
        np.minimum.at(first_a, i, rank)
        np.minimum.at(first_b, j, rank)
        best = (first_a[i] == rank) & (first_b[j] == rank)
        pairs_a.append(i[best])
        pairs_b.append(j[best])
        took_a[i[best]] = True
        took_b[j[best]] = True
        left = ~(took_a[i] | took_b[j])
        i, j = i[left], j[left]
    if not pairs_a:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    return np.concatenate(pairs_a), np.concatenate(pairs_b)


def _lone_rows(w: np.ndarray) -> tuple:
    """Words held by exactly one row of ``w`` ``(N,) uint32``, ascending, and those rows."""
    s = np.argsort(w, kind="stable")
    ws = w[s]
    edge = np.flatnonzero(np.concatenate([[True], ws[1:] != ws[:-1], [True]]))
    lone = edge[:-1][np.diff(edge) == 1]
    return ws[lone], s[lone]


def _lone_pairs(words: list) -> tuple:
    """Rows (a, b) whose colour word is held by exactly one row on each side: paired at once."""
    (va, ra), (vb, rb) = (_lone_rows(w) for w in words)
    at = np.minimum(np.searchsorted(vb, va), max(len(vb) - 1, 0))
    hit = (at < len(vb)) & (vb[at] == va) if len(vb) else np.zeros(len(va), bool)
    return ra[hit], rb[at[hit]]


def _content_pairs(a_cols: dict, b_cols: dict, *, ignore_colour: bool = False, alpha_only: bool = False) -> np.ndarray:
    """Rows of ``a_cols`` paired with rows of ``b_cols`` by what they hold, not by where they are.

    A splat pairs only with one of the same colour word (the RGBA8 word a writer keeps
    exactly: ``.splatv`` and ``.splatvq`` alike), and among those with the nearest by
    position (bit-for-bit equal positions, NaN included, at distance 0), ties going to
    the nearest temporal centre and scales: nearest first over all candidates, each splat
    in one pair at most. A colour held by one splat on each side pairs them at once; for
    the others, the candidates of each splat are the splats of its colour within
    :data:`_WINDOW` places in the Morton orders of four offset grids over the positions
    (a grid of the floats' top bits, which needs no bounds), gathered again among the
    splats left until no colour has splats left on both sides. No per-splat loop.

    ``alpha_only``: the word's alpha byte alone (a writer that rounds the colour bytes
    keeps alpha exact); ``ignore_colour``: no word at all.

    Returns
    -------
    (M,) int64 ndarray
        The ``a_cols`` row paired with each ``b_cols`` row, or -1 where none is (its
        colour word is not among the ``a_cols`` rows left).
    """
    na, nb = len(a_cols["x"]), len(b_cols["x"])
    mask = np.uint32(0xFF000000 if alpha_only else 0xFFFFFFFF)
    words = [np.zeros(n, np.uint32) if ignore_colour else _colour_words(c) & mask
             for n, c in ((na, a_cols), (nb, b_cols))]
    order = np.full(nb, -1, dtype=np.int64)
    lone_a, lone_b = _lone_pairs(words)
    order[lone_b] = lone_a
    rest_a = np.ones(na, bool)
    rest_a[lone_a] = False
    rest_a = np.flatnonzero(rest_a)
    rest_b = np.flatnonzero(order < 0)
    if not len(rest_a) or not len(rest_b):
        return order
    a_cols = {k: np.asarray(a_cols[k])[rest_a] for k in _CONTENT_READS}
    b_cols = {k: np.asarray(b_cols[k])[rest_b] for k in _CONTENT_READS}
    na, nb = len(rest_a), len(rest_b)
    keys = [_position_key(c) for c in (a_cols, b_cols)]
    pos = [[viewer.wide(c[n]) for n in ("x", "y", "z")] for c in (a_cols, b_cols)]
    centre = [viewer.wide(c["trbf_center"]) for c in (a_cols, b_cols)]
    top = (np.concatenate([_ordered_bits(keys[0]), _ordered_bits(keys[1])]) >> np.uint32(11)).astype(np.uint64)
    word = np.concatenate([words[0][rest_a], words[1][rest_b]])
    side = np.concatenate([np.zeros(na, np.int8), np.ones(nb, np.int8)])
    orders = [packing.morton_code(top + np.array(shift, np.uint64)) for shift in _GRID_SHIFTS]
    left = np.arange(na + nb)
    while len(left):
        ci, cj = _candidates(word[left], side[left], [o[left] for o in orders])
        if not len(ci):
            break
        i, j = left[ci], left[cj] - na
        pa, pb = _greedy(i, j, _nearness(pos, keys, centre, i, j), na, nb)
        order[rest_b[pb]] = rest_a[pa]
        taken = np.zeros(na + nb, bool)
        taken[pa] = True
        taken[pb + na] = True
        left = left[~taken[left]]
    return order


#: Columns :func:`_content_pairs` reads.
_CONTENT_READS = ("x", "y", "z", "trbf_center", "scale_0", "scale_1", "scale_2", "opacity", "f_dc_0", "f_dc_1",
                  "f_dc_2")


def content_order(source: Scene, converted: Scene, *, complete: bool, colour_kept: bool = True) -> np.ndarray:
    """Row order of ``source`` matching ``converted`` by content (:func:`_content_pairs`): ``(M,) int64``.

    With ``complete``, the splats whose colour word has no partner left (a damaged
    file) are then paired among themselves by position alone, and any still left in
    row order, so that every row has a partner (``verify`` needs one, and reports
    their errors); without it, they are -1 (``stats`` counts them as unpaired).
    ``colour_kept`` False (``converted`` rounds its colours: their storage is
    ``quantized``): splats pair by their alpha byte alone, then by position.
    """
    order = _content_pairs(source.columns, converted.columns, alpha_only=not colour_kept)
    if complete and (order < 0).any():
        rows_b = np.flatnonzero(order < 0)
        rows_a = np.setdiff1d(np.arange(source.count), order[order >= 0])
        sub = _content_pairs({k: np.asarray(v)[rows_a] for k, v in source.columns.items()},
                             {k: np.asarray(v)[rows_b] for k, v in converted.columns.items()}, ignore_colour=True)
        order[rows_b[sub >= 0]] = rows_a[sub[sub >= 0]]
        rest_b = rows_b[sub < 0]
        order[rest_b] = np.setdiff1d(rows_a, rows_a[sub[sub >= 0]])[:len(rest_b)]
    return order


def _matching_rows(a: np.ndarray, b: np.ndarray, order: np.ndarray) -> int:
    """Rows whose position keys agree when ``a`` is taken in ``order``."""
    return int(np.count_nonzero((a[order] == b).all(axis=1)))


def align(source: Scene, converted: Scene, source_name: str = "SOURCE", converted_name: str = "CONVERTED", *,
          storage: dict, complete: bool = True, colour_kept: bool = True):
    """Row order of ``source`` matching ``converted`` row by row.

    Tries the orders a writer produces (input order; importance, double or
    float32 key). Conversion to a ``.splatv`` or PLY keeps positions exact, so an
    order whose positions match on every row is the writer's, unless splats share
    positions (or all are NaN): then several orders match, and the one whose other
    attributes agree wins (fewest values off by more than quantization explains;
    the first listed on a tie). When none matches every row (quantized positions,
    another writer's order, a shuffled source, a damaged file), rows are paired by
    content (:func:`content_order`): the same colour word, then the nearest
    position. A damaged file's undamaged rows are then paired with their own
    splats, so the damage is all that differs.

    ``storage`` (group -> :data:`STORAGE_KINDS` name) is the quantization the
    tie-break allows for. ``complete`` and ``colour_kept``: as :func:`content_order`.

    Returns
    -------
    (N,) int64 ndarray
        ``source`` row for each ``converted`` row (-1 for one left unpaired, without ``complete``).

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
        candidates = [np.arange(n), viewer.importance_order(key), viewer.importance_order(key.astype(np.float32))]
    scored = _distinct_scored(candidates, a, b)
    if scored[0][0] < n:
        return content_order(source, converted, complete=complete, colour_kept=colour_kept)
    best = [order for count, _, order in scored if count == scored[0][0]]
    if len(best) == 1:
        return best[0]
    return min(best, key=lambda order: sum(g.unexplained for g in compare_scenes(source, converted, order, storage).values()))


def pair(source: Scene, converted: Scene, source_name: str = "SOURCE", converted_name: str = "CONVERTED", *,
         storage: dict, complete: bool = True, colour_kept: bool = True) -> tuple:
    """Row order of ``source`` matching ``converted`` (:func:`align`), also when only its drawable splats were kept.

    A writer may leave out the splats the viewer never draws
    (:func:`splatconv.viewer.undrawable`; ``.splatvq`` does): no frame changes.
    When the counts differ by exactly ``source``'s undrawable splats,
    ``converted`` is aligned against ``source``'s drawable splats and a note
    says so. A pruned file (``meta["pruned"]``, :func:`splatconv.ops.prune.leave_out`)
    that holds that many fewer of them is paired with them by content. Any
    other difference in count is refused by :func:`align`. ``colour_kept``: as
    :func:`content_order` (False where ``converted``'s format stores colours quantized).

    Returns
    -------
    order : (M,) int64 ndarray
        ``source`` row for each of the M ``converted`` rows; without ``complete``,
        -1 for a row no splat of ``source`` pairs with (:func:`content_order`).
    notes : list of str
    """
    n, m = source.count, converted.count
    if n != m:
        kinds = viewer.undrawable_kinds(source.columns)
        drawable = kinds == viewer.DRAWABLE
        pruned = converted.meta.get("pruned", 0)
        kept = drawable
        if np.count_nonzero(drawable) not in (m, m + pruned):
            # A writer that leaves out undrawable splats keeps those the viewer's depth sort needs.
            kept = drawable | viewer.sort_ends(source.columns, source.cameras, kinds)
        keep = np.flatnonzero(kept)
        extra = int(np.count_nonzero(kept & ~drawable))
        also = f" and {plural(extra, 'undrawable one')} the viewer's depth sort needs" if extra else ""
        other = " other" if extra else ""
        if pruned and len(keep) == m + pruned:
            # A pruned file (splatconv.ops.prune) holds some of the drawable splats: paired by content.
            held = Scene(columns=source.take(keep), cameras=source.cameras, variant=source.variant,
                         meta=source.meta)
            found = content_order(held, converted, complete=complete, colour_kept=colour_kept)
            order = np.where(found < 0, -1, keep[found])
            return order, [f"{converted_name} holds {m:,} of {source_name}'s "
                           f"{plural(len(keep) - extra, 'drawable splat')}{also} (its header says {pruned:,} "
                           f"were pruned, and the {n - len(keep):,}{other} undrawable ones are left out); "
                           "compared against those it holds"]
        if len(keep) == m:
            held = Scene(columns=source.take(keep), cameras=source.cameras, variant=source.variant,
                         meta=source.meta)
            found = align(held, converted, source_name, converted_name, storage=storage, complete=complete,
                          colour_kept=colour_kept)
            order = np.where(found < 0, -1, keep[found])
            left = kinds_text(viewer.kind_counts(np.where(kept, viewer.DRAWABLE, kinds).astype(kinds.dtype)))
            return order, [f"{converted_name} holds the {plural(m - extra, 'drawable splat')} of {source_name}'s "
                           f"{n:,}{also} (the {n - m:,}{other} undrawable ones, {left}, left out: no frame "
                           "changes); compared against those"]
    return align(source, converted, source_name, converted_name, storage=storage, complete=complete,
                 colour_kept=colour_kept), []


def _distinct_scored(orders: list, a: np.ndarray, b: np.ndarray) -> list:
    """``(rows matching, listed place, order)`` of each distinct order, most matching first, listed order on ties."""
    distinct = []
    for order in orders:
        if not any(np.array_equal(order, other) for other in distinct):
            distinct.append(order)
    return sorted(((_matching_rows(a, b, order), i, order) for i, order in enumerate(distinct)),
                  key=lambda t: (-t[0], t[1]))


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
    storage: str = "half"  # how the converted file stores the group (STORAGE_KINDS)

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
                          nan_stored=self.nan_stored + other.nan_stored, storage=self.storage)


def group_errors(source_cols: dict, converted_cols: dict, group: str, kind: str) -> GroupError:
    """Error statistics of one group over finite pairs; NaN must stay NaN.

    A byte cannot hold NaN: a NaN there stored as a number is explained (and
    counted in ``nan_stored``).

    Parameters
    ----------
    source_cols, converted_cols : dict of str to (N,) ndarray
        Model columns, row i of one matching row i of the other.
    group : str
        A key of :data:`splatconv.model.GROUPS`.
    kind : str
        How the converted file stores the group (:data:`STORAGE_KINDS`).
    """
    return value_errors(viewer.group_values(source_cols, group), viewer.group_values(converted_cols, group), group,
                        kind)


def value_errors(a: np.ndarray, b: np.ndarray, group: str, kind: str) -> GroupError:
    """:func:`group_errors` of values already in viewer units.

    Parameters
    ----------
    a, b : (N, k) float64 ndarray
        ``viewer.group_values`` of source and converted rows.
    group : str
    kind : str
        How the converted file stores the group (:data:`STORAGE_KINDS`).

    Notes
    -----
    Differences and ratios are taken only where both values are finite (``where=``
    masks): computing inf - inf and masking it afterwards would warn.
    """
    if kind in ("unit_quaternion_byte", "unit_quaternion"):
        a, b = _unit_rows(a), _unit_rows(b)
    both = np.isfinite(a) & np.isfinite(b)
    err = np.zeros(a.shape, dtype=np.float64)
    with np.errstate(over="ignore"):  # a difference past 1.8e308 is infinite, which is the truth
        np.subtract(a, b, out=err, where=both)
    np.abs(err, out=err)
    # Relative to the value, or to the storage's finest step where the value is
    # smaller (RESOLUTION_FLOOR): a colour of 0.001 stored as byte 0 is off by a
    # quarter of a step, not by 100%.
    scale = np.maximum(np.abs(np.where(both, a, 0.0)), RESOLUTION_FLOOR[kind])
    rel = np.zeros(a.shape, dtype=np.float64)
    with np.errstate(over="ignore"):  # an error over a float64-subnormal value may pass 1.8e308: inf is the truth
        np.divide(err, scale, out=rel, where=both & (scale != 0))
    bound = quantization_bound(group, np.where(both, a, 0.0), kind)
    # Finite values past a float range saturate (or become infinite), keeping their
    # sign; NaN stays NaN. Both are lossy but expected, and noted by the writer.
    over = np.zeros(a.shape, dtype=bool)
    if kind in ("half", "float32"):
        top = HALF_MAX if kind == "half" else F32_MAX
        over = np.isfinite(a) & (np.abs(a) > top) & (np.abs(b) >= top) & (np.signbit(a) == np.signbit(b))
    same_special = (np.isnan(a) & np.isnan(b)) | (np.isinf(a) & (a == b))
    nan_stored = np.isnan(a) & np.isfinite(b) if kind == "byte" else np.zeros(a.shape, bool)
    bad = ~(both & (err <= bound)) & ~over & ~same_special & ~nan_stored
    if kind in UNCHECKED:
        bad[:] = False
    n = int(both.sum())
    worst = float(bound[bad].max()) if bad.any() else 0.0
    top = float(err.max()) if err.size else 0.0
    # Scaled by the largest error: a saturated value's error (up to 1e308) squared would overflow.
    rmse = 0.0
    if n and top:
        rmse = top if math.isinf(top) else top * math.sqrt(float(np.square(err[both] / top).mean()))
    return GroupError(group, top, float(rel.max()) if rel.size else 0.0, rmse, int(bad.sum()), worst, n,
                      values=int(a.size), became_infinite=int((bad & np.isfinite(a) & np.isinf(b)).sum()),
                      nonfinite_changed=int((bad & ~np.isfinite(a)).sum()), nan_stored=int(nan_stored.sum()),
                      storage=kind)


#: Rows compared per step: bounds the float64 temporaries of group_errors (a few MB a column).
_ROWS = 1 << 17


def _turning_as_drawn(qa: np.ndarray, qb: np.ndarray, wa: np.ndarray, wb: np.ndarray) -> tuple:
    """Rotations and omegas of paired rows in the form the viewer turns a splat by, for a file that does not
    keep the rotation's own values (its storage ``quantized``: a ``.splatvq`` normalises it and flips its sign).

    The viewer draws normalize(q + omega * dt), which is the same rotation when q and omega are both
    multiplied by one nonzero number (q and -q are one rotation): each side is divided by the length of
    its own q, and the converted side's sign made that of the source's. Rows where either q has no
    length (zero, NaN, infinite) are left as they are.

    Parameters
    ----------
    qa, qb : (N, 4) float64 ndarray
        Source and converted rotations.
    wa, wb : (N, 4) float64 ndarray
        Source and converted omegas.

    Returns
    -------
    ((qa, qb), (wa, wb)) : (N, 4) float64 ndarrays
    """
    with np.errstate(over="ignore", invalid="ignore"):
        na = np.sqrt((qa * qa).sum(axis=1))
        nb = np.sqrt((qb * qb).sum(axis=1))
        dot = (qa * qb).sum(axis=1)
    ok = (na > 0) & (nb > 0) & np.isfinite(na) & np.isfinite(nb)
    ka = np.ones_like(na)
    kb = np.ones_like(nb)
    np.divide(1.0, na, out=ka, where=ok)
    np.divide(np.where(dot < 0, -1.0, 1.0), nb, out=kb, where=ok)
    return (qa * ka[:, None], qb * kb[:, None]), (wa * ka[:, None], wb * kb[:, None])


class Comparison:
    """Errors of converted rows against source rows, added a block at a time.

    The one measure ``verify`` and ``stats`` report: :meth:`add` each block of
    paired rows, then :meth:`errors`. Memory stays that of one block.

    Parameters
    ----------
    storage : dict of str to str
        How the converted file stores each group (its format's ``storage``).
    """

    def __init__(self, storage: dict):
        self.storage = storage
        self._errors = {}

    def add(self, source_cols: dict, converted_cols: dict, each=None) -> None:
        """Compare one block: row i of ``source_cols`` against row i of ``converted_cols``.

        Parameters
        ----------
        source_cols, converted_cols : dict of str to (M,) ndarray
            Model columns of the paired rows.
        each : callable, optional
            ``each(group, a, b)`` with the ``(M, k) float64`` values compared, for a
            caller that counts more of them (``stats``).
        """
        values = {g: (viewer.group_values(source_cols, g), viewer.group_values(converted_cols, g)) for g in GROUPS}
        if self.storage["rotation"] == "quantized":
            values["rotation"], values["omega"] = _turning_as_drawn(*values["rotation"], *values["omega"])
        for g in GROUPS:
            a, b = values[g]
            e = value_errors(a, b, g, self.storage[g])
            self._errors[g] = self._errors[g].merge(e) if g in self._errors else e
            if each is not None:
                each(g, a, b)

    def errors(self) -> dict:
        """Per-group :class:`GroupError` of every row added (zeros for a group with none)."""
        return {g: self._errors.get(g) or GroupError(g, 0.0, 0.0, 0.0, 0, 0.0, 0, storage=self.storage[g])
                for g in GROUPS}


def compare_scenes(source: Scene, converted: Scene, order: np.ndarray | None, storage: dict) -> dict:
    """Per-group errors of ``converted`` against ``source``; rows aligned by ``order``.

    ``storage`` maps each group to how the converted file stores it (its
    format's ``storage``). Computed :data:`_ROWS`
    rows at a time (:class:`Comparison`), so that memory stays bounded whatever
    the scene's size.
    """
    comparison = Comparison(storage)
    n = converted.count
    for start in range(0, n, _ROWS):
        rows = slice(start, min(start + _ROWS, n))
        pick = rows if order is None else order[rows]
        comparison.add({k: v[pick] for k, v in source.columns.items()},
                       {k: v[rows] for k, v in converted.columns.items()})
    return comparison.errors()
