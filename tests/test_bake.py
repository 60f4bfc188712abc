"""Bake a moment: proved by pixels through the float reference renderer.

A baked moment drawn as a static scene must match the 4D scene drawn at that
time, at every time the baked scene is drawn (it is static), through every
output it can be written to.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, model, viewer
from splatconv.cameras import load_cameras
from splatconv.cli import main
from splatconv.formats import base
from splatconv.model import Scene
from splatconv.errors import UsageError
from splatconv.jobs.bake import bake_frames as bake_frames_job
from splatconv.ops.bake import MAX_FRAMES, bake, baked_opacity, frame_times
from splatconv.wording import kinds_text
from splatconv.render import camera as cam
from splatconv.render.diff import compare
from splatconv.render.frames import render_scene
from splatconv.render.preview import View

from .conftest import random_columns

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data" / "dancers.ply"
CAMERAS = ROOT / "sample_data" / "cameras.json"
W, H = 192, 108
#: Times the tests bake at: both ends of the clip and two inside.
TIMES = (0.0, 0.3, 0.77, 1.0)


def sample_view(index: int = 0, width: int = W, height: int = H) -> View:
    """A small view through one of the sample's cameras."""
    c = load_cameras(CAMERAS)[index]
    full_w, _full_h, fx, fy = cam.fit(c)
    s = width / full_w
    return View(cam.view_matrix(c), fx * s, fy * s, width, height)


def draw(scene: Scene, t: float, view: View | None = None) -> np.ndarray:
    """The scene at time ``t`` through the float reference path: ``(H, W, 4) uint8``."""
    return render_scene(scene, view or sample_view(), [t])[0]


def psnr(a, b) -> float:
    return compare(a, b).psnr


@pytest.fixture(scope="module")
def sample():
    return io.read(SAMPLE)


def test_baked_moment_matches_the_4d_scene_at_that_time_at_every_time(sample):
    for t in TIMES:
        want = draw(sample, t)
        assert want[..., 3].mean() > 20  # the view sees the scene
        baked, report = bake(sample, t)
        assert report.count_out == baked.count < sample.count
        for shown in (0.0, 0.5, 1.0):
            assert psnr(want, draw(baked, shown)) >= 50, (t, shown)


def test_baking_differs_between_times(sample):
    """The test above cannot pass with a scene that does not move: the moments differ."""
    a = draw(bake(sample, 0.0)[0], 0.5)
    b = draw(bake(sample, 1.0)[0], 0.5)
    assert psnr(a, b) < 30


@pytest.mark.parametrize("suffix", [".ply", ".splatv", ".splat"])
def test_baked_file_matches_the_4d_scene(sample, tmp_path, suffix):
    """Written and read back: floats (3DGS PLY), halves (.splatv), bytes (.splat); measured 55-61 dB."""
    for t in (0.3, 1.0):
        baked, _ = bake(sample, t)
        out = tmp_path / f"m{t}{suffix}"
        io.write(baked, out)
        back = io.read(out)
        assert back.count == baked.count
        assert not base.time_varying(back.columns).any()
        want = draw(sample, t)
        for shown in (0.0, 1.0):
            assert psnr(want, draw(back, shown)) >= 50, (suffix, t, shown)


def test_baked_ply_is_plain_3dgs(sample, tmp_path):
    import plyfile

    baked, _ = bake(sample, 0.5)
    io.write(baked, tmp_path / "m.ply")
    v = plyfile.PlyData.read(str(tmp_path / "m.ply"))["vertex"]
    assert [p.name for p in v.properties] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
                                              "opacity", "scale_0", "scale_1", "scale_2",
                                              "rot_0", "rot_1", "rot_2", "rot_3"]
    # Colour as the degree-0 SH coefficient, as 3DGS tools read it.
    rgb = 0.5 + 0.28209479177387814 * v.data["f_dc_0"].astype(np.float64)
    assert np.allclose(rgb, baked.columns["f_dc_0"], atol=1e-6)


def test_baked_values(sample):
    """Positions and rotations at t, opacity x temporal opacity, static basis, only what is drawn at t."""
    t = 0.3
    baked, report = bake(sample, t)
    keep = viewer.drawn_at(sample.columns, t)
    hidden = viewer.temporal_opacity(sample.columns, t, cut=False) < viewer.TEMPORAL_CUTOFF
    left_out = {k: report.counts[k] for k in viewer.UNDRAWABLE_KINDS}
    assert left_out == viewer.not_drawn_counts_at(sample.columns, t)
    assert sum(left_out.values()) == sample.count - baked.count == np.count_nonzero(~keep)
    assert 0 < left_out["hidden_in_time"] <= np.count_nonzero(hidden) <= np.count_nonzero(~keep)
    part = sample.take(np.flatnonzero(keep))
    assert np.allclose(viewer.positions(baked.columns), viewer.position_at(part, t), atol=1e-6)
    assert np.allclose(viewer.rotation_at(baked.columns, 0.0), viewer.rotation_at(part, t), atol=1e-6)
    want = viewer.opacity(part) * viewer.temporal_opacity(part, t)
    assert np.allclose(viewer.opacity(baked.columns), want, rtol=1e-6, atol=1e-9)
    for name in model.MOTION + model.OMEGA:
        assert not baked.columns[name].any()
    assert np.array_equal(baked.columns["scale_1"], part["scale_1"])
    assert baked.cameras == sample.cameras and baked.variant == model.VARIANT_3DGS


