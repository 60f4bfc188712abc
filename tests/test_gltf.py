"""glTF ``KHR_gaussian_splatting`` (.glb, .gltf + .bin): round trips, a hand-made file, hostile files, the
turn splat-transform makes, the commands that take it, and specs/gltf.md against the code."""

from __future__ import annotations

import base64
import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, model, sh, viewer
from splatconv.cli import main
from splatconv.formats import gltf
from splatconv.formats.ply import SH_C0
from splatconv.model import COLUMNS, Scene

from .cli_checks import error_line
from .ops_helpers import assert_same_image, draw
from .scenes import moving_scene

SPEC = (Path(__file__).resolve().parent.parent / "specs" / "gltf.md").read_text(encoding="utf-8")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def static_scene(n: int = 300) -> Scene:
    """``moving_scene``'s splats held still (a static scene in front of its camera), with SH degree 3."""
    scene = moving_scene(n)
    cols = {name: np.array(scene.columns[name]) for name in COLUMNS}
    cols.update(model.static_columns(n))
    rng = np.random.default_rng(3)
    for name in model.SH_REST:
        cols[name] = rng.normal(0, 0.2, n).astype(np.float32)
    return Scene(cols, cameras=scene.cameras, variant=model.VARIANT_3DGS)


@pytest.fixture(scope="module")
def scene():
    return static_scene()


@pytest.fixture(scope="module")
def glb(tmp_path_factory, scene):
    out = tmp_path_factory.mktemp("gltf") / "scene.glb"
    io.write(scene, out)
    return out


def assert_round_trip(src: Scene, back: Scene):
    a, b = src.columns, back.columns
    assert back.count == src.count and back.sh_degree == src.sh_degree
    for name in model.POSITION + model.SH_REST[:3 * model.SH_COEFFS[src.sh_degree]]:
        assert np.array_equal(a[name], b[name]), name  # sign changes only: exact
    q = viewer.unit_quaternions(np.stack([a[n] for n in model.ROTATION], axis=1))
    assert np.abs(np.stack([b[n] for n in model.ROTATION], axis=1) - q).max() <= 1.2e-7
    for name in model.SCALE:  # exp, float32, log
        assert np.abs(b[name] - a[name]).max() <= 2e-7 * max(1.0, np.abs(a[name]).max())
    assert np.abs(viewer.sigmoid(b["opacity"]) - viewer.sigmoid(a["opacity"])).max() <= 6e-8
    for name in model.COLOR:  # (rgb - 0.5) / SH_C0 in float32 and back
        assert np.abs(b[name] - a[name]).max() <= 1.2e-7
    for name in model.MOTION + model.OMEGA:
        assert not np.asarray(b[name]).any()


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_round_trip_keeps_every_attribute_float32_allows(tmp_path, scene, suffix):
    out = tmp_path / f"scene{suffix}"
    io.write(scene, out)
    back = io.read(out)
    assert_round_trip(scene, back)
    assert back.meta["container"] == suffix[1:] and back.meta["sh_degree"] == 3
    (cam,), (was,) = back.cameras, scene.cameras
    assert {k: cam[k] for k in ("width", "height", "fx", "fy", "img_name")} == \
        {k: was[k] for k in ("width", "height", "fx", "fy", "img_name")}
    assert np.allclose(cam["position"], was["position"], atol=1e-12)
    assert np.allclose(cam["rotation"], was["rotation"], atol=1e-12)


def test_gltf_writes_its_bin_beside_it_and_reads_the_same(tmp_path, scene, glb):
    out = tmp_path / "my scene.gltf"
    r = run("convert", glb, out)
    assert r.exit_code == 0, r.output
    assert (tmp_path / "my scene.bin").exists()
    doc = json.loads(out.read_bytes())
    assert doc["buffers"][0]["uri"] == "my%20scene.bin"
    assert (tmp_path / "my scene.bin").stat().st_size == doc["buffers"][0]["byteLength"]
    a, b = io.read(glb), io.read(out)
    for name in model.attribute_names(a.columns):
        assert np.array_equal(a.columns[name], b.columns[name]), name


