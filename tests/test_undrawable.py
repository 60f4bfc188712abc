"""Undrawable splats on scenes like real trained ones: counted by info and stats, removed by
--drop-undrawable, noted when they are a large share, and proven undrawable by pixels.

Every count is checked against this file's own numpy reading of the scene (:func:`kinds`),
never against :func:`splatconv.viewer.undrawable_counts`.
"""

from __future__ import annotations

import json
import re
import struct

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io
from splatconv.cli import main
from splatconv.model import COLUMNS, Scene
from splatconv.render.layout import float_attributes
from splatconv.render.sort import viewer_order

from .ops_helpers import CAMERA, coverage, moving_scene, view_of
from .real_scenes import real_scene, unpadded_splatv

KINDS = ("zero_rotation", "nan_position", "alpha_zero", "hidden_in_time")
WORDS = {"zero_rotation": "zero rotation", "nan_position": "NaN position", "alpha_zero": "alpha zero",
         "hidden_in_time": "hidden in time"}
#: A second camera, from the right and turned towards the scene.
SIDE = dict(CAMERA, id=1, img_name="side", position=[6.0, -1.0, -7.0],
            rotation=[[0.8, 0.0, -0.6], [0.0, 1.0, 0.0], [0.6, 0.0, 0.8]])


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def f64(cols: dict, name: str) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return np.asarray(cols[name], dtype=np.float64)


def kinds(cols: dict) -> np.ndarray:
    """Each splat's undrawable kind, the independent way: index into KINDS, -1 when drawable.

    Zero rotation and omega; a NaN position or motion term; an alpha byte of 0
    (sigmoid(opacity) * 255 rounds to 0, or NaN); the temporal opacity, best at the
    centre clamped to [0, 1], below 0.02 (the test scenes' hidden splats are far below it).
    """
    n = len(cols["x"])
    out = np.full(n, -1)
    zero = np.all([f64(cols, f"{g}_{i}") == 0 for g in ("rot", "omega") for i in range(4)], axis=0)
    nan = np.any([np.isnan(f64(cols, c)) for c in ["x", "y", "z"] + [f"motion_{i}" for i in range(9)]], axis=0)
    with np.errstate(over="ignore", invalid="ignore"):
        alpha = 255.0 / (1.0 + np.exp(-f64(cols, "opacity")))
        c = f64(cols, "trbf_center")
        u = (np.clip(c, 0.0, 1.0) - c) / np.exp(f64(cols, "trbf_scale"))
        best = np.exp(-u * u)
    tests = [zero, nan, np.isnan(alpha) | (np.rint(alpha) == 0), best < 0.02 * 0.999]
    for k, test in enumerate(tests):
        out[(out == -1) & test] = k
    return out


def counts(cols: dict) -> dict:
    k = kinds(cols)
    return {kind: int(np.count_nonzero(k == i)) for i, kind in enumerate(KINDS)}


def half(x: float) -> float:
    """The nearest half (saturating), the independent way."""
    try:
        return struct.unpack("<e", struct.pack("<e", x))[0]
    except OverflowError:
        return float(np.copysign(np.inf, x))


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory):
    """A real-like scene in memory, as a PLY and as an unpadded .splatv, and what it holds."""
    scene, rows = real_scene(600, seed=3)
    folder = tmp_path_factory.mktemp("real")
    io.write(scene, folder / "real.ply")
    unpadded_splatv(scene, folder / "real.splatv")
    return scene, rows, folder


def test_the_scene_has_every_kind_as_planted(scene_files):
    scene, rows, _ = scene_files
    assert counts(scene.columns) == {
        "zero_rotation": len(rows.zero_rotation),
        "nan_position": len(rows.nan_position) + len(rows.nan_motion),
        "alpha_zero": len(rows.alpha_zero) + len(rows.nan_opacity),
        "hidden_in_time": len(rows.hidden_in_time)}
    assert np.array_equal(np.flatnonzero(kinds(scene.columns) >= 0), rows.undrawable)


# --------------------------------------------------------------------------
# info and stats


