"""PlayCanvas SOG (Spatially Ordered Gaussians), version 2: a static scene as images in a zip (specs/sog.md).

A ``.sog`` is a zip archive holding ``meta.json`` and lossless WebP images of one
pixel a splat (row-major, the same pixel in every image), what SuperSplat and
PlayCanvas splat-transform 3.7 write and read:

    means_l, means_u   x, y, z as 16 bits an axis (low, high byte) of sign(v) * log(|v| + 1)
                       between meta.json's per-axis mins and maxs
    quats              smallest three: the other three components as bytes over [-sqrt(1/2), sqrt(1/2)],
                       alpha 252 + the index of the largest (rot_0..rot_3)
    scales             log scales, each the byte index of a 256-entry codebook (meta.json)
    sh0                the degree-0 SH coefficient of each channel, a codebook index; alpha sigmoid(opacity) * 255
    shN_labels         optional, 16 bits (R low, G high): an entry of a palette of up to 65,536
    shN_centroids      the palette: 64 entries a row, an entry K pixels (K = 3, 8, 15 SH coefficients),
                       each pixel the codebook indices of the three channels' coefficient

Codebooks and the palette are fitted to the scene (a 1-D optimal quantizer on a
histogram; a k-means tree for the palette): a write is lossy and its report says how.
Splats are stored along a Morton curve (what lets the images compress). A scene
that moves or fades is refused (bake a moment first); reading gives a static scene.
Coordinates are stored as the scene holds them (no axis flip), as splat-transform does.
"""

from __future__ import annotations

import json
import math
import os
import warnings
import zipfile
import zlib
from concurrent.futures import ThreadPoolExecutor
from io import BytesIO

import numpy as np

from .. import model, packing
from ..errors import FormatError, UnsupportedError
from ..files.inputs import open_input
from ..model import Scene
from ..progress import SILENT
from ..viewer import logit, sigmoid, wide
from ..wording import plural
from .base import (Format, Scan, WriteReport, fixed_storage, meta_fields, refuse_nonfinite_positions,
                   refuse_time_varying)
from .ply import SH_C0  # rgb = 0.5 + SH_C0 * f_dc: the model keeps RGB, sh0 the coefficient

#: meta.json's version, the one written and read.
VERSION = 2
META_NAME = "meta.json"
#: Image names written (a reader takes whatever names meta.json gives).
FILES = {"means": ("means_l.webp", "means_u.webp"), "scales": ("scales.webp",), "quats": ("quats.webp",),
         "sh0": ("sh0.webp",), "shN": ("shN_centroids.webp", "shN_labels.webp")}
#: Entries of every codebook.
CODEBOOK_SIZE = 256
#: The quaternion mode byte: 252 + the index of the largest component.
QUAT_MODE = 252
#: Palette entries a row of ``shN_centroids``, and the most a palette holds (16-bit labels).
PALETTE_ROW = 64
MAX_PALETTE = 65536
#: Largest meta.json read, and the most pixels an image of the splats may have beyond its count
#: (bounds what a small file can make a reader decode).
MAX_META_BYTES = 16 << 20
SPARE_PIXELS = 65536
#: Image formats read (the spec allows any lossless 8-bit RGBA image; these are written and read).
IMAGE_FORMATS = ("WEBP", "PNG")
#: libwebp's lossless effort (Pillow's ``quality`` for lossless) and method: its own defaults.
WEBP_QUALITY, WEBP_METHOD = 75, 4
#: Histogram bins the 1-D codebook fit runs on, and the weight of a bin: count ** this
#: (below 1, so that sparse tails, a few large splats, still earn codebook entries).
HISTOGRAM_BINS = 1024
BIN_WEIGHT_POWER = 0.5
#: The palette's k-means tree: centres a node splits into, points fitted a centre, Lloyd iterations.
BRANCH = 64
FIT_POINTS_PER_CENTRE = 8
KMEANS_ITERATIONS = 6
SQRT2 = math.sqrt(2.0)
#: Other indices of a quaternion, by the largest component's index (rot_0..rot_3 order).
_OTHERS = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])

#: How each attribute group is stored (see :data:`splatconv.compare.STORAGE_KINDS`).
STORAGE = {"position": "quantized", "scale": "quantized", "color": "quantized", "opacity": "byte",
           "rotation": "quantized", "motion": "none", "omega": "none", "trbf": "none"}


def texture_size(n: int) -> tuple:
    """Width and height of the splats' images for ``n`` splats: as square as a multiple of 4 allows."""
    width = int(math.ceil(math.sqrt(n) / 4)) * 4
    height = int(math.ceil(n / width / 4)) * 4
    return width, height


