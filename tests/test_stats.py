"""``stats``: numbers checked against independent computations on small scenes."""

from __future__ import annotations

import json
import math
import re
import struct
from pathlib import Path

import numpy as np
import pytest
import zstandard
from click.testing import CliRunner

from splatconv.cli import main

from .conftest import lite_columns_with_normals, random_columns, write_ply


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def half(x: float) -> float:
    """Round to the nearest half (saturating), the independent way."""
    try:
        return struct.unpack("<e", struct.pack("<e", x))[0]
    except OverflowError:
        return math.copysign(65504.0, x)


# --------------------------------------------------------------------------
# An independent model of both writers, from specs/splatv.md and splaTV's
# JavaScript: plain numpy and Python, nothing from splatconv.

HALF_MAX = 65504.0
GROUPS = {
    "position": ["x", "y", "z"], "rotation": [f"rot_{i}" for i in range(4)],
    "scale": [f"scale_{i}" for i in range(3)], "color": [f"f_dc_{i}" for i in range(3)], "opacity": ["opacity"],
    "motion": [f"motion_{i}" for i in range(9)], "omega": [f"omega_{i}" for i in range(4)],
    "trbf": ["trbf_center", "trbf_scale"],
}
HALF_GROUPS = ("rotation", "scale", "motion", "omega", "trbf")


def viewer_units(cols: dict, group: str) -> np.ndarray:
    """(N, k) float64: linear scales, clamped colour, sigmoid opacity."""
    v = np.stack([cols[n].astype(np.float64) for n in GROUPS[group]], axis=1)
    with np.errstate(over="ignore"):
        if group == "scale":
            v = np.exp(v)
        elif group == "trbf":
            v[:, 1] = np.exp(v[:, 1])
        elif group == "color":
            v = np.clip(v, 0, 1)
        elif group == "opacity":
            v = 1 / (1 + np.exp(-v))
    return v


def js_float_to_half(x) -> float:
    """The value of the half splaTV's floatToHalf makes of float32 ``x``, transcribed from its JavaScript."""
    f = int(np.float32(x).view(np.uint32))
    sign = -1.0 if f >> 31 else 1.0
    exp, frac = (f >> 23) & 0xFF, f & 0x7FFFFF
    if exp >= 142:  # |x| >= 32768, infinity, NaN
        return sign * math.inf
    if exp >= 113:
        return sign * (1 + (frac >> 13) / 1024) * 2.0 ** (exp - 127)
    if exp > 0:
        frac = (frac | 0x800000) >> ((113 - exp) & 31)  # JavaScript's >> takes the count modulo 32
    return sign * (frac >> 13) * 2.0**-24  # new exponent 0 (bit 10 set by a wrapped shift: the same value)


def texture_values(cols: dict, group: str, compat: bool) -> np.ndarray:
    """What the viewer reads back from the texture, in viewer units."""
    if group == "position":
        return viewer_units(cols, group)
    if group in ("color", "opacity"):
        raw = np.stack([cols[n].astype(np.float64) for n in GROUPS[group]], axis=1)
        v = raw if group == "color" else 1 / (1 + np.exp(-raw))
        scaled = np.clip(np.nan_to_num(v * 255, nan=0.0), 0, 255)
        return (np.trunc(scaled) if compat else np.rint(scaled)) / 255
    with np.errstate(over="ignore", invalid="ignore"):
        v32 = viewer_units(cols, group).astype(np.float32)  # both writers round to float32 first
    if compat:
        return np.vectorize(js_float_to_half, otypes=[np.float64])(v32)
    with np.errstate(over="ignore"):
        h = v32.astype(np.float16).astype(np.float64)
    return np.where(np.isinf(h) & np.isfinite(v32), np.copysign(HALF_MAX, v32), h)  # saturated


#: The storage's finest step per group of a .splatv (specs/stats.md): relative errors are
#: taken against the larger of |source| and this (the smallest normal half; a byte step).
RESOLUTION = {"position": 0.0, "color": 1 / 255, "opacity": 1 / 255, **dict.fromkeys(HALF_GROUPS, 2.0**-14)}


#: How far the reader's float32 logarithms and logits of halves and bytes may sit from the
#: texture's own values, relative: stats compares what the files read as (the model), this model
#: the texture's values, so each error may move by this much of the converted value.
READ_BACK = 4e-6


def expected_attributes(cols: dict, compat: bool) -> tuple:
    """The ``stats`` attributes, and per group what each error may differ by (:data:`READ_BACK`)."""
    out = {}
    slack = {}
    for group in GROUPS:
        a = viewer_units(cols, group)
        b = texture_values(cols, group, compat)
        both = np.isfinite(a) & np.isfinite(b)
        err = np.abs(a[both] - b[both])
        scale = np.maximum(np.abs(a[both]), RESOLUTION[group])
        nz = scale != 0
        raw = np.stack([cols[n] for n in GROUPS[group]], axis=1)
        half = group in HALF_GROUPS
        out[group] = {
            "max_abs_error": float(err.max()),
            "max_rel_error": float((err[nz] / scale[nz]).max()),
            "rmse": float(np.sqrt(np.mean(err ** 2))),
            # Made non-finite by the conversion: a NaN or infinity the source holds too is not counted.
            "nonfinite": int(np.sum(~np.isfinite(b) & ~((np.isnan(a) & np.isnan(b)) | (np.isinf(a) & (a == b))))),
            "overflow": int(np.sum(np.isfinite(a) & (np.abs(a) > HALF_MAX))) if half else 0,
            "underflow": int(np.sum(np.isfinite(a) & (a != 0) & (b == 0))) if half else 0,
            "subnormal": int(np.sum((b != 0) & (np.abs(b) < 2.0**-14))) if half else 0,
            "clamped": (int(np.sum((np.rint(raw * 255.0) < 0) | (np.rint(raw * 255.0) > 255) | np.isnan(raw)))
                        if group == "color"
                        else int(np.sum(np.isnan(raw))) if group == "opacity" else 0),
        }
        moved = READ_BACK * np.abs(b[both])
        slack[group] = {"max_abs_error": float(moved.max()), "rmse": float(moved.max()),
                        "max_rel_error": float((moved[nz] / scale[nz]).max())}
    return out, slack


