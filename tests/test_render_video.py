"""``splatconv render`` to a video (.mp4 H.264, .webm VP9) and its camera paths (--orbit, --path)."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv.cli import main
from splatconv.render import paths
from splatconv.render.diff import compare
from splatconv.render.frames import cameras_of, load, render_frames, resolve_view

from .cli_checks import error_line

av = pytest.importorskip("av")  # the [test] extra installs it; without it only the error test below applies

SIZE = (320, 240)


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def decoded(path) -> list:
    """Every frame of a video as (H, W, 3) uint8 RGB."""
    with av.open(str(path)) as container:
        return [frame.to_ndarray(format="rgb24") for frame in container.decode(video=0)]


@pytest.fixture(scope="module")
def source(sample_splatv):
    return load(sample_splatv)


def drawn(source, cameras: list, times: list, size=SIZE) -> list:
    """What ``render`` draws of each camera at each time: the framebuffer's RGB over black."""
    views = [resolve_view([c], size=size) for c in cameras]
    return [f[..., :3].copy() for f in render_frames(source.texture(), views, times)]


def psnr(a, b) -> float:
    return compare(a, b).psnr


@pytest.mark.parametrize("suffix,codec", [(".mp4", "h264"), (".webm", "vp9")])
def test_a_video_decodes_to_the_frames_render_draws(tmp_path, sample_splatv, source, suffix, codec):
    out = tmp_path / f"clip{suffix}"
    r = run("render", sample_splatv, out, "--frames", 24, "--size", "320x240")
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith(f"wrote {out}: 320x240 ") and r.stdout.endswith(", 24 frames over t=0..1 at 24 fps\n")
    with av.open(str(out)) as container:
        stream = container.streams.video[0]
        assert (stream.codec_context.name, stream.average_rate) == (codec, 24)
    frames = decoded(out)
    assert len(frames) == 24 and all(f.shape == (240, 320, 3) for f in frames)
    camera = cameras_of(source)[0]
    wanted = drawn(source, [camera] * 24, paths.shares(24))  # frame k at t = k / 23
    assert wanted[0].mean() > 5  # the scene is in view
    assert min(psnr(w, f) for w, f in zip(wanted, frames)) >= 30
    assert psnr(wanted[0], frames[-1]) < 30  # and it moves: the last frame is not the first


def test_orbit_turns_the_camera_about_the_scenes_centre(tmp_path, sample_splatv, source):
    out = tmp_path / "orbit.mp4"
    assert run("render", sample_splatv, out, "--frames", 5, "--size", "320x240", "--orbit", 90).exit_code == 0
    frames = decoded(out)
    camera = cameras_of(source)[0]
    turned = paths.orbited(camera, paths.scene_centre(source.scene), 90)
    first, last, unturned = drawn(source, [camera, turned, camera], [0.0, 1.0, 1.0])
    assert psnr(first, frames[0]) >= 30
    assert psnr(last, frames[-1]) >= 30
    assert psnr(unturned, frames[-1]) < 20


def test_a_whole_turn_comes_back_to_the_camera(tmp_path, sample_splatv, source):
    """360 degrees: the first and last frames are the camera's own; halfway it looks back from the far side."""
    out = tmp_path / "round.mp4"
    assert run("render", sample_splatv, out, "--frames", 3, "--size", "320x240", "--orbit", 360,
               "--camera", 1).exit_code == 0
    frames = decoded(out)
    camera = cameras_of(source)[1]
    wanted = drawn(source, [camera] * 3, [0.0, 0.5, 1.0])
    assert psnr(wanted[0], frames[0]) >= 30 and psnr(wanted[2], frames[2]) >= 30
    assert psnr(wanted[1], frames[1]) < 20


def test_path_moves_from_camera_a_to_camera_b(tmp_path, sample_splatv, source):
    out = tmp_path / "path.mp4"
    assert run("render", sample_splatv, out, "--frames", 5, "--size", "320x240", "--path", "0,2").exit_code == 0
    frames = decoded(out)
    a, b = cameras_of(source)[0], cameras_of(source)[2]
    at_a, at_b, a_end, b_start = drawn(source, [a, b, a, b], [0.0, 1.0, 1.0, 0.0])
    assert psnr(at_a, frames[0]) >= 30 and psnr(at_b, frames[-1]) >= 30
    assert psnr(b_start, frames[0]) < 25 and psnr(a_end, frames[-1]) < 25  # the ends are the cameras'
    assert not any(psnr(frames[2], f) >= 30 for f in (at_a, at_b))


def test_between_slerps_rotation_and_moves_in_a_line():
    def about_z(degrees):
        a = np.radians(degrees)
        return [[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]]

    a = dict(rotation=about_z(0), position=[0, 0, 0], width=64, height=48, fx=50, fy=50)
    b = dict(rotation=about_z(120), position=[3, 0, -6], width=128, height=96, fx=200, fy=200)
    for share, degrees in ((0.25, 30), (0.5, 60), (0.75, 90)):
        c = paths.between(a, b, share)
        assert np.allclose(c["rotation"], about_z(degrees), atol=1e-9)
        assert np.allclose(c["position"], [3 * share, 0, -6 * share])
        assert (c["width"], c["height"]) == (64, 48)
        assert c["fx"] == pytest.approx(50 + share * (100 - 50))  # b's 200 in a's frame (half b's size): 100
    assert paths.between(a, b, 1)["rotation"] == b["rotation"]


