"""PlayCanvas ``compressed.ply``: read (also named ``.ply``), written within its stated quantization, SH kept,
hostile files refused, a moving scene refused with the bake hint, the commands that take it."""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from splatconv import io, model
from splatconv.cli import main
from splatconv.formats import compressed_ply, format_for
from splatconv.model import Scene
from splatconv.render.diff import compare

from .cli_checks import error_line
from .scenes import gs_columns

ROOT = Path(__file__).resolve().parent.parent
SPEC = (ROOT / "specs" / "compressed_ply.md").read_text(encoding="utf-8")
SAMPLE = ROOT / "sample_data" / "dancers.ply"

# The layout as specs/compressed_ply.md states it, typed here from the spec (not the module's constants).
CHUNK_PROPS = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y", "min_scale_z",
               "max_scale_x", "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b", "max_r", "max_g", "max_b")
VERTEX_PROPS = ("packed_position", "packed_rotation", "packed_scale", "packed_color")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def static_scene(n: int, degree: int = 3, seed: int = 1) -> Scene:
    """A plain 3DGS scene of ``n`` splats with the SH bands of ``degree``: modest scales and SH values."""
    cols = gs_columns(n, model.POSITION + model.COLOR + model.OPACITY + model.SCALE + model.ROTATION
                      + model.sh_names(degree), seed)
    for name in model.SCALE:
        cols[name] = (cols[name] * 0.5 - 3).astype(np.float32)
    for name in model.COLOR:
        cols[name] = (0.5 + 0.2 * cols[name]).astype(np.float32)
    for name in model.sh_names(degree):
        cols[name] = (cols[name] * 0.3).astype(np.float32)
    cols.update(model.static_columns(n))
    return Scene(columns=cols, variant=model.VARIANT_3DGS)


def hand_file(records: list, *, chunks: list, sh: list | None = None, chunk_props=CHUNK_PROPS,
              vertex_type="uint", sh_type="uchar", chunk_count=None, fmt="binary_little_endian") -> bytes:
    """A compressed PLY built from the spec: ``records`` (packed_position, packed_rotation, packed_scale,
    packed_color) words, ``chunks`` rows of floats, ``sh`` rows of bytes."""
    lines = ["ply", f"format {fmt} 1.0", f"element chunk {len(chunks) if chunk_count is None else chunk_count}"]
    lines += [f"property float {p}" for p in chunk_props]
    lines += [f"element vertex {len(records)}"] + [f"property {vertex_type} {p}" for p in VERTEX_PROPS]
    if sh:
        lines += [f"element sh {len(sh)}"] + [f"property {sh_type} f_rest_{i}" for i in range(len(sh[0]))]
    body = b"".join(struct.pack(f"<{len(c)}f", *c) for c in chunks)
    body += b"".join(struct.pack("<4I", *r) for r in records)
    body += b"".join(bytes(row) if sh_type == "uchar" else struct.pack(f"<{len(row)}f", *row) for row in sh or [])
    return ("\n".join(lines + ["end_header"]) + "\n").encode() + body


def w111011(a: int, b: int, c: int) -> int:
    return (a << 21) | (b << 11) | c


def rotation_word(largest: int, a: int, b: int, c: int) -> int:
    return (largest << 30) | (a << 20) | (b << 10) | c


def color_word(r: int, g: int, b: int, alpha: int) -> int:
    return (r << 24) | (g << 16) | (b << 8) | alpha


#: One chunk: positions read as the 11-10-11 integers themselves, log scales -1..1, colour 0..1.
HAND_CHUNK = [0, 0, 0, 2047, 1023, 2047, -1, -1, -1, 1, 1, 1, 0, 0, 0, 1, 1, 1]
HAND_RECORDS = [
    (w111011(5, 1023, 2047), rotation_word(0, 512, 512, 512), w111011(0, 1023, 2047), color_word(255, 0, 51, 255)),
    (w111011(2047, 0, 0), rotation_word(2, 512, 1023, 512), w111011(1023, 511, 0), color_word(0, 255, 102, 0)),
    (w111011(100, 200, 300), rotation_word(3, 512, 512, 512), w111011(2047, 0, 1), color_word(1, 2, 3, 128)),
]
HAND_SH = [[0, 255, 128, 64, 128, 128, 128, 128, 128]] * 3