def assert_attributes(got: dict, expected: dict, slack: dict) -> None:
    """``stats``' attributes against :func:`expected_attributes`: counts exact, errors within the slack."""
    for group, e in expected.items():
        assert list(got[group]) == list(e)
        for key, value in e.items():
            assert got[group][key] == pytest.approx(value, rel=1e-9, abs=slack[group].get(key, 0) + 1e-15), \
                (group, key)


def hostile_columns(n: int = 18) -> dict:
    """Benign values from simple formulas, then one hostile value per row."""
    i = np.arange(n, dtype=np.float64)
    cols = {"x": i, "y": 2 * i, "z": -i, "trbf_center": 0.1 + 0.05 * i, "trbf_scale": np.log(0.2 + 0.01 * i),
            "opacity": -1 + 0.1 * i}
    for k in range(9):
        cols[f"motion_{k}"] = 0.01 * (k + 1) + 0.001 * i
    for k in range(3):
        cols[f"f_dc_{k}"] = 0.2 + 0.03 * i + 0.01 * k
        cols[f"scale_{k}"] = np.log(0.01 + 0.001 * (i + k))
    for k in range(4):
        cols[f"rot_{k}"] = 0.5 + 0.02 * i - 0.1 * k
        cols[f"omega_{k}"] = 0.05 + 0.01 * k + 0.003 * i
    cols = {k: v.astype(np.float32) for k, v in cols.items()}
    cols["scale_0"][0] = 20.0               # exp(20) > 65504: overflow; saturates (default), infinity (splaTV)
    cols["scale_1"][1] = math.log(40000)    # a half, but >= 32768: infinity in splaTV's converter
    cols["motion_3"][2] = np.nan            # NaN: stays NaN (default), infinity (splaTV)
    cols["rot_1"][3] = 1e-6                 # a half subnormal in both
    cols["motion_2"][4] = 1e-9              # below 2^-25: zero in both
    cols["motion_0"][5] = 1e-15             # zero (default); garbage subnormal 0x0048 (splaTV)
    cols["f_dc_0"][6] = 1.5                 # clamped
    cols["f_dc_2"][7] = -0.2                # clamped
    cols["omega_0"][8] = 70000.0            # overflow: saturates (default), infinity (splaTV)
    cols["trbf_center"][9] = 3e-5           # a half subnormal in both
    cols["scale_2"][10] = math.log(2.0**-50)  # zero (default); garbage (splaTV)
    cols["opacity"][11] = 50.0              # alpha 255
    cols["opacity"][12] = -50.0             # sigmoid 2e-22: alpha 0 (a byte's rounding, not counted)
    cols["scale_0"][13] = 100.0             # exp(100) overflows float32: infinity in both
    cols["rot_3"][14] = 3e-8                # 2^-24 (default, rounds up); zero (splaTV truncates)
    cols["scale_1"][15] = math.log(2.0**-14)  # 2^-14 in float32: the smallest normal half, not subnormal
    cols["f_dc_1"][16] = np.nan             # colour byte 0: clamped
    cols["opacity"][17] = np.nan            # alpha byte 0: clamped
    return lite_columns_with_normals(cols)


#: Counts worked out by hand from the comments above: (group, key) -> (default, splatv-js).
HAND_COUNTS = {
    ("rotation", "subnormal"): (2, 1), ("rotation", "underflow"): (0, 1),
    ("scale", "overflow"): (2, 2), ("scale", "nonfinite"): (1, 3), ("scale", "underflow"): (1, 0),
    ("scale", "subnormal"): (0, 1),
    ("color", "clamped"): (3, 3), ("opacity", "clamped"): (1, 1),
    ("motion", "nonfinite"): (0, 1), ("motion", "underflow"): (2, 1), ("motion", "subnormal"): (0, 1),
    ("omega", "overflow"): (1, 1), ("omega", "nonfinite"): (0, 1),
    ("trbf", "subnormal"): (1, 1),
}


@pytest.mark.parametrize("compat", [False, True], ids=["default", "splatv-js"])
def test_errors_and_counts_match_an_independent_model(tmp_path, compat):
    cols = hostile_columns()
    src = write_ply(tmp_path / "hostile.ply", cols)
    conv = tmp_path / "h.splatv"
    assert run("convert", src, conv, *(["--compat", "splatv-js"] if compat else [])).exit_code == 0
    data = json.loads(run("stats", src, conv, "--json", "--zstd-level", "1").stdout)
    expected, slack = expected_attributes(cols, compat)
    for (group, key), counts in HAND_COUNTS.items():  # the model agrees with the reasoning
        assert expected[group][key] == counts[compat], (group, key)
    for group, e in expected.items():
        for key in ("nonfinite", "overflow", "underflow", "subnormal", "clamped"):
            if (group, key) not in HAND_COUNTS:
                assert e[key] == 0, (group, key)
    assert expected["position"]["max_abs_error"] == 0
    if not compat:  # no value sits where rounding via float32 and rounding once differ
        for group in HALF_GROUPS:
            with np.errstate(over="ignore"):
                once = viewer_units(cols, group).astype(np.float16)
                twice = viewer_units(cols, group).astype(np.float32).astype(np.float16)
            np.testing.assert_array_equal(once, twice)
    assert_attributes(data["attributes"], expected, slack)
    dmg = data["viewer"]["splatv_js_damage"]  # of the source: the same for both
    assert dmg == {"rotation": {"infinity": 0, "garbled": 0}, "scale": {"infinity": 3, "garbled": 1},
                   "motion": {"infinity": 0, "garbled": 1}, "omega": {"infinity": 1, "garbled": 0},
                   "trbf": {"infinity": 0, "garbled": 0}}