@pytest.mark.parametrize("name", ["real.ply", "real.splatv"])
def test_info_counts_undrawable_and_flat_splats(scene_files, name):
    scene, rows, folder = scene_files
    result = run("info", folder / name, "--json")
    assert result.exit_code == 0, result.output
    info = json.loads(result.stdout)
    # The file read back, counted here: an unpadded .splatv gives what the scene in memory gives.
    cols = io.read(folder / name).columns
    assert info["undrawable"] == counts(cols) == counts(scene.columns)
    assert list(info["undrawable"]) == list(KINDS)
    flat = np.any([f64(cols, f"scale_{i}") == -np.inf for i in range(3)], axis=0)
    assert info["flat"] == int(flat.sum()) == len(rows.flat)
    # Values the viewer gives no meaning, written out here: NaN, and infinities but a log scale of
    # -inf (flat), a temporal scale of +inf (always visible), an infinite opacity or colour.
    for c in COLUMNS:
        v = f64(cols, c)
        meant = (((v == -np.inf) & c.startswith("scale_")) | ((v == np.inf) & (c == "trbf_scale"))
                 | (np.isinf(v) & (c == "opacity" or c.startswith("f_dc_"))))
        assert info["nonfinite"][c] == int((~np.isfinite(v) & ~meant).sum()), c
    assert all(info["nonfinite"][f"scale_{i}"] == 0 for i in range(3))  # flat splats are not non-finite
    assert info["nonfinite"]["trbf_scale"] == 0 and info["visible_always"] == len(rows.infinite_trbf)
    # info counts what --drop-nonfinite removes: every splat with a counted value, and no other.
    kept = run("convert", folder / name, folder / "kept.ply", "--drop-nonfinite", "--force")
    assert kept.exit_code == 0, kept.output
    removed = np.zeros(600, bool)
    for c in COLUMNS:
        v = f64(cols, c)
        meant = (((v == -np.inf) & c.startswith("scale_")) | ((v == np.inf) & (c == "trbf_scale"))
                 | (np.isinf(v) & (c == "opacity" or c.startswith("f_dc_"))))
        removed |= ~np.isfinite(v) & ~meant
    assert io.read(folder / "kept.ply").count == 600 - int(removed.sum())
    text = run("info", folder / name).stdout
    total = sum(counts(cols).values())
    listed = ", ".join(f"{WORDS[k]} {v:,}" for k, v in counts(cols).items() if v)
    assert (f"undrawable: {total:,} of 600 splats ({100 * total / 600:.3g}%) the viewer can never draw: "
            f"{listed}\n") in text
    assert f"flat:      {len(rows.flat)} splats with a zero scale (log scale -inf), drawn flat\n" in text


def drawn_over_time(cols: dict, times) -> list:
    """Splats drawn at each time, from the halves the viewer reads: drawable, and not below the cut."""
    c = np.vectorize(half)(f64(cols, "trbf_center"))
    with np.errstate(over="ignore"):
        s = np.vectorize(half)(np.exp(f64(cols, "trbf_scale")))
    drawable = kinds(cols) == -1
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        return [int(np.count_nonzero(drawable & ~(np.exp(-(((t - c) / s) ** 2)) < 0.02))) for t in times]


@pytest.mark.parametrize("name", ["real.ply", "real.splatv"])
def test_stats_counts_undrawable_and_never_counts_them_drawn(scene_files, name):
    scene, _, folder = scene_files
    result = run("stats", folder / name, "--json", "--zstd-level", "1")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    # What the viewer loads: the texture, as the unpadded file holds it (the PLY converts to the same).
    cols = io.read(folder / "real.splatv").columns
    assert data["undrawable"] == counts(cols) == counts(scene.columns)
    times = data["time"]["times"]
    drawn = drawn_over_time(cols, times)
    assert data["time"]["visible"] == drawn
    assert max(drawn) <= 600 - sum(counts(cols).values())
    text = " ".join(run("stats", folder / name, "--zstd-level", "1").stdout.split())
    # The PLY is described as converting would make it; the .splatv alone, as stored.
    role = "CONVERTED" if name.endswith(".ply") else "SOURCE"
    assert data["described"]["role"] == role.lower() and data["described"]["count"] == 600
    assert f"time ({role}): 20 steps over [0, 1]: {min(drawn):,} to {max(drawn):,} splats drawn" in text
    total = sum(counts(cols).values())
    assert (f"undrawable ({role}): {total:,} of 600 splats ({100 * total / 600:.3g}%) the viewer can never "
            "draw") in text


