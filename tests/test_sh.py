"""SH bands of degrees 1 to 3 kept in the model: read, written, and carried through every edit."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, model, sh
from splatconv.cli import main
from splatconv.model import Scene
from splatconv.ops import apply_transform, make_transform
from splatconv.ops.edit import EditPlan, apply_edits
from splatconv.ops.filters import crop
from splatconv.ops.merge import overlay

from .conftest import GS_PROPS, write_ply
from .scenes import gs_columns


def sh_scene(n: int = 400, degree: int = 3, seed: int = 1) -> Scene:
    """A static 3DGS scene with SH bands of ``degree`` (each f_rest_i distinct)."""
    cols = gs_columns(n, GS_PROPS, seed)
    columns = {name: cols[name] for name in model.POSITION + model.COLOR + model.OPACITY + model.SCALE
               + model.ROTATION}
    columns.update(model.static_columns(n))
    columns.update((name, cols[name]) for name in model.sh_names(degree))
    return Scene(columns=columns, variant=model.VARIANT_3DGS)


def coefficients(columns: dict) -> np.ndarray:
    """The SH bands as ``(N, 3, K)``: channel-major, as the ``f_rest_{c * K + k}`` names say."""
    degree = model.sh_degree(columns)
    k = model.SH_COEFFS[degree]
    return np.stack([np.asarray(columns[name], np.float64) for name in model.sh_names(degree)], 1).reshape(-1, 3, k)


def unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_rotating_a_scene_turns_its_sh_with_it(degree):
    """Colour seen along d before is the colour seen along R d after, for each splat and channel."""
    scene = sh_scene(degree=degree)
    transform = make_transform(rotate="x:30,y:-70,z:115")
    moved, report = apply_transform(scene, transform)
    r = np.asarray(transform.matrix)
    d = unit(np.random.default_rng(5).normal(size=(scene.count, 3)))
    before = sh.evaluate(coefficients(scene.columns), d)
    after = sh.evaluate(coefficients(moved.columns), d @ r.T)
    assert np.abs(after - before).max() < 1e-5
    assert not np.allclose(coefficients(moved.columns), coefficients(scene.columns))
    assert "SH bands" in report.notes[0]


def test_sh_rotation_matrix_is_orthogonal_and_identity_for_no_turn():
    m = sh.rotation_matrix(np.eye(3), 3)
    assert np.abs(m - np.eye(15)).max() < 1e-12
    r = np.asarray(make_transform(rotate="quat:0.3,-0.2,0.9,0.1").matrix)
    m = sh.rotation_matrix(r, 3)
    assert np.abs(m @ m.T - np.eye(15)).max() < 1e-12


def test_scale_and_translate_keep_sh_as_they_are():
    scene = sh_scene()
    moved, _ = apply_transform(scene, make_transform(translate=(1, 2, 3), scale=2.5))
    for name in model.SH_REST:
        assert np.array_equal(moved.columns[name], scene.columns[name]), name


def test_crop_and_edits_keep_each_splats_sh():
    scene = sh_scene()
    lo, hi = (-0.5, -2.0, -2.0), (2.0, 2.0, 2.0)
    cropped, _ = crop(scene, lo, hi)
    assert 0 < cropped.count < scene.count and cropped.sh_degree == 3
    x = np.asarray(scene.columns["x"])
    kept = np.flatnonzero(np.isin(x, np.asarray(cropped.columns["x"])))
    assert np.array_equal(cropped.columns["f_rest_17"], np.asarray(scene.columns["f_rest_17"])[kept])
    # the edit planner's one pass (crop, then a turn of the survivors) keeps and turns them too
    transform = make_transform(rotate="z:90")
    edited, _ = apply_edits(scene, EditPlan(crop=(lo, hi), transform=transform, min_opacity=0.0))
    assert edited.count == cropped.count and edited.sh_degree == 3
    turned, _ = apply_transform(cropped, transform)
    assert np.allclose(coefficients(edited.columns), coefficients(turned.columns), atol=1e-6)


def test_merge_keeps_a_common_degree_and_cuts_to_the_lowest():
    a, b = sh_scene(100, 3, seed=1), sh_scene(50, 3, seed=2)
    merged, report = overlay([a, b])
    assert merged.sh_degree == 3 and merged.count == 150
    assert np.array_equal(merged.columns["f_rest_44"][100:], b.columns["f_rest_44"])
    mixed, report = overlay([a, sh_scene(50, 1, seed=3)])
    assert mixed.sh_degree == 1
    assert any(n.startswith("SH bands: input 1 cut to degree 1") for n in report.notes)


def test_scene_refuses_a_partial_set_of_bands():
    cols = dict(sh_scene(10, 1).columns)
    del cols["f_rest_8"]
    with pytest.raises(ValueError, match="not those of one SH degree"):
        Scene(columns=cols)


def test_partial_f_rest_in_a_ply_is_dropped_with_a_note(tmp_path):
    cols = gs_columns(20, GS_PROPS)
    names = [n for n in GS_PROPS if n not in model.SH_REST] + ["f_rest_0", "f_rest_1"]
    scene = io.read(write_ply(tmp_path / "partial.ply", {n: cols[n] for n in names}))
    assert scene.sh_degree == 0
    assert any(n.startswith("2 higher-order SH coefficients (f_rest_*) dropped") for n in scene.notes)


@pytest.mark.parametrize("suffix", [".splat", ".splatv"])
def test_colour_only_formats_say_they_drop_the_bands(tmp_path, gs_ply, suffix):
    out = tmp_path / f"out{suffix}"
    r = CliRunner().invoke(main, ["convert", str(gs_ply), str(out)])
    assert r.exit_code == 0, r.output
    assert f"note: dropped SH degree 1\u20133 bands: a {suffix} file holds colour only" in r.stderr


def test_rotate_through_the_cli_keeps_degree_three(tmp_path, gs_ply):
    out = tmp_path / "turned.ply"
    r = CliRunner().invoke(main, ["convert", str(gs_ply), str(out), "--rotate", "y:90"])
    assert r.exit_code == 0, r.output
    src, back = io.read(gs_ply), io.read(out)
    assert back.sh_degree == 3
    r_ = np.asarray(make_transform(rotate="y:90").matrix)
    d = unit(np.random.default_rng(2).normal(size=(src.count, 3)))
    assert np.abs(sh.evaluate(coefficients(back.columns), d @ r_.T)
                  - sh.evaluate(coefficients(src.columns), d)).max() < 1e-4


def test_bake_of_a_static_scene_keeps_its_bands():
    from splatconv.ops.bake import bake

    scene = sh_scene(200, 2)
    baked, _ = bake(scene, 0.3)
    assert baked.sh_degree == 2 and baked.count == scene.count
    assert np.array_equal(baked.columns["f_rest_23"], scene.columns["f_rest_23"])