def test_the_single_file_report_is_the_default_writers(tmp_path):
    cols = hostile_columns()
    src = write_ply(tmp_path / "hostile.ply", cols)
    data = json.loads(run("stats", src, "--json", "--zstd-level", "1").stdout)
    assert_attributes(data["attributes"], *expected_attributes(cols, False))


#: splaTV's garbage bands: magnitudes it writes as a nonzero half where the nearest half is zero.
GARBAGE_BANDS = [(2.0**-136, 2.0**-126), (2.0**-120, 2.0**-109), (2.0**-88, 2.0**-77), (2.0**-56, 2.0**-45)]


def _f32_below(x: float) -> np.float32:
    return np.nextafter(np.float32(x), np.float32(0))


@pytest.mark.parametrize("lo, hi", GARBAGE_BANDS)
def test_garbled_counts_each_band_and_nothing_just_outside(lo, hi):
    from splatconv.stats import splatvjs_damage

    inside = [lo, _f32_below(hi), -lo, (lo * hi) ** 0.5]
    outside = [_f32_below(lo), hi, -hi, 0.0]
    # The model agrees: garbage inside, zero just outside.
    assert all(js_float_to_half(v) != 0 for v in inside)
    assert all(js_float_to_half(v) == 0 for v in outside)
    for values, count in ((inside, len(inside)), (outside, 0)):
        cols = lite_columns_with_normals(random_columns(len(values), 2))
        cols["motion_4"] = np.array(values, dtype=np.float32)
        assert splatvjs_damage(cols)["motion"] == {"infinity": 0, "garbled": count}


def test_garbled_through_a_ply_and_between_the_bands(tmp_path):
    inside = [v for lo, hi in GARBAGE_BANDS for v in (lo, _f32_below(hi))]
    between = [2.0**-140, 2.0**-125, 2.0**-100, 2.0**-60, 2.0**-40, 2.0**-25, 2.0**-20]
    cols = lite_columns_with_normals(random_columns(len(inside + between), 5))
    cols["omega_2"] = np.array(inside + between, dtype=np.float32)  # float32 subnormals included
    src = write_ply(tmp_path / "tiny.ply", cols)
    data = json.loads(run("stats", src, "--json", "--zstd-level", "1").stdout)
    assert data["viewer"]["splatv_js_damage"]["omega"] == {"infinity": 0, "garbled": len(inside)}
    text = " ".join(run("stats", src, "--zstd-level", "1").stdout.split())  # undo the wrapping
    assert (f"splaTV's own converter would corrupt in SOURCE: omega: 0 to infinity, {len(inside)} garbled "
            "(garbled: a nonzero half written where the nearest half is zero)") in text


def test_files_sizes_and_zstd(tmp_path, lite_ply):
    conv = tmp_path / "s.splatv"
    assert run("convert", lite_ply, conv).exit_code == 0
    data = json.loads(run("stats", lite_ply, conv, "--json", "--zstd-level", "5").stdout)
    src, out = data["files"]
    for f, path in ((src, lite_ply), (out, conv)):
        raw = path.read_bytes()
        assert f["bytes"] == len(raw)
        assert f["bytes_per_splat"] == pytest.approx(len(raw) / 3000, abs=1e-3)
        single = len(zstandard.ZstdCompressor(level=5).compress(raw))
        assert f["zstd_bytes"] == pytest.approx(single, rel=0.03)  # multi-threaded frames differ slightly
        assert f["zstd_level"] == 5
    assert out["ratio"] == pytest.approx(out["bytes"] / src["bytes"], abs=1e-6)
    assert out["zstd_ratio"] == pytest.approx(out["zstd_bytes"] / src["bytes"], abs=1e-6)


def test_time_coverage_and_motion(tmp_path):
    cols = lite_columns_with_normals(random_columns(500, 4))
    p = write_ply(tmp_path / "t.ply", cols)
    data = json.loads(run("stats", p, "--json", "--zstd-level", "1").stdout)
    t = np.array(data["time"]["times"])
    assert len(t) == 20 and t[0] == 0 and t[-1] == 1
    # Independent: from the halves the viewer reads.
    c = np.vectorize(half)(cols["trbf_center"].astype(np.float64))
    s = np.vectorize(half)(np.exp(cols["trbf_scale"].astype(np.float64)))
    expected = [int(np.sum(np.exp(-(((tt - c) / s) ** 2)) >= 0.02)) for tt in t]
    assert data["time"]["visible"] == expected
    v = np.sqrt(sum(np.vectorize(half)(cols[f"motion_{i}"].astype(np.float64)) ** 2 for i in range(3)))
    assert data["motion"]["velocity"]["max"] == pytest.approx(v.max(), rel=1e-6)
    assert data["motion"]["velocity"]["p50"] == pytest.approx(np.median(v), rel=1e-6)


