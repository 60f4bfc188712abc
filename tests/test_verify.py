"""``verify`` and ``diff``: faithful conversions pass, real damage fails, clear errors."""

from __future__ import annotations

import json
import math
import os
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from splatconv import packing
from splatconv.cli import main
from tests import reference
from .cli_checks import error_line

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
# (see docs/verify.md): that frame passes the pixels and only the attribute check catches it.
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


def test_a_splatvq_is_called_quantized_not_static(tmp_path):
    # A .splatvq keeps motion and time (a compact 4D format): its attribute lines say quantized, never static.
    # (The default setting as named keeps colours; a proof's tuning may round them: see test_splatvq.py.)
    out = tmp_path / "dancers.splatvq"
    assert run("convert", SAMPLE, out, "--cameras", CAMERAS, "--no-proof").exit_code == 0
    r = run("verify", SAMPLE, out, *QUICK)
    assert r.exit_code == 0, r.output
    assert "static" not in r.stdout
    unchecked = [line.split()[0] for line in r.stdout.splitlines() if "the frames check it" in line]
    assert unchecked == ["position", "rotation", "scale", "motion", "omega", "trbf"]
    assert all("quantized" in line for line in r.stdout.splitlines() if "the frames check it" in line)
    storage = {g: a["storage"] for g, a in json.loads(run("verify", SAMPLE, out, *QUICK, "--json").stdout)
               ["attributes"].items()}
    assert storage["motion"] == storage["trbf"] == "quantized" and storage["color"] == "byte"


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
                                                "became_infinite", "nonfinite_changed", "nan_stored", "compared",
                                                "values", "storage", "ok"}
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
    assert error_line(r, 1).startswith(f"Error: {existing}: already exists")
    assert r.stdout == ""  # refused before anything is drawn
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
    assert error_line(r, 1) == f"Error: {d / 'cam0_t0.250_source.png'}: No space left on device"
    assert len(calls) == 1 and calls[0] != str(d / "cam0_t0.250_source.png")  # a temporary beside it
    assert not d.exists()  # no partial file, no temporary left, nor the folder this run made


@pytest.mark.parametrize("existing", [False, True])
def test_report_dir_on_a_full_disk_leaves_nothing_this_run_wrote(tmp_path, faithful, monkeypatch, existing):
    import errno

    from splatconv.render import diff as imgdiff

    save_png, calls = imgdiff.save_png, []

    def full_disk_at_sixth(img, stream):  # the second frame's second image: the first frame's four are saved
        calls.append(stream.name)
        if len(calls) == 6:
            raise OSError(errno.ENOSPC, "No space left on device")
        save_png(img, stream)

    monkeypatch.setattr(imgdiff, "save_png", full_disk_at_sixth)
    d = tmp_path / "report"
    if existing:
        d.mkdir()
        (d / "notes.txt").write_text("mine")
    r = run("verify", SAMPLE, faithful, *QUICK, "--report-dir", d)
    assert (r.exit_code, r.stdout, r.stderr) == (
        1, "", f"Error: {d / 'cam0_t0.600_converted.png'}: No space left on device\n")
    assert len(calls) == 6
    assert sorted(os.listdir(d)) == ["notes.txt"] if existing else not d.exists()


def test_report_dir_frames_with_the_same_names_are_refused(tmp_path, faithful):
    r = run("verify", SAMPLE, faithful, "--cameras", "0", "--times", "0.1001,0.1004", "--report-dir", tmp_path / "d")
    assert error_line(r, 2).startswith("Error: --report-dir: camera 0 at t=0.1001 and at t=0.1004 would both be "
                                       "saved as cam0_t0.100_source.png")
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("command", ["verify", "diff"])
@pytest.mark.parametrize("value", ["nan", "-inf", "inf", "NaN"])
def test_non_finite_min_psnr_is_a_usage_error(faithful, command, value):
    r = run(command, SAMPLE, faithful, *QUICK, "--min-psnr", value)
    assert error_line(r, 2).startswith(f"Error: Invalid value for '--min-psnr': '{value}' is not a finite number")
    assert r.stdout == ""


