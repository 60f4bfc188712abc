"""`.spz`: read (versions 2, 3, 4), written (version 4), SH bands kept, refused for a scene that moves."""

from __future__ import annotations

import gzip
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, model, viewer
from splatconv.cli import main
from splatconv.formats import spz

from .cli_checks import error_line

SPEC = (Path(__file__).resolve().parent.parent / "specs" / "spz.md").read_text(encoding="utf-8")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture
def gs_spz(tmp_path, gs_ply):
    out = tmp_path / "gs.spz"
    r = run("convert", gs_ply, out)
    assert r.exit_code == 0, r.output
    return out


def test_ply_with_sh3_to_spz_keeps_three_bands_within_quantization(gs_ply, gs_spz):
    src, back = io.read(gs_ply), io.read(gs_spz)
    assert back.count == src.count and back.sh_degree == 3 and back.meta["version"] == 4
    for name in model.POSITION:  # 1/4096 steps: half a step at most
        assert np.abs(back.columns[name] - src.columns[name]).max() <= 0.5 / 4096 + 1e-6
    for j in range(15):
        bucket = 8 if j < 3 else 16  # degree 1 to 5 bits, the rest to 4
        for c in range(3):
            name = f"f_rest_{c * 15 + j}"
            inside = np.abs(src.columns[name]) < 0.9  # not clamped at the byte range
            err = np.abs(back.columns[name] - src.columns[name])[inside]
            assert err.max() <= (bucket / 2 + 0.5) / 128 + 1e-6, name


def _v3_file(version: int = 3) -> tuple:
    """A two-splat .spz built by hand from the spec (specs/spz.md), and the values it holds."""
    header = struct.pack("<IIIBBBB", 0x5053474E, version, 2, 1, 10, 0, 0)
    fixed = [(1024, -2048, 5), (-1, 0, 512)]  # at 10 fractional bits: 1, -2, 5/1024; -1/1024, 0, 0.5
    pos = b"".join(int(v & 0xFFFFFF).to_bytes(3, "little") for p in fixed for v in p)
    alphas = bytes([255, 0])
    colors = bytes([128, 0, 255, 64, 64, 64])
    scales = bytes([160, 0, 255, 96, 96, 96])  # log scales 0, -10, 5.9375; -4 x 3
    if version == 2:
        rot = bytes([128, 128, 128, 255, 128, 128])  # ~identity; x ~ 1
    else:
        # splat 0: w largest (index 3), x = y = z = 0; splat 1: y largest (index 1), x = -sqrt(1/2) * 511/511
        w0 = 3 << 30
        w1 = (1 << 30) | (((1 << 9) | 511) << 20)
        rot = struct.pack("<II", w0, w1)
    sh = bytes([128, 160, 96, 0, 255, 128, 128, 128, 128] + [128] * 9)
    return gzip.compress(header + pos + alphas + colors + scales + rot + sh), fixed


@pytest.mark.parametrize("version", [2, 3])
def test_reads_a_hand_made_legacy_file(tmp_path, version):
    data, fixed = _v3_file(version)
    path = tmp_path / "hand.spz"
    path.write_bytes(data)
    scene = io.read(path)
    assert scene.count == 2 and scene.sh_degree == 1 and scene.meta["fractional_bits"] == 10
    assert np.allclose(scene.columns["x"], [1.0, -1 / 1024]) and np.allclose(scene.columns["y"], [-2.0, 0.0])
    assert np.allclose(scene.columns["scale_0"], [0.0, -4.0]) and np.allclose(scene.columns["scale_2"], [5.9375, -4])
    assert scene.columns["opacity"][0] > 13 and scene.columns["opacity"][1] < -13
    dc = (np.array([128, 0, 255]) / 255 - 0.5) / 0.15
    assert np.allclose([scene.columns[n][0] for n in model.COLOR], 0.5 + 0.28209479177387814 * dc, atol=1e-6)
    # SH: coefficient-major, channel-minor in the file; channel-major f_rest_{c*3+k} in the model
    assert scene.columns["f_rest_0"][0] == 0.0 and scene.columns["f_rest_3"][0] == 0.25
    assert scene.columns["f_rest_6"][0] == -0.25 and scene.columns["f_rest_1"][0] == -1.0
    assert scene.columns["f_rest_4"][0] == 127 / 128
    if version == 3:
        assert np.allclose([scene.columns[n][0] for n in model.ROTATION], [1, 0, 0, 0])
        q1 = [scene.columns[n][1] for n in model.ROTATION]  # w, x, y, z
        assert np.allclose(q1, [0, -np.sqrt(0.5), np.sqrt(0.5), 0], atol=1e-6)