def test_single_file_reports_the_conversion_it_would_get(lite_ply, tmp_path):
    data = json.loads(run("stats", lite_ply, "--json", "--zstd-level", "3").stdout)
    assert [f["role"] for f in data["files"]] == ["source", "converted"]
    assert data["files"][1]["path"] is None
    conv = tmp_path / "real.splatv"
    run("convert", lite_ply, conv)
    assert data["files"][1]["bytes"] == conv.stat().st_size
    real = json.loads(run("stats", lite_ply, conv, "--json", "--zstd-level", "3").stdout)
    assert data["attributes"] == real["attributes"]
    assert data["files"][1]["zstd_bytes"] == pytest.approx(real["files"][1]["zstd_bytes"], rel=0.02)


def test_viewer_limits(tmp_path):
    from .conftest import splatv_bytes

    recs = np.zeros((3, 16), "<u4")
    recs[:, 0] = 0x7FC00000  # NaN x
    recs[:, 15] = 0x3C00 << 16
    p = tmp_path / "nan.splatv"
    p.write_bytes(splatv_bytes(recs, cameras=[]))
    data = json.loads(run("stats", p, "--json", "--zstd-level", "1").stdout)
    v = data["viewer"]
    assert v["nan_positions"] == 3 and v["empty_cameras"] and v["cameras"] == 0
    assert v["texture_height"] == 1 and v["fits_max_texture_size"] == {"8192": True, "16384": True}
    assert v["splatv_js_damage"] is None  # already a .splatv
    text = run("stats", p, "--zstd-level", "1").stdout
    assert "cameras 0 (EMPTY: the viewer needs one)" in " ".join(text.split())


def tall_splatv(path, texheight: int):
    """One splat in a .splatv whose header declares ``texheight`` rows (data not padded)."""
    from .conftest import splatv_bytes

    rec = np.zeros((1, 16), "<u4")
    rec[0, 0] = np.float32(1.0).view(np.uint32)
    rec[0, 15] = 0x3C00 << 16  # trbf_scale 1
    chunk = {"type": "splat", "size": 4096 * texheight * 16, "texwidth": 4096, "texheight": texheight,
             "cameras": [{"id": 0, "img_name": "c", "width": 8, "height": 8, "position": [0, 0, -5],
                          "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fx": 8, "fy": 8}]}
    path.write_bytes(splatv_bytes(rec, chunks=[chunk], pad=False))
    return path


@pytest.mark.parametrize("texheight, fits", [(65536, {"8192": False, "16384": False}),
                                              (12000, {"8192": False, "16384": True}),
                                              (8192, {"8192": True, "16384": True})])
def test_texture_height_is_the_declared_one(tmp_path, texheight, fits):
    tall = tall_splatv(tmp_path / "tall.splatv", texheight)
    back = tmp_path / "back.ply"
    assert run("convert", tall, back).exit_code == 0
    # Alone, as SOURCE (against a PLY of it) and as CONVERTED: the viewer sizes its texture by the header.
    for args in ((tall,), (tall, back), (back, tall)):
        data = json.loads(run("stats", *args, "--json", "--zstd-level", "1").stdout)
        assert data["count"] == 1
        assert data["viewer"]["texture_height"] == texheight, args
        assert data["viewer"]["fits_max_texture_size"] == fits, args
        assert data["viewer"]["cameras"] == 1 and not data["viewer"]["empty_cameras"]
    text = run("stats", tall, "--zstd-level", "1").stdout
    assert f"viewer (SOURCE): texture 4096x{texheight} (fits 8192: {'yes' if fits['8192'] else 'NO'}, " in text


def test_texture_height_of_a_ply_is_what_converting_declares(tmp_path):
    p = write_ply(tmp_path / "s.ply", lite_columns_with_normals(random_columns(2049, 6)))
    conv = tmp_path / "s.splatv"
    assert run("convert", p, conv).exit_code == 0
    declared = json.loads(run("info", conv, "--json").stdout)["texture"]["height"]
    assert declared == 3  # ceil(2049 / 1024)
    for args in ((p,), (p, conv)):
        assert json.loads(run("stats", *args, "--json", "--zstd-level", "1").stdout)["viewer"]["texture_height"] == 3


def test_text_fits_100_columns_and_markdown(lite_ply, tmp_path):
    text = run("stats", lite_ply, "--zstd-level", "1").stdout
    assert max(len(line) for line in text.splitlines()) <= 100
    assert text.startswith("files:\n")
    md = run("stats", lite_ply, "--markdown", "--zstd-level", "1").stdout
    assert "| attribute | max abs err |" in md and "**files**" in md
    r = run("stats", lite_ply, "--json", "--markdown")
    assert r.exit_code == 2 and r.stderr == "Error: --json and --markdown cannot be used together\n"


@pytest.mark.parametrize("length", [64, 200])
def test_long_paths_are_elided_in_text_only(tmp_path, lite_ply, length):
    folder = tmp_path / ("d" * 40)
    folder.mkdir()
    src = folder / ("s" * (length - 4) + ".ply")
    src.write_bytes(lite_ply.read_bytes())
    conv = folder / ("c" * (length - 7) + ".splatv")
    assert run("convert", src, conv).exit_code == 0
    for args in ((src,), (src, conv)):
        text = run("stats", *args, "--zstd-level", "1").stdout
        lines = text.splitlines()
        assert max(len(line) for line in lines) <= 100, max(lines, key=len)
        rows = [line for line in lines if line.startswith(("  source ", "  converted "))]
        assert len(rows) == 2 and all("..." in r for r in rows[: len(args)])
        assert "sssss.ply " in rows[0]  # the end of the name survives
        if len(args) == 2:
            assert "ccccc.splatv " in rows[1]
        data = json.loads(run("stats", *args, "--json", "--zstd-level", "1").stdout)
        assert [f["path"] for f in data["files"]][: len(args)] == [str(a) for a in args]
        md = run("stats", *args, "--markdown", "--zstd-level", "1").stdout
        assert f"| source | {src} |" in md