def test_a_splatv_splat_whose_stored_peak_is_just_under_the_cut_is_hidden_in_time(tmp_path):
    """The test is of the values a .splatv holds: the half centre and the half linear temporal scale the
    viewer reads. Here they give a best temporal opacity of 0.019849 over [0, 1]: never drawn. A half of the
    log scale (which no file stores) once made it 0.0201, drawable, and kept by every filter."""
    scene = moving_scene(50, seed=4)
    scene.columns["opacity"][0] = 0.0  # the far splat, visible now: nothing else undrawable
    centre_bits, scale_bits = 0xA55C, 0x216A
    c = scene.columns
    c["trbf_center"][7] = np.array([centre_bits], "<u2").view("<f2")[0]
    c["trbf_scale"][7] = np.log(np.array([scale_bits], "<u2").view("<f2")[0].astype(np.float64))
    path = tmp_path / "edge.splatv"
    io.write(scene, path, sort="none")
    # The record holds exactly these halves (word 15: centre low, linear scale high).
    data = path.read_bytes()
    start = 8 + struct.unpack("<I", data[4:8])[0]
    word = struct.unpack("<I", data[start + 64 * 7 + 60:start + 64 * 7 + 64])[0]
    assert (word & 0xFFFF, word >> 16) == (centre_bits, scale_bits)
    held = io.read(path).columns
    centre, scale = f64(held, "trbf_center")[7], np.exp(f64(held, "trbf_scale")[7])
    peak = np.exp(-(centre / scale) ** 2)  # the centre is below 0: best at t = 0
    assert 0.01984 < peak < 0.01985
    assert kinds(held)[7] == 3
    info = json.loads(run("info", path, "--json").stdout)
    assert info["undrawable"] == dict(counts(held), hidden_in_time=1)
    kept = tmp_path / "kept.splatv"
    assert run("convert", path, kept, "--drop-undrawable").exit_code == 0
    assert io.read(kept).count == 49


# --------------------------------------------------------------------------
# --drop-undrawable


def note_line(result, prefix: str) -> str:
    lines = [line for line in result.stderr.splitlines() if line.startswith(prefix)]
    assert len(lines) == 1, result.stderr
    return lines[0]


def test_convert_drop_undrawable_removes_them_and_says_how_many_of_each_kind(scene_files, tmp_path):
    scene, _, folder = scene_files
    out = tmp_path / "kept.ply"
    result = run("convert", folder / "real.ply", out, "--drop-undrawable", "--sort", "none")
    assert result.exit_code == 0, result.output
    expected = counts(scene.columns)
    total = sum(expected.values())
    listed = ", ".join(f"{WORDS[k]} {v:,}" for k, v in expected.items() if v)
    assert note_line(result, "note: drop-undrawable:") == (
        f"note: drop-undrawable: removed {total:,} of 600 splats the viewer can never draw ({listed})")
    kept = io.read(out)
    keep = kinds(scene.columns) == -1
    assert kept.count == int(keep.sum()) == 600 - total
    for name in COLUMNS:
        assert np.array_equal(kept.columns[name], scene.columns[name][keep], equal_nan=True), name
    # No note suggesting what was asked for.
    assert "--drop-undrawable` removes" not in result.stderr


def test_drop_undrawable_comes_first_so_max_splats_keeps_drawable_splats(scene_files, tmp_path):
    scene, _, folder = scene_files
    drawable = int(np.count_nonzero(kinds(scene.columns) == -1))
    out = tmp_path / "top.ply"
    result = run("convert", folder / "real.ply", out, "--max-splats", 100, "--drop-undrawable",
                 "--drop-nonfinite", "--sort", "none")
    assert result.exit_code == 0, result.output
    order = [line.split(":")[1].strip() for line in result.stderr.splitlines() if line.startswith("note: ")]
    assert order == ["drop-undrawable", "drop-nonfinite", "max-splats"]
    kept = io.read(out)
    assert kept.count == 100 and (kinds(kept.columns) == -1).all()
    assert drawable > 100


def test_drop_undrawable_with_none_to_remove(tmp_path):
    scene = moving_scene(50, seed=4)
    scene.columns["opacity"][0] = 0.0  # the far splat, visible now: nothing undrawable
    assert counts(scene.columns) == dict.fromkeys(KINDS, 0)
    src = tmp_path / "clean.ply"
    io.write(scene, src)
    result = run("convert", src, tmp_path / "out.splatv", "--drop-undrawable")
    assert result.exit_code == 0, result.output
    assert note_line(result, "note: drop-undrawable:") == (
        "note: drop-undrawable: removed 0 of 50 splats: the viewer can draw every one")