def test_written_header_and_streams_are_as_the_spec_says(gs_spz):
    raw = gs_spz.read_bytes()
    magic, version, n, degree, bits, flags, streams, toc = struct.unpack_from("<IIIBBBBI", raw)
    assert (magic, version, n, degree, bits, flags, streams, toc) == (0x5053474E, 4, 500, 3, 12, 0, 6, 32)
    assert raw[20:32] == bytes(12)
    plain = [struct.unpack_from("<QQ", raw, 32 + 16 * i)[1] for i in range(streams)]
    assert plain == [9 * n, n, 3 * n, 3 * n, 4 * n, 45 * n]
    for row, value in (("0..3", "0x5053474e"), ("13", "fractional bits")):
        assert re.search(rf"^\| {re.escape(row)} \| .*{value}", SPEC, re.M)
    assert f"| 4 | 32-byte plain header" in SPEC and spz.VERSION == 4 and spz.ZSTD_LEVEL == 12
    assert "sh * 128 + 128" in SPEC and spz.SH1_BITS == 5 and spz.SH_REST_BITS == 4


def test_no_axis_flip_on_a_round_trip(tmp_path, gs_ply, gs_spz):
    back = tmp_path / "back.ply"
    assert run("convert", gs_spz, back).exit_code == 0
    src, again = io.read(gs_ply), io.read(back)
    assert np.corrcoef(src.columns["y"], again.columns["y"])[0, 1] > 0.999
    assert again.sh_degree == 3


def test_info_stats_verify_take_spz(gs_ply, gs_spz):
    r = run("info", gs_spz, "--json")
    assert r.exit_code == 0 and '"sh_degree": 3' in r.output and '"format": "spz"' in r.output
    assert run("stats", gs_spz).exit_code == 0
    r = run("verify", gs_ply, gs_spz)
    assert r.exit_code in (0, 1), r.output  # a verdict, not a failure to read


def test_render_takes_spz(tmp_path, gs_spz):
    out = tmp_path / "f.png"
    r = run("render", gs_spz, out, "--size", "32x24")
    assert r.exit_code == 0, r.output
    assert out.stat().st_size > 0


def test_moving_scene_to_spz_is_refused_with_the_bake_hint(tmp_path, lite_ply):
    out = tmp_path / "x.spz"
    r = run("convert", lite_ply, out)
    assert error_line(r, 1).startswith("Error: ")
    assert "bake" in error_line(r, 1) and not out.exists()


@pytest.mark.parametrize("data, start", [
    (b"", "Error: "),
    (gzip.compress(b"XXXX" + bytes(12)), "Error: "),
    (gzip.compress(struct.pack("<IIIBBBB", 0x5053474E, 3, 10, 0, 12, 0, 0) + bytes(20)), "Error: "),
    (struct.pack("<IIIBBBBI12x", 0x5053474E, 4, 10, 0, 12, 0, 5, 32) + bytes(8), "Error: "),
    (gzip.compress(struct.pack("<IIIBBBB", 0x5053474E, 9, 1, 0, 12, 0, 0)), "Error: "),
])
def test_bad_files_give_one_error_line(tmp_path, data, start):
    path = tmp_path / "bad.spz"
    path.write_bytes(data)
    r = run("info", path)
    assert error_line(r, 1).startswith(start)


def test_sh_bytes_match_the_float64_reference():
    from .reference import spz_sh_bytes

    rng = np.random.default_rng(3)
    ties = (np.arange(-140, 140) + 0.5) / 128.0  # halfway between bytes: rounded to even either way
    special = [0.0, -0.0, np.nan, np.inf, -np.inf, 1.0, -1.0, 127 / 128, -128 / 128, 0.999, 1e-30, -1e-30,
               2.0 ** -20, 3e38, -3e38, 1e-45, 0.5 / 128, -0.5 / 128, 1.5 / 128]
    values = np.concatenate([rng.normal(0, 0.4, 3000), ties, special]).astype(np.float32)
    k = 15
    block = np.resize(values, (len(values) // (3 * k) + 1) * 3 * k).reshape(-1, 3 * k)
    block[:, :] = np.roll(block, 7, axis=0)  # every value in every column, some 5-bit, some 4-bit
    bits = [spz.SH1_BITS if j < 3 else spz.SH_REST_BITS for _c in range(3) for j in range(k)]
    rounding = np.stack([spz._rounding_table(b) for b in bits])
    got = spz._sh_bytes(block, rounding)
    for col, b in enumerate(bits):
        assert np.array_equal(got[:, col], spz_sh_bytes(block[:, col], b)), col


def test_importance_sorted_spz_holds_the_reordered_scene(tmp_path, gs_ply):
    # Encoded in row order, then reordered: the same arrays as encoding the reordered scene.
    scene = io.read(gs_ply)
    order = viewer.importance_order(viewer.importance(scene.columns))
    moved = model.Scene(columns={name: np.asarray(c)[order] for name, c in scene.columns.items()},
                        variant=scene.variant)
    sorted_arrays = spz.encode(scene, "importance")
    moved_arrays = spz.encode(moved, "none")
    assert all(np.array_equal(a, b) for a, b in zip(sorted_arrays[0], moved_arrays[0]))
    assert sorted_arrays[1:] == moved_arrays[1:]