def palette_size(n: int) -> int:
    """Palette entries for ``n`` splats' SH bands: every splat its own up to 1,024, then 1,024 times the
    largest power of two at most n / 1,024, up to :data:`MAX_PALETTE` (splat-transform's sizes)."""
    if n <= 1024:
        return n
    return min(MAX_PALETTE, 1024 << int(math.floor(math.log2(n / 1024))))


# --------------------------------------------------------------------------
# Quantizers


def morton_order(xyz: np.ndarray) -> np.ndarray:
    """Row order along a Morton (Z-order) curve of 21 bits an axis over the positions' box: ``(N,) intp``.

    ``xyz`` is ``(N, 3)`` finite. Ties keep their order (stable).
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    if not len(xyz):
        return np.zeros(0, np.intp)
    lo = xyz.min(axis=0)
    span = xyz.max(axis=0) - lo
    span[span == 0] = 1.0
    cells = np.minimum((xyz - lo) / span * (1 << 21), (1 << 21) - 1).astype(np.uint64)
    return np.argsort(packing.morton_code(cells), kind="stable")


def fit_codebook(values: np.ndarray, size: int = CODEBOOK_SIZE) -> np.ndarray:
    """A codebook of ``size`` ascending float32 values for ``values`` (any shape; non-finite ones ignored).

    At most ``size`` distinct values are kept exactly. Otherwise the sorted values are cut into
    :data:`HISTOGRAM_BINS` bins (half at equal steps of value, half at equal counts, so that both the
    dense middle and the tails are resolved), and the ``size`` entries are the optimal 1-D quantizer
    of the bins' means weighted by count ** :data:`BIN_WEIGHT_POWER` (dynamic programming: a few
    times smaller largest and mean errors than Lloyd's iterations on the same bins, on real scales).
    Unused entries repeat the last.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = np.sort(v[np.isfinite(v)])
    out = np.zeros(size, np.float64)
    if not len(v):
        return out.astype(np.float32)
    distinct = np.unique(v)
    if len(distinct) <= size:
        out[:len(distinct)] = distinct
        out[len(distinct):] = distinct[-1]
        return out.astype(np.float32)
    half = HISTOGRAM_BINS // 2
    by_value = np.linspace(v[0], v[-1], half + 1)
    by_count = v[np.linspace(0, len(v) - 1, half + 1).astype(np.intp)]
    edges = np.concatenate([by_value, by_count])
    bounds = np.unique(np.searchsorted(v, np.unique(edges), side="left"))
    bounds = np.unique(np.concatenate([[0], bounds, [len(v)]]))
    counts = np.diff(bounds).astype(np.float64)
    sums = np.add.reduceat(v, bounds[:-1])
    keep = counts > 0
    counts, centres = counts[keep], sums[keep] / counts[keep]
    centres = _optimal_1d(centres, counts ** BIN_WEIGHT_POWER, size)
    out[:len(centres)] = centres
    out[len(centres):] = centres[-1]
    return np.sort(out.astype(np.float32))


def _optimal_1d(x: np.ndarray, w: np.ndarray, k: int) -> np.ndarray:
    """The ``k`` (or fewer) centres minimising the weighted squared error of ascending points ``x``:
    dynamic programming over contiguous runs, each run's cost from prefix sums, vectorised over runs
    (float32 for the table, float64 for the sums)."""
    h = len(x)
    if h <= k:
        return x.copy()
    pw = np.concatenate([[0.0], np.cumsum(w)])
    pwx = np.concatenate([[0.0], np.cumsum(w * x)])
    pwxx = np.concatenate([[0.0], np.cumsum(w * x * x)])
    first = np.arange(h)[:, None]  # a run's first point
    last = np.arange(h)[None, :]  # and its last
    with np.errstate(divide="ignore", invalid="ignore"):
        sw = pw[last + 1] - pw[first]
        swx = pwx[last + 1] - pwx[first]
        cost = (pwxx[last + 1] - pwxx[first]) - swx * swx / sw
    cost = np.where(last >= first, np.maximum(cost, 0.0), np.inf).astype(np.float32)
    best = cost[0].copy()  # the error of one centre for points 0..j
    # after[j, s]: one centre for points s+1..j; rows contiguous, so that each j's minimum is a row's
    after = np.ascontiguousarray(cost[1:, :].T)
    splits = np.zeros((k, h), np.int32)
    total = np.empty((h, h - 1), np.float32)
    rows = np.arange(h)
    for m in range(1, k):
        # m + 1 centres for points 0..j: the best m for 0..s, and one for s+1..j
        np.add(best[None, :-1], after, out=total)
        s = np.argmin(total, axis=1)
        best = total[rows, s]
        splits[m] = s
    centres, j = [], h - 1
    for m in range(k - 1, -1, -1):
        s = int(splits[m, j]) if m else -1
        centres.append((pwx[j + 1] - pwx[s + 1]) / (pw[j + 1] - pw[s + 1]))
        j = s
    return np.array(centres[::-1])


