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
from tests import reference

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
            r[:, w] = reference.pack_half2(packing.float_to_half(lo * 0.5), packing.float_to_half(hi * 0.5))
    elif how == "time centres shifted":
        lo, hi = halves(15)
        r[:, 15] = reference.pack_half2(packing.float_to_half(lo + 0.15), packing.float_to_half(hi))
    elif how == "quaternion reordered":
        r[:, 3], r[:, 4] = r[:, 4].copy(), r[:, 3].copy()
    recs[live] = r
    dst.write_bytes(data[:8 + n] + recs.tobytes())
    return dst


def test_faithful_conversion_passes(faithful):
    r = run("verify", SAMPLE, faithful, *QUICK)
    assert r.exit_code == 0, r.output
    assert r.stdout.rstrip().splitlines()[-1].startswith("PASS: 2 frames at or above 40 dB; worst ")


# Which check catches each damage at QUICK's two frames (t = 0.25 and 0.6, camera 0): the
# attribute check always names the damaged attribute; the pixel check fails the frames
# listed. Reordered quaternion components score 35.6 dB at t = 0.25 but 42.8 dB at 0.6
# (see README): that frame passes the pixels and only the attribute check catches it.
DAMAGES = [
    ("colour channels swapped", "color", [0.25, 0.6]),
    ("scales halved", "scale", [0.25, 0.6]),
    ("time centres shifted", "trbf", [0.25, 0.6]),
    ("quaternion reordered", "rotation", [0.25]),
]


@pytest.mark.parametrize("how,attribute,failing_times", DAMAGES, ids=[d[0] for d in DAMAGES])
def test_real_damage_fails(tmp_path, faithful, how, attribute, failing_times):
    bad = damaged(faithful, tmp_path / "bad.splatv", how)
    r = run("verify", SAMPLE, bad, *QUICK)
    assert r.exit_code == 1, r.output
    verdict = r.stdout.split("\n\n")[-1].splitlines()
    assert verdict[0].startswith(f"FAIL: {attribute} drifted: ")
    assert verdict[1].startswith(f"FAIL: {len(failing_times)} of 2 frames below 40 dB; worst: ")
    data = json.loads(run("verify", SAMPLE, bad, *QUICK, "--json").stdout)
    assert not data["passed"]
    drifted = [k for k, v in data["attributes"].items() if not v["ok"]]
    assert drifted == [attribute]
    assert [f["time"] for f in data["frames"] if f["psnr"] < 40] == failing_times


def test_reordered_quaternions_are_caught_by_the_attribute_check_alone(tmp_path, faithful):
    # At t = 0.5 every camera's frame stays above 40 dB (about 43-44 dB): the pixels alone
    # would pass this damage; the rotation check makes verify fail.
    bad = damaged(faithful, tmp_path / "bad.splatv", "quaternion reordered")
    r = run("verify", SAMPLE, bad, "--times", "0.5", "--size", "240x135", "--json")
    data = json.loads(r.stdout)
    assert r.exit_code == 1
    assert all(f["psnr"] >= 40 for f in data["frames"]) and len(data["frames"]) == 3
    assert [k for k, v in data["attributes"].items() if not v["ok"]] == ["rotation"]
    text = run("verify", SAMPLE, bad, "--times", "0.5", "--size", "240x135").stdout
    assert text.rstrip().split("\n\n")[-1].startswith("FAIL: rotation drifted: ")
    assert "frames below" not in text


def test_splatv_to_ply_conversion_verifies(tmp_path, faithful):
    ply = tmp_path / "back.ply"
    assert run("convert", faithful, ply).exit_code == 0
    r = run("verify", faithful, ply, *QUICK, "--json")
    data = json.loads(r.stdout)
    assert r.exit_code == 0 and data["passed"]
    assert all(v["unexplained"] == 0 for v in data["attributes"].values())


def test_compat_conversion_of_the_sample_verifies(tmp_path):
    out = tmp_path / "js.splatv"
    assert run("convert", SAMPLE, out, "--compat", "splatv-js", "--cameras", CAMERAS).exit_code == 0
    assert run("verify", SAMPLE, out, *QUICK).exit_code == 0