def test_static_basis_keeps_full_opacity_over_the_clip():
    """The baked scene's temporal opacity at every time in [0, 1] is 1 to within float32 rounding."""
    cols = {"trbf_center": np.array([model.STATIC_TRBF_CENTER]), "trbf_scale": np.array([model.STATIC_TRBF_SCALE])}
    for t in np.linspace(0, 1, 101):
        assert viewer.temporal_opacity(cols, t)[0] > 1 - 1e-6
    # A temporal scale of 1 would not do: at the ends the splat fades by a fifth.
    assert viewer.temporal_opacity({"trbf_center": np.array([0.5]), "trbf_scale": np.array([0.0])}, 0.0)[0] < 0.8


def test_baked_opacity_is_precise_at_the_extremes():
    op = np.array([-40.0, -5.0, 0.0, 5.0, 30.0, 40.0, np.inf, -np.inf, np.nan])
    one = np.ones_like(op)
    assert np.array_equal(baked_opacity(op, one), op, equal_nan=True)
    half = baked_opacity(op, np.full_like(op, 0.5))
    # sigmoid(x) / 2 for a very opaque splat: logit(0.5) = 0, not a rounded 1.
    assert half[5] == pytest.approx(0.0, abs=1e-12) and half[6] == pytest.approx(0.0, abs=1e-12)
    # A faint splat: sigmoid(-40) / 2 has logit close to -40 - log 2, not -inf.
    assert half[0] == pytest.approx(-40 - math.log(2), abs=1e-9)
    assert half[7] == -np.inf and np.isnan(half[8])


def test_nan_and_infinite_values():
    """NaN times, NaN positions: left out and counted; infinities the viewer gives a meaning to: finite stand-ins."""
    cols = random_columns(200, seed=3)
    cols["trbf_center"][:] = 0.4
    cols["opacity"][:] = 3.0
    cols["trbf_center"][:5] = np.nan  # NaN dt: the rotation at t is NaN first
    cols["trbf_scale"][5:8] = np.nan  # NaN temporal opacity: NaN alpha, stored as 0
    cols["trbf_scale"][8:10] = np.inf  # visible at every time
    cols["x"][10:12] = np.nan  # drawn nowhere
    cols["opacity"][12:14] = np.inf
    cols["trbf_scale"][12] = np.inf  # temporal opacity 1: opacity stays infinite, written as 40
    cols["trbf_center"][13] = 0.41  # temporal opacity a little under 1: sigmoid(inf) * that, finite
    cols["scale_2"][14] = -np.inf  # flat: drawn
    cols["f_dc_1"][15] = np.inf
    cols["f_dc_2"][16] = -np.inf
    scene = Scene(columns=cols)
    baked, report = bake(scene, 0.4)
    assert baked.count == 200 - 10
    assert any(n.startswith("left out 10 splats the viewer does not draw at t=0.4 (zero rotation 5, "
                            "NaN position 2, alpha zero 3)") for n in report.notes)
    b = baked.columns
    for name in model.POSITION + model.ROTATION + model.SCALE + model.COLOR + ("opacity",):
        assert np.isfinite(b[name]).all(), name
    assert report.counts["opaque"] == 1 and np.count_nonzero(b["opacity"] == 40.0) == 1
    assert viewer.opacity(b)[b["opacity"] == 40.0][0] == 1.0
    i = int(np.searchsorted(np.flatnonzero(viewer.drawn_at(cols, 0.4)), 13))  # baking keeps the row order
    assert viewer.opacity(b)[i] == pytest.approx(viewer.temporal_opacity(cols, 0.4)[13], rel=1e-6)
    assert report.counts["flat"] == 1 and np.count_nonzero(b["scale_2"] == -120.0) == 1
    assert np.count_nonzero(viewer.scales(b).astype(np.float32) == 0) == 1  # still flat in float32
    assert report.counts["color"] == 2 and b["f_dc_1"].max() == 1.0 and b["f_dc_2"].min() == 0.0


