"""``splatconv render``: outputs, options and errors."""

from __future__ import annotations

import errno
import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from splatconv.cli import main

from .conftest import lite_columns_with_normals, random_columns, write_ply
from .cli_checks import error_line

SAMPLE = "sample_data/dancers.ply"


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_single_frame_png(tmp_path, sample_splatv):
    out = tmp_path / "f.png"
    r = run("render", sample_splatv, out, "--time", "0.5", "--size", "160x90", "--fx", "125", "--fy", "125")
    assert r.exit_code == 0, r.output
    assert r.stdout == f"wrote {out}: 160x90, t=0.5\n"
    img = np.asarray(Image.open(out))
    assert img.shape == (90, 160, 3)
    assert img.mean() > 5  # the scene is in view


def test_default_size_is_the_cameras_scaled_to_1280(tmp_path, sample_splatv):
    r = run("render", sample_splatv, tmp_path / "d.png")
    assert r.exit_code == 0, r.output
    assert Image.open(tmp_path / "d.png").size == (1280, 720)


def test_ply_renders_like_its_conversion(tmp_path, sample_splatv):
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    args = ["--size", "128x72", "--fx", "100", "--fy", "100", "--time", "0.3", "--camera", "1"]
    cams = root / "sample_data/cameras.json"
    ply_with_cams = tmp_path / "c.ply"
    assert run("convert", sample_splatv, ply_with_cams).exit_code == 0
    assert run("render", ply_with_cams, tmp_path / "a.png", *args).exit_code == 0
    assert run("render", sample_splatv, tmp_path / "b.png", *args).exit_code == 0
    assert np.array_equal(np.asarray(Image.open(tmp_path / "a.png")), np.asarray(Image.open(tmp_path / "b.png")))
    assert cams.exists()


def test_view_matrix_option_matches_camera(tmp_path, sample_splatv):
    from splatconv.formats import splatv
    from splatconv.render import camera as cam

    _, chunk, _, _ = splatv.read_records(sample_splatv)
    view = json.dumps(cam.view_matrix(chunk["cameras"][2]))
    common = ["--size", "96x54", "--fx", "80", "--fy", "80"]
    assert run("render", sample_splatv, tmp_path / "v.png", "--view", view, *common).exit_code == 0
    assert run("render", sample_splatv, tmp_path / "c.png", "--camera", "2", *common).exit_code == 0
    assert np.array_equal(np.asarray(Image.open(tmp_path / "v.png")), np.asarray(Image.open(tmp_path / "c.png")))


@pytest.mark.parametrize("name,frames,check", [
    ("a.gif", 4, lambda im: im.n_frames == 4),
    ("a.webp", 3, lambda im: im.n_frames == 3),
    ("sheet.png", 4, lambda im: im.size == (2 * 64, 2 * 36)),
])
def test_time_sweeps(tmp_path, sample_splatv, name, frames, check):
    out = tmp_path / name
    r = run("render", sample_splatv, out, "--frames", frames, "--size", "64x36", "--fx", "50", "--fy", "50")
    assert r.exit_code == 0, r.output
    assert check(Image.open(out))


@pytest.mark.parametrize("args,code,message", [
    (["o.jpg"], 2, "Error: o.jpg: cannot write .jpg: use .png (or --frames N with .gif, .webp, .mp4, .webm)\n"),
    (["o.gif"], 2, "Error: o.gif: cannot write .gif: use .png (or --frames N with .gif, .webp, .mp4, .webm)\n"),
    (["o.png", "--camera", "7"], 2, "Error: {src}: --camera 7: the file has 3 cameras, 0..2\n"),
    (["o.png", "--camera", "0", "--view", "[]"], 2, "Error: --camera and --view cannot be used together\n"),
    (["o.png", "--view", "[1, 2]"], 2,
     "Error: --view: expected a JSON list of 16 finite numbers (a column-major view matrix)\n"),
    (["o.png", "--view", "{"], 2, "Error: --view: invalid JSON: Expecting property name enclosed in double quotes\n"),
    (["o.png", "--size", "12by4"], 2, "Error: --size: expected WIDTHxHEIGHT, got '12by4'\n"),
    (["o.png", "--size", "0x10"], 2, "Error: --size: 0x10 is outside 1..16384\n"),
])
def test_render_usage_errors(tmp_path, sample_splatv, monkeypatch, args, code, message):
    monkeypatch.chdir(tmp_path)
    r = run("render", sample_splatv, *args)
    assert r.exit_code == code
    assert r.stderr == message.format(src=sample_splatv)
    assert not (tmp_path / args[0]).exists()