def test_hand_built_file_reads_as_the_spec_says(tmp_path):
    path = tmp_path / "hand.compressed.ply"
    path.write_bytes(hand_file(HAND_RECORDS, chunks=[HAND_CHUNK], sh=HAND_SH))
    s = io.read(path)
    c = s.columns
    assert s.count == 3 and s.sh_degree == 1 and s.variant == model.VARIANT_3DGS
    assert list(c["x"]) == [5, 2047, 100] and list(c["y"]) == [1023, 0, 200] and list(c["z"]) == [2047, 0, 300]
    assert np.allclose(c["scale_0"], [-1, -1 + 2 * 1023 / 2047, 1], atol=1e-6)
    assert np.allclose(c["scale_1"], [1, -1 + 2 * 511 / 1023, -1], atol=1e-6)
    assert np.allclose(c["scale_2"], [1, -1, -1 + 2 / 2047], atol=1e-6)
    assert np.allclose(c["f_dc_0"], [1, 0, 1 / 255]) and np.allclose(c["f_dc_2"], [0.2, 0.4, 3 / 255])
    assert c["opacity"][0] > 13 and c["opacity"][1] < -13 and abs(c["opacity"][2] - np.log(128 / 127)) < 1e-5
    # Rotation: the largest by index (w x y z), the other three in index order, (q - 1/2) / sqrt(1/2).
    q = np.stack([c[n] for n in model.ROTATION], axis=1)
    small = (512 / 1023 - 0.5) / np.sqrt(0.5)
    assert np.allclose(q[0], [np.sqrt(1 - 3 * small ** 2), small, small, small], atol=1e-6)
    assert np.allclose(q[1], [small, np.sqrt(0.5), np.sqrt(max(0, 0.5 - 2 * small ** 2)), small], atol=1e-6)
    assert np.allclose(q[2, :3], [small] * 3, atol=1e-6) and q[2, 3] > 0.99
    # SH bytes: 0 -> -4, 255 -> +4, else (b + 1/2) / 256 * 8 - 4.
    assert [c[f"f_rest_{i}"][0] for i in range(4)] == [-4.0, 4.0, 0.015625, -1.984375]


def test_chunk_without_colour_bounds_reads_colour_bytes_as_rgb(tmp_path):
    path = tmp_path / "old.compressed.ply"
    path.write_bytes(hand_file(HAND_RECORDS, chunks=[HAND_CHUNK[:12]], chunk_props=CHUNK_PROPS[:12]))
    s = io.read(path)
    assert np.allclose(s.columns["f_dc_2"], [51 / 255, 102 / 255, 3 / 255]) and s.meta["chunk_color"] is False


def test_a_compressed_ply_named_ply_is_read_as_such(tmp_path):
    path = tmp_path / "named.ply"
    path.write_bytes(hand_file(HAND_RECORDS, chunks=[HAND_CHUNK], sh=HAND_SH))
    as_ply = io.read(path)
    assert as_ply.count == 3 and as_ply.meta["layout"] == "compressed" and as_ply.sh_degree == 1
    assert list(as_ply.columns["x"]) == [5, 2047, 100]
    r = run("info", path, "--json")
    assert r.exit_code == 0 and '"layout": "compressed"' in r.output and '"format": "ply"' in r.output
    plain = tmp_path / "plain.ply"
    assert run("convert", path, plain).exit_code == 0
    head = plain.read_bytes()[:2000]
    assert b"packed_position" not in head and b"property float f_rest_8" in head
    assert np.array_equal(io.read(plain).columns["x"], as_ply.columns["x"])


def test_suffix_chooses_the_format():
    assert format_for("a/x.compressed.ply").name == "compressed_ply"
    assert format_for("X.COMPRESSED.PLY.zst").name == "compressed_ply"
    assert format_for("x.ply").name == "ply" and format_for("compressed.ply").name == "ply"


@pytest.fixture(scope="module")
def trip(tmp_path_factory):
    """A 1,000-splat SH3 scene (not a multiple of 256) written as a compressed PLY and read back."""
    folder = tmp_path_factory.mktemp("trip")
    scene = static_scene(1000)
    path = folder / "s.compressed.ply"
    report = io.write(scene, path)
    return scene, io.read(path), path, report