def test_frame_times():
    assert list(frame_times(5)) == [0.0, 0.25, 0.5, 0.75, 1.0]
    with pytest.raises(Exception, match="at least 2 frames"):
        frame_times(1)
    for count in (MAX_FRAMES + 1, 10 ** 20):
        with pytest.raises(UsageError, match=f"--frames {count}: at most 100,000 frames"):
            frame_times(count)
    assert len(frame_times(MAX_FRAMES)) == MAX_FRAMES == 100_000


def test_a_frame_count_past_the_most_is_refused_before_reading(tmp_path):
    """A usage error at once: no frame name made, the input (damaged here) never read, no folder made.
    (10**20, which once built names without end, takes the same path; not run here, so that this test
    cannot exhaust memory on the code before it.)"""
    count = MAX_FRAMES + 1
    bad = tmp_path / "bad.splat"
    bad.write_bytes(b"\0" * 33)
    out = tmp_path / "frames"
    r = run("bake", bad, out, "--frames", count)
    assert r.exit_code == 2
    assert r.stderr.splitlines()[-1].startswith(f"Error: Invalid value for '--frames': {count} is not in the range "
                                                "2<=x<=100000.")
    with pytest.raises(UsageError, match="at most 100,000 frames"):
        bake_frames_job(bad, out, frames=count)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.splat"]


# --------------------------------------------------------------------------
# The command


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_bake_command_writes_a_3dgs_ply(tmp_path, sample_splatv, sample):
    out = tmp_path / "m.ply"
    r = run("bake", sample_splatv, out, "--time", "0.77")
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith(f"wrote {out}: ")
    src = io.read(sample_splatv)
    counts = viewer.not_drawn_counts_at(src.columns, 0.77)
    assert counts["hidden_in_time"] > 0
    kinds = kinds_text(counts)  # the words info uses
    assert (f"note: left out {sum(counts.values()):,} splats the viewer does not draw at t=0.77 ({kinds}): "
            "the viewer draws none of them then, so no pixel is lost\n") in r.stderr
    back = io.read(out)
    assert back.variant == model.VARIANT_3DGS and len(back.cameras) == 3
    assert psnr(draw(src, 0.77), draw(back, 0.0)) >= 50


def test_bake_and_info_name_a_zero_rotation_alike(tmp_path):
    cols = random_columns(40, seed=8)
    cols.update({name: np.array(column) for name, column in model.static_columns(40).items()})
    cols["opacity"][:] = 5.0
    for name in model.ROTATION:
        cols[name][:6] = 0.0  # no direction: never drawn
    src = tmp_path / "z.ply"
    io.write(Scene(columns=cols), src)
    r = run("bake", src, tmp_path / "m.ply", "--time", "0.5")
    assert r.exit_code == 0, r.output
    assert "(zero rotation 6)" in r.stderr and "direction" not in r.stderr
    # info's count of the same splats, under the same name.
    assert "zero rotation 6" in run("info", src).stdout


def test_bake_frames_writes_every_moment(tmp_path, sample_splatv):
    out = tmp_path / "flip"
    r = run("bake", sample_splatv, out, "--frames", "3")
    assert r.exit_code == 0, r.output
    names = sorted(p.name for p in out.iterdir())
    assert names == ["frame_0000.ply", "frame_0001.ply", "frame_0002.ply"]
    src = io.read(sample_splatv)
    for name, t in zip(names, (0.0, 0.5, 1.0)):
        assert psnr(draw(src, t), draw(io.read(out / name), 0.5)) >= 50
    # Again: refused without --force, nothing changed; with --force replaced.
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    r = run("bake", sample_splatv, out, "--frames", "3")
    assert r.exit_code == 1
    assert r.stderr == f"Error: {out / 'frame_0000.ply'}: already exists (use --force to replace it)\n"
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
    assert run("bake", sample_splatv, out, "--frames", "3", "--force").exit_code == 0


def test_bake_frames_all_or_nothing(tmp_path):
    """A frame that cannot be written (no splats for a .splat) leaves no frame and no folder."""
    cols = random_columns(50, seed=5)
    cols["trbf_center"][:] = 0.0
    cols["trbf_scale"][:] = np.log(0.05)  # gone long before t = 1
    src = tmp_path / "early.ply"
    io.write(Scene(columns=cols), src)
    out = tmp_path / "frames"
    r = run("bake", src, out, "--frames", "4", "--frame-suffix", ".splat")
    assert r.exit_code == 1
    assert r.stderr.splitlines()[-1] == (f"Error: {out / 'frame_0001.splat'}: no splats to write; a .splat file "
                                         "cannot hold an empty scene")
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["early.ply"]


