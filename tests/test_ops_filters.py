"""Clean-up filters on hand-made scenes whose survivors are known; NaN- and inf-laden input; the edit pipeline."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, viewer
from splatconv.cli import main
from splatconv.errors import UsageError
from splatconv.model import COLUMNS, Scene
from splatconv.ops import filters
from splatconv.ops import (EditPlan, apply_edits, apply_transform, crop, drop_nonfinite, drop_undrawable,
                           make_transform, max_splats, min_opacity, trim)
from tests.cli_checks import error_line
from tests.ops_helpers import moving_scene


def plain(n: int) -> dict:
    """n harmless splats; row i has f_dc_0 = i / 1000 so survivors can be named."""
    cols = {name: np.zeros(n, np.float32) for name in COLUMNS}
    cols["rot_0"][:] = 1
    cols["trbf_center"][:] = 0.5
    cols["f_dc_0"][:] = np.arange(n) / 1000
    return cols


def ids(scene: Scene) -> list:
    return [int(round(v * 1000)) for v in scene.columns["f_dc_0"]]


# --------------------------------------------------------------------------
# drop-nonfinite

# (column, value, removed?)
NONFINITE_CASES = [(name, value, True) for name in
                   ("x", "y", "z", "rot_0", "rot_3", "motion_0", "motion_8", "omega_2", "trbf_center")
                   for value in (math.nan, math.inf, -math.inf)] + [
    # A log scale of -inf is a linear scale of 0: a flat splat, which the viewer draws.
    ("scale_0", math.nan, True), ("scale_1", math.inf, True), ("scale_1", -math.inf, False),
    ("scale_2", -math.inf, False),
    ("trbf_scale", math.nan, True), ("trbf_scale", -math.inf, True), ("trbf_scale", math.inf, False),
    ("opacity", math.nan, True), ("opacity", math.inf, False), ("opacity", -math.inf, False),
    ("f_dc_1", math.nan, True), ("f_dc_1", math.inf, False), ("f_dc_2", -math.inf, False),
]


@pytest.mark.parametrize("name, value, removed", NONFINITE_CASES)
def test_drop_nonfinite_one_value(name, value, removed):
    cols = plain(4)
    cols[name][2] = value
    out, report = drop_nonfinite(Scene(cols))
    assert ids(out) == ([0, 1, 3] if removed else [0, 1, 2, 3])
    assert report.removed == int(removed)


def test_drop_nonfinite_counts_per_group_and_leaves_the_input_alone():
    cols = plain(10)
    cols["x"][1] = np.nan
    cols["y"][1] = np.inf  # same splat, same group: counted once
    cols["motion_4"][1] = np.nan  # same splat, another group
    cols["rot_2"][3] = -np.inf
    cols["trbf_scale"][5] = np.nan
    cols["trbf_scale"][6] = np.inf  # kept
    cols["opacity"][7] = np.nan
    cols["f_dc_2"][8] = np.nan
    scene = Scene(cols)
    before = {k: v.copy() for k, v in cols.items()}
    out, report = drop_nonfinite(scene)
    assert ids(out) == [0, 2, 4, 6, 9]
    assert report.counts == {"position": 1, "motion": 1, "rotation": 1, "trbf scale": 1, "opacity": 1, "color": 1}
    assert report.notes == ["drop-nonfinite: removed 5 of 10 splats with a NaN or infinite value (position 1, "
                            "rotation 1, motion 1, trbf scale 1, opacity 1, color 1; a splat may count in several)"]
    for k in COLUMNS:
        assert np.array_equal(scene.columns[k], before[k], equal_nan=True)
    assert out.notes == report.notes


def test_drop_nonfinite_on_a_large_scene_matches_a_plain_isfinite_reference():
    """The chunked sum-of-zeros mask against the obvious definition, across chunk edges."""
    rng = np.random.default_rng(9)
    n = 70_000
    cols = {k: rng.normal(size=n).astype(np.float32) for k in COLUMNS}
    specials = np.array([np.nan, np.inf, -np.inf], np.float32)
    for k in COLUMNS:
        rows = rng.choice(n, 40, replace=False)
        cols[k][rows] = specials[rng.integers(0, 3, 40)]
    out, report = drop_nonfinite(Scene(cols))
    bad = np.zeros(n, bool)
    for k in COLUMNS:
        v = cols[k]
        if k == "trbf_scale":
            bad |= np.isnan(v) | (v == -np.inf)
        elif k in ("scale_0", "scale_1", "scale_2"):
            bad |= np.isnan(v) | (v == np.inf)
        elif k in ("opacity", "f_dc_0", "f_dc_1", "f_dc_2"):
            bad |= np.isnan(v)
        else:
            bad |= ~np.isfinite(v)
    assert report.removed == bad.sum() and out.count == n - bad.sum()
    assert np.array_equal(out.columns["x"], cols["x"][~bad])


# --------------------------------------------------------------------------
# min-opacity


def test_min_opacity_keeps_peak_opacity_at_or_above():
    cols = plain(6)
    cols["opacity"][:] = [viewer.logit(0.1), viewer.logit(0.5), np.nan, np.inf, -np.inf, viewer.logit(0.3)]
    out, report = min_opacity(Scene(cols), 0.3)
    assert ids(out) == [1, 3, 5]
    assert report.notes == ["min-opacity: removed 3 of 6 splats with peak opacity below 0.3"]
    out, _ = min_opacity(Scene(cols), 0.0)
    assert ids(out) == [0, 1, 3, 4, 5]  # only NaN is below 0
    with pytest.raises(UsageError, match="--min-opacity"):
        min_opacity(Scene(cols), 1.5)


@pytest.mark.parametrize("minimum", [0.0, 1e-300, 0.02, 0.5, 0.999999, 1.0])
def test_min_opacity_threshold_decides_as_the_sigmoid(minimum):
    # The mask compares the float32 opacity with one threshold: it must keep exactly the rows
    # whose float64 sigmoid reaches the minimum, at the threshold's neighbours too.
    least = filters.opacity_threshold(minimum)
    bits = int(np.array([least], np.float32).view(np.uint32)[0])
    near = (np.arange(bits - 2000, bits + 2000) % (1 << 32)).astype(np.uint32).view(np.float32)
    values = np.concatenate([near, np.random.default_rng(0).normal(0, 30, 20_000).astype(np.float32),
                             np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 3e38, -3e38], np.float32)])
    cols = {"opacity": values, "x": values}
    with np.errstate(invalid="ignore"):
        expected = viewer.opacity(cols) >= minimum
    assert np.array_equal(filters.opacity_mask(cols, minimum), expected)


# --------------------------------------------------------------------------
# crop


def test_crop_uses_the_centre_at_the_time_of_peak_opacity():
    cols = plain(6)
    cols["motion_0"][:] = 1.0  # moving along +x at one unit per clip
    # peak time = trbf centre clamped to [0, 1]; x at it = x + (t - centre)
    cols["trbf_center"][:] = [0.5, 1.5, -0.5, 0.2, np.nan, 0.5]
    cols["x"][:] = [0.0, 0.0, 0.0, 0.45, 0.0, 0.2]
    # x at peak: 0 (t .5), -0.5 (t 1), 0.5 (t 0), 0.45 (t .2), NaN, 0.2
    out, report = crop(Scene(cols), (-0.5, -1, -1), (0.45, 1, 1))
    assert ids(out) == [0, 1, 3, 5]  # bounds inclusive; NaN never inside
    assert report.removed == 2
    assert report.notes == ["crop: removed 2 of 6 splats whose centre at peak opacity lies outside "
                            "(-0.5, -1, -1) .. (0.45, 1, 1)"]


def test_crop_counts_the_undrawable_splats_it_keeps():
    cols = plain(8)
    cols["x"][6:] = 5.0  # outside the box
    for name in ("rot_0", "rot_1", "rot_2", "rot_3"):
        cols[name][[1, 2, 6]] = 0.0  # zero rotation: never drawn (row 6 is outside)
    cols["opacity"][3] = -np.inf  # alpha zero
    out, report = crop(Scene(cols), (-1, -1, -1), (1, 1, 1))
    assert ids(out) == [0, 1, 2, 3, 4, 5] and report.removed == 2
    assert report.counts == {"zero_rotation": 2, "nan_position": 0, "alpha_zero": 1, "hidden_in_time": 0}
    assert len(report.notes) == 2 and "zero rotation 2" in report.notes[1] and "alpha zero 1" in report.notes[1]
    # The pipeline says the same; after --drop-undrawable (which comes first) the box keeps none.
    edited, reports = apply_edits(Scene(cols), EditPlan(crop=((-1, -1, -1), (1, 1, 1))))
    assert reports[0].counts == report.counts and reports[0].notes == report.notes
    edited, reports = apply_edits(Scene(cols), EditPlan(drop_undrawable=True, crop=((-1, -1, -1), (1, 1, 1))))
    assert ids(edited) == [0, 4, 5] and sum(reports[1].counts.values()) == 0 and len(reports[1].notes) == 1


def test_convert_crop_notes_the_undrawable_splats_in_the_box(tmp_path):
    cols = plain(40)
    cols["x"][:] = np.linspace(-2, 2, 40)
    for name in ("rot_0", "rot_1", "rot_2", "rot_3"):
        cols[name][::4] = 0.0  # every fourth: zero rotation
    src = tmp_path / "in.ply"
    io.write(Scene(cols), src)
    result = CliRunner().invoke(main, ["convert", str(src), str(tmp_path / "out.splatv"), "--crop", "-1,-1,-1,1,1,1"])
    assert result.exit_code == 0, result.output
    kept = io.read(tmp_path / "out.splatv")
    undrawable = int(viewer.undrawable(kept.columns).sum())
    assert undrawable > 0
    line = next(line for line in result.stderr.splitlines() if "can never draw" in line)
    assert line.startswith(f"note: crop: {undrawable:,} of the {kept.count:,} splats kept")
    assert f"zero rotation {undrawable:,}" in line


@pytest.mark.parametrize("lo, hi", [((-0.1, -1e-8, -1e39), (0.1, 2.000000001, 1e39)), ((1e39, 0, 0), (1e40, 1, 1)),
                                    ((-1e40, -1, -1), (-1e39, 1, 1))])
def test_crop_bounds_decide_as_in_float64(lo, hi):
    # The positions are compared with float32 bounds: at and around each bound (and at the
    # infinities) they must decide as the float64 bounds do.
    edges = []
    for v in lo + hi:
        with np.errstate(over="ignore"):
            f = np.float32(v)
        edges += [f, np.nextafter(f, np.float32(np.inf)), np.nextafter(f, np.float32(-np.inf))]
    edges = np.array(edges + [np.inf, -np.inf, np.nan, 0.0], np.float32)
    grid = np.stack(np.meshgrid(edges, edges, edges, indexing="ij"), axis=-1).reshape(-1, 3)
    cols = plain(len(grid))
    for i, name in enumerate("xyz"):
        cols[name][:] = grid[:, i]
    wide = grid.astype(np.float64)
    expected = ((wide >= np.array(lo)) & (wide <= np.array(hi))).all(axis=1)
    assert np.array_equal(filters.crop_mask(cols, lo, hi), expected)


@pytest.mark.parametrize("lo, hi, message", [((1, 0, 0), (0, 1, 1), "empty along x"),
                                             ((0, 0, math.nan), (1, 1, 1), "six finite numbers")])
def test_bad_crop_box(lo, hi, message):
    with pytest.raises(UsageError, match=message):
        crop(Scene(plain(2)), lo, hi)


# --------------------------------------------------------------------------
# max-splats


def test_max_splats_keeps_the_most_important_in_input_order():
    cols = plain(7)
    # importance = exp(s0 + s1 + s2) * sigmoid(opacity): vary the first scale
    cols["scale_0"][:] = [0.0, 2.0, 1.0, np.nan, 2.0, -1.0, 3.0]
    out, report = max_splats(Scene(cols), 3)
    assert ids(out) == [1, 4, 6]  # 6 first, then the tie 1/4: both fit
    out, _ = max_splats(Scene(cols), 2)
    assert ids(out) == [1, 6]  # of the tie, the earlier row
    out, _ = max_splats(Scene(cols), 6)
    assert ids(out) == [0, 1, 2, 4, 5, 6]  # NaN goes last
    out, report = max_splats(Scene(cols), 10)
    assert out.count == 7 and report.removed == 0
    out, _ = max_splats(Scene(cols), 0)
    assert out.count == 0


# --------------------------------------------------------------------------
# NaN- and inf-laden input through every op, no RuntimeWarning (pytest makes them errors)


def laden(n: int = 2000, seed: int = 0) -> Scene:
    scene = moving_scene(n, seed)
    rng = np.random.default_rng(seed)
    specials = np.array([np.nan, np.inf, -np.inf], np.float32)
    for name in COLUMNS:
        rows = rng.choice(np.arange(1, n), 15, replace=False)
        scene.columns[name][rows] = specials[rng.integers(0, 3, 15)]
    return scene


def test_every_op_takes_nan_and_inf_without_warnings():
    scene = laden()
    drop_nonfinite(scene)
    min_opacity(scene, 0.2)
    crop(scene, (-1, -1, -1), (1, 1, 1))
    max_splats(scene, 100)
    trim(scene, 0.1, 0.4)
    moved, report = apply_transform(scene, make_transform((1, 2, 3), "x:37,z:-20", 3.0))
    # A vector with a non-finite component stays non-finite; a finite one stays finite (nothing
    # here is near float32's limits).
    for group in (("x", "y", "z"), ("motion_3", "motion_4", "motion_5"), ("rot_0", "rot_1", "rot_2", "rot_3"),
                  ("omega_0", "omega_1", "omega_2", "omega_3"), ("scale_2",)):
        finite_in = np.all([np.isfinite(scene.columns[n]) for n in group], axis=0)
        finite_out = np.all([np.isfinite(moved.columns[n]) for n in group], axis=0)
        assert np.array_equal(finite_in, finite_out), group
    cleaned, _ = drop_nonfinite(moved)
    assert all(np.isfinite(cleaned.columns[k]).all() for k in ("x", "y", "z", "motion_0", "omega_0", "rot_0"))


# --------------------------------------------------------------------------
# The pipeline equals the ops one after another


PLANS = [
    EditPlan(drop_nonfinite=True, trim=(0.2, 0.7), crop=((-2, -1.5, -1), (2, 1.5, 1.5)), min_opacity=0.3,
             max_splats=150, transform=make_transform((1, 0, -2), "y:30", 1.5)),
    EditPlan(drop_nonfinite=True, min_opacity=0.5),
    EditPlan(drop_undrawable=True, drop_nonfinite=True, trim=(0.1, 0.9), max_splats=150),
    EditPlan(drop_undrawable=True),
    EditPlan(crop=((-1, -1, -1), (1, 1, 1)), max_splats=50),
    EditPlan(max_splats=10_000),
    EditPlan(transform=make_transform(None, "x:180", None)),
    EditPlan(trim=(0.0, 1.0)),
]


@pytest.mark.parametrize("plan", PLANS)
def test_pipeline_equals_ops_in_order(plan):
    scene = laden(seed=2)
    for name in ("rot_0", "rot_1", "rot_2", "rot_3", "omega_0", "omega_1", "omega_2", "omega_3"):
        scene.columns[name][100:400] = 0.0  # zero rotations, as trained scenes hold: undrawable
    out, reports = apply_edits(scene, plan)
    step, expected = scene, []
    if plan.drop_undrawable:
        step, r = drop_undrawable(step)
        expected.append(r)
    if plan.drop_nonfinite:
        step, r = drop_nonfinite(step)
        expected.append(r)
    if plan.trim:
        step, r = trim(step, *plan.trim)
        expected.append(r)
    if plan.crop:
        step, r = crop(step, *plan.crop)
        expected.append(r)
    if plan.min_opacity is not None:
        step, r = min_opacity(step, plan.min_opacity)
        expected.append(r)
    if plan.max_splats is not None:
        step, r = max_splats(step, plan.max_splats)
        expected.append(r)
    if plan.transform is not None:
        step, r = apply_transform(step, plan.transform)
        expected.append(r)
    assert [r.notes for r in reports] == [r.notes for r in expected]
    assert [(r.op, r.count_in, r.count_out) for r in reports] == [(r.op, r.count_in, r.count_out) for r in expected]
    for name in COLUMNS:
        assert np.array_equal(out.columns[name], step.columns[name], equal_nan=True), name
    assert out.cameras == step.cameras
    assert out.notes == scene.notes + [n for r in expected for n in r.notes]


def test_pipeline_without_removals_copies_nothing():
    scene = moving_scene(50)
    out, reports = apply_edits(scene, EditPlan(min_opacity=0.0, max_splats=100))
    assert out.columns is scene.columns and [r.removed for r in reports] == [0, 0]


# --------------------------------------------------------------------------
# On the command line


def test_convert_drop_nonfinite_reports_true_counts(tmp_path):
    cols = plain(10)
    cols["x"][[2, 5]] = np.nan
    cols["omega_1"][7] = np.inf
    src = tmp_path / "in.ply"
    io.write(Scene(cols), src)
    result = CliRunner().invoke(main, ["convert", str(src), str(tmp_path / "out.splatv"), "--drop-nonfinite"])
    assert result.exit_code == 0, result.output
    assert "note: drop-nonfinite: removed 3 of 10 splats with a NaN or infinite value (position 2, omega 1; " \
           "a splat may count in several)\n" in result.stderr
    assert result.stdout.startswith(f"wrote {tmp_path / 'out.splatv'}: 7 splats")


def test_convert_max_splats_with_sort_none_keeps_input_order(tmp_path):
    cols = plain(8)
    cols["scale_2"][:] = [0, 5, 1, 4, 2, 3, 6, -1]
    src = tmp_path / "in.ply"
    io.write(Scene(cols), src)
    out = tmp_path / "out.ply"
    result = CliRunner().invoke(main, ["convert", str(src), str(out), "--max-splats", "3", "--sort", "none"])
    assert result.exit_code == 0, result.output
    assert ids(io.read(out)) == [1, 3, 6]
    assert "note: max-splats: kept the 3 most important of 8 splats, removed 5\n" in result.stderr


def test_convert_without_edits_writes_the_same_bytes(tmp_path):
    src = tmp_path / "in.ply"
    io.write(moving_scene(200), src)
    CliRunner().invoke(main, ["convert", str(src), str(tmp_path / "a.splatv")])
    result = CliRunner().invoke(main, ["convert", str(src), str(tmp_path / "b.splatv"), "--min-opacity", "0",
                                       "--scale", "1"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "a.splatv").read_bytes() == (tmp_path / "b.splatv").read_bytes()


@pytest.mark.parametrize("args, message", [
    (["--crop", "1,2,3"], "Error: Invalid value for '--crop': '1,2,3': expected 6 numbers separated by commas "
                          "(X0,Y0,Z0,X1,Y1,Z1). See 'main convert --help'.\n"),
    (["--crop", "0,0,0,1,1,-1"], "Error: --crop: the box is empty along z (0 > -1)\n"),
    (["--trim", "0.6,0.2"], "Error: --trim: expected 0 <= T0 < T1 <= 1, got 0.6,0.2\n"),
    (["--trim", "a,b"], "Error: Invalid value for '--trim': 'a,b': expected 2 numbers separated by commas "
                        "(T0,T1). See 'main convert --help'.\n"),
    (["--min-opacity", "nan"], "Error: Invalid value for '--min-opacity': 'nan' is not in [0, 1]."
                               " See 'main convert --help'.\n"),
    (["--max-splats", "-1"], "Error: Invalid value for '--max-splats': -1 is not in the range x>=0."
                             " See 'main convert --help'.\n"),
    (["--translate", "1,2,nan"], "Error: Invalid value for '--translate': '1,2,nan': every number must be "
                                 "finite. See 'main convert --help'.\n"),
    (["--rotate", "x:90,q:1"], "Error: Invalid value for '--rotate': cannot read 'q:1'; expected steps such as "
                               "x:90,y:-45 or quat:W,X,Y,Z. See 'main convert --help'.\n"),
    (["--scale", "-2"], "Error: Invalid value for '--scale': -2.0 is not in the range x>0."
                        " See 'main convert --help'.\n"),
    (["--scale", "inf"], "Error: --scale: expected a finite number > 0, got inf\n"),
])
def test_bad_edit_options_are_usage_errors_and_write_nothing(tmp_path, args, message):
    src = tmp_path / "in.ply"
    io.write(moving_scene(20), src)
    result = CliRunner().invoke(main, ["convert", str(src), str(tmp_path / "out.splatv"), *args])
    assert result.exit_code == 2
    assert result.stderr.endswith(message)
    assert not (tmp_path / "out.splatv").exists()


def test_edits_that_leave_nothing_fail_and_write_nothing(tmp_path):
    src = tmp_path / "in.ply"
    io.write(moving_scene(20), src)
    out = tmp_path / "out.ply"
    result = CliRunner().invoke(main, ["convert", str(src), str(out), "--crop", "50,50,50,60,60,60"])
    assert error_line(result, 1).startswith(f"Error: {src}: the edits leave no splats (crop removed 20)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ply"]


def test_blocks_and_threads_change_nothing(monkeypatch):
    """A scene of many blocks (worked on by two threads) gives what one block gives, counts included."""
    from splatconv.ops import _table

    scene = laden(40_000, seed=5)
    for row in (3, 30_000):  # splats that survive every filter, with a jerk that outgrows float32 when scaled
        for name in COLUMNS:
            scene.columns[name][row] = 0.0
        scene.columns["rot_0"][row] = 1.0
        scene.columns["opacity"][row] = 10.0
        scene.columns["trbf_center"][row] = 0.5
        scene.columns["motion_7"][row] = 3.4e38
    plan = EditPlan(drop_nonfinite=False, trim=(0.1, 0.8), crop=((-2, -2, -2), (2, 2, 2)), min_opacity=0.1,
                    max_splats=20_000, transform=make_transform((1, 2, 3), "x:33,y:-10", 10.0))
    assert len(_table.run_blocks(scene.count, lambda part: part)) > 2
    many, many_reports = apply_edits(scene, plan)
    monkeypatch.setattr(_table, "CHUNK", 1 << 20)
    assert len(_table.run_blocks(scene.count, lambda part: part)) == 1
    one, one_reports = apply_edits(scene, plan)
    assert [r.notes for r in many_reports] == [r.notes for r in one_reports]
    assert many_reports[-1].counts["overflow"] >= 2
    for name in COLUMNS:
        assert np.array_equal(many.columns[name], one.columns[name], equal_nan=True), name


def test_signalling_nans_raise_no_warning():
    """A hostile file may hold signalling NaNs, which warn when widened or compared unless handled."""
    scene = moving_scene(3000, seed=6)
    snan = np.array([0x7F800001, 0xFFC00001], dtype=np.uint32).view(np.float32)
    for i, name in enumerate(COLUMNS):
        scene.columns[name][[10 + i, 2000 + i]] = snan
    for plan in PLANS:
        out, _ = apply_edits(scene, plan)
    cleaned, report = drop_nonfinite(scene)
    assert report.removed == 2 * len(COLUMNS)
    trim(scene, 0.2, 0.4)
    crop(scene, (-1, -1, -1), (1, 1, 1))
    min_opacity(scene, 0.5)
    max_splats(scene, 10)
    apply_transform(scene, make_transform((1, 2, 3), "y:20", 2))


def test_convert_help_states_the_edit_order_and_an_example():
    text = CliRunner().invoke(main, ["convert", "--help"], terminal_width=200).output
    assert ("Edits apply in this order, whatever the order of the options: --drop-undrawable, --drop-nonfinite, "
            "--trim, --crop, "
            "--min-opacity, --max-splats, then --translate/--rotate/--scale, as p' = R(S p) + T") in text
    example = "\n    splatconv convert scene.ply clean.splatv --drop-nonfinite --trim 0.25,0.75 --rotate x:180\n"
    # In the Example block, as a line of its own, before the paragraph that follows the block.
    assert example in text and text.index(example) < text.index("A .splatvq OUTPUT proves its quality")
    for option in ("--drop-undrawable", "--drop-nonfinite", "--trim T0,T1", "--crop X0,Y0,Z0,X1,Y1,Z1", "--min-opacity A",
                   "--max-splats N", "--translate X,Y,Z", "--rotate STEPS", "--scale S"):
        assert f"  {option} " in text, option