# --------------------------------------------------------------------------
# The note when undrawable splats are a large share


def share_scene(path, undrawable: int, n: int = 100):
    """A scene of ``n`` splats of which ``undrawable`` (at least 1: the far splat) are undrawable."""
    scene = moving_scene(n, seed=5)
    for name in ("rot_0", "rot_1", "rot_2", "rot_3", "omega_0", "omega_1", "omega_2", "omega_3"):
        scene.columns[name][1:undrawable] = 0.0
    assert sum(counts(scene.columns).values()) == undrawable
    io.write(scene, path)
    return path


NOTE = re.compile(r"^note: .*: (\d+) of ([\d,]+) splats \(([\d.]+)%\) can never be drawn \((.*)\); "
                  r"`splatconv convert --drop-undrawable` removes them$", re.M)


def test_a_note_suggests_drop_undrawable_from_a_tenth_of_the_splats(tmp_path):
    many = share_scene(tmp_path / "many.ply", 10)  # 10%: noted
    few = share_scene(tmp_path / "few.ply", 9)
    result = run("info", many)
    assert result.exit_code == 0
    assert NOTE.findall(result.stderr) == [("10", "100", "10", "zero rotation 9, alpha zero 1")]
    assert result.stderr.startswith(f"note: {many}: ")
    assert NOTE.findall(run("info", few).stderr) == []


@pytest.mark.parametrize("command", [
    ["info", "{a}"], ["stats", "{a}", "--zstd-level", "1"], ["render", "{a}", "{out}.png"],
    ["convert", "{a}", "{out}.splatv"], ["diff", "{a}", "{b}"], ["verify", "{a}", "{b}", "--times", "0.5"],
    ["bake", "{a}", "{out}.ply", "--time", "0.5"], ["merge", "{a}", "{b}", "{out}.splatv"],
])
def test_every_command_that_reads_a_scene_notes_it_once(scene_files, tmp_path, command):
    _, _, folder = scene_files
    args = [part.format(a=folder / "real.splatv", b=folder / "real.ply", out=tmp_path / "out") for part in command]
    result = run(*args)
    assert len(NOTE.findall(result.stderr)) == 1, result.stderr  # two scenes read (or one twice): one note
    assert "can never be drawn (" not in result.stdout  # notes go to stderr


def test_no_note_with_drop_undrawable(scene_files, tmp_path):
    _, _, folder = scene_files
    result = run("convert", folder / "real.splatv", tmp_path / "out.splatv", "--drop-undrawable")
    assert result.exit_code == 0, result.output
    assert NOTE.findall(result.stderr) == []


# --------------------------------------------------------------------------
# Proof by pixels: removing them changes no pixel of any frame.

TIMES = np.linspace(0.0, 1.0, 9)


def record_map(kept: np.ndarray, full: np.ndarray) -> np.ndarray:
    """For each record of ``kept`` ((K, 16) uint32), the index of the byte-identical record of ``full``."""
    keys = {full[i].tobytes(): i for i in range(len(full))}
    assert len(keys) == len(full), "every record of the full file is distinct"
    return np.array([keys[r.tobytes()] for r in kept])