def _chunk_ranges(values: np.ndarray) -> np.ndarray:
    """Per splat, its chunk's max - min of ``values`` in written order."""
    n = len(values)
    pad = np.concatenate([values, np.repeat(values[-1:], -n % 256)]).reshape(-1, 256)
    return np.repeat(pad.max(axis=1) - pad.min(axis=1), 256)[:n]


def test_round_trip_within_the_stated_quantization(trip):
    scene, back, path, report = trip
    assert back.count == 1000 and back.sh_degree == 3
    src = scene.columns
    xyz = np.stack([src[n].astype(np.float64) for n in model.POSITION], axis=1)
    order = compressed_ply.morton_order(xyz)
    for name, bits in zip(model.POSITION + model.SCALE, (11, 10, 11) * 2):
        v = src[name][order].astype(np.float64)
        err = np.abs(back.columns[name] - v)
        assert (err <= _chunk_ranges(v) / (2 * ((1 << bits) - 1)) * (1 + 1e-4) + 1e-6).all(), name
    for name in model.COLOR:
        v = src[name][order].astype(np.float64)
        assert (np.abs(back.columns[name] - v) <= _chunk_ranges(v) / 510 * (1 + 1e-4) + 1e-6).all(), name
    alpha = 1 / (1 + np.exp(-src["opacity"][order].astype(np.float64)))
    back_alpha = 1 / (1 + np.exp(-back.columns["opacity"].astype(np.float64)))
    assert np.abs(back_alpha - alpha).max() <= 1 / 510 + 1e-6
    q = np.stack([src[n][order] for n in model.ROTATION], axis=1).astype(np.float64)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    got = np.stack([back.columns[n] for n in model.ROTATION], axis=1).astype(np.float64)
    sign = np.sign((q * got).sum(axis=1, keepdims=True))
    # Three components within sqrt(2)/2046 each; the largest, derived, within the same order.
    assert np.abs(got * sign - q).max() <= 4 * np.sqrt(2) / 2046
    for name in model.sh_names(3):
        v = src[name][order].astype(np.float64)
        inner = (v > -4 + 1 / 32) & (v < 4 - 1 / 32)
        assert np.abs(back.columns[name] - v)[inner].max() <= 1 / 64 + 1e-6, name
    assert any("quantized to a compressed PLY" in note for note in report.notes)


def test_written_header_is_as_the_spec_says(trip):
    _scene, _back, path, _report = trip
    raw = path.read_bytes()
    head = raw[:raw.index(b"end_header\n") + 11].decode()
    lines = head.splitlines()
    assert lines[:3] == ["ply", "format binary_little_endian 1.0", "element chunk 4"]
    assert lines[3:21] == [f"property float {p}" for p in CHUNK_PROPS]
    assert lines[21:26] == ["element vertex 1000"] + [f"property uint {p}" for p in VERTEX_PROPS]
    assert lines[26] == "element sh 1000" and lines[27:72] == [f"property uchar f_rest_{i}" for i in range(45)]
    assert len(raw) == len(head) + 4 * 72 + 1000 * 16 + 1000 * 45
    # The chunk bounds are the bounds of each chunk's splats (the last: its 232 alone).
    chunk = np.frombuffer(raw, "<f4", 4 * 18, len(head)).reshape(4, 18)
    back = io.read(path)
    last = slice(768, 1000)
    assert chunk[3, 0] == back.columns["x"][last].min() and chunk[3, 3] == back.columns["x"][last].max()


