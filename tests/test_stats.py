"""``stats``: numbers checked against independent computations on small scenes."""

from __future__ import annotations

import json
import math
import struct

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


@pytest.fixture
def hostile(tmp_path):
    cols = lite_columns_with_normals(random_columns(64, 9))
    cols["scale_0"][0] = 20.0            # exp(20) > 65504: overflow (and infinity in splaTV's converter)
    cols["scale_1"][1] = math.log(40000)  # 40000: fine as a half, infinity in splaTV's converter
    cols["motion_3"][2] = np.nan          # non-finite
    cols["rot_1"][3] = 1e-6               # becomes a half subnormal
    cols["motion_2"][4] = 1e-9            # nonzero that becomes zero
    cols["motion_0"][5] = 1e-15           # splaTV's shift wraps: garbage instead of zero
    cols["f_dc_0"][6] = 1.5               # clamped
    cols["f_dc_2"][7] = -0.2              # clamped
    return cols, write_ply(tmp_path / "hostile.ply", cols)


def test_counts_and_errors_of_a_hostile_source(tmp_path, hostile):
    cols, src = hostile
    conv = tmp_path / "h.splatv"
    assert run("convert", src, conv).exit_code == 0
    data = json.loads(run("stats", src, conv, "--json", "--zstd-level", "3").stdout)
    a = data["attributes"]
    assert a["scale"]["overflow"] == 1
    assert a["motion"]["nonfinite"] == 1
    assert a["rotation"]["subnormal"] >= 1
    assert a["motion"]["underflow"] == 2  # 1e-9 and 1e-15
    assert a["color"]["clamped"] == 2
    assert a["position"] == {"max_abs_error": 0.0, "max_rel_error": 0.0, "rmse": 0.0, "nonfinite": 0,
                             "overflow": 0, "underflow": 0, "subnormal": 0, "clamped": 0}
    # Independent: omega is stored as plain halves, rounded to nearest.
    om = np.stack([cols[f"omega_{i}"] for i in range(4)], axis=1).astype(np.float64)
    err = np.abs(om - np.vectorize(half)(om))
    assert a["omega"]["max_abs_error"] == pytest.approx(err.max(), rel=1e-12)
    assert a["omega"]["rmse"] == pytest.approx(np.sqrt((err ** 2).mean()), rel=1e-9)
    nz = om != 0
    assert a["omega"]["max_rel_error"] == pytest.approx((err[nz] / np.abs(om[nz])).max(), rel=1e-9)
    # Colour: clamp, x255, round -> error against the clamped value.
    c = np.clip(np.stack([cols[f"f_dc_{i}"] for i in range(3)], axis=1).astype(np.float64), 0, 1)
    ce = np.abs(c - np.round(c * 255) / 255)
    assert a["color"]["max_abs_error"] == pytest.approx(ce.max(), abs=1e-7)
    dmg = data["viewer"]["splatv_js_damage"]
    assert dmg["scale"]["infinity"] == 2  # exp(20) and 40000: both >= 32768
    assert dmg["motion"]["garbled"] == 1


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
    assert "cameras 0 (EMPTY: the viewer needs one)" in text


def test_text_fits_100_columns_and_markdown(lite_ply, tmp_path):
    text = run("stats", lite_ply, "--zstd-level", "1").stdout
    assert max(len(line) for line in text.splitlines()) <= 100
    assert text.startswith("files:\n")
    md = run("stats", lite_ply, "--markdown", "--zstd-level", "1").stdout
    assert "| attribute | max abs err |" in md and "**files**" in md
    r = run("stats", lite_ply, "--json", "--markdown")
    assert r.exit_code == 2 and r.stderr == "Error: --json and --markdown cannot be used together\n"


def test_json_keys_are_documented():
    from pathlib import Path

    spec = (Path(__file__).resolve().parent.parent / "specs" / "stats.md").read_text()
    for key in ("files", "role", "path", "bytes", "bytes_per_splat", "zstd_bytes", "zstd_level", "ratio",
                "zstd_ratio", "count", "bounds", "time", "visible", "motion", "attributes", "max_abs_error",
                "max_rel_error", "rmse", "nonfinite", "overflow", "underflow", "subnormal", "clamped", "viewer",
                "texture_height", "fits_max_texture_size", "empty_cameras", "nan_positions", "splatv_js_damage",
                "infinity", "garbled"):
        assert f"`{key}`" in spec, key