def carried(order: np.ndarray, index: np.ndarray, size: int, filler: int) -> np.ndarray:
    """``order`` (one file's draw order) in another file's record numbers: ``index[i]`` is record i's number
    there, -1 for none (left out); padded to ``size`` with ``filler`` (a record that draws nothing)."""
    mapped = index[order]
    mapped = mapped[mapped >= 0]
    return np.concatenate([mapped, np.full(size - len(mapped), filler)]).astype(np.int32)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dropping_undrawable_splats_changes_no_pixel(renderer, tmp_path, seed):
    """The .splatv of a real-like scene and the one ``convert --drop-undrawable`` writes from it draw
    byte-identical frames at 9 times in [0, 1] from two cameras, through the texture and the float path.

    Both files are drawn in one draw order: the viewer's for one file, carried over to the other
    (the removed records left out, or drawn last). The viewer's own sort cannot be used on both:
    it spreads 65,536 depth buckets between the nearest and farthest record, drawn or not, leaves
    out the farthest record when a float rounds so, and draws record 0 in its place (see
    :func:`tests.ops_helpers.moving_scene`). Removing any record that sets the depth range (as
    moving_scene's far splat, an alpha-0 one, does here) moves the buckets, so splats of nearly
    equal depth may swap and another splat becomes the farthest; the draw order changes, though no
    removed splat was ever drawn. Holding the order leaves one question: do the removed splats add
    anything to any pixel? They must not, wherever in the order they are drawn.
    """
    scene, rows = real_scene(600, seed)
    scene.cameras = [dict(CAMERA), dict(SIDE)]
    full_path, kept_path = tmp_path / "full.splatv", tmp_path / "kept.splatv"
    unpadded_splatv(scene, full_path)
    result = run("convert", full_path, kept_path, "--drop-undrawable")
    assert result.exit_code == 0, result.output
    full, full_scene = io.read_texture(full_path)
    kept, kept_scene = io.read_texture(kept_path)
    n_full, n_kept = full_scene.count, kept_scene.count
    assert n_kept == 600 - len(rows.undrawable) and n_kept > 250
    to_full = record_map(kept[:n_kept], full[:n_full])
    # Every record kept is a drawable splat of the full file, and every drawable one is kept.
    assert sorted(to_full) == list(np.flatnonzero(kinds(full_scene.columns) == -1))
    to_kept = np.full(len(full), -1)
    to_kept[to_full] = np.arange(n_kept)
    to_kept[n_full:] = -1  # the full file's padding: not in the kept file's order
    kept_padding, full_padding = len(kept) - 1, len(full) - 1  # zero records: draw nothing
    assert kept_padding >= n_kept and full_padding >= n_full
    # The full file's records the kept one lacks (undrawable ones first, then padding), drawn after
    # the kept order in the full file, as many as the full file's record count leaves room for.
    removed = np.setdiff1d(np.arange(len(full)), to_full)
    undrawable = n_full - n_kept
    paths = {
        "texture": (lambda r: r.load_records(full), lambda r: r.load_records(kept)),
        "float": (lambda r: r.load_float(float_attributes(full_scene, None, len(full))),
                  lambda r: r.load_float(float_attributes(kept_scene, None, len(kept)))),
    }
    drawn = 0
    for path, (load_full, load_kept) in paths.items():
        for camera in scene.cameras:
            view = view_of(camera)
            full_order = viewer_order(full[:, 0:3].view(np.float32), view.view_proj())
            kept_order = viewer_order(kept[:, 0:3].view(np.float32), view.view_proj())
            seq = to_full[kept_order[kept_order < n_kept]]
            tail = removed[:len(full) - len(seq)]
            assert len(tail) >= undrawable  # every removed splat is drawn in b
            kept_in_full = np.concatenate([seq, tail]).astype(np.int32)
            for t in TIMES:
                load_full(renderer)
                a = renderer.draw(view, float(t))  # the full file as the viewer draws it
                b = renderer.draw(view, float(t), order=kept_in_full)  # in the kept file's order, removed last
                load_kept(renderer)
                c = renderer.draw(view, float(t), order=carried(full_order, to_kept, len(kept), kept_padding))
                d = renderer.draw(view, float(t))  # the kept file as the viewer draws it
                where = f"{path} camera {camera['id']} t={t:g}"
                assert coverage(a) > 0.2, where
                assert np.array_equal(a, c), where
                assert np.array_equal(b, d), where
                drawn += 1
    assert drawn == 2 * 2 * len(TIMES)


def test_the_splats_kept_are_drawn(renderer):
    """The pixel test above can fail: the drawable kinds that look broken do change frames when removed."""
    scene, rows = real_scene(600, seed=0)
    for planted in (rows.zero_rotation_spinning, rows.flat, rows.infinite_trbf):
        keep = np.ones(600, bool)
        keep[planted] = False
        without = Scene({k: v[keep] for k, v in scene.columns.items()}, cameras=scene.cameras)
        view = view_of(CAMERA)
        changed = 0
        for t in TIMES:
            renderer.load_float(float_attributes(scene))
            a = renderer.draw(view, float(t), order=None)
            order = renderer.last_order
            renderer.load_float(float_attributes(without))
            index = np.full(600, -1)
            index[keep] = np.arange(int(keep.sum()))
            # Row 0 (the invisible far splat, kept) fills the order's end: it draws nothing.
            b = renderer.draw(view, float(t), order=carried(order, index, int(keep.sum()), 0))
            changed += not np.array_equal(a, b)
        assert changed, planted


