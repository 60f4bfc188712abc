"""Reports as data: what a scene file holds (``info``), what a conversion costs and loses
(``stats``). Never prints."""

from __future__ import annotations

import math
import os

import numpy as np

from . import viewer
from .compare import HALF_MAX, align, group_errors
from .io import read
from .cameras import framing_camera
from .packing import float_to_half, float_to_half_splatvjs
from .transport import DEFAULT_LEVEL, compressed_size, plain_input, written_sizes
from .formats import format_for, splatv
from .formats.splatv_layout import TEXWIDTH, texture_bytes, texture_height
from .model import COLOR, COLUMNS, GROUPS, Scene
from .viewer import TEMPORAL_CUTOFF


def _finite_range(values: np.ndarray):
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    return [float(v.min()), float(v.max())]


def describe(scene: Scene, path: str, module) -> dict:
    """Facts about a scene file, as JSON-able data.

    Parameters
    ----------
    scene : Scene
    path : str
    module : format module
        The file's format (see :mod:`splatconv.formats`); its ``info_fields``
        add what only that format has.

    Returns
    -------
    dict
        Keys: path, format, variant, count, file_bytes (uncompressed),
        compressed_bytes (on disk, for .zst files, else None), cameras,
        time_range, visible_time_range, bounds, nonfinite, the format's own
        fields, notes.
    """
    cols = scene.columns
    n = scene.count
    meta = scene.meta
    bounds = None
    pos = viewer.positions(cols)
    pos = pos[np.isfinite(pos).all(axis=1)]
    if len(pos):
        bounds = {"min": pos.min(axis=0).tolist(), "max": pos.max(axis=0).tolist()}
    centre = np.asarray(cols["trbf_center"], dtype=np.float64)
    lo, hi = viewer.visible_interval(cols)
    info = {
        "path": path,
        "format": module.NAME,
        "variant": scene.variant,
        "count": n,
        "file_bytes": meta.get("file_bytes"),
        "compressed_bytes": meta.get("compressed_bytes"),
        "cameras": [{"id": c.get("id"), "img_name": c.get("img_name"), "width": c.get("width"),
                     "height": c.get("height")} for c in (scene.cameras or [])],
        "texture": _texture(scene),
        "time_range": _finite_range(centre),
        "visible_time_range": _visible_range(lo, hi),
        "visible_always": int(np.count_nonzero(np.isinf(hi) & np.isinf(lo))),
        "bounds": bounds,
        "nonfinite": {name: int(np.count_nonzero(~np.isfinite(cols[name]))) for name in COLUMNS},
    }
    info.update(module.info_fields(scene))
    info["notes"] = list(scene.notes)
    return info


def _visible_range(lo: np.ndarray, hi: np.ndarray):
    """[earliest, latest] time any splat is drawn; an end is None (JSON null) where some
    splat is drawn at every time (infinite temporal scale: see ``visible_always``)."""
    lo, hi = lo[~np.isnan(lo)], hi[~np.isnan(hi)]
    if lo.size == 0:
        return None
    first, last = float(lo.min()), float(hi.max())
    return [first if math.isfinite(first) else None, last if math.isfinite(last) else None]


def _texture(scene: Scene) -> dict:
    """The texture the viewer holds for the scene: as a .splatv declares it, or as converting would make it."""
    meta = scene.meta
    height = meta.get("texheight", texture_height(scene.count))
    return {"width": TEXWIDTH, "height": height, "declared_bytes": meta.get("declared_bytes", texture_bytes(height)),
            "actual_bytes": meta.get("actual_bytes")}


# --------------------------------------------------------------------------
# ``stats``: sizes, transport size and what a conversion loses.

#: Time steps at which the number of drawn splats is counted.
TIME_STEPS = 20
#: GPU texture size limits the report checks the texture height against.
MAX_TEXTURE_SIZES = (8192, 16384)
#: Groups stored as halves (colour and opacity are bytes, positions float32).
HALF_GROUPS = ("rotation", "scale", "motion", "omega", "trbf")


def _percentiles(v: np.ndarray) -> dict:
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"p50": None, "p90": None, "p99": None, "max": None}
    p = np.percentile(v, [50, 90, 99])
    return {"p50": float(p[0]), "p90": float(p[1]), "p99": float(p[2]), "max": float(v.max())}