def test_an_odd_camera_size_is_rounded_down_to_even(tmp_path, sample_splatv):
    import json

    import splatconv

    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    cams = json.loads((root / "sample_data/cameras.json").read_text())
    for c in cams:
        c.update(width=161, height=91, fx=c["fx"] / 8, fy=c["fy"] / 8)
    (tmp_path / "cams.json").write_text(json.dumps(cams))
    odd = tmp_path / "odd.splatv"
    splatconv.convert(root / "sample_data/dancers.ply", odd, cameras=tmp_path / "cams.json")
    r = run("render", odd, tmp_path / "o.mp4", "--frames", 2)
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith(f"wrote {tmp_path / 'o.mp4'}: 160x90 (the camera's 161x91 rounded down to even")
    assert {f.shape for f in decoded(tmp_path / "o.mp4")} == {(90, 160, 3)}


def test_gif_takes_fps_and_a_camera_path(tmp_path, sample_splatv):
    from PIL import Image

    out = tmp_path / "o.gif"
    r = run("render", sample_splatv, out, "--frames", 3, "--size", "64x36", "--fps", 5, "--orbit", 30)
    assert r.exit_code == 0, r.output
    with Image.open(out) as image:
        assert (image.n_frames, image.info["duration"]) == (3, 200)


@pytest.mark.parametrize("args,code,start", [
    (["o.mp4", "--frames", 4, "--size", "321x240"], 2, "Error: --size: 321x240: a .mp4 video needs an even"),
    (["o.webm", "--frames", 4, "--size", "320x239"], 2, "Error: --size: 320x239: a .webm video needs an even"),
    (["o.mp4", "--frames", 4, "--path", "0"], 2, "Error: --path: expected two camera indices A,B, got '0'"),
    (["o.mp4", "--frames", 4, "--path", "0,7"], 2, "Error: {src}: --path 0,7: the file has 3 cameras, 0..2"),
    (["o.mp4", "--frames", 4, "--path", "0,1", "--camera", 1], 2, "Error: --path A,B names its cameras"),
    (["o.mp4", "--frames", 4, "--orbit", 10, "--path", "0,1"], 2, "Error: --orbit and --path cannot be used"),
    (["o.mp4", "--frames", 4, "--camera", 7], 2, "Error: {src}: --camera 7: the file has 3 cameras"),
    (["o.mp4", "--frames", 4, "--orbit", 10, "--camera", 7], 2, "Error: {src}: --camera 7: the file has 3"),
    (["o.png", "--orbit", 10], 2, "Error: --orbit moves the camera over a sweep: give --frames N"),
    (["o.png", "--fps", 10], 2, "Error: o.png: --fps sets the rate of an animation or a video"),
    (["o.mp4", "--frames", 4, "--fps", 500], 2, "Error: --fps: expected 1 to 240, got 500"),
    (["o.mp4"], 2, "Error: o.mp4: cannot write .mp4: use .png (or --frames N with .gif, .webp, .mp4, .webm)"),
])
def test_bad_video_options_are_one_error_line_and_no_file(tmp_path, sample_splatv, monkeypatch, args, code, start):
    monkeypatch.chdir(tmp_path)
    r = run("render", sample_splatv, *args)
    assert error_line(r, code).startswith(start.format(src=sample_splatv))
    assert r.stdout == ""
    assert list(tmp_path.iterdir()) == []


def test_without_pyav_a_video_is_one_error_line(tmp_path, sample_splatv, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "av", None)  # import av raises ImportError
    r = run("render", sample_splatv, tmp_path / "o.mp4", "--frames", 4)
    assert error_line(r, 1).startswith("Error: writing video needs PyAV")
    assert "pip install 'splatconv[video]'" in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_video_leaves_no_file(tmp_path, sample_splatv, monkeypatch):
    from splatconv.render import preview
    from splatconv.render.commands import render_file

    draw, calls = preview.Renderer.draw, []

    def interrupted(self, *a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return draw(self, *a, **k)

    monkeypatch.setattr(preview.Renderer, "draw", interrupted)
    with pytest.raises(KeyboardInterrupt):
        render_file(sample_splatv, tmp_path / "o.mp4", frames=6, size="64x36")
    assert list(tmp_path.iterdir()) == []


def test_frames_are_encoded_as_they_come_none_kept(tmp_path):
    """write_video takes each frame when it is drawn and keeps none: at most one is alive at a time."""
    import weakref

    from splatconv.render.video import write_video

    alive = []

    def frames():
        for k in range(8):
            frame = np.full((16, 32, 4), 20 * k, np.uint8)
            alive.append(weakref.ref(frame))
            yield frame
            del frame
            assert sum(ref() is not None for ref in alive) <= 1  # the one just taken, if the loop still names it

    with open(tmp_path / "o.mp4", "wb") as stream:
        assert write_video(frames(), stream, ".mp4") == 8
    assert len(decoded(tmp_path / "o.mp4")) == 8
