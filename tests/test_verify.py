"""``verify`` and ``diff``: faithful conversions pass, real damage fails, clear errors."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from splatconv import packing
from splatconv.cli import main

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data" / "dancers.ply"
CAMERAS = ROOT / "sample_data" / "cameras.json"
QUICK = ["--cameras", "0", "--times", "0.25,0.6", "--size", "240x135"]


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def faithful(tmp_path_factory):
    out = tmp_path_factory.mktemp("v") / "dancers.splatv"
    assert run("convert", SAMPLE, out, "--cameras", CAMERAS).exit_code == 0
    return out


def damaged(src: Path, dst: Path, how: str) -> Path:
    data = src.read_bytes()
    n = struct.unpack("<I", data[4:8])[0]
    recs = np.frombuffer(data[8 + n:], "<u4").reshape(-1, 16).copy()
    live = recs.any(axis=1)
    r = recs[live]

    def halves(w):
        return packing.half_to_float(r[:, w] & 0xFFFF), packing.half_to_float(r[:, w] >> 16)

    if how == "colour channels swapped":
        c = r[:, 7]
        r[:, 7] = (c & 0xFF00FF00) | ((c & 0xFF) << 16) | ((c >> 16) & 0xFF)
    elif how == "scales halved":
        for w in (5, 6):
            lo, hi = halves(w)
            r[:, w] = packing.pack_half2(packing.float_to_half(lo * 0.5), packing.float_to_half(hi * 0.5))
    elif how == "time centres shifted":
        lo, hi = halves(15)
        r[:, 15] = packing.pack_half2(packing.float_to_half(lo + 0.15), packing.float_to_half(hi))
    elif how == "quaternion reordered":
        r[:, 3], r[:, 4] = r[:, 4].copy(), r[:, 3].copy()
    recs[live] = r
    dst.write_bytes(data[:8 + n] + recs.tobytes())
    return dst


def test_faithful_conversion_passes(faithful):
    r = run("verify", SAMPLE, faithful, *QUICK)
    assert r.exit_code == 0, r.output
    assert r.stdout.rstrip().splitlines()[-1].startswith("PASS: 2 frames at or above 40 dB; worst ")


@pytest.mark.parametrize("how,attribute", [
    ("colour channels swapped", "color"),
    ("scales halved", "scale"),
    ("time centres shifted", "trbf"),
    ("quaternion reordered", "rotation"),
])
def test_real_damage_fails(tmp_path, faithful, how, attribute):
    bad = damaged(faithful, tmp_path / "bad.splatv", how)
    r = run("verify", SAMPLE, bad, *QUICK)
    assert r.exit_code == 1, r.output
    assert f"FAIL: {attribute} drifted: " in r.stdout
    data = json.loads(run("verify", SAMPLE, bad, *QUICK, "--json").stdout)
    assert not data["passed"]
    assert not data["structure"][attribute]["ok"]
    drifted = [k for k, v in data["structure"].items() if not v["ok"]]
    assert drifted == [attribute]


def test_splatv_to_ply_conversion_verifies(tmp_path, faithful):
    ply = tmp_path / "back.ply"
    assert run("convert", faithful, ply).exit_code == 0
    r = run("verify", faithful, ply, *QUICK, "--json")
    data = json.loads(r.stdout)
    assert r.exit_code == 0 and data["passed"]
    assert all(v["unexplained"] == 0 for v in data["structure"].values())


def test_compat_conversion_of_the_sample_verifies(tmp_path):
    out = tmp_path / "js.splatv"
    assert run("convert", SAMPLE, out, "--compat", "splatv-js", "--cameras", CAMERAS).exit_code == 0
    assert run("verify", SAMPLE, out, *QUICK).exit_code == 0


def test_json_shape(faithful):
    data = json.loads(run("verify", SAMPLE, faithful, *QUICK, "--json").stdout)
    assert set(data) == {"paths", "count", "min_psnr", "passed", "structure", "frames", "worst"}
    assert data["count"] == 5000 and data["min_psnr"] == 40.0
    assert set(data["structure"]) == {"position", "rotation", "scale", "color", "opacity", "motion", "omega",
                                      "trbf"}
    assert set(data["structure"]["scale"]) == {"max_abs_error", "max_rel_error", "rmse", "unexplained",
                                               "compared", "ok"}
    assert [(f["time"], f["camera"]) for f in data["frames"]] == [(0.25, 0), (0.6, 0)]
    assert set(data["frames"][0]) == {"time", "camera", "psnr", "max_abs_error", "mean_abs_error", "share_off",
                                      "tolerance"}
    assert data["structure"]["position"]["max_abs_error"] == 0


def test_report_dir(tmp_path, faithful):
    d = tmp_path / "report"
    assert run("verify", SAMPLE, faithful, *QUICK, "--report-dir", d).exit_code == 0
    names = sorted(p.name for p in d.iterdir())
    assert len(names) == 8 and "cam0_t0.250_side_by_side.png" in names
    assert Image.open(d / "cam0_t0.250_side_by_side.png").size == (3 * 240 + 8, 135)


def test_min_psnr_threshold_decides(faithful):
    r = run("verify", SAMPLE, faithful, *QUICK, "--min-psnr", "99")
    assert r.exit_code == 1
    assert "FAIL: 2 of 2 frames below 99 dB; worst: " in r.stdout


def test_different_counts_is_a_clear_error(tmp_path, faithful):
    from .conftest import lite_columns_with_normals, random_columns, write_ply

    other = write_ply(tmp_path / "other.ply", lite_columns_with_normals(random_columns(10)))
    r = run("verify", other, faithful)
    assert r.exit_code == 1
    assert r.stderr == f"Error: {other} has 10 splats but {faithful} has 5,000\n"


def write_png(path, arr):
    Image.fromarray(arr.astype(np.uint8), "RGB").save(path)
    return path


def test_image_diff(tmp_path):
    a = np.zeros((20, 30, 3), np.uint8)
    b = a.copy()
    b[5, 5] = [30, 0, 0]
    pa, pb = write_png(tmp_path / "a.png", a), write_png(tmp_path / "b.png", b)
    r = run("diff", pa, pb, "--json", "--out", tmp_path / "heat.png")
    data = json.loads(r.stdout)
    mse = 30**2 / (20 * 30 * 3)
    assert data["frames"][0]["psnr"] == pytest.approx(10 * np.log10(255**2 / mse), abs=1e-3)
    assert data["frames"][0]["max_abs_error"] == 30
    assert data["frames"][0]["share_off"] == pytest.approx(1 / 600, abs=1e-6)
    assert r.exit_code == 0
    heat = np.asarray(Image.open(tmp_path / "heat.png"))
    assert heat[5, 5].any() and not heat[0, 0].any()
    r = run("diff", pa, pa)
    assert r.exit_code == 0 and "inf" in r.stdout
    assert run("diff", pa, pb, "--min-psnr", "60").exit_code == 1


def test_image_diff_size_mismatch(tmp_path):
    pa = write_png(tmp_path / "a.png", np.zeros((20, 30, 3)))
    pb = write_png(tmp_path / "b.png", np.zeros((21, 30, 3)))
    r = run("diff", pa, pb)
    assert r.exit_code == 1
    assert r.stderr == "Error: images differ in size: 30x20 and 30x21\n"


def test_diff_of_scene_files(tmp_path, faithful):
    bad = damaged(faithful, tmp_path / "bad.splatv", "scales halved")
    r = run("diff", faithful, bad, "--size", "160x90", "--json")
    assert r.exit_code == 1 and json.loads(r.stdout)["frames"][0]["psnr"] < 40
    r = run("diff", faithful, SAMPLE, "--size", "160x90")
    assert r.exit_code == 0 and "inf" in r.stdout  # a PLY is drawn as its conversion


def test_diff_mixed_inputs_is_usage_error(tmp_path, faithful):
    pa = write_png(tmp_path / "a.png", np.zeros((4, 4, 3)))
    r = run("diff", pa, faithful)
    assert r.exit_code == 2
    assert r.stderr == "Error: compare two images or two scene files, not one of each\n"