def test_gltf_with_an_existing_bin_is_refused_and_nothing_is_written(tmp_path, glb):
    (tmp_path / "x.bin").write_bytes(b"keep")
    r = run("convert", glb, tmp_path / "x.gltf")
    assert error_line(r, 1).startswith("Error: ") and "x.bin" in error_line(r, 1)
    assert not (tmp_path / "x.gltf").exists() and (tmp_path / "x.bin").read_bytes() == b"keep"
    assert run("convert", glb, tmp_path / "x.gltf", "--force").exit_code == 0
    assert (tmp_path / "x.bin").stat().st_size > 4


def test_gltf_zst_is_refused(tmp_path, glb):
    r = run("convert", glb, tmp_path / "x.gltf.zst")
    assert error_line(r, 2).startswith("Error: ")
    assert run("convert", glb, tmp_path / "x.glb.zst").exit_code == 0


# --------------------------------------------------------------------------
# A file made by hand from the spec, not by our writer.

#: Two splats as the file holds them (glTF's frame): position, quaternion x y z w, linear scale, opacity,
#: DC coefficient, degree-1 coefficients (3 of them, r g b each).
HAND = {
    "position": [[1.0, 2.0, 3.0], [-0.5, 0.25, -4.0]],
    "rotation": [[0.0, 0.0, 0.0, 1.0], [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)]],
    "scale": [[0.1, 0.2, 0.3], [1.0, 0.5, 0.25]],
    "opacity": [[0.5], [0.75]],
    "dc": [[0.0, 1.0, -1.0], [0.5, 0.5, 0.5]],
    "sh1": [[[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]], [[0.7, 0.8, 0.9], [-0.1, -0.2, -0.3]],
            [[0.01, 0.02, 0.03], [0.04, 0.05, 0.06]]],  # coefficient, splat, channel
}


def hand_gltf(**changes) -> tuple:
    """``(json dict, bin bytes)`` of a two-splat file with SH degree 1, from the spec; ``changes`` patch the JSON
    (``accessor_N`` keys patch accessor N, ``drop`` removes an attribute)."""
    arrays = [("POSITION", "VEC3", HAND["position"]), ("KHR_gaussian_splatting:ROTATION", "VEC4", HAND["rotation"]),
              ("KHR_gaussian_splatting:SCALE", "VEC3", HAND["scale"]),
              ("KHR_gaussian_splatting:OPACITY", "SCALAR", HAND["opacity"]),
              ("KHR_gaussian_splatting:SH_DEGREE_0_COEF_0", "VEC3", HAND["dc"])]
    arrays += [(f"KHR_gaussian_splatting:SH_DEGREE_1_COEF_{n}", "VEC3", HAND["sh1"][n]) for n in range(3)]
    data, views, accessors, attributes = b"", [], [], {}
    for i, (name, kind, values) in enumerate(arrays):
        raw = np.asarray(values, "<f4").tobytes()
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(raw)})
        acc = {"bufferView": i, "componentType": 5126, "count": 2, "type": kind}
        if name == "POSITION":
            acc["min"], acc["max"] = [-0.5, 0.25, -4.0], [1.0, 2.0, 3.0]
        accessors.append(acc)
        attributes[name] = i
        data += raw
    for key, patch in changes.items():
        if key.startswith("accessor_"):
            accessors[int(key[9:])].update(patch)
    if "drop" in changes:
        del attributes[changes["drop"]]
    ext = {"KHR_gaussian_splatting": {"kernel": "ellipse", "colorSpace": "srgb_rec709_display"}}
    doc = {"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_gaussian_splatting"],
           "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": attributes, "mode": changes.get("mode", 0), "extensions": ext}]}],
           "buffers": [{"byteLength": len(data)}], "bufferViews": views, "accessors": accessors}
    doc.update(changes.get("doc", {}))
    return doc, data