def test_text_fits_100_columns_with_huge_counts(lite_ply):
    from splatconv.text import stats_text
    from splatconv.stats import stats_findings

    data = stats_findings(str(lite_ply), zstd_level=1)
    for a in data["attributes"].values():  # as many as a 67-million-splat texture could hold
        a.update(nonfinite=268_435_456, overflow=268_435_456, underflow=268_435_456, subnormal=99_999_999,
                 clamped=201_326_592, max_abs_error=3.402e38, max_rel_error=1.0, rmse=1.234e-30)
    data["viewer"].update(texture_height=65536, nan_positions=67_108_864, empty_cameras=True, cameras=0)
    text = stats_text(data)
    assert max(len(line) for line in text.splitlines()) <= 100
    assert "268435456" in text and "NaN positions 67,108,864" in " ".join(text.split())


# --------------------------------------------------------------------------
# specs/json.md: the keys it lists are the keys info and stats print, in order.

JSON_SPEC = (Path(__file__).resolve().parent.parent / "specs" / "json.md").read_text(encoding="utf-8")


def spec_keys(section: str) -> dict:
    """The key tree of a section of specs/json.md: ``{key: subtree}`` from its bullet lists.

    A bullet's keys are the backquoted names before its first colon; sub-bullets
    (two more spaces) are the keys inside it.
    """
    text = JSON_SPEC.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
    root: dict = {}
    stack = [(-1, root)]
    for line in text.splitlines():
        m = re.match(r"( *)\* (.*)", line)
        if not m:
            continue
        indent, body = len(m.group(1)), m.group(2)
        while stack[-1][0] >= indent:
            stack.pop()
        node: dict = {}
        for key in re.findall(r"`(\w+)`", body.split(":", 1)[0]):
            stack[-1][1][key] = node
        stack.append((indent, node))
    return root


def test_info_keys_are_documented_for_every_format(tmp_path, lite_ply, gs_ply):
    from splatconv.formats import REGISTRY

    spec = spec_keys("info")
    details = spec.pop("details")
    modules = {m.name: m for m in REGISTRY.values() if m.can_read}  # info reads: a write-only format has no details
    assert set(details) == set(modules), "every readable format's details are documented"
    for name, module in modules.items():
        if not (module.can_write and module.can_read):
            continue
        path = tmp_path / f"written{module.suffixes[0]}"
        assert run("convert", lite_ply if module.dynamic else gs_ply, path).exit_code == 0, name
        info = json.loads(run("info", path, "--json").stdout)
        assert [k for k in info if k != "details"] == list(spec), name
        assert list(info).index("details") == list(info).index("notes") - 1  # where the spec lists it
        assert info["schema"] == "splatconv.info/2"
        assert list(info["details"]) == list(details[name]), name
        assert list(info["texture"]) == list(spec["texture"])
        assert list(info["bounds"]) == ["min", "max"]
    cams = json.loads(run("info", lite_ply, "--json").stdout)
    assert cams["cameras"] == []


def test_stats_keys_are_documented(tmp_path, lite_ply):
    from splatconv.model import GROUPS

    spec = spec_keys("stats")
    conv = tmp_path / "s.splatv"
    assert run("convert", lite_ply, conv).exit_code == 0
    data = json.loads(run("stats", lite_ply, conv, "--json", "--zstd-level", "1").stdout)
    assert list(data) == list(spec)
    assert data["schema"] == "splatconv.stats/4"
    for entry in data["files"]:
        assert list(entry) == list(spec["files"])
    assert list(data["time"]) == list(spec["time"])
    # Maps keyed by name list the names in their bullet's text and each entry's keys below it.
    section = JSON_SPEC.split("\n## stats\n", 1)[1]
    motion_text = section.split("* `motion`", 1)[1].split("\n  *", 1)[0]
    assert re.findall(r"`(\w+)`\s+\(", motion_text) == list(data["motion"])
    for values in data["motion"].values():
        assert list(values) == list(spec["motion"])
    attributes_text = section.split("* `attributes`", 1)[1].split("\n  *", 1)[0]
    assert re.findall(r"`(\w+)`", attributes_text.split("One entry per group", 1)[1]) == list(GROUPS)
    assert list(data["attributes"]) == list(GROUPS)
    for group in data["attributes"].values():
        assert list(group) == list(spec["attributes"])
    assert list(data["viewer"]) == list(spec["viewer"])
    damage = data["viewer"]["splatv_js_damage"]
    assert list(damage) == list(HALF_GROUPS)
    damage_text = section.split("* `splatv_js_damage`", 1)[1].split("\n    *", 1)[0]
    names = damage_text.split("One entry per group stored as halves", 1)[1].split(", in viewer units", 1)[0]
    assert re.findall(r"`(\w+)`", names) == list(damage)
    for group in damage.values():
        assert list(group) == list(spec["viewer"]["splatv_js_damage"])


