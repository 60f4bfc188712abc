"""Frame sequences -> 4D: fits proven by rendering (float reference path) against the source scene."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, viewer
from splatconv.cli import main
from splatconv.errors import UsageError
from splatconv.model import MOTION, OMEGA, STATIC_TRBF_CENTER, STATIC_TRBF_SCALE, Scene
from splatconv.ops import sequence
from splatconv.render.diff import compare
from splatconv.render.frames import render_scene
from splatconv.jobs.frames import frame_paths, natural_key

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data/dancers.ply"
CAMERAS = json.loads((ROOT / "sample_data/cameras.json").read_text())


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def snapshot(cols: dict, t: float) -> Scene:
    """What the viewer shows of a 4D scene at ``t`` as a static frame (unnormalised rotation kept)."""
    out = dict(cols)
    p = viewer.position_at(cols, t)
    q = viewer.rotation_at(cols, t, normalize=False)
    a = viewer.opacity(cols) * viewer.temporal_opacity(cols, t)
    for i, name in enumerate("xyz"):
        out[name] = p[:, i].astype(np.float32)
    for i in range(4):
        out[f"rot_{i}"] = q[:, i].astype(np.float32)
    with np.errstate(divide="ignore"):
        out["opacity"] = viewer.logit(a).astype(np.float32)
    n = len(a)
    for name in MOTION + OMEGA:
        out[name] = np.zeros(n, np.float32)
    out["trbf_center"] = np.full(n, STATIC_TRBF_CENTER, np.float32)
    out["trbf_scale"] = np.full(n, STATIC_TRBF_SCALE, np.float32)
    return Scene(columns=out)


def draw(scenes, times, size=(320, 240)):
    """Float-reference frames of each scene at each time from camera 0: an array per scene."""
    return [render_scene(s, CAMERAS[0], times, size=size) for s in scenes]


def write_frames(directory: Path, scenes, stem="frame_") -> list:
    directory.mkdir(exist_ok=True)
    paths = []
    for k, s in enumerate(scenes):
        p = directory / f"{stem}{k}.ply"
        io.write(s, p)
        paths.append(p)
    return paths


def test_natural_order_directories_globs_and_lists(tmp_path):
    names = ["f_10.ply", "f_2.ply", "f_1.ply", "notes.txt"]
    for n in names:
        (tmp_path / n).write_bytes(b"")
    by_dir = [Path(p).name for p in frame_paths([tmp_path])]
    assert by_dir == ["f_1.ply", "f_2.ply", "f_10.ply"]
    assert [Path(p).name for p in frame_paths([str(tmp_path / "f_*.ply")])] == by_dir
    assert [Path(p).name for p in frame_paths([tmp_path / "f_10.ply", tmp_path / "f_2.ply"])] == ["f_2.ply", "f_10.ply"]
    assert sorted(["a12", "a3", "a100"], key=natural_key) == ["a3", "a12", "a100"]


def test_sampled_4d_scene_fits_back_and_renders_the_same_at_and_between_frames(tmp_path):
    source = io.read(SAMPLE)
    times = np.linspace(0, 1, 16)
    paths = write_frames(tmp_path / "frames", [snapshot(source.columns, t) for t in times])
    out = tmp_path / "clip.ply"
    r = run("convert", str(tmp_path / "frames" / "frame_*.ply"), out)
    assert r.exit_code == 0, r.output
    assert "the same 5,000 splats in each: motion fitted" in r.stdout
    fitted = io.read(out)
    assert fitted.count == source.count and len(paths) == 16
    check = [0.0, times[5], 0.5 * (times[5] + times[6]), 0.37, times[11], 0.5 * (times[14] + times[15]), 1.0]
    a, b = draw([source, fitted], check)
    for t, ia, ib in zip(check, a, b):
        psnr = compare(ia, ib).psnr
        assert psnr >= 40, (t, psnr)
        assert ia[..., :3].max() > 0  # something is drawn


def test_fit_is_exact_for_a_lite_scene_with_unit_or_flipped_quaternions():
    rng = np.random.default_rng(4)
    cols = {k: np.asarray(v) for k, v in io.read(SAMPLE).columns.items()}
    times = np.linspace(0, 1, 9)

    def frame(k):
        s = snapshot(cols, times[k])
        c = dict(s.columns)
        q = viewer.rotation_at(cols, times[k])  # unit, with random signs
        sign = rng.choice([-1.0, 1.0], size=len(q))[:, None]
        for i in range(4):
            c[f"rot_{i}"] = (q[:, i] * sign[:, 0]).astype(np.float32)
        return Scene(columns=c)

    scene, report = sequence.fit_sequence(frame, len(times))
    assert report.same_splats and report.split_splats == 0
    assert report.position_error["max"] < 1e-5
    assert report.rotation_error_deg["max"] < 0.01
    assert report.opacity_error["p99"] < 1e-3
    for t in (0.1, 0.45, 0.93):  # between frames too
        assert np.abs(viewer.position_at(scene.columns, t) - viewer.position_at(cols, t)).max() < 1e-4
    # Where the scene has no motion or turn, the fit leaves none: not round-off near 1e-13 or the
    # frames' float32 rounding near 5e-8, which a .splatv writer reported as thousands of lost values.
    for group in (MOTION, OMEGA):
        still = np.all([cols[name] == 0 for name in group], axis=0)
        assert still.any() and all((scene.columns[name][still] == 0).all() for name in group), group


def test_different_splats_per_frame_show_each_frame_exactly_at_its_time(tmp_path):
    source = io.read(SAMPLE)
    rng = np.random.default_rng(2)
    times = [0.0, 0.3, 0.45, 1.0]  # uneven: the cut follows the nearer neighbour
    frames = []
    for t in times:
        keep = np.sort(rng.choice(source.count, size=int(rng.integers(2000, 4000)), replace=False))
        frames.append(snapshot({k: np.asarray(v)[keep] for k, v in source.columns.items()}, t))
    write_frames(tmp_path / "f", frames)
    out = tmp_path / "flip.ply"
    r = run("convert", tmp_path / "f", out, "--frame-times", ",".join(map(str, times)))
    assert r.exit_code == 0, r.output
    assert "different splats per frame" in r.stdout
    flip = io.read(out)
    assert flip.count == sum(f.count for f in frames)
    images = draw([flip, *frames], times)
    for k, t in enumerate(times):
        assert compare(images[0][k], images[k + 1][k]).psnr >= 60, t
    # Before the neighbouring frame's time each frame is already cut (the 0.02 cutoff).
    c = flip.columns
    for k, t in enumerate(times):
        rows = np.isclose(c["trbf_center"], t)
        for other in times:
            if other != t:
                assert not viewer.visible({n: v[rows] for n, v in c.items()}, other).any()


def test_motion_one_cubic_cannot_follow_is_split_into_pieces_that_composite_to_the_opacity():
    n = 200
    times = np.linspace(0, 1, 40)
    base = {k: np.asarray(v)[:n] for k, v in io.read(SAMPLE).columns.items()}
    alpha = 0.9

    def frame(k):
        s = snapshot(base, times[k])
        c = dict(s.columns)
        ang = 2 * np.pi * 1.25 * times[k] + np.arange(n)
        c["x"], c["y"] = (2 * np.cos(ang)).astype(np.float32), (2 * np.sin(ang)).astype(np.float32)
        c["opacity"] = np.full(n, viewer.logit(alpha), np.float32)
        return Scene(columns=c)

    scene, report = sequence.fit_sequence(frame, len(times), max_error=0.01)
    assert report.split_splats == n
    assert report.pieces_added == scene.count - n > 0
    assert report.position_error["max"] <= 0.01
    # The pieces of one splat: composited, their opacity stays near the splat's at and between frames.
    c = scene.columns
    ang0 = 2 * np.pi * 1.25 * times + 0
    mine = np.isclose(c["f_dc_0"], base["f_dc_0"][0]) & np.isclose(c["f_dc_1"], base["f_dc_1"][0])
    part = {k: v[mine] for k, v in c.items()}
    for t in np.linspace(0, 1, 81):
        a = viewer.opacity(part) * viewer.temporal_opacity(part, t)
        assert abs(1 - np.prod(1 - a) - alpha) < 0.05, t
    at = [viewer.position_at(part, t)[np.argmax(viewer.temporal_opacity(part, t))] for t in times]
    err = np.hypot(np.array(at)[:, 0] - 2 * np.cos(ang0), np.array(at)[:, 1] - 2 * np.sin(ang0))
    assert err.max() <= 0.01


@pytest.mark.parametrize("args, message", [
    (["--frame-times", "0,1"], "Error: --frame-times gives 2 times for 3 frames\n"),
    (["--frame-times", "0,0.5,0.5"], "Error: --frame-times must increase strictly\n"),
    (["--same-splats", "yes"], "Error: --same-splats yes, but the frames hold different counts (10 to 12 splats)\n"),
    # The viewer plays [0, 1]; far outside it the fit overflowed into NaN with numpy warnings.
    (["--frame-times", "0,1e300,2e300"], "Error: --frame-times: 1e+300 is not in the viewer's time range [0, 1]\n"),
    (["--frame-times", "-0.5,0,1"], "Error: --frame-times: -0.5 is not in the viewer's time range [0, 1]\n"),
    # A .splatv stores temporal centres as halves: two frames there would share one time.
    (["--frame-times", "0,1e-300,1"], "Error: --frame-times: 0.0 and 1e-300 are one time once stored as float16, "
                                      "the output's precision for times\n"),
    (["--frame-times", "0,0.5,0.5001"], "Error: --frame-times: 0.5 and 0.5001 are one time once stored as float16, "
                                        "the output's precision for times\n"),
])
def test_sequence_usage_errors(tmp_path, args, message):
    cols = io.read(SAMPLE).columns
    write_frames(tmp_path / "f", [snapshot({k: np.asarray(v)[:n] for k, v in cols.items()}, 0.5) for n in (10, 12, 11)])
    out = tmp_path / "o.splatv"
    r = run("convert", tmp_path / "f", out, *args)
    assert (r.exit_code, r.stderr) == (2, message)
    assert not out.exists()


def test_frame_times_stay_apart_as_the_output_stores_them(tmp_path):
    """Times apart in float32 but one half float: a PLY (float32 centres) keeps them apart, a .splatv refuses."""
    cols = io.read(SAMPLE).columns
    write_frames(tmp_path / "f", [snapshot({k: np.asarray(v)[:n] for k, v in cols.items()}, 0.5) for n in (10, 12, 11)])
    r = run("convert", tmp_path / "f", tmp_path / "o.ply", "--frame-times", "0,0.5,0.5001")
    assert r.exit_code == 0, r.output
    centres = sorted(set(np.asarray(io.read(tmp_path / "o.ply").columns["trbf_center"]).tolist()))
    assert centres == pytest.approx([0.0, 0.5, 0.5001], abs=1e-7)
    # The default times k / (N - 1) too: beyond 2,049 frames neighbours near t = 1 are one half float.
    with pytest.raises(UsageError, match=r"2,100 frames at k / \(N - 1\): .* are one time once stored as float16"):
        sequence.check_times(None, 2100, np.float16)
    assert len(sequence.check_times(None, 2100, np.float32)) == 2100
    assert len(sequence.check_times(None, 2049, np.float16)) == 2049


def test_sequence_options_need_a_sequence_and_missing_frames_are_clear(tmp_path, lite_ply):
    r = run("convert", lite_ply, tmp_path / "o.splatv", "--max-error", "0.1")
    assert (r.exit_code, r.stderr) == (2, "Error: --frame-times, --same-splats and --max-error apply to frame "
                                          "sequences only\n")
    r = run("convert", str(tmp_path / "none_*.ply"), tmp_path / "o.splatv")
    assert (r.exit_code, r.stderr) == (2, f"Error: {tmp_path / 'none_*.ply'}: no files match\n")
    assert not (tmp_path / "o.splatv").exists()


def test_frame_windows_cut_before_neighbours():
    t = np.array([0.0, 0.1, 0.5, 0.55, 1.0])
    s = np.exp(sequence.frame_windows(t))
    gaps = np.minimum(np.r_[np.inf, np.diff(t)], np.r_[np.diff(t), np.inf])
    assert (gaps > viewer.VISIBLE_RADIUS * s).all()
    assert math.isclose(sequence.frame_windows(np.array([0.3]))[0], float(STATIC_TRBF_SCALE))


def test_scales_and_colours_average_the_finite_frames_and_one_frame_reads_as_one(tmp_path):
    cols = {k: np.asarray(v)[:6] for k, v in io.read(SAMPLE).columns.items()}
    frames = []
    for k, t in enumerate((0.0, 0.5, 1.0)):
        c = {n: np.array(v) for n, v in snapshot(cols, t).columns.items()}
        c["scale_0"][0] = np.inf          # infinite in every frame: stays infinite (it was a scale of 1)
        c["f_dc_0"][1] = np.nan           # NaN in every frame: stays NaN (it was 0)
        if k == 1:
            c["f_dc_1"][2] = np.nan       # NaN in one frame: the mean of the other two (it was 2/3 of it)
            c["scale_1"][3] = -np.inf
        frames.append(Scene(columns=c))
    scene, _ = sequence.fit_sequence(lambda k: frames[k], 3)
    out = scene.columns
    assert out["scale_0"][0] == np.inf and np.isnan(out["f_dc_0"][1])
    assert out["f_dc_1"][2] == pytest.approx(float(frames[0].columns["f_dc_1"][2]))
    assert out["scale_1"][3] == pytest.approx(float(frames[0].columns["scale_1"][3]))
    write_frames(tmp_path / "one", frames[:1])
    r = run("convert", tmp_path / "one", tmp_path / "one.ply")
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith("1 frame (t 0.5), the same 6 splats in each: motion fitted\n")


def test_frames_whose_rows_are_not_one_splat_suggest_same_splats_no():
    cols = {k: np.asarray(v)[:400] for k, v in io.read(SAMPLE).columns.items()}
    rng = np.random.default_rng(3)
    frames = []
    for t in np.linspace(0, 1, 5):
        c = snapshot(cols, t).columns
        order = rng.permutation(400)  # as a .splat writer's importance order reshuffles rows
        frames.append(Scene(columns={k: np.asarray(v)[order] for k, v in c.items()}))
    _, report = sequence.fit_sequence(lambda k: frames[k], 5)
    assert any(n.endswith("change colour by more than 0.1 between frames: if row i is not the same splat in every "
                          "frame (.splat files, for one, are sorted by importance), use --same-splats no")
               for n in report.notes), report.notes
    _, report = sequence.fit_sequence(lambda k: Scene(columns=snapshot(cols, k / 4).columns), 5)
    assert not any("--same-splats no" in n for n in report.notes)


def test_each_format_counts_splats_from_its_header_as_read_would(tmp_path, gs_ply):
    scene = io.read(SAMPLE)
    small = Scene(columns={k: np.asarray(v)[:1500] for k, v in scene.columns.items()})
    paths = [tmp_path / "a.ply", tmp_path / "a.splatv", tmp_path / "a.splat", gs_ply]
    io.write(small, paths[0])
    io.write(small, paths[1])
    io.write(snapshot(small.columns, 0.5), paths[2])
    ascii_ply = tmp_path / "ascii.ply"
    text = b"ply\nformat ascii 1.0\nelement vertex 2\n" + b"".join(
        b"property float %s\n" % n.encode() for n in ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                                                      "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2",
                                                      "rot_3")) + b"end_header\n" + b"0 " * 13 + b"1\n" + b"1 " * 14 + b"\n"
    ascii_ply.write_bytes(text)
    for p in paths + [ascii_ply]:
        assert io.splat_count(p) == io.read(p).count, p
    # Where only reading can tell, the answer is None, never a wrong count.
    truncated = tmp_path / "cut.ply"
    truncated.write_bytes(paths[0].read_bytes()[:-10])
    odd = tmp_path / "odd.splat"
    odd.write_bytes(paths[2].read_bytes()[:-3])
    padded = tmp_path / "padded.splatv"
    raw = bytearray(paths[1].read_bytes())
    raw[-64:] = b"\x01" * 64  # data in the padding after the header's count: read counts up to it
    padded.write_bytes(bytes(raw))
    compressed = tmp_path / "a.ply.zst"
    io.write(small, compressed)
    empty = tmp_path / "empty.splat"
    empty.write_bytes(b"")
    for p in (truncated, odd, padded, compressed, empty):
        assert io.splat_count(p) is None, p
    assert io.read(padded).count > small.count


def test_convert_reads_each_frame_once_when_the_counts_come_from_headers(tmp_path, monkeypatch):
    from splatconv.jobs import frames as frame_jobs
    source = io.read(SAMPLE)
    frames = [snapshot({name: np.asarray(v)[: 1000 + 10 * k] for name, v in source.columns.items()}, k / 3)
              for k in range(4)]
    write_frames(tmp_path / "f", frames)
    reads = []
    real = frame_jobs.read
    monkeypatch.setattr(frame_jobs, "read", lambda path, **kw: reads.append(path) or real(path, **kw))
    frame_jobs.convert_frames([tmp_path / "f"], tmp_path / "out.splatv")
    assert len(reads) == len(frames)