@pytest.mark.parametrize("command", ["verify", "diff"])
@pytest.mark.parametrize("value", ["nan", "0.5,inf", "-inf"])
def test_non_finite_times_are_a_usage_error(faithful, command, value):
    r = run(command, SAMPLE, faithful, "--times", value)
    assert error_line(r, 2).startswith(f"Error: --times: expected comma-separated numbers, got {value!r}")
    assert r.stdout == ""


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
    assert error_line(r, 1).startswith(f"Error: {other} has 10 splats but {faithful} has 5,000")


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
    # The write is said on stderr, as every write is, and stays out of stdout (the JSON).
    size = (tmp_path / "heat.png").stat().st_size
    assert r.stderr == f"note: wrote {tmp_path / 'heat.png'}: difference heatmap, 30x20, {size:,} bytes\n"
    assert data["notes"] == [f"wrote {tmp_path / 'heat.png'}: difference heatmap, 30x20, {size:,} bytes"]
    r = run("diff", pa, pa)
    assert r.exit_code == 0 and "inf" in r.stdout
    assert run("diff", pa, pb, "--min-psnr", "60").exit_code == 1


def test_psnr_of_rgba_frames_counts_rgb_only_and_exactly():
    """A proof's frames (RGBA, as drawn) and images (RGB): the same figure, the alpha left out, every error
    as large as a byte allows."""
    from splatconv.render import diff as imgdiff

    rng = np.random.default_rng(3)
    a = rng.integers(0, 256, (37, 53, 4), dtype=np.uint8)
    b = a.copy()
    b[..., 3] = 255 - a[..., 3]  # alpha differs everywhere: not counted
    b[0, 0, :3] = 255 - a[0, 0, :3]
    b[36, 52, 0] = 0 if a[36, 52, 0] > 127 else 255
    d = a[..., :3].astype(np.int64) - b[..., :3].astype(np.int64)
    expected = 10 * math.log10(255.0**2 / float((d * d).sum() / d.size))
    assert imgdiff.psnr(a, b) == expected == imgdiff.psnr(a[..., :3], b[..., :3]) == imgdiff.psnr(a, b[..., :3].copy())
    assert imgdiff.compare(a, b).psnr == expected
    full = np.zeros((4, 4, 4), np.uint8)
    assert imgdiff.psnr(full, full + 255) == 0.0 and imgdiff.psnr(a, a) == math.inf


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
    assert error_line(r, 1).startswith("Error: images differ in size: 30x20 and 30x21")


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
    assert error_line(r, 2).startswith("Error: compare two images or two scene files")


# --------------------------------------------------------------------------
# Figures true, false verdicts gone, bounded work, progress, JSON as documented.

TINY = ["--times", "0.5", "--size", "64x36"]


def _scene_file(tmp_path, name, cols):
    from .conftest import lite_columns_with_normals, write_ply

    return write_ply(tmp_path / name, lite_columns_with_normals(cols))


def _convert(src, dst, *extra):
    r = run("convert", src, dst, "-q", *extra)
    assert r.exit_code == 0, r.output
    return dst


@pytest.mark.parametrize("how", ["one position", "all NaN", "NaN positions"])
def test_faithful_conversions_of_tied_positions_pass(tmp_path, how):
    from .conftest import random_columns

    cols = random_columns(3000, seed=7)
    if how == "all NaN":
        cols = {k: np.full(3000, np.nan, np.float32) for k in cols}
    for k in "xyz":
        cols[k][:] = 0.5 if how == "one position" else np.nan
    src = _scene_file(tmp_path, "tie.ply", cols)
    out = _convert(src, tmp_path / "tie.splatv")
    r = run("verify", src, out, *TINY, "--json")
    data = json.loads(r.stdout)
    assert r.exit_code == 0 and data["passed"], r.stdout
    assert all(g["unexplained"] == 0 for g in data["attributes"].values())


def test_rows_matched_by_position_break_ties_by_colour_and_opacity(tmp_path):
    # CONVERTED is SOURCE's rows shuffled (no writer's order): rows are matched by
    # position, and splats sharing a position by their opacity and colour bytes.
    from .conftest import random_columns

    cols = random_columns(400, seed=8)
    for k in "xyz":
        cols[k] = np.repeat(cols[k][:40], 10)
    perm = np.random.default_rng(1).permutation(400)
    src = _scene_file(tmp_path, "a.ply", cols)
    shuffled = _scene_file(tmp_path, "b.ply", {k: v[perm] for k, v in cols.items()})
    data = json.loads(run("verify", src, shuffled, *TINY, "--json").stdout)
    assert data["passed"] and all(g["max_abs_error"] == 0 for g in data["attributes"].values())


