"""glTF with the draft ``KHR_gaussian_splatting_compression_spz_2``: the ``spz`` layout's round trip (values
within SPZ's quantization, a picture against the plain .glb), a file made by hand from the draft's text,
hostile files, the option refused where it does not apply, and specs/gltf.md's section against the code."""

from __future__ import annotations

import gzip
import json
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, model, viewer
from splatconv.cli import main
from splatconv.formats import gltf
from splatconv.formats.ply import SH_C0

from .cli_checks import error_line
from .ops_helpers import assert_same_image, draw
from .test_gltf import glb_bytes, static_scene

SPEC = (Path(__file__).resolve().parent.parent / "specs" / "gltf.md").read_text(encoding="utf-8")
NAME = "KHR_gaussian_splatting_compression_spz_2"


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def scene():
    return static_scene()


@pytest.fixture(scope="module")
def written(tmp_path_factory, scene):
    """The scene as a plain .glb and as an SPZ-compressed .glb: ``(plain path, compressed path, report)``."""
    folder = tmp_path_factory.mktemp("gltf_spz")
    plain, packed = folder / "plain.glb", folder / "spz.glb"
    io.write(scene, plain)
    report = io.write(scene, packed, layout="spz")
    return plain, packed, report


def _chunks(path: Path) -> tuple:
    raw = path.read_bytes()
    json_length = struct.unpack_from("<I", raw, 12)[0]
    doc = json.loads(raw[20:20 + json_length])
    bin_length = struct.unpack_from("<I", raw, 20 + json_length)[0]
    return doc, raw[28 + json_length:28 + json_length + bin_length]


def _unit_xyz(cols: dict) -> np.ndarray:
    """x, y, z of each splat's unit quaternion, its sign chosen so that w >= 0 (what SPZ v2 stores)."""
    q = viewer.unit_quaternions(np.stack([cols[n] for n in model.ROTATION], axis=1))
    q = np.where(q[:, :1] < 0, -q, q)
    return q[:, 1:]


def test_round_trip_is_within_spz_quantization(written, scene):
    plain, packed, report = written
    a, b = scene.columns, io.read(packed).columns
    back = io.read(packed)
    assert back.count == scene.count and back.sh_degree == 3 and back.meta["compression"] == NAME
    for name in model.POSITION:  # 12 fractional bits: half a step
        assert np.abs(b[name] - a[name]).max() <= 0.5 / 4096 + 1e-6, name
    for name in model.SCALE:  # (log + 10) * 16 as a byte
        assert np.abs(b[name] - a[name]).max() <= 0.5 / 16 + 1e-5, name
    assert np.abs(viewer.sigmoid(b["opacity"]) - viewer.sigmoid(a["opacity"])).max() <= 0.5 / 255 + 1e-6
    for name in model.COLOR:  # the DC coefficient * 0.15 * 255 as a byte
        assert np.abs(b[name] - a[name]).max() <= SH_C0 * 0.5 / (0.15 * 255) + 1e-6, name
    stored_xyz = np.stack([b[n] for n in model.ROTATION[1:]], axis=1)  # as decoded, w >= 0 derived
    assert np.abs(stored_xyz - _unit_xyz(a)).max() <= 0.5 / 127.5 + 1e-6  # v2: x, y, z as bytes
    k = model.SH_COEFFS[3]
    for j in range(k):  # degree 1 to 5 bits (steps of 8/128), higher to 4 (16/128), then the byte's half step
        bound = (4.5 if j < 3 else 8.5) / 128 + 1e-6
        for c in range(3):
            name = f"f_rest_{c * k + j}"
            assert np.abs(b[name] - a[name]).max() <= bound, name
    assert packed.stat().st_size * 4 < plain.stat().st_size
    assert any(note.startswith("quantized to .spz") for note in report.notes)
    assert any(NAME in note for note in report.notes)


def test_draws_as_the_plain_glb(renderer, written):
    plain, packed, _report = written
    a, b = io.read(plain), io.read(packed)
    for camera in (None, a.cameras[0]):
        assert_same_image(draw(renderer, a, 0.5, camera), draw(renderer, b, 0.5, camera), min_psnr=40.0)  # 48 dB measured


def test_written_json_is_the_drafts(written, scene):
    _plain, packed, _report = written
    doc, data = _chunks(packed)
    assert doc["extensionsUsed"] == ["KHR_gaussian_splatting", NAME]
    assert doc["extensionsRequired"] == ["KHR_gaussian_splatting", NAME]
    (prim,) = doc["meshes"][0]["primitives"]
    assert prim["extensions"]["KHR_gaussian_splatting"]["extensions"] == {NAME: {"bufferView": 0}}
    (view,) = doc["bufferViews"]
    assert view == {"buffer": 0, "byteOffset": 0, "byteLength": view["byteLength"]}
    assert all("bufferView" not in acc and acc["count"] == scene.count for acc in doc["accessors"])
    assert len(prim["attributes"]) == 6 + 15
    stream = gzip.decompress(data[:view["byteLength"]])
    assert struct.unpack_from("<IIIBBBB", stream) == (0x5053474E, 2, scene.count, 3, 12, 0, 0)
    back = io.read(packed)
    gl = np.stack([-back.columns["x"], -back.columns["y"], back.columns["z"]], axis=1)  # the scene in glTF's frame
    pos = doc["accessors"][prim["attributes"]["POSITION"]]
    assert pos["min"] == gl.min(axis=0).tolist() and pos["max"] == gl.max(axis=0).tolist()