def glb_bytes(doc: dict, data: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    data += b"\0" * (-len(data) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def assert_hand_values(scene: Scene):
    """The hand-made file's splats, read: the turn (x, y, z -> -x, -y, z) undone."""
    c = scene.columns
    pos = np.asarray(HAND["position"])
    assert np.array_equal(np.stack([c["x"], c["y"], c["z"]], 1), pos * [-1, -1, 1])
    # Splat 0: identity in the file is the turn itself in the scene: 180 degrees about z (w, x, y, z = 0, 0, 0, 1
    # up to sign). Splat 1: 90 degrees about y in the file.
    q = np.stack([c[n] for n in model.ROTATION], axis=1)
    assert np.allclose(np.abs(q[0]), [0, 0, 0, 1])
    turn = np.array([[-1, 0, 0], [0, -1, 0], [0, 0, 1.0]])
    about_y = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]])
    w, x, y, z = q[1]
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    assert np.allclose(turn @ r, about_y, atol=1e-6)  # the file's rotation is the turn after the scene's
    assert np.allclose(np.exp(np.stack([c[n] for n in model.SCALE], 1)), HAND["scale"], rtol=1e-6)
    assert np.allclose(viewer.sigmoid(c["opacity"]), [0.5, 0.75], atol=1e-7)
    assert np.allclose(np.stack([c[n] for n in model.COLOR], 1), 0.5 + SH_C0 * np.asarray(HAND["dc"]), atol=1e-7)
    assert scene.sh_degree == 1
    signs = (-1, 1, -1)  # under the turn, the basis functions -y and -x change sign, z does not
    for n in range(3):
        for ch in range(3):
            assert np.allclose(c[f"f_rest_{ch * 3 + n}"], signs[n] * np.asarray(HAND["sh1"][n])[:, ch]), (n, ch)


def test_hand_made_glb_is_read_with_the_turn_undone(tmp_path):
    path = tmp_path / "hand.glb"
    path.write_bytes(glb_bytes(*hand_gltf()))
    assert_hand_values(io.read(path))


def test_hand_made_gltf_with_a_bin_file_and_with_a_data_uri(tmp_path):
    doc, data = hand_gltf()
    doc["buffers"][0]["uri"] = "hand%20data.bin"
    (tmp_path / "hand data.bin").write_bytes(data)
    (tmp_path / "a.gltf").write_text(json.dumps(doc))
    assert_hand_values(io.read(tmp_path / "a.gltf"))
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    (tmp_path / "b.gltf").write_text(json.dumps(doc))
    assert_hand_values(io.read(tmp_path / "b.gltf"))


def test_a_foreign_camera_gets_a_size_from_its_field_of_view(tmp_path):
    doc, data = hand_gltf(doc={"cameras": [{"type": "perspective", "perspective": {"yfov": 1.0, "aspectRatio": 2.0,
                                                                                  "znear": 0.1}}],
                               "nodes": [{"mesh": 0}, {"camera": 0, "translation": [1, 2, 3]}]})
    path = tmp_path / "cam.glb"
    path.write_bytes(glb_bytes(doc, data))
    (cam,) = io.read(path).cameras
    assert (cam["width"], cam["height"]) == (1440, 720)
    assert cam["fx"] == cam["fy"] == pytest.approx(360 / np.tan(0.5))
    assert cam["position"] == [-1.0, -2.0, 3.0]
    # glTF's camera looks along its -z with y up; the scene's looks along its third axis with y down.
    assert np.allclose(cam["rotation"], np.diag([-1.0, 1.0, -1.0]))


def test_sh_signs_are_the_turns_rotation_of_the_sh():
    m = sh.rotation_matrix(gltf.TURN, 3)
    assert np.allclose(m, np.diag(gltf.SH_SIGNS), atol=1e-9)
    assert list(gltf.SH_SIGNS) == [-1.0 if k % 2 == 0 else 1.0 for k in range(15)]


def test_turn_is_splat_transforms_per_the_spec():
    """A file's positions are the scene's with x and y negated (the header's POSITION bounds too)."""
    cols = {name: np.zeros(1, np.float32) for name in COLUMNS}
    cols.update(x=np.float32([1.5]), y=np.float32([-2.0]), z=np.float32([3.0]), rot_0=np.float32([1.0]))
    cols.update(model.static_columns(1))
    scene = Scene(cols, variant=model.VARIANT_3DGS)
    import io as pyio
    buf = pyio.BytesIO()
    gltf.write(scene, buf)
    raw = buf.getvalue()
    length = struct.unpack_from("<I", raw, 12)[0]
    doc = json.loads(raw[20:20 + length])
    pos = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    assert pos["min"] == pos["max"] == [-1.5, 2.0, 3.0]
    rot = np.frombuffer(raw, "<f4", 4, 20 + length + 8 + doc["bufferViews"][2]["byteOffset"])
    assert list(rot) == [0.0, 0.0, 1.0, 0.0]  # identity turned: 180 degrees about z, x y z w


# --------------------------------------------------------------------------
# Hostile files: one Error line, exit 1, nothing written.