@pytest.mark.parametrize("args, code, message", [
    (["--time", "0.5", "--frames", "3"], 2, "give either --time T (one moment) or --frames N (a folder of moments)"),
    ([], 2, "give either --time T (one moment) or --frames N (a folder of moments)"),
    (["--time", "nan"], 2, "Invalid value for '--time': 'nan' is not a finite number. See 'main bake --help'."),
    (["--time", "1.5"], 2, "Invalid value for '--time': '1.5' is not in the viewer's time range [0, 1]."
                           " See 'main bake --help'."),
    (["--frames", "1"], 2, "Invalid value for '--frames': 1 is not in the range 2<=x<=100000. See 'main bake --help'."),
])
def test_bake_usage_errors(tmp_path, sample_splatv, args, code, message):
    r = run("bake", sample_splatv, tmp_path / "m.ply", *args)
    assert r.exit_code == code
    assert r.stderr.splitlines()[-1] == f"Error: {message}"
    assert not (tmp_path / "m.ply").exists()


def test_bake_bad_input_one_error_line(tmp_path):
    bad = tmp_path / "bad.splat"
    bad.write_bytes(b"\0" * 33)
    r = run("bake", bad, tmp_path / "m.ply", "--time", "0.5")
    assert r.exit_code == 1
    assert r.stderr == (f"Error: {bad}: size 33 bytes is not a whole number of 32-byte records: 1 bytes after "
                        "record 1; file truncated?\n")
    assert not (tmp_path / "m.ply").exists()


def test_frames_output_must_be_a_folder(tmp_path, sample_splatv):
    out = tmp_path / "file.ply"
    out.write_bytes(b"x")
    r = run("bake", sample_splatv, out, "--frames", "2")
    assert r.exit_code == 1 and r.stderr == f"Error: {out}: is not a folder\n"
    assert out.read_bytes() == b"x"


def test_write_sequence_leaves_nothing_when_a_scene_fails(tmp_path, sample):
    """An error while making the third of four frames: no frame is left, the folder made for them is gone."""
    def frames():
        for k in range(4):
            if k == 2:
                raise RuntimeError("boom")
            yield bake(sample, k / 3)[0]

    with pytest.raises(RuntimeError, match="boom"):
        io.write_sequence(frames(), tmp_path / "out", [f"f{k}.ply" for k in range(4)])
    assert list(tmp_path.iterdir()) == []
    # Into an existing folder with other files: those stay, no frame is added.
    (tmp_path / "keep").mkdir()
    (tmp_path / "keep" / "other.txt").write_text("x")
    with pytest.raises(RuntimeError, match="boom"):
        io.write_sequence(frames(), tmp_path / "keep", [f"f{k}.ply" for k in range(4)])
    assert [p.name for p in (tmp_path / "keep").iterdir()] == ["other.txt"]


def test_bake_drop_nonfinite(tmp_path):
    """Infinite positions and scales and NaN colours are drawn (or not) by the viewer but break 3DGS tools:
    --drop-nonfinite removes them from what is written, and every value written is then finite."""
    cols = random_columns(100, seed=12)
    cols["trbf_center"][:] = 0.5
    cols["opacity"][:] = 3.0
    cols["x"][:3] = np.inf
    cols["scale_0"][3] = np.inf
    cols["f_dc_0"][4] = np.nan
    cols["motion_0"][5] = np.float32(3e38)
    cols["x"][5] = np.float32(3e38)  # finite, but the position at t overflows float32
    cols["trbf_center"][5] = 0.0
    cols["scale_1"][6] = -np.inf  # flat: finite when written, and kept
    src = tmp_path / "nan.ply"
    io.write(Scene(columns=cols), src)
    kept = tmp_path / "kept.ply"
    assert run("bake", src, kept, "--time", "0.5").exit_code == 0
    assert np.isinf(io.read(kept).columns["x"]).sum() == 4
    clean = tmp_path / "clean.ply"
    r = run("bake", src, clean, "--time", "0.5", "--drop-nonfinite")
    assert r.exit_code == 0, r.output
    assert ("note: drop-nonfinite: removed 6 of 100 splats with a NaN or infinite value (position 4, scale 1, "
            "color 1; a splat may count in several)\n") in r.stderr
    import plyfile

    v = plyfile.PlyData.read(str(clean))["vertex"].data
    assert len(v) == 94
    assert all(np.isfinite(v[name]).all() for name in v.dtype.names)
    assert np.count_nonzero(v["scale_1"] == -120.0) == 1


def test_bake_frames_notes_stale_frames(tmp_path, sample_splatv):
    out = tmp_path / "flip"
    assert run("bake", sample_splatv, out, "--frames", "4").exit_code == 0
    r = run("bake", sample_splatv, out, "--frames", "2", "--force")
    assert r.exit_code == 0
    assert (f"note: {out} also holds 2 other frame files from before (frame_0002.ply, ...): a flipbook player "
            "would show them too\n") in r.stderr