def test_spec_tables_are_the_code(trip):
    assert compressed_ply.CHUNK_PROPERTIES == CHUNK_PROPS and compressed_ply.PACKED == VERTEX_PROPS
    table = re.findall(r"^\| (`[^|]+`) \| [^|]+ \|$", SPEC[SPEC.index("The chunk's properties"):], re.M)[:3]
    assert tuple(name.strip("`") for row in table for name in row.split(", ")) == CHUNK_PROPS
    assert "x in bits 21..31 (11 bits), y in bits 11..20 (10 bits), z in bits 0..10 (11 bits)" in SPEC
    assert compressed_ply.WORD_111011 == ((21, 11), (11, 10), (0, 11))
    assert "r in bits 24..31, g in 16..23, b in 8..15" in SPEC and compressed_ply.WORD_8888[0] == (24, 8)
    assert "trunc((v / 8 + 0.5) · 256)" in SPEC and compressed_ply.SH_RANGE == 8
    assert "clamped to ±20" in SPEC and compressed_ply.SCALE_LIMIT == 20
    assert "max − min < 1e-5" in SPEC and compressed_ply.MIN_RANGE == 1e-5
    assert "ceil(N / 256)" in SPEC and compressed_ply.CHUNK_SPLATS == 256


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_sh_bands_kept(tmp_path, degree):
    path = tmp_path / "s.compressed.ply"
    io.write(static_scene(300, degree), path)
    back = io.read(path)
    assert back.sh_degree == degree
    assert (b"element sh 300" in path.read_bytes()[:3000]) == (degree > 0)


def _hostile(kind: str) -> bytes:
    n = 300  # two chunks
    records = [HAND_RECORDS[i % 3] for i in range(n)]
    chunks = [HAND_CHUNK, HAND_CHUNK]
    if kind == "too_few_chunks":
        return hand_file(records, chunks=chunks[:1])
    if kind == "truncated":
        return hand_file(records, chunks=chunks)[:-100]
    if kind == "nan_bound":
        return hand_file(records, chunks=[HAND_CHUNK, HAND_CHUNK[:4] + [float("nan")] + HAND_CHUNK[5:]])
    if kind == "float_packed":
        return hand_file(records, chunks=chunks, vertex_type="float")
    if kind == "float_sh":
        return hand_file(records, chunks=chunks, sh=[HAND_SH[0]] * n, sh_type="float")
    if kind == "sh_not_a_degree":
        return hand_file(records, chunks=chunks, sh=[HAND_SH[0][:7]] * n)
    if kind == "ascii":
        head = ["ply", "format ascii 1.0", "element chunk 1", *(f"property float {p}" for p in CHUNK_PROPS),
                "element vertex 1", *(f"property uint {p}" for p in VERTEX_PROPS), "end_header"]
        return "\n".join(head + [" ".join(map(str, HAND_CHUNK)), "1 2 3 4", ""]).encode()
    if kind == "lists_before_sh":  # an element of lists of varying length (1, then 2 values) before sh
        head, body = hand_file(records, chunks=chunks).split(b"end_header\n")
        head += b"element extra 2\nproperty list uchar uchar v\nelement sh 300\n"
        head += b"".join(f"property uchar f_rest_{i}\n".encode() for i in range(9))
        return head + b"end_header\n" + body + b"\x01\x07\x02\x07\x07" + bytes(9 * 300)
    raise ValueError(kind)


@pytest.mark.parametrize("kind, where", [
    ("too_few_chunks", "element 'chunk': 1 chunks for 300 splats"),
    ("truncated", "element 'vertex': header declares 300 rows"),
    ("nan_bound", "element 'chunk': property 'max_y': row 1: nan is not a finite bound"),
    ("float_packed", "element 'vertex': property 'packed_position': float32, not the uint32"),
    ("float_sh", "element 'sh': property 'f_rest_0': float32, not the uint8"),
    ("sh_not_a_degree", "element 'sh': 7 properties"),
    ("ascii", "an ASCII compressed PLY"),
    ("lists_before_sh", "element 'sh' after an element of lists of varying length"),
])
@pytest.mark.parametrize("suffix", [".compressed.ply", ".ply"])
def test_hostile_files_give_one_error_line_and_no_output(tmp_path, kind, where, suffix):
    path = tmp_path / f"hostile{suffix}"
    path.write_bytes(_hostile(kind))
    before = path.read_bytes()
    out = tmp_path / "out.splat"
    r = run("convert", path, out)
    assert error_line(r, 1).startswith(f"Error: {path}: {where}"), kind
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name] and path.read_bytes() == before


def test_moving_scene_is_refused_with_the_bake_hint(tmp_path, lite_ply):
    out = tmp_path / "x.compressed.ply"
    r = run("convert", lite_ply, out)
    assert "bake" in error_line(r, 1) and not out.exists()


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """The sample scene baked at t = 0.5 to a plain PLY and to a compressed PLY."""
    folder = tmp_path_factory.mktemp("baked")
    plain, packed = folder / "moment.ply", folder / "moment.compressed.ply"
    for out in (plain, packed):
        r = run("bake", SAMPLE, out, "--time", "0.5")
        assert r.exit_code == 0, r.output
    return folder, plain, packed