@pytest.mark.parametrize("option,value,why", [
    ("--time", "nan", "is not a finite number"),
    ("--time", "inf", "is not a finite number"),
    ("--time", "-inf", "is not a finite number"),
    ("--fx", "nan", "is not a finite number"),
    ("--fx", "inf", "is not a finite number"),
    ("--fx", "-3", "is not a positive number"),
    ("--fy", "0", "is not a positive number"),
    ("--fy", "-inf", "is not a finite number"),
])
def test_non_finite_or_non_positive_numbers_are_usage_errors(tmp_path, sample_splatv, option, value, why):
    r = run("render", sample_splatv, tmp_path / "o.png", option, value)
    assert error_line(r, 2).startswith(f"Error: Invalid value for '{option}': '{value}' {why}")
    assert r.stdout == ""
    assert not (tmp_path / "o.png").exists()


def test_library_refuses_non_finite_time_and_focal_length(tmp_path, sample_splatv):
    from splatconv.errors import UsageError
    from splatconv.render.commands import render_file

    with pytest.raises(UsageError, match="--time: expected a finite number, got nan"):
        render_file(sample_splatv, tmp_path / "o.png", time=float("nan"))
    with pytest.raises(UsageError, match="--fx must be a positive number"):
        render_file(sample_splatv, tmp_path / "o.png", fx=float("inf"))
    for frames in (0, 1001):  # the CLI's range is the library's (MAX_FRAMES)
        with pytest.raises(UsageError, match=f"--frames: expected 1 to 1000, got {frames}"):
            render_file(sample_splatv, tmp_path / "o.gif", frames=frames)
    assert not (tmp_path / "o.png").exists()


def test_explicit_size_keeps_the_cameras_focal_length_as_the_viewer_does(tmp_path, sample_splatv):
    # Camera 0 is 1280x720 with fx = fy = 1000. An explicit --size is a viewer window of
    # that size: fx = fy = 1000, the camera's. Without --size the preview is the camera's
    # image scaled to fit 1280 wide, focal lengths scaled along.
    assert run("render", sample_splatv, tmp_path / "s.png", "--size", "640x360").exit_code == 0
    assert run("render", sample_splatv, tmp_path / "c.png", "--size", "640x360", "--fx", "1000", "--fy", "1000",
               ).exit_code == 0
    assert np.array_equal(np.asarray(Image.open(tmp_path / "s.png")), np.asarray(Image.open(tmp_path / "c.png")))
    assert run("render", sample_splatv, tmp_path / "f.png", "--size", "640x360", "--fx", "500", "--fy", "500",
               ).exit_code == 0
    assert not np.array_equal(np.asarray(Image.open(tmp_path / "s.png")), np.asarray(Image.open(tmp_path / "f.png")))