def codebook_labels(values: np.ndarray, codebook: np.ndarray) -> np.ndarray:
    """The index of the nearest ``codebook`` entry (ascending) to each of ``values``: uint8, same shape.

    A NaN is labelled as 0 would be; infinities as the nearest end.
    """
    v = np.nan_to_num(np.asarray(values, dtype=np.float64), nan=0.0)
    c = codebook.astype(np.float64)
    middles = (c[:-1] + c[1:]) / 2
    return np.searchsorted(middles, v, side="left").astype(np.uint8)


def _nearest(points: np.ndarray, centres: np.ndarray, chunk: int = 16384) -> np.ndarray:
    """Index of the nearest of ``centres`` ``(K, D)`` to each of ``points`` ``(M, D)`` float32: ``(M,) int64``,
    by matrix products a chunk of points at a time."""
    norms = np.einsum("ij,ij->i", centres, centres)
    out = np.empty(len(points), np.int64)
    for start in range(0, len(points), chunk):
        block = points[start:start + chunk]
        out[start:start + chunk] = np.argmin(norms[None, :] - 2.0 * (block @ centres.T), axis=1)
    return out


def _kmeans(points: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """``k`` centres of ``points`` ``(M, D)`` float32 (M > k): Lloyd's iterations on a sample of
    :data:`FIT_POINTS_PER_CENTRE` points a centre, seeded with distinct sample points."""
    fit = points
    if len(points) > FIT_POINTS_PER_CENTRE * k:
        fit = points[np.sort(rng.choice(len(points), FIT_POINTS_PER_CENTRE * k, replace=False))]
    centres = fit[np.sort(rng.choice(len(fit), k, replace=False))].copy()
    for _ in range(KMEANS_ITERATIONS):
        labels = _nearest(fit, centres)
        order = np.argsort(labels, kind="stable")
        present, starts = np.unique(labels[order], return_index=True)
        sums = np.add.reduceat(fit[order].astype(np.float64), starts, axis=0)
        counts = np.diff(np.append(starts, len(fit)))
        centres[present] = (sums / counts[:, None]).astype(np.float32)  # an empty centre stays put
    return centres


def fit_palette(vectors: np.ndarray, size: int, seed: int = 0) -> tuple:
    """A palette of at most ``size`` entries for ``vectors`` ``(N, D)`` and each vector's entry.

    Every vector is its own entry when N <= ``size``. Otherwise a tree of k-means: a node with a
    budget of more than :data:`BRANCH` entries splits its points among budget / :data:`BRANCH`
    centres (2 to :data:`BRANCH`) and shares its budget among them by their counts; a node of at
    most :data:`BRANCH` is a leaf whose k-means centres are entries. A vector's entry is the
    nearest centre of its leaf (not always the nearest of the palette: the price of the speed).

    Returns
    -------
    palette : (P, D) float32 ndarray
    labels : (N,) int64 ndarray
    """
    points = np.ascontiguousarray(np.nan_to_num(np.asarray(vectors, dtype=np.float32)))
    n = len(points)
    if n <= size:
        return points.copy(), np.arange(n, dtype=np.int64)
    rng = np.random.default_rng(seed)
    labels = np.empty(n, np.int64)
    palette = []
    used = 0
    stack = [(np.arange(n), size)]
    while stack:
        index, budget = stack.pop()
        members = points[index]
        if len(index) <= budget:
            palette.append(members)
            labels[index] = used + np.arange(len(index))
            used += len(index)
            continue
        # a leaf fits its budget; an inner node splits into about budget / BRANCH leaves' worth
        k = budget if budget <= BRANCH else min(BRANCH, max(2, -(-budget // BRANCH)))
        centres = _kmeans(members, k, rng)
        nearest = _nearest(members, centres)
        if budget <= BRANCH:
            present, local = np.unique(nearest, return_inverse=True)
            palette.append(centres[present])
            labels[index] = used + local
            used += len(present)
            continue
        counts = np.bincount(nearest, minlength=k)
        shares = _shares(counts, budget)
        order = np.argsort(nearest, kind="stable")
        starts = np.concatenate([[0], np.cumsum(counts)])
        for c in np.nonzero(counts)[0]:
            stack.append((index[order[starts[c]:starts[c + 1]]], int(shares[c])))
    return np.concatenate(palette).astype(np.float32), labels


def _shares(counts: np.ndarray, budget: int) -> np.ndarray:
    """``budget`` shared among groups of ``counts`` (some zero) in proportion: at least 1 and at most its
    count for each non-empty group, summing to at most ``budget``."""
    live = counts > 0
    quota = budget * counts / counts.sum()
    share = np.where(live, np.maximum(np.floor(quota), 1), 0).astype(np.int64)
    share = np.minimum(share, counts)
    spare = budget - share.sum()
    while spare < 0:  # the floor of 1 overspent: take back from the largest shares
        take = np.argsort(-share, kind="stable")[:-spare]
        share[take] -= (share[take] > 1)
        spare = budget - share.sum()
    if spare > 0:  # hand the rest out by remainder, within each group's count
        room = counts - share
        order = np.argsort(-(quota - np.floor(quota)), kind="stable")
        order = order[room[order] > 0][:spare]
        share[order] += 1
    return share


# --------------------------------------------------------------------------
# Images and the archive


def _webp(pixels: np.ndarray) -> bytes:
    """``(H, W, 4) uint8`` RGBA as lossless WebP, every byte kept (RGB under a zero alpha too)."""
    from PIL import Image

    out = BytesIO()
    Image.fromarray(pixels, "RGBA").save(out, "WEBP", lossless=True, exact=True, quality=WEBP_QUALITY,
                                         method=WEBP_METHOD)
    return out.getvalue()


def _image(pixels: np.ndarray, width: int, height: int) -> np.ndarray:
    """``(N, 4) uint8`` rows as a ``(height, width, 4)`` image, zero after the last."""
    out = np.zeros((height * width, 4), np.uint8)
    out[:len(pixels)] = pixels
    return out.reshape(height, width, 4)


def _zip_entry(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))  # no timestamps: two runs, one file
    info.compress_type = zipfile.ZIP_STORED  # WebP is compressed already
    info.external_attr = 0o644 << 16
    return info


# --------------------------------------------------------------------------
# Writing


def _json_floats(values) -> list:
    """Float64 values for JSON, each exactly."""
    return [float(v) for v in np.asarray(values, dtype=np.float64)]


def _json_codebook(book: np.ndarray) -> list:
    """A float32 codebook for JSON: each entry the shortest decimal that reads back as the same float32."""
    return [float(str(v)) for v in np.asarray(book, dtype=np.float32)]


def encode(scene: Scene) -> tuple:
    """The images and meta.json of ``scene`` as a ``.sog`` holds them.

    Returns
    -------
    images : dict of str to (H, W, 4) uint8 ndarray
        By file name.
    meta : dict
        meta.json's content.
    facts : dict
        What the write changed, for its report (largest errors, NaN counts, palette).
    """
    cols = scene.columns
    n = scene.count
    xyz = np.stack([wide(cols[name]) for name in model.POSITION], axis=1)
    refuse_nonfinite_positions(int(np.count_nonzero(~np.isfinite(xyz).all(axis=1))),
                               ".sog holds positions between finite bounds")
    order = morton_order(xyz)
    xyz = xyz[order]
    width, height = texture_size(n)
    facts = {}

    # means: 16 bits an axis of the log-transformed position, between its extremes
    logged = np.sign(xyz) * np.log1p(np.abs(xyz))
    mins, maxs = logged.min(axis=0), logged.max(axis=0)
    span = np.where(maxs > mins, maxs - mins, 1.0)
    q = np.rint((logged - mins) / span * 65535.0).astype(np.uint16)
    low = np.concatenate([(q & 0xFF).astype(np.uint8), np.full((n, 1), 255, np.uint8)], axis=1)
    high = np.concatenate([(q >> 8).astype(np.uint8), np.full((n, 1), 255, np.uint8)], axis=1)
    back = _unlog(mins + span * (q / 65535.0))
    facts["position"] = float(np.abs(back - xyz).max())

    # quats: smallest three
    rot = np.stack([wide(cols[name])[order] for name in model.ROTATION], axis=1)
    quats, facts["rotation_nan"] = _pack_quaternions(rot)

    # scales and colours: one codebook each over their three columns
    scales = np.stack([wide(cols[name])[order] for name in model.SCALE], axis=1)
    rgb = np.stack([wide(cols[name])[order] for name in model.COLOR], axis=1)
    dc = (rgb - 0.5) / SH_C0
    scale_book, scale_labels, facts["scale"], facts["scale_nan"] = _quantize(scales)
    color_book, color_labels, facts["color"], facts["color_nan"] = _quantize(dc)
    facts["color"] *= SH_C0  # in RGB, the model's unit
    with np.errstate(invalid="ignore"):
        alpha = sigmoid(wide(cols["opacity"])[order]) * 255.0
    facts["opacity_nan"] = int(np.count_nonzero(np.isnan(alpha)))
    alpha = np.clip(np.rint(np.nan_to_num(alpha, nan=0.0)), 0, 255).astype(np.uint8)
    scale_px = np.concatenate([scale_labels, np.full((n, 1), 255, np.uint8)], axis=1)
    color_px = np.concatenate([color_labels, alpha[:, None]], axis=1)

    names = {key: list(files) for key, files in FILES.items()}
    images = {names["means"][0]: _image(low, width, height), names["means"][1]: _image(high, width, height),
              names["quats"][0]: _image(quats, width, height), names["scales"][0]: _image(scale_px, width, height),
              names["sh0"][0]: _image(color_px, width, height)}
    meta = {"version": VERSION, "asset": {"generator": "splatconv"}, "count": n,
            "means": {"mins": _json_floats(mins), "maxs": _json_floats(maxs), "files": names["means"]},
            "scales": {"codebook": _json_codebook(scale_book), "files": names["scales"]},
            "quats": {"files": names["quats"]},
            "sh0": {"codebook": _json_codebook(color_book), "files": names["sh0"]}}

    degree = scene.sh_degree
    if degree:
        k = model.SH_COEFFS[degree]
        # float32, as the palette is fitted: 45 float64 columns of 1M splats would be 360 MB
        rest = np.stack([np.asarray(cols[name], dtype=np.float32)[order] for name in model.sh_names(degree)],
                        axis=1)  # (n, 3k)
        facts["sh_nan"] = int(np.count_nonzero(np.isnan(rest)))
        palette, labels = fit_palette(rest, palette_size(n))
        book, book_labels, _, _ = _quantize(palette)  # (P, 3k) bytes
        stored = book[book_labels]  # (P, 3k) float32
        facts["sh"] = max(float(np.abs(stored[labels, j].astype(np.float64) - np.nan_to_num(rest[:, j])).max())
                          for j in range(rest.shape[1]))
        facts["palette"] = len(palette)
        # entry i, coefficient j: pixel i * k + j of rows of 64 entries, RGB = channels' coefficient j
        rows = -(-len(palette) // PALETTE_ROW)
        centroid_px = np.zeros((rows * PALETTE_ROW, k, 4), np.uint8)
        centroid_px[:len(palette), :, :3] = book_labels.reshape(len(palette), 3, k).transpose(0, 2, 1)
        centroid_px[:len(palette), :, 3] = 255
        label_px = np.zeros((n, 4), np.uint8)
        label_px[:, 0] = labels & 0xFF
        label_px[:, 1] = labels >> 8
        label_px[:, 3] = 255
        images[names["shN"][0]] = centroid_px.reshape(rows, PALETTE_ROW * k, 4)
        images[names["shN"][1]] = _image(label_px, width, height)
        meta["shN"] = {"count": len(palette), "bands": degree, "codebook": _json_codebook(book), "files": names["shN"]}
    return images, meta, facts


def _unlog(values: np.ndarray) -> np.ndarray:
    """Inverse of sign(v) * log(|v| + 1)."""
    return np.sign(values) * np.expm1(np.abs(values))


def _quantize(values: np.ndarray) -> tuple:
    """A codebook for ``values`` ``(M, C)``, their labels ``(M, C) uint8``, the largest error of a finite
    value, and the NaNs (stored as 0 would be)."""
    book = fit_codebook(values)
    labels = codebook_labels(values, book)
    finite = np.isfinite(values)
    err = np.abs(book.astype(np.float64)[labels] - values)[finite]
    return book, labels, float(err.max()) if err.size else 0.0, int(np.count_nonzero(np.isnan(values)))


def _pack_quaternions(rot: np.ndarray) -> tuple:
    """Quaternions ``(n, 4)`` (rot_0..rot_3) as smallest-three pixels ``(n, 4) uint8``, and how many had no
    direction (zero or non-finite: written as the identity)."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        q = rot / np.sqrt((rot * rot).sum(axis=1, keepdims=True))
    bad = ~np.isfinite(q).all(axis=1)
    q[bad] = (1.0, 0.0, 0.0, 0.0)
    largest = np.argmax(np.abs(q), axis=1)
    rows = np.arange(len(q))
    q *= np.where(q[rows, largest] < 0, -1.0, 1.0)[:, None]
    others = q[rows[:, None], _OTHERS[largest]]
    px = np.empty((len(q), 4), np.uint8)
    px[:, :3] = np.clip(np.rint((others * SQRT2 * 0.5 + 0.5) * 255.0), 0, 255)
    px[:, 3] = QUAT_MODE + largest
    return px, int(np.count_nonzero(bad))


def write(scene: Scene, stream, *, progress=SILENT, **_options) -> WriteReport:
    """Write ``scene`` as a version-2 ``.sog`` (see the module docstring).

    Raises
    ------
    UnsupportedError
        For a scene that moves or fades over time, an empty one, or a NaN or infinite position.
    """
    refuse_time_varying(scene.columns, "a .sog file")
    n = scene.count
    if not n:
        raise UnsupportedError("an empty scene: a .sog holds at least one splat")
    report = WriteReport(count=n)
    with progress.stage("writing", n, "splat") as advance:
        images, meta, facts = encode(scene)
        names = list(images)
        with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
            encoded = list(pool.map(_webp, (images[name] for name in names)))
        with zipfile.ZipFile(stream, "w") as archive:
            archive.writestr(_zip_entry(META_NAME), json.dumps(meta, separators=(",", ":")).encode("utf-8"))
            for name, data in zip(names, encoded):
                archive.writestr(_zip_entry(name), data)
        advance(n)
    report.notes.extend(_notes(scene.sh_degree, facts))
    return report


def _notes(degree: int, facts: dict) -> list:
    notes = [f"quantized to .sog: positions to 16 bits an axis of log(|v| + 1) (largest error "
             f"{facts['position']:.3g}), log scales and colours each to a 256-entry codebook (largest error "
             f"{facts['scale']:.3g} and {facts['color']:.3g}), opacity and rotation to bytes"]
    if degree:
        bands = "1" if degree == 1 else f"1\u2013{degree}"
        notes.append(f"SH degree {bands} bands: a palette of {plural(facts['palette'], 'entry', 'entries')} "
                     f"(k-means) over a 256-entry codebook, largest coefficient error {facts['sh']:.3g}")
    notes.append("splats stored in Morton (spatial) order, which lets the images compress (--sort does not apply)")
    for key, what in (("scale_nan", "scale"), ("color_nan", "color"), ("opacity_nan", "opacity"),
                      ("sh_nan", "SH")):
        if facts.get(key):
            notes.append(f"{what}: {plural(facts[key], 'NaN value')} written as 0")
    if facts["rotation_nan"]:
        notes.append(f"rotation: {plural(facts['rotation_nan'], 'quaternion')} with no direction written as "
                     "the identity")
    return notes


# --------------------------------------------------------------------------
# Reading


def _fail(message: str, path: str):
    raise FormatError(message, path)


def _meta(archive: zipfile.ZipFile, path: str) -> dict:
    """meta.json of ``archive``, checked: every field a reader uses is there and of its kind."""
    try:
        info = archive.getinfo(META_NAME)
    except KeyError:
        _fail(f"the archive holds no {META_NAME}: not a .sog file", path)
    if info.file_size > MAX_META_BYTES:
        _fail(f"{META_NAME} declares {info.file_size:,} bytes (at most {MAX_META_BYTES:,})", path)
    try:
        meta = json.loads(_entry(archive, META_NAME, path).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
        _fail(f"{META_NAME} is not JSON ({e})", path)
    if not isinstance(meta, dict):
        _fail(f"{META_NAME} is not a JSON object", path)
    version = meta.get("version")
    if version is None:
        raise UnsupportedError(f"a version 1 .sog ({META_NAME} without a version; read: {VERSION})", path)
    if version != VERSION or isinstance(version, bool):
        raise UnsupportedError(f".sog version {version!r} (read: {VERSION})", path)
    count = meta.get("count")
    if not isinstance(count, int) or isinstance(count, bool) or count < 0:
        _fail(f"{META_NAME}: count is {count!r}, not a whole number of splats", path)
    for key in ("means", "scales", "quats", "sh0"):
        _section(meta, key, path)
    for key in ("mins", "maxs"):
        _numbers(meta["means"], "means", key, 3, path)
    for key in ("scales", "sh0"):
        _numbers(meta[key], key, "codebook", CODEBOOK_SIZE, path)
    if "shN" in meta:
        shn = _section(meta, "shN", path)
        bands = shn.get("bands")
        if bands not in (1, 2, 3) or isinstance(bands, bool):
            _fail(f"{META_NAME}: shN.bands is {bands!r} (expected 1, 2 or 3)", path)
        entries = shn.get("count")
        if not isinstance(entries, int) or isinstance(entries, bool) or not 1 <= entries <= MAX_PALETTE:
            _fail(f"{META_NAME}: shN.count is {entries!r} (expected 1 to {MAX_PALETTE:,})", path)
        _numbers(shn, "shN", "codebook", CODEBOOK_SIZE, path)
    return meta


def _section(meta: dict, key: str, path: str) -> dict:
    section = meta.get(key)
    wanted = len(FILES[key])
    if not isinstance(section, dict):
        _fail(f"{META_NAME} has no {key} object", path)
    files = section.get("files")
    if not isinstance(files, list) or len(files) < wanted or not all(isinstance(f, str) for f in files[:wanted]):
        _fail(f"{META_NAME}: {key}.files must name {plural(wanted, 'image')}", path)
    return section


def _numbers(section: dict, key: str, field: str, size: int, path: str) -> np.ndarray:
    values = section.get(field)
    if (not isinstance(values, list) or len(values) != size
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)):
        _fail(f"{META_NAME}: {key}.{field} must be {size} numbers", path)
    out = np.array(values, dtype=np.float64)
    if not np.isfinite(out).all():
        _fail(f"{META_NAME}: {key}.{field} holds a NaN or infinite value", path)
    return out


def _entry(archive: zipfile.ZipFile, name: str, path: str) -> bytes:
    try:
        return archive.read(name)
    except KeyError:
        _fail(f"{META_NAME} names {name!r}, which the archive lacks", path)
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, RuntimeError, NotImplementedError, ValueError) as e:
        _fail(f"{name}: the archive's entry is damaged ({e})", path)


def _pixels(archive: zipfile.ZipFile, name: str, path: str, *, least: int, most: int, width: int | None = None) \
        -> tuple:
    """The RGBA pixels ``(W * H, 4) uint8`` of image ``name``, and its width, checked to hold between
    ``least`` and ``most`` pixels (and ``width`` wide when given) before it is decoded."""
    from PIL import Image

    try:
        declared = archive.getinfo(name).file_size
    except KeyError:
        _fail(f"{META_NAME} names {name!r}, which the archive lacks", path)
    if declared > 8 * most + (1 << 20):
        _fail(f"{name} declares {declared:,} bytes, more than an image of {most:,} pixels takes", path)
    data = _entry(archive, name, path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # bounded below, by the count
            with Image.open(BytesIO(data)) as im:
                if im.format not in IMAGE_FORMATS:
                    _fail(f"{name} is {im.format}, not {' or '.join(IMAGE_FORMATS)}", path)
                w, h = im.size
                if w * h < least or w * h > most or (width is not None and w != width):
                    want = f"{width} pixels wide, " if width is not None else ""
                    _fail(f"{name} is {w} x {h} pixels: {want}{least:,} to {most:,} pixels expected", path)
                if im.mode not in ("RGB", "RGBA"):
                    _fail(f"{name} is a {im.mode} image, not 8-bit RGB or RGBA", path)
                rgba = np.asarray(im.convert("RGBA"))
    except FormatError:
        raise
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as e:
        _fail(f"{name} is not a readable image ({e})", path)
    return rgba.reshape(-1, 4), w


def _book(section: dict) -> np.ndarray:
    return np.array(section["codebook"], dtype=np.float64).astype(np.float32)


def decode(archive: zipfile.ZipFile, meta: dict, path: str) -> dict:
    """The model columns ``(N,) float32`` of a ``.sog`` archive whose meta.json is ``meta`` (checked)."""
    n = meta["count"]
    least, most = n, 2 * n + SPARE_PIXELS
    jobs = {"low": meta["means"]["files"][0], "high": meta["means"]["files"][1], "quats": meta["quats"]["files"][0],
            "scales": meta["scales"]["files"][0], "sh0": meta["sh0"]["files"][0]}
    if "shN" in meta:
        jobs["labels"] = meta["shN"]["files"][1]
    with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
        done = {key: pool.submit(_pixels, archive, name, path, least=least, most=most) for key, name in jobs.items()}
        px = {key: future.result()[0][:n] for key, future in done.items()}
    cols = {}
    q = (px["low"][:, :3].astype(np.uint32) | (px["high"][:, :3].astype(np.uint32) << 8)).astype(np.float64)
    mins, maxs = np.array(meta["means"]["mins"], np.float64), np.array(meta["means"]["maxs"], np.float64)
    span = np.where(maxs != mins, maxs - mins, 1.0)
    with np.errstate(over="ignore"):
        xyz = _unlog(mins + span * (q / 65535.0)).astype(np.float32)
    for i, name in enumerate(model.POSITION):
        cols[name] = xyz[:, i]
    mode = px["quats"][:, 3].astype(np.intp) - QUAT_MODE
    if n and (mode.min() < 0 or mode.max() > 3):
        bad = int(np.count_nonzero((mode < 0) | (mode > 3)))
        _fail(f"{jobs['quats']}: {plural(bad, 'splat')} with a quaternion mode outside 252..255", path)
    three = (px["quats"][:, :3].astype(np.float64) / 255.0 * 2.0 - 1.0) / SQRT2
    rot = np.zeros((n, 4))
    rows = np.arange(n)
    rot[rows[:, None], _OTHERS[mode]] = three
    rot[rows, mode] = np.sqrt(np.maximum(0.0, 1.0 - (three * three).sum(axis=1)))
    for i, name in enumerate(model.ROTATION):
        cols[name] = rot[:, i].astype(np.float32)
    scale_book, color_book = _book(meta["scales"]), _book(meta["sh0"])
    for i, name in enumerate(model.SCALE):
        cols[name] = scale_book[px["scales"][:, i]]
    for i, name in enumerate(model.COLOR):
        cols[name] = (0.5 + SH_C0 * color_book[px["sh0"][:, i]].astype(np.float64)).astype(np.float32)
    alpha = np.clip(px["sh0"][:, 3].astype(np.float64) / 255.0, 1e-6, 1 - 1e-6)
    cols["opacity"] = logit(alpha).astype(np.float32)  # clamped off 0 and 1, as splat-transform reads it
    cols.update(model.static_columns(n))
    if "shN" in meta:
        cols.update(_decode_sh(archive, meta, px["labels"], path))
    return cols


def _decode_sh(archive: zipfile.ZipFile, meta: dict, label_px: np.ndarray, path: str) -> dict:
    shn = meta["shN"]
    degree, entries = shn["bands"], shn["count"]
    k = model.SH_COEFFS[degree]
    rows = -(-entries // PALETTE_ROW)
    name = shn["files"][0]
    centroid_px, _ = _pixels(archive, name, path, least=rows * PALETTE_ROW * k,
                             most=(MAX_PALETTE // PALETTE_ROW) * PALETTE_ROW * k, width=PALETTE_ROW * k)
    labels = label_px[:, 0].astype(np.int64) | (label_px[:, 1].astype(np.int64) << 8)
    if len(labels) and labels.max() >= entries:
        bad = int(np.count_nonzero(labels >= entries))
        _fail(f"{shn['files'][1]}: {plural(bad, 'splat')} label a palette entry past shN.count ({entries:,})",
              path)
    book = _book(shn)
    # entry i, coefficient j at pixel i * k + j; RGB: the channels
    palette = centroid_px[:entries * k, :3].reshape(entries, k, 3)
    values = book[palette[labels]]  # (n, k, 3)
    return {f"f_rest_{c * k + j}": np.ascontiguousarray(values[:, j, c]) for c in range(3) for j in range(k)}


def _open(path: str):
    with open_input(path) as f:
        raw = f.read()
    if not raw:
        _fail("file is empty", path)
    try:
        return zipfile.ZipFile(BytesIO(raw))
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, NotImplementedError) as e:
        _fail(f"not a .sog file (not a zip archive: {e})", path)


def read(path: str | os.PathLike, **_options) -> Scene:
    """Read a version-2 ``.sog`` file as a static :class:`Scene`, with its SH bands."""
    path = os.fspath(path)
    with _open(path) as archive:
        meta = _meta(archive, path)
        columns = decode(archive, meta, path)
    facts = {"file_bytes": os.path.getsize(path), "version": VERSION,
             "sh_degree": meta["shN"]["bands"] if "shN" in meta else 0,
             "palette": meta["shN"]["count"] if "shN" in meta else 0,
             "generator": str((meta.get("asset") or {}).get("generator", "")) if isinstance(meta.get("asset"), dict)
             else "", "antialias": meta.get("antialias") is True}
    notes = ["trained with antialiasing (the flag is kept in no other format)"] if facts["antialias"] else []
    return Scene(columns=columns, variant=model.VARIANT_3DGS, meta=facts, notes=notes)


def scan(path: str | os.PathLike, **options) -> Scan:
    """Read a ``.sog`` for ``info``: its images are compressed whole, so the scene comes as one piece."""
    out = Scan(variant=model.VARIANT_3DGS)

    def pieces():
        scene = read(path, **options)
        out.meta.update(scene.meta)
        out.notes.extend(scene.notes)
        yield {name: scene.columns[name] for name in model.attribute_names(scene.columns)}

    out.pieces = pieces()
    return out


def splat_count(path: str | os.PathLike) -> int | None:
    """The splats a ``.sog`` declares (its meta.json's count), or None when it cannot be told."""
    path = os.fspath(path)
    try:
        with _open(path) as archive:
            return _meta(archive, path)["count"]
    except (FormatError, UnsupportedError):
        return None


def most_splats(path: str | os.PathLike) -> int:
    """At most the splats a ``.sog`` gives: its meta.json's count (0 for one it refuses)."""
    return splat_count(path) or 0




FORMAT = Format(
    name="sog",
    suffixes=(".sog",),
    default_sort="none",
    holds_empty=False,
    dynamic=False,
    read=read, scan=scan, splat_count=splat_count, most_splats=most_splats,
    write=write, holds_sh=True, expands=True,
    info_fields=meta_fields('version', 'sh_degree', 'palette', 'generator', 'antialias'), storage=fixed_storage(STORAGE),
)
