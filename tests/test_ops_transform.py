"""Motion-aware transforms: the transformed scene, seen by the transformed camera, is the original at every time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io
from splatconv.cli import main
from splatconv.errors import UsageError
from splatconv.model import MOTION, OMEGA, POSITION, ROTATION, SCALE
from splatconv.ops import Transform, apply_transform, make_transform, parse_rotation
from splatconv.ops.transform import axis_rotation, left_product_matrix, quaternion_matrix, transform_cameras
from tests.ops_helpers import CAMERA, assert_same_image, draw, moving_scene, psnr

TIMES = (0.0, 0.3, 0.65, 1.0)


# --------------------------------------------------------------------------
# The rotation text and its maths


@pytest.mark.parametrize("text, point, expected", [
    ("x:90", (0, 1, 0), (0, 0, 1)),
    ("y:90", (0, 0, 1), (1, 0, 0)),
    ("z:90", (1, 0, 0), (0, 1, 0)),
    ("x:180", (0, 1, 0), (0, -1, 0)),
    ("x:-90", (0, 0, 1), (0, 1, 0)),
    ("x:90,y:90", (0, 1, 0), (1, 0, 0)),  # x first: +y -> +z, then y: +z -> +x
    ("y:90,x:90", (0, 1, 0), (0, 0, 1)),  # y leaves +y alone, then x: +y -> +z
    ("X:450", (0, 1, 0), (0, 0, 1)),
])
def test_axis_steps_are_right_handed_and_apply_left_to_right(text, point, expected):
    q, m = parse_rotation(text)
    assert np.array_equal(m @ np.array(point, float), np.array(expected, float))  # exact at 90 degrees
    assert np.allclose(quaternion_matrix(q), m, atol=1e-15)


def test_axis_rotation_quaternion_is_the_half_angle_form():
    q, m = axis_rotation("y", 60)
    assert np.allclose(q, [math.cos(math.radians(30)), 0, math.sin(math.radians(30)), 0])
    assert np.allclose(m, [[0.5, 0, math.sqrt(3) / 2], [0, 1, 0], [-math.sqrt(3) / 2, 0, 0.5]])


def test_quaternion_form_and_steps_agree():
    q_steps, m_steps = parse_rotation("x:30, y:-70,z:12.5")
    q = ",".join(repr(float(v)) for v in q_steps)
    q_text, m_text = parse_rotation(f"quat:{q}".replace(" ", ""))
    assert np.allclose(m_text, m_steps, atol=1e-14)
    # An unnormalised quaternion means the same rotation.
    _, m_big = parse_rotation("quat:" + ",".join(str(3 * v) for v in q_steps))
    assert np.allclose(m_big, m_steps, atol=1e-14)
    # A mix: a quaternion step, then an axis step.
    _, m_mix = parse_rotation("quat:0,1,0,0,z:90")
    assert np.allclose(m_mix, parse_rotation("x:180,z:90")[1], atol=1e-15)


def test_left_product_is_the_hamilton_product_and_composes_matrices():
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.normal(size=4), rng.normal(size=4)
        a /= np.linalg.norm(a)
        b /= np.linalg.norm(b)
        ab = left_product_matrix(a) @ b
        assert np.allclose(quaternion_matrix(ab), quaternion_matrix(a) @ quaternion_matrix(b))
        w1, v1, w2, v2 = a[0], a[1:], b[0], b[1:]
        assert np.allclose(ab, np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)]))


@pytest.mark.parametrize("text", ["", "x", "x:", "w:90", "x:90,", "x:90;y:3", "quat:1,2,3", "quat:0,0,0,0",
                                  "x:nan", "x:inf", "quat:1,nan,0,0", "x:1e999"])
def test_bad_rotation_text_is_a_usage_error(text):
    with pytest.raises(UsageError, match="--rotate"):
        parse_rotation(text)


@pytest.mark.parametrize("kwargs", [{"scale": 0}, {"scale": -1}, {"scale": math.inf}, {"scale": math.nan},
                                    {"translate": (0, math.nan, 0)}, {"translate": (1, 2)}])
def test_bad_transform_values_are_usage_errors(kwargs):
    with pytest.raises(UsageError):
        make_transform(**kwargs)


def test_transform_formula_on_attributes():
    """p' = R(S p) + T for positions, R S m for motion, q (x) r for rot and omega, + log S for scales."""
    scene = moving_scene(50, seed=4)
    tf = make_transform((1.5, -2, 0.25), "x:30,z:-110", 1.7)
    out, report = apply_transform(scene, tf)
    c, o = scene.columns, out.columns
    R, q = np.asarray(tf.matrix), np.asarray(tf.rotation)

    def stack(cols, names):
        return np.stack([cols[n].astype(np.float64) for n in names], axis=1)

    assert np.allclose(stack(o, POSITION), stack(c, POSITION) @ (1.7 * R).T + (1.5, -2, 0.25), atol=1e-5)
    for k in range(3):
        names = MOTION[3 * k:3 * k + 3]
        assert np.allclose(stack(o, names), stack(c, names) @ (1.7 * R).T, atol=1e-5)
    L = left_product_matrix(q)
    assert np.allclose(stack(o, ROTATION), stack(c, ROTATION) @ L.T, atol=1e-5)
    assert np.allclose(stack(o, OMEGA), stack(c, OMEGA) @ L.T, atol=1e-5)
    assert np.allclose(stack(o, SCALE), stack(c, SCALE) + math.log(1.7), atol=1e-6)
    for name in ("trbf_center", "trbf_scale", "opacity", "f_dc_0", "f_dc_1", "f_dc_2"):
        assert np.array_equal(o[name], c[name])
    # The input is not changed; the report says what was done, counts true.
    assert np.array_equal(scene.columns["x"], moving_scene(50, seed=4).columns["x"])
    assert report.count_in == report.count_out == 50 and report.counts["cameras"] == 1
    assert "50 splats and 1 camera" in report.notes[0] and "S = 1.7" in report.notes[0]
    assert out.notes[-1] == report.notes[0]