def test_a_splatv_alone_is_reported_as_stored(tmp_path, lite_ply):
    conv = tmp_path / "s.splatv"
    assert run("convert", lite_ply, conv).exit_code == 0
    data = json.loads(run("stats", conv, "--json", "--zstd-level", "1").stdout)
    assert [f["role"] for f in data["files"]] == ["source"]
    assert data["attributes"] is None and data["viewer"]["splatv_js_damage"] is None
    assert data["count"] == 3000 and sum(data["time"]["visible"]) > 0
    text = run("stats", conv, "--zstd-level", "1").stdout
    assert "converted" not in text and "against source" not in text
    assert "attributes: none compared (SOURCE alone is a splatv file, which the viewer loads as stored)" in text
    md = run("stats", conv, "--markdown", "--zstd-level", "1").stdout
    assert "| attribute |" not in md and "- attributes: none compared" in md


def test_plurals(tmp_path):
    from .conftest import splatv_bytes

    rec = np.zeros((1, 16), "<u4")
    rec[0, 0] = np.float32(1.0).view(np.uint32)
    rec[0, 15] = 0x3C00 << 16  # trbf_scale 1: visible at every time step
    rec[0, 3] = 0x3C00  # rotation (1, 0, 0, 0) and alpha byte 255: drawable
    rec[0, 7] = 0xFF000000
    p = tmp_path / "one.splatv"
    p.write_bytes(splatv_bytes(rec))
    info = run("info", p).stdout
    assert "count:     1 splat\n" in info
    text = run("stats", p, "--zstd-level", "1").stdout
    assert f"count: SOURCE {p}: 1 splat\n" in text
    assert "time (SOURCE): 20 steps over [0, 1]: 1 splat drawn at each" in text
    for output in (info, text):
        assert not re.search(r"\b1 (splats|values|frames|cameras|bytes)\b|\(s\)", output), output


def test_info_says_when_splats_are_drawn_at_every_time(tmp_path):
    cols = lite_columns_with_normals(random_columns(6, 3))
    cols["trbf_scale"][:2] = np.inf  # two splats visible always
    cols["trbf_center"][2] = np.nan  # no interval: left out
    cols["trbf_center"][3] = np.inf  # never drawn at a finite time: left out
    src = write_ply(tmp_path / "always.ply", cols)
    info = json.loads(run("info", src, "--json").stdout)
    assert info["visible_time_range"] == [None, None] and info["visible_always"] == 2
    # An infinite temporal scale means "always visible" (counted there), not a value without meaning.
    assert info["nonfinite"]["trbf_center"] == 2 and info["nonfinite"]["trbf_scale"] == 0
    text = run("info", src).stdout
    assert "visible at every time (2 splats with an infinite temporal scale)" in text
    # Without them, the ends are those of the splats with finite centres only.
    cols["trbf_scale"][:2] = 0.0
    info = json.loads(run("info", write_ply(tmp_path / "finite.ply", cols), "--json").stdout)
    c = cols["trbf_center"].astype(np.float64)[[0, 1, 4, 5]]
    reach = np.exp(cols["trbf_scale"].astype(np.float64)[[0, 1, 4, 5]]) * math.sqrt(-math.log(0.02))
    assert info["visible_time_range"] == pytest.approx([(c - reach).min(), (c + reach).max()], rel=1e-12)
    assert info["visible_always"] == 0
    # No finite centre at all: no range, said in words.
    cols["trbf_center"][:] = np.nan
    none = write_ply(tmp_path / "none.ply", cols)
    assert json.loads(run("info", none, "--json").stdout)["visible_time_range"] is None
    assert "visible never (no splat has a finite time centre)" in run("info", none).stdout


def test_info_of_several_files_is_a_list_each_with_its_schema(tmp_path, lite_ply):
    conv = tmp_path / "s.splatv"
    assert run("convert", lite_ply, conv).exit_code == 0
    both = json.loads(run("info", lite_ply, conv, "--json").stdout)
    assert [i["schema"] for i in both] == ["splatconv.info/2"] * 2
    assert [i["format"] for i in both] == ["ply", "splatv"]
    assert [list(i) for i in both][0] == [list(i) for i in both][1]


# --------------------------------------------------------------------------
# Real trained scenes carry NaN positions, infinite temporal scales and huge
# values: no figure may fail and no numpy warning may reach the user.

#: Values a trained scene's float32 columns hold, the hostile ones included.
NASTY = (np.nan, np.inf, -np.inf, 3.4e38, -3.4e38, 1e30, -1e30, 1e-45, -1e-45, 0.0, -0.0, 88.0, 89.0, -104.0)


def nasty_columns(n_plain: int = 40) -> dict:
    """Plausible rows, then every NASTY value in every column (one column per row, the rest plausible),
    then rows where every column holds the same NASTY value."""
    plain = random_columns(n_plain, 11)
    names = list(plain)
    rows = [plain]
    for value in NASTY:
        block = random_columns(len(names), 12)
        for i, name in enumerate(names):
            block[name][i] = value
        rows.append(block)
        rows.append({name: np.full(1, value, np.float32) for name in names})
    cols = {name: np.concatenate([r[name] for r in rows]) for name in names}
    # Distinct finite positions for most rows, so that matching rows by position is not the point here.
    return lite_columns_with_normals(cols)


@pytest.fixture(scope="module")
def nasty_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("nasty")
    src = write_ply(folder / "nasty.ply", nasty_columns())
    default, compat = folder / "nasty.splatv", folder / "nasty_js.splatv"
    assert run("convert", src, default).exit_code == 0
    assert run("convert", src, compat, "--compat", "splatv-js").exit_code == 0
    back = folder / "back.ply"
    assert run("convert", default, back).exit_code == 0
    return src, default, compat, back