def test_gltf_and_glb_hold_the_same_and_writes_repeat(tmp_path, written):
    _plain, packed, _report = written
    again = tmp_path / "again.glb"
    assert run("convert", packed, tmp_path / "x.gltf", "--layout", "spz").exit_code == 0
    assert run("convert", packed, again, "--layout", "spz").exit_code == 0
    a, b = io.read(packed), io.read(tmp_path / "x.gltf")
    for name in model.attribute_names(a.columns):
        assert np.array_equal(a.columns[name], b.columns[name]), name
    assert io.read(again).count == a.count
    assert run("convert", packed, tmp_path / "twice.glb", "--layout", "spz").exit_code == 0
    assert (tmp_path / "twice.glb").read_bytes() == again.read_bytes()


def test_info_names_the_extension(written):
    r = run("info", written[1])
    assert r.exit_code == 0 and NAME in r.output


# --------------------------------------------------------------------------
# A file made by hand from the draft's text and specs/spz.md, not by our writer.

#: Two splats as the SPZ stream stores them (the SPZ library's right-up-back frame, packed from glTF's LUF).
STORED = {
    "position": [[1.5, -2.25, 0.125], [-3.0, 0.5, 4.0]],  # multiples of 1/4096: exact at 12 fractional bits
    "alpha": [191, 64],
    "color": [[128, 200, 50], [0, 255, 100]],
    "scale": [[100, 120, 140], [160, 80, 60]],
    "rotation": [[255, 128, 128], [160, 100, 140]],  # x, y, z bytes; w derived
    "sh": [[[136, 120, 128], [160, 96, 144], [128, 128, 72]],  # per splat: coefficient, channel
           [[40, 200, 128], [128, 136, 112], [248, 8, 128]]],
}
#: The reference library's SH sign table (flipSh) for a conversion that keeps x and flips y and z: right-up-back
#: (stored) to right-down-front (PLY's, the scene's) through glTF's left-up-front. Degree 1: y, z, x.
FLIP_SH_DEGREE_1 = (-1, -1, 1)


def _spz_v2_stream(n: int = 2, version: int = 2, degree: int = 1) -> bytes:
    """The stream of :data:`STORED` built per specs/spz.md: a 16-byte header, then the arrays, gzip."""
    fixed = np.rint(np.asarray(STORED["position"]) * 4096).astype(np.int64) & 0xFFFFFF
    pos = np.stack([(fixed >> s) & 0xFF for s in (0, 8, 16)], axis=2).astype(np.uint8)
    rot = np.asarray(STORED["rotation"], np.uint8)
    if version == 3:
        rot = np.concatenate([rot, rot[:, :1]], axis=1)
    body = (struct.pack("<IIIBBBB", 0x5053474E, version, n, degree, 12, 0, 0) + pos.tobytes()
            + bytes(STORED["alpha"]) + np.asarray(STORED["color"], np.uint8).tobytes()
            + np.asarray(STORED["scale"], np.uint8).tobytes() + rot.tobytes()
            + np.asarray(STORED["sh"], np.uint8).tobytes())
    return gzip.compress(body)


def hand_spz_gltf(stream: bytes | None = None, name: str = NAME, count: int = 2, degree_attributes: int = 1,
                  ext: dict | None = None) -> bytes:
    """A .glb as the draft's schema example writes one: placeholder accessors (no bufferView), the stream in
    buffer view 0, the extension nested in the primitive's ``KHR_gaussian_splatting``."""
    stream = _spz_v2_stream() if stream is None else stream
    names = ["POSITION", "COLOR_0", "KHR_gaussian_splatting:SCALE", "KHR_gaussian_splatting:ROTATION"]
    names += [f"KHR_gaussian_splatting:SH_DEGREE_{d}_COEF_{n}" for d in range(1, degree_attributes + 1)
              for n in range(2 * d + 1)]
    kinds = {"POSITION": "VEC3", "COLOR_0": "VEC4", "KHR_gaussian_splatting:ROTATION": "VEC4"}
    accessors = [{"componentType": 5126, "count": count, "type": kinds.get(n, "VEC3")} for n in names]
    doc = {"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_gaussian_splatting", name],
           "extensionsRequired": ["KHR_gaussian_splatting", name],
           "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {n: i for i, n in enumerate(names)}, "mode": 0,
                                       "extensions": {"KHR_gaussian_splatting": {
                                           "extensions": {name: {"bufferView": 0} if ext is None else ext}}}}]}],
           "buffers": [{"byteLength": len(stream)}],
           "bufferViews": [{"buffer": 0, "byteLength": len(stream)}], "accessors": accessors}
    return glb_bytes(doc, stream)