@pytest.mark.parametrize("size,expected", [
    (None, (640, 360, 500.0, 500.0)),
    ((640, 360), (640, 360, 500.0, 500.0)),
    ((2560, 1440), (2560, 1440, 2000.0, 2000.0)),
    ((640, 640), (640, 640, 500.0, 500.0)),  # another aspect: the whole width still in view
    ((1280, 360), (1280, 360, 500.0, 500.0)),
])
def test_fit_scales_focal_lengths_with_the_size(size, expected):
    from splatconv.render import camera as cam
    from splatconv.render.frames import frame_views

    c = {"width": 1280, "height": 720, "fx": 1000.0, "fy": 1000.0, "position": [0, 0, 0],
         "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}
    assert cam.fit(c, size, max_width=640) == expected
    (_, v), = frame_views([c], [0], size, max_width=640)
    assert (v.width, v.height, v.fx, v.fy) == expected  # verify and diff draw this way


@pytest.mark.parametrize("code,message", [(errno.EFBIG, "File too large"), (errno.ENOSPC, "No space left on device")])
def test_os_error_while_writing_names_the_output_and_leaves_nothing(tmp_path, sample_splatv, monkeypatch,
                                                                    code, message):
    from .test_cli import fail_writes_after

    fail_writes_after(monkeypatch, 100, code, message)
    monkeypatch.chdir(tmp_path)
    before = sorted(tmp_path.iterdir())
    r = run("render", sample_splatv, "o.png", "--size", "64x36", "--fx", "50", "--fy", "50")
    assert error_line(r, 1).startswith(f"Error: o.png: {message}")
    assert r.stdout == ""
    assert sorted(tmp_path.iterdir()) == before


def test_refuses_existing_output(tmp_path, sample_splatv):
    out = tmp_path / "o.png"
    out.write_bytes(b"x")
    r = run("render", sample_splatv, out)
    assert error_line(r, 1).startswith(f"Error: {out}: already exists")
    assert out.read_bytes() == b"x"


def test_no_opengl_gives_one_line_with_what_to_install(tmp_path, sample_splatv, monkeypatch):
    import moderngl

    def fail(**kw):
        raise Exception("libEGL.so.1: cannot open shared object file")

    monkeypatch.setattr(moderngl, "create_context", fail)
    r = run("render", sample_splatv, tmp_path / "o.png", "--size", "8x8")
    assert r.exit_code == 1
    assert r.stderr == ("Error: no OpenGL context (libEGL.so.1: cannot open shared object file); install an "
                        "EGL driver: on Debian or Ubuntu the packages libegl1 and libgl1-mesa-dri (Mesa's "
                        "llvmpipe renders on the CPU, no GPU or display needed)\n")
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("name,size,message", [
    ("sheet.png", (192, 108), "192x108 contact sheet of 4 frames (96x54 each) over t=0..1"),
    ("clip.gif", (96, 54), "96x54, 4 frames over t=0..1"),
    ("one.png", (96, 54), "96x54, t=0.5"),
])
def test_render_prints_the_size_it_writes(tmp_path, sample_splatv, name, size, message):
    frames = "1" if name == "one.png" else "4"
    r = run("render", sample_splatv, tmp_path / name, "--frames", frames, "--size", "96x54")
    assert r.exit_code == 0, r.output
    assert r.stdout == f"wrote {tmp_path / name}: {message}\n"
    assert Image.open(tmp_path / name).size == size


def test_render_scene_is_what_render_draws(tmp_path):
    # The public entry for drawing an in-memory Scene (the ops' pixel tests use it):
    # the float reference path by default, the .splatv packing with reference=False.
    from splatconv import io
    from splatconv.model import Scene
    from splatconv.render.frames import render_scene

    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    cams = json.loads((root / "sample_data/cameras.json").read_text())
    sample = root / SAMPLE
    scene = io.read(sample)
    frames = render_scene(scene, cams[1], [0.3, 0.7], size=(96, 54))
    assert frames.shape == (2, 54, 96, 4) and frames.dtype == np.uint8
    from splatconv.render import camera as cam

    view = json.dumps(cam.view_matrix(cams[1]))
    args = ["--view", view, "--size", "96x54", "--fx", "78.75", "--fy", "78.75", "--time"]  # 1050 * 96 / 1280
    for i, t in enumerate((0.3, 0.7)):
        for reference, drawn in ((True, frames[i]), (False, render_scene(scene, cams[1], t, reference=False,
                                                                             size=(96, 54))[0])):
            out = tmp_path / f"{t}{reference}.png"
            r = run("render", sample, out, *args, t, *(["--reference"] if reference else []))
            assert r.exit_code == 0, r.output
            assert np.array_equal(np.asarray(Image.open(out)), drawn[..., :3])
    assert frames[0, ..., 3].any() and not np.array_equal(frames[0], frames[1])
    empty = Scene(columns={k: v[:0] for k, v in scene.columns.items()})
    assert not render_scene(empty, cams[0], 0.5, size=(16, 9)).any()


def test_a_contact_sheet_too_large_to_write_is_refused_before_drawing(tmp_path, sample_splatv):
    r = run("render", sample_splatv, tmp_path / "s.png", "--frames", "200")
    assert r.exit_code == 2 and r.stdout == ""
    assert r.stderr == (f"Error: {tmp_path / 's.png'}: --frames 200 of 1280x720 make a 19200x10080 contact sheet, "
                        "over 16,384 pixels a side: use fewer frames, a smaller --size, or .gif / .webp\n")
    assert not (tmp_path / "s.png").exists()


@pytest.mark.parametrize("command", ["render", "diff", "verify"])
def test_an_empty_scene_file_is_bad_input_not_usage(tmp_path, command):
    """A PLY that holds no splats: one Error line, exit 1 (the file is at fault, not the command)."""
    cols = {k: v[:0] for k, v in random_columns(1).items()}
    empty = write_ply(tmp_path / "empty.ply", lite_columns_with_normals(cols))
    args = {"render": [empty, tmp_path / "o.png"], "diff": [empty, empty], "verify": [empty, empty]}[command]
    r = run(command, *args)
    assert (r.exit_code, r.stdout) == (1, "")
    assert r.stderr.startswith("Error: ") and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "o.png").exists()