def test_json_shape(faithful):
    data = json.loads(run("verify", SAMPLE, faithful, *QUICK, "--json").stdout)
    assert list(data) == ["schema", "paths", "count", "min_psnr", "passed", "attributes", "frames", "worst", "notes"]
    assert data["schema"] == "splatconv.verify/1" and data["notes"] == []
    assert data["count"] == 5000 and data["min_psnr"] == 40.0
    assert set(data["attributes"]) == {"position", "rotation", "scale", "color", "opacity", "motion", "omega",
                                      "trbf"}
    assert set(data["attributes"]["scale"]) == {"max_abs_error", "max_rel_error", "rmse", "unexplained",
                                                "became_infinite", "nan_stored", "compared", "values", "ok"}
    assert data["attributes"]["scale"]["values"] == 3 * 5000
    assert [(f["time"], f["camera"]) for f in data["frames"]] == [(0.25, 0), (0.6, 0)]
    assert list(data["frames"][0]) == ["time", "camera", "psnr", "identical", "max_abs_error", "mean_abs_error",
                                       "share_off", "tolerance"]
    assert data["attributes"]["position"]["max_abs_error"] == 0


def test_report_dir(tmp_path, faithful):
    d = tmp_path / "report"
    assert run("verify", SAMPLE, faithful, *QUICK, "--report-dir", d).exit_code == 0
    names = sorted(p.name for p in d.iterdir())
    assert len(names) == 8 and "cam0_t0.250_side_by_side.png" in names
    assert Image.open(d / "cam0_t0.250_side_by_side.png").size == (3 * 240 + 8, 135)


def test_report_dir_refuses_existing_files_unless_force(tmp_path, faithful):
    d = tmp_path / "report"
    d.mkdir()
    existing = d / "cam0_t0.600_diff.png"
    existing.write_bytes(b"keep")
    r = run("verify", SAMPLE, faithful, *QUICK, "--report-dir", d)
    assert r.exit_code == 1 and r.stdout == ""  # refused before anything is drawn
    assert r.stderr == f"Error: {existing}: already exists (use --force to replace it)\n"
    assert existing.read_bytes() == b"keep" and [p.name for p in d.iterdir()] == [existing.name]
    r = run("verify", SAMPLE, faithful, *QUICK, "--report-dir", d, "--force")
    assert r.exit_code == 0, r.output
    assert Image.open(existing).size == (240, 135)
    assert sorted(p.name for p in d.iterdir()) == sorted(
        f"cam0_t{t}_{k}.png" for t in ("0.250", "0.600") for k in ("source", "converted", "diff", "side_by_side"))