def test_values_made_infinite_by_splatvjs_are_called_so(tmp_path):
    # splaTV's converter writes |x| >= 32768 as infinity: 700 temporal scales of 40,000.
    from .conftest import random_columns

    cols = random_columns(3000, seed=9)
    cols["trbf_scale"][:700] = np.float32(np.log(40000.0))
    src = _scene_file(tmp_path, "s.ply", cols)
    out = _convert(src, tmp_path / "js.splatv", "--compat", "splatv-js")
    r = run("verify", src, out, *TINY)
    assert r.exit_code == 1
    assert r.stdout.rstrip().splitlines()[-1] == ("FAIL: trbf drifted: 700 of 6,000 values became infinite "
                                                  "(finite in the source)")
    trbf = json.loads(run("verify", src, out, *TINY, "--json").stdout)["attributes"]["trbf"]
    assert (trbf["unexplained"], trbf["became_infinite"], trbf["values"], trbf["ok"]) == (700, 700, 6000, False)
    assert _convert(src, tmp_path / "ok.splatv")  # the default writer saturates nothing here: it passes
    assert run("verify", src, tmp_path / "ok.splatv", *TINY).exit_code == 0


def test_nan_colour_and_opacity_stored_in_bytes_are_explained_and_counted(tmp_path):
    from .conftest import random_columns

    cols = random_columns(3000, seed=10)
    for k in ("opacity", "f_dc_0", "f_dc_1", "f_dc_2"):
        cols[k][:] = np.nan
    src = _scene_file(tmp_path, "n.ply", cols)
    out = _convert(src, tmp_path / "n.splatv")
    r = run("verify", src, out, *TINY)
    assert r.exit_code == 0, r.stdout
    assert "color: 9,000 NaN values stored as numbers (a byte cannot hold NaN)\n" in r.stdout
    assert "opacity: 3,000 NaN values stored as numbers (a byte cannot hold NaN)\n" in r.stdout
    data = json.loads(run("verify", src, out, *TINY, "--json").stdout)
    assert [data["attributes"][g]["nan_stored"] for g in ("color", "opacity", "scale")] == [9000, 3000, 0]


def test_drift_counts_are_out_of_every_value_of_the_attribute(tmp_path, faithful):
    bad = damaged(faithful, tmp_path / "bad.splatv", "scales halved")
    r = run("verify", SAMPLE, bad, *QUICK)
    line = r.stdout.split("\n\n")[-1].splitlines()[0]
    assert re.fullmatch(r"FAIL: scale drifted: [\d,]+ of 15,000 values off by more than quantization explains "
                        r"\(largest error between finite values [\d.e+-]+, relative [\d.e+-]+%\)", line), line


def test_one_frame_is_one_frame_and_identical_frames_are_said_to_be(tmp_path, faithful):
    r = run("diff", faithful, faithful, *TINY)
    assert r.exit_code == 0
    lines = r.stdout.splitlines()
    assert lines[1].split()[2] == "inf"
    assert lines[2] == ("(errors out of 255; pixels off: a channel off by more than 8; inf: the two frames are "
                        "identical)")
    assert lines[-1] == "PASS: 1 frame at or above 40 dB; worst inf dB at t=0.5 camera 0"
    frame = json.loads(run("diff", faithful, faithful, *TINY, "--json").stdout)["frames"][0]
    assert frame["psnr"] is None and frame["identical"] is True
    r = run("verify", SAMPLE, faithful, *TINY, "--cameras", "0", "--min-psnr", "99")
    assert r.stdout.rstrip().splitlines()[-1].startswith("FAIL: 1 of 1 frame below 99 dB; worst: t=0.5 camera 0 (")