def with_anchors(scene: Scene) -> Scene:
    """``scene`` with two drawable splats that hold the viewer's depth range and its record 0.

    One far ahead (faint, large: the most important splat, so record 0 of the .splatv)
    and one far behind the camera (never on screen). The nearest and the farthest record
    from either camera are then drawable splats, in both files.
    """
    extra = {name: np.zeros(2, np.float32) for name in COLUMNS}
    extra["x"][:], extra["y"][:], extra["z"][:] = 0.3, -0.2, [1000.0, -1000.0]
    extra["rot_0"][:] = 1.0
    for i in range(3):
        extra[f"scale_{i}"][:] = np.log(50.0)
        extra[f"f_dc_{i}"][:] = 0.5
    extra["opacity"][:] = np.log(3.0 / 252.0)  # alpha byte 3
    extra["trbf_center"][:], extra["trbf_scale"][:] = 0.5, np.log(1e4)
    cols = {name: np.concatenate([scene.columns[name], extra[name]]) for name in COLUMNS}
    return Scene(cols, cameras=scene.cameras)


@pytest.mark.parametrize("seed", [0, 1])
def test_with_drawable_depth_extremes_the_viewer_draws_the_same_frames(renderer, tmp_path, seed):
    """The viewer's own draw order on both files: identical frames once the records that set its depth
    range and record 0 are drawable splats (what the order-holding test above leaves to chance)."""
    scene, rows = real_scene(600, seed)
    scene = with_anchors(scene)
    scene.cameras = [dict(CAMERA), dict(SIDE)]
    full_path, kept_path = tmp_path / "full.splatv", tmp_path / "kept.splatv"
    unpadded_splatv(scene, full_path)
    assert run("convert", full_path, kept_path, "--drop-undrawable").exit_code == 0
    full, full_scene = io.read_texture(full_path)
    kept, kept_scene = io.read_texture(kept_path)
    assert kept_scene.count == 602 - len(rows.undrawable)
    assert np.array_equal(full[0], kept[0])  # record 0: the far anchor in both
    for camera in scene.cameras:
        view = view_of(camera)
        for t in TIMES:
            frames = []
            for records, decoded in ((full, full_scene), (kept, kept_scene)):
                renderer.load_records(records)
                texture = renderer.draw(view, float(t))
                renderer.load_float(float_attributes(decoded, None, len(records)))
                frames.append((texture, renderer.draw(view, float(t))))
            where = f"camera {camera['id']} t={t:g}"
            assert coverage(frames[0][0]) > 0.2, where
            assert np.array_equal(frames[0][0], frames[1][0]), "texture " + where
            assert np.array_equal(frames[0][1], frames[1][1]), "float " + where


@pytest.mark.parametrize("zero_share, noted", [(0.4, True), (0.0, False)])
def test_a_large_scene_is_noted_with_exact_counts_after_its_probe(zero_share, noted, tmp_path):
    # From 65,536 splats a probe of every 16th row decides whether to count the scene whole: the
    # note's figures are still the whole scene's, counted here by numpy.
    scene, _ = real_scene(600, seed=4, zero_share=zero_share)
    reps = 70_000 // 600 + 1
    big = Scene({k: np.tile(v, reps)[:70_000] for k, v in scene.columns.items()}, cameras=scene.cameras)
    mine = counts(big.columns)
    heard = []
    with io.noting_undrawable(heard.append):
        io._check_undrawable(big, tmp_path / "big.ply")
    total = sum(mine.values())
    assert (total >= 0.1 * 70_000) == noted
    if noted:
        listed = ", ".join(f"{WORDS[k]} {v:,}" for k, v in mine.items() if v)
        assert heard == [f"{tmp_path / 'big.ply'}: {total:,} of 70,000 splats ({100 * total / 70_000:.3g}%) can never "
                         f"be drawn ({listed}); `splatconv convert --drop-undrawable` removes them"]
    else:
        assert heard == []