def _hostile():
    good = glb_bytes(*hand_gltf())
    doc, data = hand_gltf()
    cases = {
        "empty": b"",
        "truncated": good[:len(good) - 10],
        "bad magic": b"glTX" + good[4:],
        "version 1": good[:4] + struct.pack("<I", 1) + good[8:],
        "chunk past the end": good[:12] + struct.pack("<I", 1 << 20) + good[16:],
        "accessor out of range": glb_bytes(*hand_gltf(accessor_0={"bufferView": 99})),
        "count past the view": glb_bytes(*hand_gltf(accessor_0={"count": 3}, accessor_1={"count": 3},
                                                    accessor_2={"count": 3}, accessor_3={"count": 3},
                                                    accessor_4={"count": 3}, accessor_5={"count": 3},
                                                    accessor_6={"count": 3}, accessor_7={"count": 3})),
        "missing attribute": glb_bytes(*hand_gltf(drop="KHR_gaussian_splatting:SCALE")),
        "wrong component type": glb_bytes(*hand_gltf(accessor_3={"componentType": 5125})),
        "wrong type": glb_bytes(*hand_gltf(accessor_1={"type": "VEC3"})),
        "component type a list": glb_bytes(*hand_gltf(accessor_2={"componentType": [5126]})),
        "not points": glb_bytes(*hand_gltf(mode=4)),
        "half a degree": glb_bytes(*hand_gltf(drop="KHR_gaussian_splatting:SH_DEGREE_1_COEF_2")),
        "required extension": glb_bytes(*hand_gltf(doc={"extensionsRequired": ["EXT_meshopt_compression"]})),
        "node transform": glb_bytes(*hand_gltf(doc={"nodes": [{"mesh": 0, "translation": [1, 0, 0]}]})),
        "node cycle": glb_bytes(*hand_gltf(doc={"nodes": [{"mesh": 0, "children": [1]}, {"children": [0]}]})),
        "nan": glb_bytes(*hand_gltf()).replace(b'"min": [-0.5', b'"min": [NaN ', 1),
        "json garbage": good[:20] + b"x" + good[21:],
        "no splats": glb_bytes(dict(doc, meshes=[]), data),
    }
    assert cases["nan"] != good
    return cases


HOSTILE = _hostile()


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_hostile_file_gives_one_error_line_and_no_output(tmp_path, name):
    path = tmp_path / "bad.glb"
    path.write_bytes(HOSTILE[name])
    assert error_line(run("info", path), 1).startswith("Error: ")
    out = tmp_path / "out.ply"
    assert error_line(run("convert", path, out), 1).startswith("Error: ")
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.glb"]


def test_blocks_change_nothing_and_info_reads_pieces(tmp_path, monkeypatch, scene, glb):
    """Written and scanned a few rows at a time: the same bytes, and the pieces are the scene read whole."""
    monkeypatch.setattr(gltf, "BLOCK", 7)
    small = tmp_path / "small.glb"
    io.write(scene, small)
    assert small.read_bytes() == glb.read_bytes()
    whole = io.read(glb)
    with io.scanning(glb) as scan:
        pieces = list(scan.pieces)
    assert len(pieces) == -(-scene.count // 7) and scan.meta["sh_degree"] == 3 and len(scan.cameras) == 1
    for name in model.attribute_names(whole.columns):
        assert np.array_equal(np.concatenate([p[name] for p in pieces]), whole.columns[name]), name


def test_frames_as_gltf_each_with_its_bin(tmp_path, lite_ply):
    out = tmp_path / "frames"
    r = run("bake", lite_ply, out, "--frames", "2", "--frame-suffix", ".gltf")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.iterdir()) == ["frame_0000.bin", "frame_0000.gltf", "frame_0001.bin",
                                                     "frame_0001.gltf"]
    assert io.read(out / "frame_0001.gltf").count > 0


def test_importance_order_is_kept_and_read_back(tmp_path, glb):
    out = tmp_path / "sorted.glb"
    assert run("convert", glb, out, "--sort", "importance").exit_code == 0
    a, b = io.read(glb), io.read(out)
    key = viewer.importance(b.columns)
    assert (np.diff(key) <= 0).all() and sorted(a.columns["x"]) == sorted(b.columns["x"])