def test_json_keys_are_those_specs_json_md_lists(tmp_path, faithful):
    spec = (ROOT / "specs" / "json.md").read_text(encoding="utf-8")

    def keys(section: str, sub: str | None = None) -> list:
        text = spec.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
        text = text.split(f"\n### {sub}\n", 1)[1] if sub else text
        text = text.split("\n### ", 1)[0]
        return re.findall(r"^\| `(\w+)` \|", text, re.M)

    v = json.loads(run("verify", SAMPLE, faithful, *TINY, "--cameras", "0", "--json").stdout)
    assert list(v) == keys("verify") and v["schema"] == "splatconv.verify/1"
    assert all(list(g) == keys("verify", "`attributes` entries") for g in v["attributes"].values())
    assert list(v["frames"][0]) == keys("verify", "`frames` entries") == list(v["worst"])
    d = json.loads(run("diff", faithful, SAMPLE, *TINY, "--json").stdout)
    assert list(d) == keys("diff") and d["schema"] == "splatconv.diff/1"
    assert list(d["frames"][0]) == keys("verify", "`frames` entries")
    a = write_png(tmp_path / "a.png", np.zeros((4, 4, 3)))
    i = json.loads(run("diff", a, a, "--json").stdout)
    assert list(i) == keys("diff") and list(i["frames"][0]) == ["a", "b"] + keys("verify", "`frames` entries")[2:]


def test_verify_draws_the_first_8_cameras_unless_told(tmp_path):
    cams = json.loads(CAMERAS.read_text())
    many = [dict(cams[i % 3], id=i, img_name=f"cam{i:02}") for i in range(12)]
    (tmp_path / "cams.json").write_text(json.dumps(many))
    out = _convert(SAMPLE, tmp_path / "many.splatv", "--cameras", tmp_path / "cams.json")
    r = run("verify", SAMPLE, out, *TINY, "--json")
    data = json.loads(r.stdout)
    assert [f["camera"] for f in data["frames"]] == list(range(8))
    assert data["notes"] == ["drew the first 8 of 12 cameras (--cameras all draws every one)"]
    assert r.stderr == "note: drew the first 8 of 12 cameras (--cameras all draws every one)\n"
    data = json.loads(run("verify", SAMPLE, out, *TINY, "--json", "--cameras", "all").stdout)
    assert [f["camera"] for f in data["frames"]] == list(range(12)) and data["notes"] == []


class Recorder:
    """A Progress that records each stage and how far it advanced."""

    def __init__(self):
        self.stages = []

    def stage(self, label, total=None, unit="it"):
        import contextlib

        @contextlib.contextmanager
        def cm():
            done = [label, total, unit, 0]
            self.stages.append(done)

            def advance(n=1):
                done[3] += n

            yield advance

        return cm()


def test_verify_and_diff_report_progress(faithful):
    from splatconv.render.commands import diff_files
    from splatconv.render.verify import verify

    rec = Recorder()
    verify(SAMPLE, faithful, times=[0.2, 0.4, 0.6], cameras="0,1", size=(32, 18), progress=rec)
    assert rec.stages == [["reading", 2, "file", 2], ["checking attributes", 2, "step", 2],
                          ["drawing", 6, "frame", 6]]
    rec = Recorder()
    diff_files(SAMPLE, faithful, size="32x18", progress=rec)
    assert rec.stages == [["reading", 2, "file", 2], ["drawing", 1, "frame", 1]]


def test_report_dir_saves_each_frame_as_it_is_drawn(tmp_path, faithful, monkeypatch):
    # Images are never all kept: each frame's files are written before the next is drawn.
    from splatconv.render import diff as imgdiff
    from splatconv.render.preview import Renderer

    draws, saved_after = [], []
    real_draw, real_save = Renderer.draw, imgdiff.save_png
    monkeypatch.setattr(Renderer, "draw", lambda self, *a, **k: draws.append(1) or real_draw(self, *a, **k))
    monkeypatch.setattr(imgdiff, "save_png", lambda img, stream: saved_after.append(len(draws)) or real_save(img, stream))
    r = run("verify", SAMPLE, faithful, "--cameras", "0", "--times", "0.1,0.5,0.9", "--size", "32x18",
            "--report-dir", tmp_path / "rep")
    assert r.exit_code == 0, r.output
    assert saved_after == [2] * 4 + [4] * 4 + [6] * 4


