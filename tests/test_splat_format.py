"""antimatter15's .splat and the 3DGS PLY layout: facts, round trips, refusals, notes."""

from __future__ import annotations

import json
import struct

import numpy as np
import plyfile
import pytest
from click.testing import CliRunner

from splatconv import io, model, viewer
from splatconv.cli import main
from splatconv.formats import format_for, ply, splat
from splatconv.model import Scene

from .conftest import random_columns, write_ply

SH_C0 = 0.28209479177387814


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def static_columns(n: int, seed: int = 0) -> dict:
    """Plausible attributes of a static scene: random_columns without motion, with the static basis."""
    cols = random_columns(n, seed)
    for name in model.MOTION + model.OMEGA:
        cols[name][:] = 0.0
    cols["trbf_center"][:] = model.STATIC_TRBF_CENTER
    cols["trbf_scale"][:] = model.STATIC_TRBF_SCALE
    return cols


def decode_reference(data: bytes) -> list:
    """Records as antimatter15's viewer reads them, one struct.unpack a record (test oracle)."""
    out = []
    for i in range(len(data) // 32):
        v = struct.unpack_from("<3f3f4B4B", data, 32 * i)
        out.append({"pos": v[0:3], "scale": v[3:6], "rgba": v[6:10], "rot": tuple((b - 128) / 128 for b in v[10:14])})
    return out


def random_splat_bytes(n: int, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    rec = np.zeros(n, splat.RECORD)
    rec["position"] = rng.normal(0, 2, (n, 3))
    rec["scale"] = rng.uniform(0.001, 0.2, (n, 3))
    rec["rgba"] = rng.integers(0, 256, (n, 4))
    q = rng.normal(0, 1, (n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    # Unit quaternions as a converter writes them: truncated (antimatter15's) for half, rounded for the rest.
    steps = q * 128 + 128
    rec["rot"] = np.clip(np.where(np.arange(n)[:, None] % 2 == 0, np.floor(steps), np.rint(steps)), 0, 255)
    return rec.tobytes()


def test_reads_records_as_the_viewer_does(tmp_path):
    data = random_splat_bytes(300)
    path = tmp_path / "a.splat"
    path.write_bytes(data)
    scene = io.read(path)
    assert scene.count == 300 and scene.variant == model.VARIANT_3DGS and scene.cameras is None
    ref = decode_reference(data)
    rot = viewer.rotation_at(scene.columns, 0.5, normalize=False)
    rgba = np.concatenate([viewer.colors(scene.columns), viewer.opacity(scene.columns)[:, None]], axis=1)
    for i, r in enumerate(ref):
        assert tuple(viewer.positions(scene.columns)[i]) == pytest.approx(r["pos"], rel=0, abs=0)
        assert tuple(viewer.scales(scene.columns)[i]) == pytest.approx(r["scale"], rel=1e-6)
        assert tuple(rot[i]) == r["rot"]
        assert tuple(np.rint(rgba[i] * 255)) == r["rgba"]
    assert not any(scene.columns[name].any() for name in model.MOTION + model.OMEGA)
    assert viewer.temporal_opacity(scene.columns, 0.0).min() > 1 - 1e-6


def test_byte_round_trip_is_exact(tmp_path):
    """A .splat read and written again gives its bytes back (scales aside) and says nothing changed."""
    data = random_splat_bytes(1000, seed=2)
    src = tmp_path / "a.splat"
    src.write_bytes(data)
    out = tmp_path / "b.splat"
    report = io.write(io.read(src), out, sort="none")
    assert report.notes == []  # nothing changed, nothing reported
    back = out.read_bytes()
    rec, want = np.frombuffer(back, splat.RECORD), np.frombuffer(data, splat.RECORD)
    for field in ("position", "rgba", "rot"):
        assert np.array_equal(rec[field], want[field])
    # Scales pass through log and exp in float32: within a few float32 steps.
    assert np.allclose(rec["scale"], want["scale"], rtol=1e-6, atol=0)


def test_writes_known_values(tmp_path):
    cols = static_columns(5)
    cols["x"][:], cols["y"][:], cols["z"][:] = 1.0, -2.0, 3.5
    for i in range(3):
        cols[f"scale_{i}"][:] = np.log(0.25)
    cols["f_dc_0"][:] = [0.0, 0.5, 1.0, -1.0, 2.0]
    cols["opacity"][:] = [0.0, 100.0, -100.0, 0.0, 0.0]
    quats = [(1, 0, 0, 0), (0, 0, 0, 2), (0.5, 0.5, 0.5, 0.5), (-1, 0, 0, 0), (3, 4, 0, 0)]
    for i in range(4):
        cols[f"rot_{i}"][:] = [q[i] for q in quats]
    out = tmp_path / "k.splat"
    report = io.write(Scene(columns=cols, variant=model.VARIANT_3DGS), out, sort="none")
    rec = decode_reference(out.read_bytes())
    assert [r["pos"] for r in rec] == [(1.0, -2.0, 3.5)] * 5
    assert [r["scale"] for r in rec] == [(0.25, 0.25, 0.25)] * 5
    assert [r["rgba"][0] for r in rec] == [0, 128, 255, 0, 255]  # 127.5 rounds to even 128; clamped ends
    assert [r["rgba"][3] for r in rec] == [128, 255, 0, 128, 128]
    assert [tuple(round(c * 128 + 128) for c in r["rot"]) for r in rec] == [
        (255, 128, 128, 128), (128, 128, 128, 255), (192, 192, 192, 192), (0, 128, 128, 128), (205, 230, 128, 128)]
    assert "color: 2 values outside [0, 1] clamped" in report.notes
    # (0.5, 0.5, 0.5, 0.5) and (-1, 0, 0, 0) are bytes' values already: kept, not reported.
    assert "rotation: 3 of 5 splats normalised and rounded to 8 bits a component" in report.notes


def test_notes_count_what_the_bytes_change(tmp_path):
    cols = static_columns(100, seed=4)
    cols["f_dc_1"][:10] = np.nan
    cols["opacity"][10:13] = np.nan
    for i in range(4):
        cols[f"rot_{i}"][20:22] = 0.0  # zero: written as 128s, read back as zero: unchanged
    cols["rot_2"][30] = np.nan
    report = io.write(Scene(columns=cols, variant=model.VARIANT_3DGS), tmp_path / "n.splat")
    assert report.notes == [
        "color: 100 of 100 splats rounded to 8 bits a channel",
        "opacity: 100 of 100 splats rounded to 8 bits",
        "rotation: 97 of 100 splats normalised and rounded to 8 bits a component",
        "rotation: 1 non-finite quaternions written as zero (drawn unrotated)",
        "color: 10 NaN values written as 0",
        "alpha: 3 NaN values written as 0",
    ]


def test_round_trip_within_quantisation(tmp_path):
    cols = static_columns(2000, seed=6)
    scene = Scene(columns=cols, variant=model.VARIANT_3DGS)
    io.write(scene, tmp_path / "q.splat", sort="none")
    back = io.read(tmp_path / "q.splat")
    assert np.array_equal(viewer.positions(back.columns), viewer.positions(cols))
    assert np.allclose(viewer.scales(back.columns), viewer.scales(cols), rtol=1e-6)
    assert np.abs(viewer.colors(back.columns) - viewer.colors(cols)).max() <= 0.5 / 255 + 1e-7
    assert np.abs(viewer.opacity(back.columns) - viewer.opacity(cols)).max() <= 0.5 / 255 + 1e-7
    # Each normalised component within half a step of 1/128.
    want = viewer.rotation_at(cols, 0.5)
    got = viewer.rotation_at(back.columns, 0.5, normalize=False)
    assert np.abs(got - np.clip(want, -1, 127 / 128)).max() <= 0.5 / 128 + 1e-7


def test_importance_order_by_default(tmp_path):
    cols = static_columns(500, seed=7)
    io.write(Scene(columns=cols, variant=model.VARIANT_3DGS), tmp_path / "s.splat")
    back = io.read(tmp_path / "s.splat")
    order = np.argsort(-viewer.importance(cols), kind="stable")
    assert np.array_equal(back.columns["x"], cols["x"][order])


@pytest.mark.parametrize("data, message", [
    (b"", "file is empty"),
    (b"\0" * 31, "size 31 bytes is not a whole number of 32-byte records: 31 bytes after record 0; file truncated?"),
    (b"\0" * 70, "size 70 bytes is not a whole number of 32-byte records: 6 bytes after record 2; file truncated?"),
    (b"ply\nformat binary_little_endian 1.0\n" + b"\0" * 29, "this is a PLY file, not a .splat (name it .ply)"),
    (struct.pack("<II", 0x674B, 10) + b"\0" * 56, "this is a .splatv file, not a .splat (name it .splatv)"),
])
def test_bad_files_give_one_error_line(tmp_path, data, message):
    path = tmp_path / "bad.splat"
    path.write_bytes(data)
    r = run("info", path)
    assert r.exit_code == 1 and r.stderr == f"Error: {path}: {message}\n"


def test_a_moving_scene_is_refused(tmp_path, lite_ply):
    out = tmp_path / "x.splat"
    r = run("convert", lite_ply, out)
    assert r.exit_code == 1
    assert r.stderr == (f"Error: {out}: 3,000 of 3,000 splats move, turn or fade over time and a .splat file is "
                        "static; bake one moment with `splatconv bake INPUT OUTPUT --time T`\n")
    assert not out.exists() and list(tmp_path.iterdir()) == [lite_ply]


def test_nonfinite_scales_and_positions(tmp_path):
    cols = static_columns(10, seed=8)
    cols["x"][0] = np.nan
    cols["scale_0"][1] = np.inf
    cols["scale_1"][2] = 200.0  # exp overflows float32
    report = io.write(Scene(columns=cols, variant=model.VARIANT_3DGS), tmp_path / "f.splat", sort="none")
    assert "scale: 1 value past the float32 range written as infinity" in report.notes
    back = io.read(tmp_path / "f.splat")
    assert np.isnan(back.columns["x"][0]) and np.isinf(back.columns["scale_0"][1])


def test_splat_zst_and_determinism(tmp_path):
    src = tmp_path / "a.splat"
    src.write_bytes(random_splat_bytes(100, seed=9))
    for name in ("b.splat.zst", "c.splat.zst"):
        assert run("convert", src, tmp_path / name).exit_code == 0
    assert (tmp_path / "b.splat.zst").read_bytes() == (tmp_path / "c.splat.zst").read_bytes()
    assert io.read(tmp_path / "b.splat.zst").count == 100
    assert format_for("x.SPLAT").name == "splat" and format_for("x.splatv").name == "splatv"
    # A .splat is a static 3DGS scene: to .ply it goes as a 3DGS PLY, and back to the same bytes.
    assert run("convert", src, tmp_path / "d.ply").exit_code == 0
    assert io.read(tmp_path / "d.ply").variant == model.VARIANT_3DGS
    assert run("convert", tmp_path / "d.ply", tmp_path / "e.splat", "--sort", "none").exit_code == 0
    back, want = (np.frombuffer(p.read_bytes(), splat.RECORD) for p in (tmp_path / "e.splat", src))
    assert all(np.array_equal(back[f], want[f]) for f in ("position", "rgba", "rot"))


# --------------------------------------------------------------------------
# 3DGS PLY output


def test_3dgs_ply_round_trip(tmp_path, gs_ply):
    out = tmp_path / "back.ply"
    r = run("convert", gs_ply, out)
    assert r.exit_code == 0, r.output
    assert "f_rest" not in r.stderr and "dropped" not in r.stderr
    # 3DGS's own order, its SH bands (degree 3) after f_dc_2
    names = [p.name for p in plyfile.PlyData.read(str(out))["vertex"].properties]
    assert names == list(ply.gs_layout(3)) and names[9] == "f_rest_0" and names[53] == "f_rest_44"
    src, back = io.read(gs_ply), io.read(out)
    assert back.variant == model.VARIANT_3DGS and back.sh_degree == 3
    for name in model.POSITION + model.OPACITY + model.SCALE + model.ROTATION + model.SH_REST:
        assert np.array_equal(back.columns[name], src.columns[name]), name
    raw_src = plyfile.PlyData.read(str(gs_ply))["vertex"].data
    raw_back = plyfile.PlyData.read(str(out))["vertex"].data
    for name in model.COLOR:
        assert np.allclose(raw_back[name], raw_src[name], rtol=1e-6, atol=1e-6)


def test_ply_layout_option(tmp_path, gs_ply, lite_ply):
    lite = tmp_path / "lite.ply"
    r = run("convert", gs_ply, lite, "--ply-layout", "lite")
    assert r.exit_code == 0
    # the lite layout holds colour only: the SH bands go, and the note says so
    assert "note: dropped SH degree 1\u20133 bands: a Spacetime Gaussians lite PLY holds colour only" in r.stderr
    assert io.read(lite).variant == model.VARIANT_LITE and io.read(lite).sh_degree == 0
    # A lite file of a static scene goes to 3DGS when asked.
    again = tmp_path / "again.ply"
    assert run("convert", lite, again, "--ply-layout", "3dgs").exit_code == 0
    assert io.read(again).variant == model.VARIANT_3DGS
    # A moving scene cannot.
    out = tmp_path / "moving.ply"
    r = run("convert", lite_ply, out, "--ply-layout", "3dgs")
    assert r.exit_code == 1 and "splats move, turn or fade over time and a 3DGS PLY is static" in r.stderr
    assert not out.exists()
    r = run("convert", gs_ply, tmp_path / "x.splatv", "--ply-layout", "3dgs")
    assert r.exit_code == 2 and r.stderr == f"Error: {tmp_path / 'x.splatv'}: layout 3dgs applies to .ply output only\n"


def test_3dgs_drops_a_nearly_static_basis_with_a_note(tmp_path):
    cols = static_columns(20, seed=10)
    cols["trbf_scale"][:] = np.log(200.0)  # within half an alpha step of 1 over [0, 1]
    out = tmp_path / "s.ply"
    report = io.write(Scene(columns=cols), out, layout="3dgs")
    assert report.notes == ["trbf: temporal basis dropped (every splat is within half an alpha step of full "
                            "opacity over the whole clip)"]
    cols["trbf_scale"][:] = np.log(5.0)  # fades by more
    with pytest.raises(Exception, match="20 of 20 splats move, turn or fade"):
        io.write(Scene(columns=cols), tmp_path / "t.ply", layout="3dgs")


def test_3dgs_static_file_from_another_tool_reads_as_written(tmp_path):
    """A 3DGS PLY whose properties come in another order and with f_rest_* is read, then written in ours."""
    rng = np.random.default_rng(11)
    cols = {name: rng.normal(0, 1, 50).astype(np.float32) for name in reversed(ply.GS_LAYOUT)}
    src = write_ply(tmp_path / "other.ply", cols, extra_props=("f_rest_0", "f_rest_1"))
    out = tmp_path / "ours.ply"
    assert run("convert", src, out).exit_code == 0
    data = plyfile.PlyData.read(str(out))["vertex"].data
    for name in ("x", "opacity", "scale_2", "rot_3"):
        assert np.array_equal(data[name], cols[name])
    assert np.allclose(data["f_dc_2"], cols["f_dc_2"], atol=1e-6)


def test_spec_table_matches_the_record():
    """specs/splat.md's record table is the code's RECORD."""
    from pathlib import Path

    text = (Path(__file__).resolve().parent.parent / "specs" / "splat.md").read_text()
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in text.splitlines()
            if line.startswith("| ") and "–" in line.split("|")[1]]
    assert [r[2] for r in rows] == list(splat.RECORD.names)
    for span, kind, name, _meaning in rows:
        start, stop = (int(v) for v in span.split("–"))
        dtype, count = splat.RECORD.fields[name][0], splat.RECORD.fields[name][0].shape[0]
        assert splat.RECORD.fields[name][1] == start and stop - start + 1 == dtype.itemsize
        assert kind == f"{dtype.base.name} ×{count}"
    assert splat.RECORD.itemsize == 32


def test_arbitrary_bytes_read_and_write_without_warnings(tmp_path):
    """Random records (NaN, infinities, negative scales, any byte) go through every command path quietly."""
    rng = np.random.default_rng(13)
    data = bytearray(rng.integers(0, 256, 32 * 500, dtype=np.uint8).tobytes())
    floats = np.frombuffer(data, "<f4").reshape(500, 8)
    floats[:20, :6] = np.nan
    floats[20:40, 3:6] = np.inf
    floats[40:60, 3:6] = -1.0
    floats.view("<u4")[60:62, 0] = 0x7F800001  # signalling NaN: widening it to float64 would warn
    src = tmp_path / "noise.splat"
    src.write_bytes(bytes(data))
    scene = io.read(src)
    assert scene.count == 500 and any("negative values have no logarithm" in n for n in scene.notes)
    assert any(n.startswith("position: ") and "signalling NaN values read as quiet NaN" in n for n in scene.notes)
    assert np.isnan(scene.columns["x"][60:62]).all()
    for name in ("a.splatv", "b.ply", "c.splat"):
        r = run("convert", src, tmp_path / name)
        assert r.exit_code == 0, (name, r.output)
    assert run("info", tmp_path / "c.splat").exit_code == 0
    assert run("bake", src, tmp_path / "d.ply", "--time", "0.5").exit_code == 0


def test_verify_a_splat_conversion_passes_within_its_own_quantisation(tmp_path, gs_ply):
    """verify judges a .splat by what a .splat stores: byte rotations, no time, float32 scales."""
    src = tmp_path / "gs.ply"
    cols = {p.name: np.asarray(plyfile.PlyData.read(gs_ply)["vertex"][p.name]) for p in
            plyfile.PlyData.read(gs_ply)["vertex"].properties}
    cols["rot_0"][:3] = np.nan  # no direction: written as zero, drawn unrotated (noted)
    cols["rot_1"][3:5] = np.inf
    cols["rot_2"][5:50] *= 40.0  # far from unit length: normalised first
    write_ply(src, cols)
    out = tmp_path / "gs.splat"
    assert run("convert", src, out).exit_code == 0
    # One small frame: the scene is static (every time draws the same) and its splats are huge (e^3 units), so
    # each frame at the default size costs seconds of overdraw and tells no more.
    small = ("--times", "0.5", "--size", "160x120")
    result = run("verify", src, out, *small, "--json")
    assert result.exit_code == 0, result.stdout
    data = json.loads(result.stdout)
    rot = data["attributes"]["rotation"]
    assert rot["storage"] == "unit_quaternion_byte" and rot["ok"] and 0 < rot["max_abs_error"] <= 2 / 128
    assert {data["attributes"][g]["storage"] for g in ("motion", "omega", "trbf")} == {"none"}
    text = run("verify", src, out, *small).stdout
    assert "trbf        not stored by CONVERTED (a static format)" in text and "PASS" in text

    # A real fault in the stored rotations is still caught: turn 40 splats half a turn about x.
    data = bytearray(out.read_bytes())
    records = np.frombuffer(data, splat.RECORD).copy()
    q = (records["rot"][:40].astype(np.float64) - 128) / 128
    w, x, y, z = q.T
    turned = np.stack([-x, w, -z, y], axis=1)  # (0, 1, 0, 0) * q
    records["rot"][:40] = np.clip(np.rint(turned * 128 + 128), 0, 255)
    out.write_bytes(records.tobytes())
    result = run("verify", src, out, *small)
    assert result.exit_code == 1
    assert "FAIL: rotation drifted" in result.stdout


def test_every_format_says_how_it_stores_each_group(tmp_path):
    from splatconv.compare import STORAGE_KINDS
    from splatconv.formats import REGISTRY

    scene = Scene(columns=static_columns(4), variant=model.VARIANT_3DGS)
    for module in set(REGISTRY.values()):
        kinds = module.storage(scene)
        assert set(kinds) == set(model.GROUPS) and set(kinds.values()) <= set(STORAGE_KINDS), module.name
    assert ply.storage(scene)["trbf"] == "none" and ply.storage(Scene(columns=static_columns(4)))["trbf"] == "exact"


def _tricky_quaternions() -> np.ndarray:
    """Quaternions on and off the byte grid, tiny, zero, huge, NaN, infinite, subnormal, and random ones."""
    rng = np.random.default_rng(5)
    grid = (rng.integers(0, 256, (200, 4)) - 128) / 128.0
    unit = rng.normal(size=(200, 4))
    unit_grid = np.rint(unit / np.linalg.norm(unit, axis=1, keepdims=True) * 128) / 128.0
    special = np.array([[1, 0, 0, 0], [0, 0, 0, 0], [-0.0, 0, 0, 0], [1, 1e-30, 0, 0], [1e-30, 1, 0, 0],
                        [2.0 ** -21, 1, 0, 0], [2.0 ** -20, 1, 0, 0], [1, 2.0 ** -21, 2.0 ** -40, 0],
                        [np.nan, 1, 0, 0], [1, np.nan, 0, 0], [np.inf, 0, 0, 0], [1, -np.inf, 0, 0],
                        [1e-45, 0, 0, 0], [3e38, 3e38, 0, 0], [-1, 0, 0, 0], [0.5, 0.5, 0.5, 0.5],
                        [127 / 128, 1 / 128, 0, 0], [-128 / 128, 0, 0, 0], [1.0078125, 0, 0, 0],
                        [0.5 + 2.0 ** -9, 0.5, 0.5, 0.5], [1e20, 0, 0, 0], [1e-30, 127 / 128, 0, 0],
                        [-1e-30, 0, -127 / 128, 1 / 128]])
    rows = [rng.normal(size=(500, 4)), grid, unit_grid, special, rng.normal(size=(100, 4)) * 1e-30]
    return np.concatenate(rows).astype(np.float32)


def test_rotation_bytes_match_the_float64_reference():
    from .reference import splat_rotation_bytes

    q = _tricky_quaternions()
    got = splat._rotation_bytes(q)
    want = splat_rotation_bytes(q)
    assert np.array_equal(got[0], want[0])
    assert got[1:] == want[1:]


def test_importance_sorted_records_are_the_records_of_the_importance_order(tmp_path):
    # The writer encodes in row order and gathers records; the same bytes as encoding the reordered scene.
    cols = random_columns(3000, seed=9)
    cols.update(model.static_columns(3000))
    scene = Scene(columns=cols, variant=model.VARIANT_3DGS)
    order = viewer.importance_order(viewer.importance(cols))
    moved = Scene(columns={name: np.asarray(c)[order] for name, c in cols.items()}, variant=model.VARIANT_3DGS)
    io.write(scene, tmp_path / "sorted.splat", sort="importance")
    io.write(moved, tmp_path / "moved.splat", sort="none")
    assert (tmp_path / "sorted.splat").read_bytes() == (tmp_path / "moved.splat").read_bytes()