def test_missing_bin_and_bad_data_uri_give_one_error_line(tmp_path):
    doc, data = hand_gltf()
    doc["buffers"][0]["uri"] = "nowhere.bin"
    (tmp_path / "a.gltf").write_text(json.dumps(doc))
    assert "nowhere.bin" in error_line(run("info", tmp_path / "a.gltf"), 1)
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64,@@@@"
    (tmp_path / "b.gltf").write_text(json.dumps(doc))
    assert error_line(run("info", tmp_path / "b.gltf"), 1).startswith("Error: ")
    (tmp_path / "c.bin").write_bytes(data[:-8])  # shorter than its byteLength
    doc["buffers"][0]["uri"] = "c.bin"
    (tmp_path / "c.gltf").write_text(json.dumps(doc))
    assert "truncated" in error_line(run("info", tmp_path / "c.gltf"), 1)


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_moving_scene_is_refused_with_the_bake_hint(tmp_path, lite_ply, suffix):
    out = tmp_path / f"x{suffix}"
    r = run("convert", lite_ply, out)
    assert "bake" in error_line(r, 1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.ply"]


# --------------------------------------------------------------------------
# Pixels and the commands that take it.


def test_round_trip_draws_the_same(tmp_path, renderer, scene, glb):
    back = io.read(glb)
    before = draw(renderer, scene, 0.5)
    assert_same_image(before, draw(renderer, back, 0.5), min_psnr=60.0)
    assert_same_image(before, draw(renderer, back, 0.5, back.cameras[0]), min_psnr=60.0)


def test_bake_convert_info_stats_verify_render_take_gltf(tmp_path, lite_ply, gs_ply):
    moment = tmp_path / "moment.glb"
    r = run("bake", lite_ply, moment, "--time", "0.5")
    assert r.exit_code == 0, r.output
    assert io.read(moment).count > 0
    chain = [gs_ply, tmp_path / "a.glb", tmp_path / "b.gltf", tmp_path / "c.spz", tmp_path / "d.glb",
             tmp_path / "e.splat"]
    for src, dst in zip(chain, chain[1:]):
        r = run("convert", src, dst)
        assert r.exit_code == 0, (dst, r.output)
    src, again = io.read(gs_ply), io.read(tmp_path / "b.gltf")
    assert np.array_equal(src.columns["y"], again.columns["y"]) and again.sh_degree == 3
    r = run("info", tmp_path / "a.glb", "--json")
    assert r.exit_code == 0 and '"format": "gltf"' in r.output and '"container": "glb"' in r.output
    assert run("stats", tmp_path / "a.glb").exit_code == 0
    r = run("verify", gs_ply, tmp_path / "a.glb")
    assert r.exit_code == 0, r.output
    out = tmp_path / "f.png"
    assert run("render", tmp_path / "b.gltf", out, "--size", "32x24").exit_code == 0 and out.stat().st_size


# --------------------------------------------------------------------------
# specs/gltf.md against the code.


def test_spec_attribute_table_is_what_is_written():
    rows = re.findall(r"^\| `([A-Za-z_:0-9{}]+)` \| (\w+) \| (\w+) \|", SPEC, re.M)
    written = [(name, kind, {gltf.FLOAT: "float", gltf.UNSIGNED_BYTE: "ubyte"}[component])
               for name, kind, component, *_ in gltf.segments(1)]
    table = [(n.replace("{l}", "1").replace("{n}", "0"), k, c) for n, k, c in rows]
    assert table == written[:len(table)] and len(table) == 7  # the first SH rest coefficient stands for all


@pytest.mark.parametrize("text, value", [
    ("`0x46546c67`", gltf.MAGIC), ("`0x4e4f534a`", gltf.CHUNK_JSON), ("`0x004e4942`", gltf.CHUNK_BIN),
    ("version 2", gltf.VERSION), ("znear 0.01", gltf.ZNEAR),
])
def test_spec_constants_are_the_codes(text, value):
    assert text in SPEC
    number = re.search(r"0x[0-9a-f]+|\d+(\.\d+)?", text).group()
    assert float(int(number, 16) if number.startswith("0x") else float(number)) == float(value)


def test_spec_states_the_extension_object_written():
    block = SPEC[SPEC.index("```json"):]
    block = block[block.index("\n") + 1:block.index("```", 7)]
    assert json.loads(block) == {"KHR_gaussian_splatting": gltf.PRIMITIVE_EXTENSION}