def test_option_order_does_not_matter_scale_then_rotate_then_translate():
    tf = make_transform(translate=(1, 0, 0), rotate="z:90", scale=2)
    assert np.allclose(tf.apply_points([[1, 0, 0]]), [[1, 2, 0]])  # R(2 * (1,0,0)) + (1,0,0)


# --------------------------------------------------------------------------
# By pixels: the transformed scene from the transformed camera is the original


TRANSFORMS = [
    ("x:180", None, None),
    ("x:90,y:45", (0.5, -1.0, 2.0), None),
    ("quat:0.3,-0.5,0.7,0.2", (3.0, 1.0, -4.0), 1.6),
    ("z:-33", (-1.0, 0.0, 0.0), 0.7),
]


@pytest.mark.parametrize("rotate, translate, scale", TRANSFORMS)
def test_transformed_scene_matches_from_the_transformed_camera(renderer, rotate, translate, scale):
    scene = moving_scene()
    tf = make_transform(translate, rotate, scale)
    moved, _ = apply_transform(scene, tf)
    assert moved.cameras[0] != scene.cameras[0]
    for t in TIMES:
        assert_same_image(draw(renderer, scene, t), draw(renderer, moved, t))


def _naive(scene, tf):
    """What the scripts that exist do: positions and rest rotations only, motion and omega left alone."""
    moved, _ = apply_transform(scene, tf)
    for name in MOTION + OMEGA:
        moved.columns[name][:] = scene.columns[name]
    return moved


def test_the_pixel_check_catches_a_transform_that_forgets_the_motion(renderer):
    """The comparison above can fail: untransformed motion and omega are far below 50 dB away from rest time."""
    scene = moving_scene()
    tf = make_transform(None, "x:90,y:45", None)
    naive = _naive(scene, tf)
    worst = min(psnr(draw(renderer, scene, t), draw(renderer, naive, t)) for t in TIMES)
    assert worst < 30