# --------------------------------------------------------------------------
# --fit: the camera's whole view at any --size


@pytest.fixture(scope="module")
def small_camera_scene(tmp_path_factory):
    """The sample with its cameras at 320x180 (fx, fy a quarter of 1280x720's: the same view), quick to draw."""
    from pathlib import Path

    import splatconv

    root = Path(__file__).resolve().parent.parent
    folder = tmp_path_factory.mktemp("fit")
    cameras = json.loads((root / "sample_data/cameras.json").read_text())
    for c in cameras:
        c.update(width=320, height=180, fx=c["fx"] / 4, fy=c["fy"] / 4)
    (folder / "cameras.json").write_text(json.dumps(cameras))
    splatconv.convert(root / SAMPLE, folder / "small.splatv", cameras=folder / "cameras.json")
    return folder / "small.splatv"


def _frames(path) -> list:
    """Every frame of an image file as (H, W, 3) float64 (a contact sheet: the whole sheet)."""
    from PIL import ImageSequence

    return [np.asarray(f.convert("RGB"), dtype=np.float64) for f in ImageSequence.Iterator(Image.open(path))]


def _halved(img: np.ndarray) -> np.ndarray:
    """An image at half its width and height: each output pixel the mean of a 2x2 block."""
    h, w = img.shape[0] // 2, img.shape[1] // 2
    return img[:2 * h, :2 * w].reshape(h, 2, w, 2, -1).mean(axis=(1, 3))


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(255.0**2 / max(np.mean((a - b) ** 2), 1e-12)))


#: A contact sheet's time labels (drawn at a fixed size, top left of each 160x90 tile) are left out of the comparison.
def _unlabelled(img: np.ndarray, tile: tuple) -> np.ndarray:
    out = img.copy()
    out.reshape(-1, tile[1], out.shape[1] // tile[0], tile[0], 3)[:, :16, :, :80] = 0
    return out


@pytest.mark.parametrize("name, frames", [("f.png", 1), ("sheet.png", 4), ("clip.webp", 3)])
def test_fit_shows_the_cameras_whole_view_at_another_size(tmp_path, small_camera_scene, name, frames):
    """At half the camera's size, --fit draws the full-size frame halved; without it, the frame's centre."""
    full, fit, crop = (tmp_path / f"{kind}-{name}" for kind in ("full", "fit", "crop"))
    sweep = ["--frames", frames] if frames > 1 else ["--time", "0.5"]
    assert run("render", small_camera_scene, full, *sweep).exit_code == 0  # the camera's own 320x180
    r = run("render", small_camera_scene, fit, *sweep, "--size", "160x90", "--fit")
    assert r.exit_code == 0, r.output
    assert run("render", small_camera_scene, crop, *sweep, "--size", "160x90").exit_code == 0
    wanted = [_halved(f) for f in _frames(full)]
    fitted, cropped = _frames(fit), _frames(crop)
    assert len(wanted) == len(fitted) == len(cropped) == (1 if name.endswith(".png") else frames)
    if name == "sheet.png":
        wanted, fitted, cropped = ([_unlabelled(f, (160, 90)) for f in images] for images in (wanted, fitted, cropped))
    assert wanted[0].mean() > 5  # the scene is in view
    for want, got, centre in zip(wanted, fitted, cropped):
        assert got.shape == want.shape
        assert _psnr(want, got) >= 35
        assert _psnr(want, centre) < 20


def test_fit_letterboxes_another_aspect_ratio(tmp_path, small_camera_scene):
    """160x160 from a 16:9 camera: the whole width, the view halved in the middle 90 rows, black bands around."""
    assert run("render", small_camera_scene, tmp_path / "full.png").exit_code == 0
    assert run("render", small_camera_scene, tmp_path / "sq.png", "--size", "160x160", "--fit").exit_code == 0
    square = _frames(tmp_path / "sq.png")[0]
    assert square.shape == (160, 160, 3)
    assert not square[:30].any() and not square[130:].any()
    assert _psnr(_halved(_frames(tmp_path / "full.png")[0]), square[35:125]) >= 35


def test_fit_with_fx_or_fy_is_a_usage_error(tmp_path, small_camera_scene):
    for option in ("--fx", "--fy"):
        r = run("render", small_camera_scene, tmp_path / "o.png", "--size", "160x90", "--fit", option, "100")
        assert r.exit_code == 2 and r.stdout == ""
        assert r.stderr.startswith("Error: --fit scales the camera's fx and fy")
    assert not (tmp_path / "o.png").exists()