def time_coverage(cols: dict, steps: int = TIME_STEPS) -> dict:
    """How many splats the viewer draws at each of ``steps`` times over [0, 1]."""
    centre = np.asarray(cols["trbf_center"], dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        scale = np.exp(np.asarray(cols["trbf_scale"], dtype=np.float64))
        times = np.linspace(0.0, 1.0, steps)
        visible = [int(np.count_nonzero(np.exp(-(((t - centre) / scale) ** 2)) >= TEMPORAL_CUTOFF)) for t in times]
    return {"times": [round(float(t), 6) for t in times], "visible": visible}


def motion_summary(cols: dict) -> dict:
    """Percentiles of |velocity|, |acceleration|, |jerk| (motion_0..8) and |omega|."""

    def norm(names):
        return np.sqrt(sum(np.asarray(cols[n], dtype=np.float64) ** 2 for n in names))

    return {
        "velocity": _percentiles(norm(("motion_0", "motion_1", "motion_2"))),
        "acceleration": _percentiles(norm(("motion_3", "motion_4", "motion_5"))),
        "jerk": _percentiles(norm(("motion_6", "motion_7", "motion_8"))),
        "omega": _percentiles(norm(tuple(f"omega_{i}" for i in range(4)))),
    }


#: Smallest normal half: converted values below it (and not zero) are subnormal.
_HALF_MIN_NORMAL = 2.0**-14


def _counts(source_cols: dict, converted_cols: dict, group: str) -> dict:
    """Per-group counts: nonfinite, overflow, underflow, subnormal, clamped."""

    a = viewer.group_values(source_cols, group)
    b = viewer.group_values(converted_cols, group)
    raw = np.stack([np.asarray(source_cols[n], dtype=np.float64) for n in GROUPS[group]], axis=1)
    finite = np.isfinite(a)
    out = {"nonfinite": int(np.count_nonzero(~np.isfinite(b))), "overflow": 0, "underflow": 0, "subnormal": 0,
           "clamped": 0}
    if group in HALF_GROUPS:
        out["overflow"] = int(np.count_nonzero(finite & (np.abs(a) > HALF_MAX)))
        # Compared in float32: a half read back through exp() may land a hair
        # below 2^-14 in double, never in float32.
        with np.errstate(over="ignore"):
            b32 = np.abs(b.astype(np.float32))
        out["subnormal"] = int(np.count_nonzero((b32 != 0) & (b32 < _HALF_MIN_NORMAL)))
    if group != "position":
        out["underflow"] = int(np.count_nonzero(finite & (a != 0) & (b == 0)))
    if group == "color":
        # NaN is clamped too: the writers store it as 0.
        out["clamped"] = int(np.count_nonzero((raw < 0) | (raw > 1) | np.isnan(raw)))
    elif group == "opacity":
        out["clamped"] = int(np.count_nonzero(np.isnan(raw)))  # sigmoid(NaN): stored as alpha 0
    return out


def splatvjs_damage(cols: dict) -> dict:
    """What splaTV's own converter would corrupt in these attributes, per group.

    Parameters
    ----------
    cols : dict of str to (N,) ndarray
        Model columns of the source.

    Returns
    -------
    dict
        For each group stored as halves, ``infinity``: finite values (after
        exp for scales) it writes as infinity, those of magnitude 32768 or more
        once rounded to float32; ``garbled``: values it writes as a nonzero half
        where the nearest half is zero -- its shift count wraps modulo 32, and it
        keeps a float32 subnormal's top mantissa bits -- which are exactly the
        magnitudes in [2^-136, 2^-126), [2^-120, 2^-109), [2^-88, 2^-77) and
        [2^-56, 2^-45).
    """

    out = {}
    for group in HALF_GROUPS:
        with np.errstate(over="ignore", invalid="ignore"):
            exact = viewer.group_values(cols, group).ravel()
            v = exact.astype(np.float32)  # the converter stores through a Float32Array
        garbled = ((float_to_half_splatvjs(v) & 0x7FFF) != 0) & ((float_to_half(v) & 0x7FFF) == 0)
        out[group] = {"infinity": int(np.count_nonzero(np.isfinite(exact) & (np.abs(v) >= 32768))),
                      "garbled": int(np.count_nonzero(garbled))}
    return out


def _texture_columns(cols: dict) -> dict:
    """Columns of a scene read from a ``.splatv``, giving back the texture's own values.

    The model keeps float32 logarithms and logits chosen so that writing them
    gives the same halves and bytes again; through exp() and the sigmoid they
    come within about 2e-6 (relative) of what the viewer reads, not onto it.
    These float64 columns give the halves and bytes / 255 to double precision,
    so the reported errors are the texture's own.

    Parameters
    ----------
    cols : dict of str to (N,) float32 ndarray

    Returns
    -------
    dict of str to (N,) ndarray
        ``cols`` with the scale, temporal scale, colour and opacity columns
        replaced by float64 ones.
    """
    out = dict(cols)
    with np.errstate(all="ignore"):  # 0 -> log 0, bytes 0 and 255 -> infinite logits
        for name in splatv.EXP_ATTRIBUTES:
            stored = np.exp(np.asarray(cols[name], dtype=np.float64)).astype(np.float16)  # the nearest half
            out[name] = np.log(stored.astype(np.float64))
        for name in COLOR:
            out[name] = np.rint(np.asarray(cols[name], dtype=np.float64) * 255) / 255
        alpha = np.rint(255 / (1 + np.exp(-np.asarray(cols["opacity"], dtype=np.float64)))) / 255
        out["opacity"] = np.log(alpha) - np.log1p(-alpha)
    return out


def _sizes(path: str, level: int) -> tuple:
    """(bytes, zstd bytes at ``level``) of a file's content: a ``.zst`` file's decompressed."""


    with plain_input(path) as plain:
        return os.path.getsize(plain), compressed_size(plain, level)


def _file_entry(role: str, path, fmt: str, size: int, count: int, zstd_bytes: int, level: int,
                source_bytes: int) -> dict:
    return {
        "role": role,
        "path": path,
        "format": fmt,
        "bytes": size,
        "bytes_per_splat": round(size / count, 3) if count else None,
        "zstd_bytes": zstd_bytes,
        "zstd_level": level,
        "ratio": round(size / source_bytes, 6) if source_bytes else None,
        "zstd_ratio": round(zstd_bytes / source_bytes, 6) if source_bytes else None,
    }


def _simulated_conversion(source: Scene, level: int) -> tuple:
    """What ``convert`` would write for ``source``: (scene it decodes to, bytes, zstd bytes).

    The file is written once through the zstd counter, which keeps none of it,
    then encoded again in memory to decode: two uncompressed copies of it never
    exist at once.
    """

    size, zstd_bytes = written_sizes(lambda out: splatv.write(source, out), level)
    records, _ = splatv.encode(source)
    columns, _ = splatv.decode_records(records[:source.count])
    cols = source.columns
    cameras = source.cameras or [framing_camera(cols["x"], cols["y"], cols["z"])]
    return Scene(columns=columns, cameras=cameras), size, zstd_bytes


def _viewer_limits(scene: Scene) -> dict:
    """The ``viewer`` checks of the file the viewer would load (``scene``)."""
    # A .splatv's texture is as tall as its header says, whatever it holds;
    # anything else is as tall as converting it would declare.
    texheight = scene.meta.get("texheight", splatv.texture_height(scene.count))
    xyz = np.stack([scene.columns[c] for c in ("x", "y", "z")])
    return {
        "texture_height": texheight,
        "fits_max_texture_size": {str(s): texheight <= s for s in MAX_TEXTURE_SIZES},
        "cameras": len(scene.cameras or []),
        "empty_cameras": not scene.cameras,
        "nan_positions": int(np.count_nonzero((~np.isfinite(xyz)).any(axis=0))),
    }


def stats_report(source_path: str, converted_path: str | None = None, *, zstd_level: int | None = None,
                 color: str = "auto") -> dict:
    """The ``stats`` report as JSON-able data (keys documented in ``specs/stats.md``).

    With one file, the conversion it would get (default writer) is simulated in
    memory and reported as ``converted``, with ``path`` null; a ``.splatv`` (or
    an empty PLY, which ``convert`` refuses) is reported as what it is.
    """
    level = DEFAULT_LEVEL if zstd_level is None else zstd_level
    source = read(source_path, color=color)
    src_mod = format_for(source_path)
    src_bytes, src_zstd = _sizes(source_path, level)
    files = [_file_entry("source", source_path, src_mod.NAME, src_bytes, source.count, src_zstd, level, src_bytes)]
    if converted_path is not None:
        converted = read(converted_path, color=color)
        conv_mod = format_for(converted_path)
        order = align(source, converted, source_path, converted_path)
        conv_bytes, conv_zstd = _sizes(converted_path, level)
        files.append(_file_entry("converted", converted_path, conv_mod.NAME, conv_bytes, converted.count, conv_zstd,
                                 level, src_bytes))
    elif src_mod.STORES_TEXTURE or source.count == 0:
        converted, conv_mod, order = source, src_mod, None  # already what the viewer reads
    else:
        converted, size, zstd_bytes = _simulated_conversion(source, level)
        conv_mod = splatv
        order = align(source, converted)
        files.append(_file_entry("converted", None, conv_mod.NAME, size, source.count, zstd_bytes, level, src_bytes))
    src_cols = source.columns if order is None else source.take(order)
    conv_cols = converted.columns
    if src_mod.STORES_TEXTURE:
        src_cols = _texture_columns(src_cols)
    if conv_mod.STORES_TEXTURE:
        conv_cols = _texture_columns(conv_cols)
    attributes = {}
    for group in GROUPS:
        e = group_errors(src_cols, conv_cols, group)
        attributes[group] = {"max_abs_error": e.max_abs_error, "max_rel_error": e.max_rel_error, "rmse": e.rmse,
                             **_counts(src_cols, conv_cols, group)}
    info = describe(converted, files[-1]["path"] or source_path, conv_mod)
    # The viewer loads the texture side; with none (PLY to PLY), the converted file as converting would make it.
    viewed = source if src_mod.STORES_TEXTURE and not conv_mod.STORES_TEXTURE else converted
    return {
        "files": files,
        "count": source.count,
        "bounds": info["bounds"],
        "time": time_coverage(conv_cols),
        "motion": motion_summary(conv_cols),
        "attributes": attributes,
        "viewer": {
            **_viewer_limits(viewed),
            "splatv_js_damage": splatvjs_damage(source.columns) if not src_mod.STORES_TEXTURE else None,
        },
    }