@pytest.mark.parametrize("args", [("src",), ("default",), ("src", "default"), ("src", "compat"),
                                  ("default", "back"), ("back", "default"), ("default", "default")])
def test_nasty_scenes_give_figures_and_no_warning(nasty_files, args):
    # pytest turns RuntimeWarning into errors: a warning would fail the command (exit 1).
    files = dict(zip(("src", "default", "compat", "back"), nasty_files))
    paths = [files[a] for a in args]
    result = run("stats", *paths, "--json", "--zstd-level", "1")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["count"] == len(nasty_columns()["x"])
    text = run("stats", *paths, "--zstd-level", "1")
    assert text.exit_code == 0 and "count: " in text.stdout
    for path in paths:
        info = run("info", path, "--json")
        assert info.exit_code == 0, info.output
        assert json.loads(info.stdout)["nonfinite"]["x"] > 0


def test_identical_records_count_nothing_lost(nasty_files):
    # A .splatv against itself, and against its lossless PLY (which converts back to the same
    # records): nothing overflowed, underflowed or was clamped, and every error is zero (the PLY
    # holds the very float32 logarithms and logits the .splatv reads as).
    _, default, _, back = nasty_files
    for pair in ((default, default), (default, back), (back, default)):
        data = json.loads(run("stats", *pair, "--json", "--zstd-level", "1").stdout)
        for group, a in data["attributes"].items():
            assert (a["overflow"], a["underflow"], a["clamped"]) == (0, 0, 0), (pair, group)
            assert (a["max_abs_error"], a["max_rel_error"], a["rmse"]) == (0, 0, 0), (pair, group)


def test_the_largest_half_round_trips_without_overflow(tmp_path):
    # exp(log 65504) is 65504.000000000015 in double: stored and read back, 65504 is not past the range.
    from .conftest import splatv_bytes

    rec = np.zeros((2, 16), "<u4")
    rec[:, 0] = np.float32(1.0).view(np.uint32), np.float32(2.0).view(np.uint32)
    rec[:, 15] = np.uint32(0x7BFF << 16)  # trbf_scale: the largest half
    rec[:, 13] = 0x7BFF | (0x7BFF << 16)  # omega_0, omega_1 too
    p = tmp_path / "max.splatv"
    p.write_bytes(splatv_bytes(rec))
    back = tmp_path / "max.ply"
    assert run("convert", p, back).exit_code == 0
    for pair in ((p, back), (back, p), (p, p)):
        attributes = json.loads(run("stats", *pair, "--json", "--zstd-level", "1").stdout)["attributes"]
        assert attributes["trbf"]["overflow"] == 0 and attributes["omega"]["overflow"] == 0, pair
    # A PLY value whose float32 is 65520 or more has no finite nearest half: that is overflow; below, rounding.
    cols = lite_columns_with_normals(random_columns(3, 1))
    cols["omega_0"] = np.array([65519.99, 65520.0, -1e6], np.float32)
    src = write_ply(tmp_path / "edge.ply", cols)
    assert json.loads(run("stats", src, "--json", "--zstd-level", "1").stdout)["attributes"]["omega"]["overflow"] == 2


def test_group_errors_of_infinities_and_nan_without_warning():
    from splatconv.compare import value_errors

    a = np.array([[np.inf], [-np.inf], [np.nan], [1.0], [np.inf], [5e-324], [1e308]])
    b = np.array([[np.inf], [np.inf], [np.nan], [1.5], [2.0], [1.0], [-1e308]])
    e = value_errors(a, b, "motion", "half")  # warnings are errors here
    # Only the finite pairs are compared: 1 vs 1.5, 5e-324 vs 1, 1e308 vs -1e308 (a difference past
    # the float64 range: infinite, and said so).
    assert e.compared == 3 and e.max_abs_error == math.inf and e.rmse == math.inf
    assert e.unexplained == 5  # -inf -> inf, inf -> 2, and the three finite pairs
    finite = value_errors(a[3:4], b[3:4], "motion", "half")
    assert (finite.max_abs_error, finite.max_rel_error, finite.rmse) == (0.5, 0.5, 0.5)



@pytest.mark.parametrize("kind, unexplained", [("exact", 6), ("half", 3), ("byte", 2), ("float32", 5), ("none", 0), ("quantized", 0)])
def test_each_storage_kind_explains_its_own_errors(kind, unexplained):
    """The same pairs judged by how CONVERTED stores them (``compare.STORAGE_KINDS``)."""
    from splatconv.compare import value_errors

    # Off by 2^-12 and 2^-20, NaN stored as 0, inf as 7, 1e5 saturated to the half range, 0.25 off by 1/512.
    a = np.array([[1.0, 2.0, np.nan], [np.inf, 1e5, 0.25]])
    b = np.array([[1.0 + 2**-12, 2.0 + 2**-20, 0.0], [7.0, 65504.0, 0.25 + 1 / 512]])
    e = value_errors(a, b, "motion", kind)
    assert e.unexplained == unexplained and e.storage == kind
    assert e.nan_stored == (kind == "byte")  # a byte cannot hold NaN: stored as 0, explained