@pytest.mark.parametrize("name", [NAME, "KHR_gaussian_splatting_compression_spz"])
def test_hand_made_compressed_glb_is_read(tmp_path, name):
    path = tmp_path / "hand.glb"
    path.write_bytes(hand_spz_gltf(name=name))
    scene = io.read(path)
    c = scene.columns
    assert scene.count == 2 and scene.sh_degree == 1
    stored = np.asarray(STORED["position"])
    # Stored (RUB) -> glTF (LUF): x and z negated; glTF -> the scene (PLY's frame): x and y negated.
    assert np.array_equal(np.stack([c["x"], c["y"], c["z"]], 1), stored * [1, -1, -1])
    assert np.allclose(viewer.sigmoid(c["opacity"]), np.asarray(STORED["alpha"]) / 255, atol=1e-6)
    dc = (np.asarray(STORED["color"]) / 255 - 0.5) / 0.15
    assert np.allclose(np.stack([c[n] for n in model.COLOR], 1), 0.5 + SH_C0 * dc, atol=1e-6)
    assert np.allclose(np.stack([c[n] for n in model.SCALE], 1), np.asarray(STORED["scale"]) / 16 - 10, atol=1e-6)
    xyz = np.asarray(STORED["rotation"]) / 127.5 - 1
    w = np.sqrt(np.maximum(0, 1 - (xyz * xyz).sum(axis=1)))
    # The reference library's quaternion signs for x kept, y and z flipped: (y z, x z, x y) = (+, -, -).
    want = np.stack([w, xyz[:, 0], -xyz[:, 1], -xyz[:, 2]], axis=1)
    assert np.allclose(np.stack([c[n] for n in model.ROTATION], 1), want, atol=1e-6)
    sh = (np.asarray(STORED["sh"]) - 128) / 128  # splat, coefficient, channel
    for j in range(3):
        for ch in range(3):
            assert np.allclose(c[f"f_rest_{ch * 3 + j}"], FLIP_SH_DEGREE_1[j] * sh[:, j, ch]), (j, ch)


def test_spz_sh_signs_are_the_reference_librarys():
    """SPZ_SH_SIGNS against the reference library's flipSh table, typed here, for x kept, y and z flipped."""
    x, y, z = 1, -1, -1
    flip = [y, z, x, x * y, y * z, 1, x * z, 1, y, x * y * z, y, z, x, z, x]
    assert gltf.SPZ_SH_SIGNS.tolist() == flip
    assert np.array_equal(gltf.SPZ_TURN, np.diag([1.0, -1.0, -1.0]))


# --------------------------------------------------------------------------
# Hostile files and the option where it does not apply.


def _hostile():
    good = _spz_v2_stream()
    raw = gzip.decompress(good)
    return {
        "bad gzip": hand_spz_gltf(good[:10] + b"\xff" * 20 + good[30:]),
        "truncated stream": hand_spz_gltf(gzip.compress(raw[:-5])),
        "count mismatch": hand_spz_gltf(count=3),
        "version 3": hand_spz_gltf(_spz_v2_stream(version=3)),
        "not spz": hand_spz_gltf(gzip.compress(b"NOPE" + raw[4:])),
        "not gzip": hand_spz_gltf(b"hello, world"),
        "no bufferView": hand_spz_gltf(ext={}),
        "view out of range": hand_spz_gltf(ext={"bufferView": 7}),
        "sh degree mismatch": hand_spz_gltf(degree_attributes=2),
    }


HOSTILE = _hostile()


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_hostile_compressed_file_gives_one_error_line_and_no_output(tmp_path, name):
    path = tmp_path / "bad.glb"
    path.write_bytes(HOSTILE[name])
    out = tmp_path / "out.ply"
    assert error_line(run("convert", path, out), 1).startswith("Error: ")
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.glb"]


@pytest.mark.parametrize("output", ["out.ply", "out.spz", "out.splat"])
def test_spz_layout_is_refused_for_other_outputs(tmp_path, written, output):
    r = run("convert", written[0], tmp_path / output, "--layout", "spz")
    assert error_line(r, 2).startswith("Error: ") and ".glb" in error_line(r, 2)
    assert not (tmp_path / output).exists()


def test_ply_layouts_are_refused_for_gltf(tmp_path, written):
    r = run("convert", written[0], tmp_path / "out.glb", "--layout", "3dgs")
    assert error_line(r, 2).startswith("Error: ")
    assert not (tmp_path / "out.glb").exists()


def test_spec_states_the_compressed_json_written():
    section = SPEC[SPEC.index("## SPZ compression"):]
    block = section[section.index("```json") + 7:]
    block = block[:block.index("```")]
    doc = json.loads(block)
    assert doc["extensionsUsed"] == doc["extensionsRequired"] == ["KHR_gaussian_splatting", gltf.SPZ_EXTENSION]
    ext = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"]
    assert ext == {**gltf.PRIMITIVE_EXTENSION, "extensions": {gltf.SPZ_EXTENSION: {"bufferView": 0}}}