def test_bake_convert_info_take_it(baked):
    folder, plain, packed = baked
    n = io.read(plain).count
    assert io.read(packed).count == n == 4400  # the sample's splats shown at t = 0.5
    r = run("info", packed)
    assert r.exit_code == 0 and "format:    compressed_ply" in r.output and "chunk_count: 18" in r.output
    written = []
    for name in ("again.compressed.ply", "twice.compressed.ply"):
        r = run("convert", plain, folder / name, "--force")
        assert r.exit_code == 0 and "quantized to a compressed PLY" in r.output
        written.append((folder / name).read_bytes())
    assert written[0] == written[1] and len(written[0]) == len(packed.read_bytes())  # deterministic


def test_render_before_and_after_a_round_trip(baked):
    """The pictures of the baked moment and of its compressed PLY agree above 40 dB."""
    folder, plain, packed = baked
    pictures = []
    for src in (plain, packed):
        out = folder / f"{src.name}.png"
        r = run("render", src, out, "--size", "160x120", "--fx", "150", "--fy", "150", "--force")
        assert r.exit_code == 0, r.output
        pictures.append(np.asarray(Image.open(out).convert("RGB")))
    assert pictures[0].std() > 5  # something is drawn
    assert compare(*pictures).psnr >= 40


def test_a_plain_ply_named_compressed_is_refused_plainly(tmp_path, gs_ply):
    path = tmp_path / "plain.compressed.ply"
    path.write_bytes(Path(gs_ply).read_bytes())
    assert error_line(run("info", path), 1).startswith(f"Error: {path}: not a compressed PLY")


def test_far_splats_take_chunks_of_their_own(tmp_path):
    """A few splats far out (real scenes hold them) would widen their chunks' bounds for near neighbours:
    they go last, in chunks of their own, the note says so, and the picture holds."""
    scene = static_scene(11 * 256 + 3, degree=0, seed=4)  # 11 chunks of near splats, then the far ones
    for i, row in enumerate((17, 900, 2500)):  # scattered, so that Morton order alone would mix them in
        scene.columns["x"][row] = (-1) ** i * 1e30
    plain, packed = tmp_path / "far.ply", tmp_path / "far.compressed.ply"
    io.write(scene, plain)
    r = run("convert", plain, packed)
    assert r.exit_code == 0 and "position: 3 splats more than 4096 scene extents from the rest" in r.output
    assert "share their first chunk" not in r.output
    back = io.read(packed)
    assert (np.abs(back.columns["x"][-3:]) > 1e29).all() and (np.abs(back.columns["x"][:-3]) < 10).all()
    pictures = []
    for src in (plain, packed):
        out = tmp_path / f"{src.name}.png"
        r = run("render", src, out, "--size", "160x120", "--fx", "150", "--fy", "150")
        assert r.exit_code == 0, r.output
        pictures.append(np.asarray(Image.open(out).convert("RGB")))
    assert pictures[0].std() > 5 and compare(*pictures).psnr >= 40


def test_the_least_important_splats_share_the_far_splats_chunk(tmp_path):
    scene = static_scene(11 * 256 + 13, degree=0, seed=4)  # 2,828 near splats: 12 past 11 whole chunks
    scene.columns["x"][5] = 1e30
    scene.columns["opacity"][:] = 2.0
    scene.columns["opacity"][[3, 4, 6, 7, 8, 9, 10, 11, 12, 40, 41, 2000]] = -6.0  # the 12 least important
    plain, packed = tmp_path / "far.ply", tmp_path / "far.compressed.ply"
    io.write(scene, plain)
    r = run("convert", plain, packed)
    assert r.exit_code == 0 and "the 12 least important splats of the rest share their first chunk" in r.output
    alpha = 1 / (1 + np.exp(-io.read(packed).columns["opacity"].astype(np.float64)))
    assert (alpha[-13:-1] < 0.01).all() and (alpha[:-13] > 0.8).all()
