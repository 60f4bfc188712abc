"""`.sog` (PlayCanvas SOG v2): written and read within its quantization, a hand-made file read from the spec,
SH bands kept, hostile archives refused with one error line, a moving scene refused with the bake hint."""

from __future__ import annotations

import json
import math
import re
import zipfile
from io import BytesIO
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, model
from splatconv.cli import main
from splatconv.formats import sog
from splatconv.model import Scene

from .cli_checks import error_line
from .conftest import GS_PROPS, write_ply
from .scenes import gs_columns

SPEC = (Path(__file__).resolve().parent.parent / "specs" / "sog.md").read_text(encoding="utf-8")
SH_C0 = 0.28209479177387814


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _unlog(n):
    return np.sign(n) * (np.exp(np.abs(n)) - 1)


def _meta(path) -> dict:
    with zipfile.ZipFile(path) as z:
        return json.loads(z.read("meta.json"))


def _nearest_error(values, codebook):
    """How far each value is from the nearest codebook entry: what a faithful write stores."""
    c = np.asarray(codebook, np.float64)
    return np.abs(np.asarray(values, np.float64)[..., None] - c).min(axis=-1)


def _sh_scene(n: int, degree: int, seed: int = 1) -> Scene:
    names = GS_PROPS[:GS_PROPS.index("f_rest_0")] + model.sh_names(degree) + GS_PROPS[GS_PROPS.index("opacity"):]
    cols = gs_columns(n, names, seed=seed)
    columns = {name: np.asarray(cols[name], np.float32) for name in model.POSITION + model.OPACITY + model.SCALE
               + model.ROTATION + model.sh_names(degree)}
    for name in model.COLOR:  # the model keeps RGB; a 3DGS PLY the coefficient
        columns[name] = (0.5 + SH_C0 * np.asarray(cols[name], np.float64)).astype(np.float32)
    columns.update(model.static_columns(n))
    return Scene(columns=columns, variant=model.VARIANT_3DGS)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A 500-splat SH-3 scene written to .sog once: (source scene in the file's order, path, report)."""
    scene = _sh_scene(500, 3)
    path = tmp_path_factory.mktemp("sog") / "gs.sog"
    report = io.write(scene, path)
    order = sog.morton_order(np.stack([scene.columns[c] for c in model.POSITION], axis=1))
    stored = Scene(columns=scene.take(order), variant=scene.variant)
    return stored, path, report


def test_round_trip_is_within_the_stated_quantization(written):
    src, path, report = written
    back = io.read(path)
    meta = _meta(path)
    assert back.count == src.count == meta["count"] == 500 and back.sh_degree == 3
    s, b = src.columns, back.columns
    # positions: half a 16-bit step of log(|v| + 1), per axis
    mins, maxs = np.array(meta["means"]["mins"]), np.array(meta["means"]["maxs"])
    for i, name in enumerate(model.POSITION):
        n_src = np.sign(s[name]) * np.log1p(np.abs(s[name].astype(np.float64)))
        n_back = np.sign(b[name]) * np.log1p(np.abs(b[name].astype(np.float64)))
        assert np.abs(n_back - n_src).max() <= 0.5 * (maxs[i] - mins[i]) / 65535 + 1e-6, name
    # scales and colours: each value is its nearest codebook entry
    for group, book, to_stored in (
            (model.SCALE, meta["scales"]["codebook"], lambda v: v),
            (model.COLOR, meta["sh0"]["codebook"], lambda v: (v - 0.5) / SH_C0)):
        for name in group:
            err = np.abs(to_stored(b[name].astype(np.float64)) - to_stored(s[name].astype(np.float64)))
            assert np.allclose(err, _nearest_error(to_stored(s[name].astype(np.float64)), book), atol=2e-5), name
    alpha_err = np.abs(1 / (1 + np.exp(-b["opacity"].astype(np.float64))) - 1 / (1 + np.exp(-s["opacity"])))
    assert alpha_err.max() <= 0.5 / 255 + 1e-6
    q_src = np.stack([s[n] for n in model.ROTATION], axis=1).astype(np.float64)
    q_src /= np.linalg.norm(q_src, axis=1, keepdims=True)
    q_back = np.stack([b[n] for n in model.ROTATION], axis=1)
    q_src *= np.sign((q_src * q_back).sum(axis=1))[:, None]
    assert np.abs(q_back - q_src).max() <= 0.01  # three at half of sqrt(2)/255, the largest derived
    # SH: 500 splats, each its own palette entry: only the codebook's error
    assert meta["shN"]["count"] == 500 and meta["shN"]["bands"] == 3
    sh_err = max(np.abs(b[n] - s[n]).max() for n in model.sh_names(3))
    assert sh_err == pytest.approx(max(_nearest_error(s[n], meta["shN"]["codebook"]).max()
                                       for n in model.sh_names(3)), abs=1e-6)
    # the report states the largest errors it made
    note = report.notes[0]
    stated = [float(x) for x in re.findall(r"largest error ([\d.e+-]+)", note)]
    scale_err = max(np.abs(b[n] - s[n]).max() for n in model.SCALE)
    assert note.startswith("quantized to .sog") and stated[1] == pytest.approx(scale_err, rel=1e-2)
    assert f"largest coefficient error {sh_err:.3g}" in report.notes[1]


def test_two_writes_give_the_same_bytes(written, tmp_path):
    src, path, _ = written
    again = tmp_path / "again.sog"
    io.write(_sh_scene(500, 3), again)
    assert again.read_bytes() == path.read_bytes()


@pytest.mark.parametrize("degree", [1, 2])
def test_sh_bands_of_each_degree_are_kept(tmp_path, degree):
    scene = _sh_scene(300, degree, seed=degree)
    path = tmp_path / "d.sog"
    io.write(scene, path)
    back, meta = io.read(path), _meta(path)
    assert back.sh_degree == degree and meta["shN"]["bands"] == degree
    with zipfile.ZipFile(path) as z:
        from PIL import Image
        width = Image.open(BytesIO(z.read(meta["shN"]["files"][0]))).size[0]
    assert width == 64 * model.SH_COEFFS[degree]
    order = sog.morton_order(np.stack([scene.columns[c] for c in model.POSITION], axis=1))
    for name in model.sh_names(degree):
        src = np.asarray(scene.columns[name])[order]
        assert np.allclose(np.abs(back.columns[name] - src), _nearest_error(src, meta["shN"]["codebook"]), atol=1e-6)


def test_a_large_scene_shares_a_palette_of_its_size():
    rng = np.random.default_rng(0)
    vectors = rng.normal(0, 0.2, (5000, 9)).astype(np.float32)
    palette, labels = sog.fit_palette(vectors, sog.palette_size(5000))
    assert sog.palette_size(5000) == 4096 and len(palette) <= 4096 and labels.max() < len(palette)
    # nearer than a random entry: the tree's leaves fit their splats
    err = np.linalg.norm(palette[labels] - vectors, axis=1).mean()
    assert err < 0.5 * np.linalg.norm(vectors - vectors[::-1], axis=1).mean()


# --------------------------------------------------------------------------
# A file made from the spec alone (Pillow and zipfile, not the writer)


def _webp(pixels) -> bytes:
    from PIL import Image

    out = BytesIO()
    Image.fromarray(np.asarray(pixels, np.uint8), "RGBA").save(out, "WEBP", lossless=True, exact=True)
    return out.getvalue()


def _hand_files(meta_change=None, images_change=None) -> bytes:
    """A two-splat, SH degree 1 .sog written from specs/sog.md, as zip bytes."""
    px = lambda rows: np.array(rows, np.uint8).reshape(1, len(rows), 4)  # noqa: E731  (W x 1 image)
    images = {
        "means_l.webp": px([[0x00, 0xFF, 0x00, 255], [0xFF, 0x00, 0x00, 255]]),
        "means_u.webp": px([[0x00, 0xFF, 0x00, 255], [0xFF, 0x00, 0x00, 255]]),  # q = 0 / 65535
        "quats.webp": px([[255, 128, 128, 255], [0, 255, 128, 252]]),
        "scales.webp": px([[0, 255, 128, 255], [10, 20, 30, 255]]),
        "sh0.webp": px([[0, 255, 128, 255], [64, 64, 64, 0]]),
        "shN_centroids.webp": np.array([[[i, 255 - i, 7, 255] for i in range(64 * 3)]], np.uint8),
        "shN_labels.webp": px([[1, 0, 0, 255], [0, 0, 0, 255]]),
    }
    meta = {"version": 2, "count": 2,
            "means": {"mins": [-math.log(2), -1.0, 0.0], "maxs": [math.log(4), 1.0, 2.0],
                      "files": ["means_l.webp", "means_u.webp"]},
            "scales": {"codebook": list(np.linspace(-10, 2, 256)), "files": ["scales.webp"]},
            "quats": {"files": ["quats.webp"]},
            "sh0": {"codebook": list(np.linspace(-2, 2, 256)), "files": ["sh0.webp"]},
            "shN": {"count": 2, "bands": 1, "codebook": list(np.linspace(-1, 1, 256)),
                    "files": ["shN_centroids.webp", "shN_labels.webp"]}}
    if meta_change:
        meta_change(meta)
    if images_change:
        images_change(images)
    out = BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("meta.json", meta if isinstance(meta, str) else json.dumps(meta))
        for name, pixels in images.items():
            z.writestr(name, pixels if isinstance(pixels, bytes) else _webp(pixels))
    return out.getvalue()


def test_reads_a_hand_made_file(tmp_path):
    path = tmp_path / "hand.sog"
    path.write_bytes(_hand_files())
    c = io.read(path).columns
    assert np.allclose(c["x"], [-1.0, 3.0]) and np.allclose(c["y"], [math.e - 1, -(math.e - 1)])
    assert np.allclose(c["z"], [0.0, 0.0])
    # splat 0: mode 255 (rot_3 largest), rot_0..2 from bytes 255, 128, 128
    small = (128 / 255 * 2 - 1) / math.sqrt(2)
    q0 = [1 / math.sqrt(2), small, small, math.sqrt(0.5 - 2 * small * small)]
    assert np.allclose([c[n][0] for n in model.ROTATION], q0, atol=1e-6)
    # splat 1: mode 252 (rot_0 largest), rot_1..3 from 0, 255, 128
    q1 = [0.0, -1 / math.sqrt(2), 1 / math.sqrt(2), small]
    q1[0] = math.sqrt(max(0.0, 1 - sum(v * v for v in q1)))
    assert np.allclose([c[n][1] for n in model.ROTATION], q1, atol=1e-6)
    book = np.linspace(-10, 2, 256)
    assert np.allclose([c[n][0] for n in model.SCALE], book[[0, 255, 128]], atol=1e-6)
    colors = 0.5 + SH_C0 * np.linspace(-2, 2, 256)[[0, 255, 128]]
    assert np.allclose([c[n][0] for n in model.COLOR], colors, atol=1e-6)
    assert c["opacity"][0] > 13 and c["opacity"][1] < -13  # 255 and 0, clamped off 0 and 1
    # SH: splat 0 labels entry 1 (pixels 3..5), splat 1 entry 0; R red, G green, B blue
    sh = np.linspace(-1, 1, 256)
    assert [c[f"f_rest_{j}"][0] for j in range(3)] == pytest.approx(list(sh[[3, 4, 5]]), abs=1e-6)
    assert [c[f"f_rest_{3 + j}"][1] for j in range(3)] == pytest.approx(list(sh[[255, 254, 253]]), abs=1e-6)
    assert c["f_rest_8"][1] == pytest.approx(sh[7], abs=1e-6)


def _set(path_keys, value):
    def change(meta):
        node = meta
        for key in path_keys[:-1]:
            node = node[key]
        node[path_keys[-1]] = value
    return change


HOSTILE = {
    "not a zip": b"PK not really a zip archive at all",
    "empty": b"",
    "no meta.json": (lambda: _zip_with("meta.json", None)),
    "missing image": (lambda: _zip_with("quats.webp", None)),
    "image of wrong size": (lambda: _hand_files(images_change=lambda im: im.update(
        {"scales.webp": np.zeros((1, 1, 4), np.uint8)}))),
    "count past the images": (lambda: _hand_files(_set(["count"], 1000))),
    "bad json": (lambda: _zip_with("meta.json", b'{"version": 2, "count": ')),
    "nan in mins": (lambda: _hand_files(_set(["means", "mins"], [float("nan"), 0.0, 0.0]))),
    "short codebook": (lambda: _hand_files(_set(["scales", "codebook"], [0.0] * 10))),
    "version 1": (lambda: _hand_files(lambda m: m.pop("version"))),
    "quaternion mode": (lambda: _hand_files(images_change=lambda im: im.update(
        {"quats.webp": np.full((1, 2, 4), 7, np.uint8)}))),
    "label past the palette": (lambda: _hand_files(_set(["shN", "count"], 1))),
    "centroids of wrong width": (lambda: _hand_files(_set(["shN", "bands"], 2))),
    "not an image": (lambda: _hand_files(images_change=lambda im: im.update({"sh0.webp": b"RIFF....WEBPjunk"}))),
}


def _zip_with(name: str, data: bytes | None) -> bytes:
    """The hand-made file with entry ``name`` replaced by ``data`` (left out when None)."""
    with zipfile.ZipFile(BytesIO(_hand_files())) as z:
        kept = {n: z.read(n) for n in z.namelist() if n != name}
    if data is not None:
        kept[name] = data
    out = BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for n, data in kept.items():
            z.writestr(n, data)
    return out.getvalue()


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_files_give_one_error_line_and_no_output(tmp_path, case):
    data = HOSTILE[case]
    path = tmp_path / "bad.sog"
    path.write_bytes(data if isinstance(data, bytes) else data())
    before = path.read_bytes()
    assert error_line(run("info", path), 1).startswith(f"Error: {path}")
    out = tmp_path / "out.ply"
    assert error_line(run("convert", path, out), 1).startswith("Error: ")
    assert not out.exists() and path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.sog"]


def test_moving_scene_is_refused_with_the_bake_hint(tmp_path, lite_ply):
    out = tmp_path / "x.sog"
    line = error_line(run("convert", lite_ply, out), 1)
    assert line.startswith("Error: ") and "bake" in line and not out.exists()


def test_bake_convert_info_render_take_sog(tmp_path, lite_ply, gs_ply):
    baked = tmp_path / "b.sog"
    r = run("bake", lite_ply, baked, "--time", "0.5")
    assert r.exit_code == 0, r.output
    assert io.read(baked).count > 0
    out = tmp_path / "g.sog"
    assert run("convert", gs_ply, out).exit_code == 0
    r = run("info", out, "--json")
    assert r.exit_code == 0 and '"format": "sog"' in r.output and '"sh_degree": 3' in r.output
    png = tmp_path / "f.png"
    r = run("render", out, png, "--size", "32x24")
    assert r.exit_code == 0, r.output
    assert png.stat().st_size > 0


#: Worst PSNR (dB) a static scene's pictures keep through a .sog round trip (measured: 52.1 dB, dancers at t = 0.5).
ROUND_TRIP_PSNR = 45.0


def test_pictures_survive_a_round_trip(tmp_path):
    sample = Path(__file__).resolve().parent.parent / "sample_data" / "dancers.ply"
    static = tmp_path / "static.ply"
    assert run("bake", sample, static, "--time", "0.5").exit_code == 0
    out = tmp_path / "s.sog"
    assert run("convert", static, out).exit_code == 0
    r = run("verify", static, out, "--times", "0.5", "--size", "96x64", "--json")
    frames = json.loads(r.stdout)["frames"]
    assert frames and min(f["psnr"] for f in frames) >= ROUND_TRIP_PSNR, frames


def test_spec_states_the_codes_constants():
    for text, value in (("`CODEBOOK_SIZE`", sog.CODEBOOK_SIZE == 256), ("65,536 (`MAX_PALETTE`)",
                        sog.MAX_PALETTE == 65536), ("2 · `count` + 65,536 (`SPARE_PIXELS`)",
                        sog.SPARE_PIXELS == 65536), ("252 + the index of the largest (`QUAT_MODE`)",
                        sog.QUAT_MODE == 252), ("1,024 bins (`HISTOGRAM_BINS`", sog.HISTOGRAM_BINS == 1024),
                        ("count^0.5 (`BIN_WEIGHT_POWER`)", sog.BIN_WEIGHT_POWER == 0.5),
                        ("`BRANCH` = 64", sog.BRANCH == 64), ("6 Lloyd iterations", sog.KMEANS_ITERATIONS == 6),
                        ("8 points a centre", sog.FIT_POINTS_PER_CENTRE == 8), ("at most 16 MiB",
                        sog.MAX_META_BYTES == 16 << 20)):
        assert text in SPEC and value, text
    # W = ceil(sqrt(N) / 4) * 4, H = ceil(N / W / 4) * 4; palette sizes
    assert sog.texture_size(38267) == (196, 196) and sog.texture_size(2) == (4, 4)
    assert [sog.palette_size(n) for n in (500, 1024, 2047, 5000, 10 ** 6)] == [500, 1024, 1024, 4096, 65536]