def test_attribute_check_in_row_blocks_gives_the_whole_scenes_figures(faithful, monkeypatch):
    # compare_scenes works a block of rows at a time (bounded memory on 1M splats);
    # the merged figures are those of one pass over every row.
    from splatconv import compare, io
    from splatconv.formats import splatv

    source, converted = io.read(SAMPLE), io.read(faithful)
    order = compare.align(source, converted, storage=splatv.STORAGE)
    whole = compare.compare_scenes(source, converted, order, splatv.STORAGE)
    monkeypatch.setattr(compare, "_ROWS", 1000)
    blocks = compare.compare_scenes(source, converted, order, splatv.STORAGE)
    for g, e in whole.items():
        b = blocks[g]
        assert (b.max_abs_error, b.max_rel_error, b.unexplained, b.compared, b.values) == (
            e.max_abs_error, e.max_rel_error, e.unexplained, e.compared, e.values)
        assert b.rmse == pytest.approx(e.rmse, rel=1e-9)


def test_nonfinite_values_that_splatvjs_changes_are_called_so(tmp_path):
    # splaTV's converter writes NaN as infinity: the verdict says so instead of an error of 0.
    from .conftest import random_columns

    cols = random_columns(3000, seed=11)
    cols["omega_0"][:50] = np.nan
    cols["motion_0"][:20] = np.float32(40000.0)
    src = _scene_file(tmp_path, "s.ply", cols)
    out = _convert(src, tmp_path / "js.splatv", "--compat", "splatv-js")
    data = json.loads(run("verify", src, out, *TINY, "--json").stdout)
    omega, motion = data["attributes"]["omega"], data["attributes"]["motion"]
    assert (omega["unexplained"], omega["nonfinite_changed"], omega["became_infinite"]) == (50, 50, 0)
    assert (motion["unexplained"], motion["nonfinite_changed"], motion["became_infinite"]) == (20, 0, 20)
    verdict = run("verify", src, out, *TINY).stdout.split("\n\n")[-1].splitlines()
    assert verdict[:2] == [
        "FAIL: motion drifted: 20 of 27,000 values became infinite (finite in the source)",
        "FAIL: omega drifted: 50 of 12,000 values that were NaN or infinite in the source were stored as "
        "something else"]


@pytest.mark.parametrize("cameras,message", [
    ("3", "--cameras: no camera 3; there are 3 (0..2)"),
    ("0,-1", "--cameras: no camera -1; there are 3 (0..2)"),
    ("first", "--cameras: expected 'all' or comma-separated indices, got 'first'"),
])
def test_cameras_that_do_not_exist_are_usage_errors(faithful, cameras, message):
    r = run("verify", SAMPLE, faithful, "--cameras", cameras)
    assert error_line(r, 2).startswith(f"Error: {message}") and r.stdout == ""


def test_one_camera_is_one_camera(tmp_path):
    from .conftest import random_columns

    src = _scene_file(tmp_path, "s.ply", random_columns(50))  # no cameras: one framing camera
    r = run("diff", src, src, "--cameras", "1")
    assert error_line(r, 2).startswith("Error: --cameras: no camera 1; there is 1 (0)")


def test_malformed_options_are_refused_before_any_file_is_read(tmp_path, monkeypatch):
    # A 1M-splat verify spends seconds reading and checking: option typos fail first.
    from splatconv.render import frames

    monkeypatch.setattr(frames, "read_texture", lambda path: pytest.fail("read before the options were checked"))
    for args in (["--cameras", "x"], ["--times", "a"], ["--size", "3"], ["--min-psnr", "nan"]):
        r = run("verify", tmp_path / "a.ply", tmp_path / "b.splatv", *args)
        assert r.exit_code == 2, (args, r.output)
        r = run("diff", tmp_path / "a.ply", tmp_path / "b.splatv", *args)
        assert r.exit_code == 2, (args, r.output)


def test_diff_of_scenes_says_which_frame_its_heatmap_shows(tmp_path, faithful):
    heat = tmp_path / "heat.png"
    r = run("diff", SAMPLE, faithful, "--times", "0.2,0.7", "--size", "48x27", "--out", heat, "--json")
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    worst = data["worst"]
    assert r.stderr == (f"note: wrote {heat}: difference heatmap (t={worst['time']:g}, camera {worst['camera']}, "
                        f"the worst frame), 48x27, {heat.stat().st_size:,} bytes\n")