def test_cameras_move_with_the_scene():
    tf = make_transform((1, 2, 3), "y:90", 2)
    (moved,) = transform_cameras([CAMERA], tf)
    assert np.allclose(moved["position"], tf.apply_points([CAMERA["position"]])[0])
    assert np.allclose(moved["rotation"], np.asarray(tf.matrix) @ np.asarray(CAMERA["rotation"]))
    assert {k: v for k, v in moved.items() if k not in ("position", "rotation")} == \
        {k: v for k, v in CAMERA.items() if k not in ("position", "rotation")}
    assert transform_cameras(None, tf) is None


def test_convert_rotates_and_the_stored_camera_still_sees_the_scene(tmp_path, renderer):
    """Through the CLI and a PLY file: the output's own camera 0 sees what the input's saw."""
    scene = moving_scene(seed=5)
    src = tmp_path / "in.ply"
    io.write(scene, src)
    out = tmp_path / "out.ply"
    result = CliRunner().invoke(main, ["convert", str(src), str(out), "--scale", "1.25", "--rotate", "x:180",
                                       "--translate", "0,1,5"])
    assert result.exit_code == 0, result.output
    assert "note: transform: p' = R(S p) + T with S = 1.25, R = x:180" in result.stderr
    assert "300 splats and 1 camera" in result.stderr
    back = io.read(out)
    assert back.cameras[0]["position"] != CAMERA["position"]
    for t in (0.1, 0.8):
        assert_same_image(draw(renderer, scene, t), draw(renderer, back, t))


def test_identity_transform_changes_nothing():
    scene = moving_scene(20)
    out, _ = apply_transform(scene, Transform())
    for name in scene.columns:
        assert np.array_equal(out.columns[name], scene.columns[name])
    assert Transform().is_identity and not make_transform(scale=2).is_identity


@pytest.mark.parametrize("kwargs, changed", [
    ({"translate": (1, 0, 0)}, "(positions)"),
    ({"scale": 2.0}, "(positions, motion, scales)"),
    ({"rotate": "z:10"}, "(positions, motion, rotations, omega)"),
    ({"rotate": "z:10", "scale": 0.5, "translate": (0, 0, 1)}, "(positions, motion, rotations, omega, scales)"),
])
def test_transform_note_names_only_what_changed(kwargs, changed):
    scene = moving_scene(10)
    out, report = apply_transform(scene, make_transform(**kwargs))
    assert report.notes[0].endswith(f"applied to 10 splats and 1 camera {changed}")
    untouched = {"(positions)": ("motion_0", "rot_0", "omega_0", "scale_0"),
                 "(positions, motion, scales)": ("rot_0", "omega_0")}.get(changed, ())
    for name in untouched:
        assert np.array_equal(out.columns[name], scene.columns[name]), name


@pytest.mark.parametrize("seed", range(4))
def test_every_time_the_viewer_maths_sees_the_transformed_scene(seed):
    """position_at(t) and the rotation matrix at t of the transformed scene are R S p(t) + T and R R(t)."""
    from splatconv import viewer

    rng = np.random.default_rng(seed)
    scene = moving_scene(100, seed=seed)
    q = rng.normal(size=4)
    tf = make_transform(tuple(rng.normal(size=3)), "quat:" + ",".join(repr(float(v)) for v in q),
                        float(rng.uniform(0.3, 3)))
    moved, _ = apply_transform(scene, tf)
    R = np.asarray(tf.matrix)
    for t in (-0.2, 0.0, 0.37, 1.0):
        want = tf.apply_points(viewer.position_at(scene.columns, t))
        assert np.allclose(viewer.position_at(moved.columns, t), want, rtol=1e-5, atol=1e-5)
        before = viewer.rotation_at(scene.columns, t)
        after = viewer.rotation_at(moved.columns, t)
        for a, b in zip(before[1:], after[1:]):  # splat 0 is the still one
            assert np.allclose(quaternion_matrix(b), R @ quaternion_matrix(a), atol=1e-5)
        assert np.allclose(viewer.scales(moved.columns), viewer.scales(scene.columns) * tf.scale, rtol=1e-5)