def test_report_dir_writes_atomically(tmp_path, faithful, monkeypatch):
    import errno

    from splatconv.render import diff as imgdiff

    calls = []

    def full_disk(img, stream):
        calls.append(stream.name)
        stream.write(b"\x89PNG partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(imgdiff, "save_png", full_disk)
    d = tmp_path / "report"
    r = run("verify", SAMPLE, faithful, *QUICK, "--report-dir", d)
    assert r.exit_code == 1
    assert r.stderr == f"Error: {d / 'cam0_t0.250_source.png'}: No space left on device\n"
    assert len(calls) == 1 and calls[0] != str(d / "cam0_t0.250_source.png")  # a temporary beside it
    assert list(d.iterdir()) == []  # no partial file, no temporary left


def test_report_dir_frames_with_the_same_names_are_refused(tmp_path, faithful):
    r = run("verify", SAMPLE, faithful, "--cameras", "0", "--times", "0.1001,0.1004", "--report-dir", tmp_path / "d")
    assert r.exit_code == 2
    assert r.stderr == ("Error: --report-dir: camera 0 at t=0.1001 and at t=0.1004 would both be saved as "
                        "cam0_t0.100_source.png; give cameras and times that differ (times in the first 3 decimals)\n")
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("command", ["verify", "diff"])
@pytest.mark.parametrize("value", ["nan", "-inf", "inf", "NaN"])
def test_non_finite_min_psnr_is_a_usage_error(faithful, command, value):
    r = run(command, SAMPLE, faithful, *QUICK, "--min-psnr", value)
    assert r.exit_code == 2 and r.stdout == ""
    assert r.stderr.startswith(f"Usage: main {command} ")
    assert r.stderr.endswith(f"Error: Invalid value for '--min-psnr': '{value}' is not a finite number.\n")


@pytest.mark.parametrize("command", ["verify", "diff"])
@pytest.mark.parametrize("value", ["nan", "0.5,inf", "-inf"])
def test_non_finite_times_are_a_usage_error(faithful, command, value):
    r = run(command, SAMPLE, faithful, "--times", value)
    assert r.exit_code == 2 and r.stdout == ""
    assert r.stderr == f"Error: --times: expected comma-separated numbers, got {value!r}\n"


def test_library_refuses_non_finite_min_psnr(faithful):
    from splatconv.errors import UsageError
    from splatconv.render.commands import diff_files
    from splatconv.render.verify import verify

    with pytest.raises(UsageError, match="--min-psnr: expected a finite number of dB, got nan"):
        verify(SAMPLE, faithful, min_psnr=float("nan"))
    with pytest.raises(UsageError, match="--min-psnr: expected a finite number of dB, got -inf"):
        diff_files(SAMPLE, faithful, min_psnr=float("-inf"))


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
    psnr = 10 * np.log10(255**2 / mse)
    assert data["frames"][0]["psnr"] == pytest.approx(psnr, abs=1e-3)
    assert data["frames"][0]["max_abs_error"] == 30
    assert data["frames"][0]["share_off"] == pytest.approx(1 / 600, abs=1e-6)
    assert r.exit_code == 0
    heat = np.asarray(Image.open(tmp_path / "heat.png"))
    assert heat[5, 5].any() and not heat[0, 0].any()
    r = run("diff", pa, pa)
    assert r.exit_code == 0 and "inf" in r.stdout
    assert run("diff", pa, pb, "--min-psnr", "60").exit_code == 1


def test_image_diff_rows_name_the_images_not_a_time_or_camera(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    a = np.zeros((20, 30, 3), np.uint8)
    b = a.copy()
    b[5, 5] = [30, 0, 0]
    write_png(tmp_path / "a.png", a), write_png(tmp_path / "b.png", b)
    data = json.loads(run("diff", "a.png", "b.png", "--json").stdout)
    row = {"a": "a.png", "b": "b.png", "psnr": 51.141, "identical": False, "max_abs_error": 30, "mean_abs_error": 0.0167,
           "share_off": 0.001667, "tolerance": 8}
    assert data["frames"] == [row] and data["worst"] == row
    r = run("diff", "a.png", "b.png")
    assert r.exit_code == 0
    assert r.stdout == ("A      B       PSNR dB  max err  mean err  pixels off\n"
                        "a.png  b.png     51.14       30     0.017      0.167%\n"
                        "(errors out of 255; pixels off: a channel off by more than 8)\n"
                        "\n"
                        "PASS: a.png vs b.png: 51.14 dB, at or above 40 dB\n")
    r = run("diff", "a.png", "b.png", "--min-psnr", "60")
    assert r.exit_code == 1 and r.stdout.endswith("FAIL: a.png vs b.png: 51.14 dB, below 60 dB\n")
    assert "time" not in r.stdout and "camera" not in r.stdout


def test_image_diff_size_mismatch(tmp_path):
    pa = write_png(tmp_path / "a.png", np.zeros((20, 30, 3)))
    pb = write_png(tmp_path / "b.png", np.zeros((21, 30, 3)))
    r = run("diff", pa, pb)
    assert r.exit_code == 1
    assert r.stderr == "Error: images differ in size: 30x20 and 30x21\n"


def test_diff_of_scene_files(tmp_path, faithful):
    bad = damaged(faithful, tmp_path / "bad.splatv", "scales halved")
    r = run("diff", faithful, bad, "--size", "160x90", "--json")
    data = json.loads(r.stdout)
    assert r.exit_code == 1 and data["frames"][0]["psnr"] < 40
    # diff's defaults: one frame, t = 0.5 from camera 0 (verify: five times from every camera)
    assert [(f["time"], f["camera"]) for f in data["frames"]] == [(0.5, 0)]
    r = run("diff", faithful, SAMPLE, "--size", "160x90")
    assert r.exit_code == 0 and "inf" in r.stdout  # a PLY is drawn as its conversion


def test_diff_mixed_inputs_is_usage_error(tmp_path, faithful):
    pa = write_png(tmp_path / "a.png", np.zeros((4, 4, 3)))
    r = run("diff", pa, faithful)
    assert r.exit_code == 2
    assert r.stderr == "Error: compare two images or two scene files, not one of each\n"