def test_quaternions_stored_as_bytes_compare_normalised():
    from splatconv.compare import QUATERNION_STEP, value_errors

    q = np.array([[2.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5], [np.nan, 0, 0, 0], [0.0, 0, 0, 0], [1.0, 0, 0, 0]])
    stored = np.array([[1.0, 0, 0, 0], [0.5, 0.5, 0.5, 0.5 + QUATERNION_STEP], [0.0, 0, 0, 0], [0.0, 0, 0, 0],
                       [0.0, 1.0, 0, 0]])
    e = value_errors(q, stored, "rotation", "unit_quaternion_byte")
    # Length 2 vs 1: the same rotation; one step off: explained; no direction on both sides: alike;
    # the last turned half a turn: all four of its components are unexplained.
    assert e.unexplained == 2 and e.nonfinite_changed == 0


def test_blocks_merge_to_the_whole(monkeypatch, tmp_path):
    # The report is computed a block of rows at a time; with blocks of 7 rows it is the same.
    from splatconv import stats

    cols = lite_columns_with_normals(random_columns(50, 9))
    src = write_ply(tmp_path / "s.ply", cols)
    conv = tmp_path / "s.splatv"
    assert run("convert", src, conv).exit_code == 0
    whole = stats.stats_findings(str(src), str(conv), zstd_level=1)
    monkeypatch.setattr(stats, "BLOCK", 7)
    monkeypatch.setattr(stats, "_GATHER", 3)
    parts = stats.stats_findings(str(src), str(conv), zstd_level=1)
    for group, a in whole["attributes"].items():
        for key, value in a.items():
            assert parts["attributes"][group][key] == pytest.approx(value, rel=1e-12), (group, key)
    assert {k: v for k, v in parts.items() if k != "attributes"} == {k: v for k, v in whole.items()
                                                                    if k != "attributes"}


def test_no_warning_reaches_the_user(nasty_files):
    # The real command line, warnings at numpy's defaults: stderr holds nothing.
    import subprocess
    import sys

    src, default, _, _ = nasty_files
    for args in (("stats", src, default, "--zstd-level", "1"), ("info", src, default)):
        p = subprocess.run([sys.executable, "-m", "splatconv", *map(str, args)], capture_output=True, text=True,
                           env={**__import__("os").environ, "PYTHONWARNINGS": "default"})
        assert p.returncode == 0 and p.stderr == "", p.stderr


def test_a_faithful_conversion_of_a_nasty_scene_is_all_explained(nasty_files):
    # NaN colours and opacities are stored as byte 0, values past the half range saturate, NaN
    # stays NaN: all expected of the default writer, so no group drifted (the check verify runs).
    from splatconv import read
    from splatconv.compare import align, compare_scenes
    from splatconv.formats.splatv import STORAGE

    src, default, _, back = nasty_files
    for a, b in ((src, default), (default, back)):
        source, converted = read(a), read(b)
        errors = compare_scenes(source, converted, align(source, converted, storage=STORAGE), STORAGE)
        assert {g: e.unexplained for g, e in errors.items()} == dict.fromkeys(errors, 0), (a, b)


def test_progress_stages_cover_the_work(tmp_path, lite_ply):
    # stats_findings reports a stage per file read, one per file compressed and one for the comparison,
    # each advanced to its total.
    import contextlib

    from splatconv.progress import Progress
    from splatconv.stats import stats_findings

    class Recorder(Progress):
        def __init__(self):
            self.stages = []

        @contextlib.contextmanager
        def stage(self, label, total=None, unit="it"):
            entry = [label, total, unit, 0]
            self.stages.append(entry)

            def advance(n=1):
                entry[3] += n

            yield advance

    conv = tmp_path / "s.splatv"
    assert run("convert", lite_ply, conv).exit_code == 0
    for args, expected in (((lite_ply, conv), ["reading", "zstd-1 scene.ply", "reading", "zstd-1 s.splatv",
                                               "comparing"]),
                           ((lite_ply,), ["reading", "zstd-1 scene.ply", "zstd-1 (as converted)", "sizing .splatvq",
                                          "comparing"]),
                           ((conv,), ["reading", "zstd-1 s.splatv", "sizing .splatvq", "reading values"])):
        recorder = Recorder()
        stats_findings(*map(str, args), zstd_level=1, progress=recorder)
        assert [s[0] for s in recorder.stages] == expected
        for label, total, unit, done in recorder.stages:
            units = {"comparing": "splat", "reading values": "splat", "reading": "file", "sizing .splatvq": "setting"}
            assert done == total and unit == units.get(label, "byte")
        assert recorder.stages[-1][1] == 3000


def test_one_splat_reads_as_one_splat_in_every_command(tmp_path):
    """Notes and summaries agree with a count of one: convert with edits, bake, merge."""
    cols = lite_columns_with_normals(random_columns(2, 5))
    cols["trbf_scale"][:] = np.inf  # visible at every time
    cols["opacity"][:] = 5.0
    cols["x"][1] = np.nan  # the one drop-nonfinite removes
    src = tmp_path / "two.ply"
    write_ply(src, cols)
    outputs = []
    for args in (("convert", src, tmp_path / "one.splatv", "--drop-nonfinite", "--rotate", "y:90"),
                 ("bake", tmp_path / "one.splatv", tmp_path / "one.ply", "--time", "0.5"),
                 ("merge", tmp_path / "one.ply", tmp_path / "one.splatv", tmp_path / "both.splatv"),
                 ("convert", tmp_path / "one.splatv", tmp_path / "trim.splatv", "--trim", "0.2,0.4")):
        result = run(*args)
        outputs.append(result.stdout + result.stderr)
    text = "\n".join(outputs)
    assert "removed 1 of 2 splats" in text and "wrote " in text
    assert "applied to 1 splat" in text and ": 1 splat," in text, text
    assert not re.search(r"\b1 (splats|values|frames|cameras)\b|\(s\)", text), text
