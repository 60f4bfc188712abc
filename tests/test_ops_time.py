"""Time maps and trim: the remapped scene at t' is the original at origin + t' * duration, by pixels."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, viewer
from splatconv.cli import main
from splatconv.errors import UsageError
from splatconv.model import COLUMNS, Scene
from splatconv.ops import place_in, remap_time, trim
from tests.ops_helpers import assert_same_image, draw, moving_scene, psnr


@pytest.mark.parametrize("t0, t1", [(0.2, 0.6), (0.0, 0.5), (0.55, 1.0), (0.3, 0.35)])
def test_trimmed_scene_at_t_is_the_original_at_t0_plus_t_d(renderer, t0, t1):
    scene = moving_scene(seed=1)
    trimmed, report = trim(scene, t0, t1)
    d = t1 - t0
    for t in (0.0, 0.25, 0.6, 1.0):
        assert_same_image(draw(renderer, scene, t0 + t * d), draw(renderer, trimmed, t))
    assert report.count_out == trimmed.count < scene.count


def test_the_pixel_check_catches_a_trim_that_forgets_the_motion(renderer):
    """Rescaling the trbf only (the motion and omega left in the old time units) is visibly wrong."""
    scene = moving_scene(seed=1)
    trimmed, _ = trim(scene, 0.2, 0.6)
    survivors = viewer.visible_interval(scene.columns)
    keep = (survivors[1] >= 0.2) & (survivors[0] <= 0.6)
    for name in [n for n in COLUMNS if n.startswith(("motion", "omega"))]:
        trimmed.columns[name][:] = scene.columns[name][keep]
    worst = min(psnr(draw(renderer, scene, 0.2 + t * 0.4), draw(renderer, trimmed, t)) for t in (0.0, 1.0))
    assert worst < 30


def test_place_in_and_reversed_time_by_pixels(renderer):
    scene = moving_scene(seed=2)
    placed, _ = place_in(scene, 0.25, 0.75)
    reversed_, _ = remap_time(scene, 1.0, -1.0)  # t' = 1 - t: the clip backwards
    for t in (0.0, 0.4, 1.0):
        assert_same_image(draw(renderer, scene, t), draw(renderer, placed, 0.25 + 0.5 * t))
        assert_same_image(draw(renderer, scene, t), draw(renderer, reversed_, 1.0 - t))


def test_time_map_terms():
    """centre (c - a)/d, log scale s - log|d|, motion of degree k times d^k, omega times d."""
    scene = moving_scene(40, seed=3)
    a, d = 0.3, 0.25
    out, report = remap_time(scene, a, d)
    c, o = scene.columns, out.columns
    f64 = lambda v: np.asarray(v, dtype=np.float64)  # noqa: E731
    assert np.allclose(o["trbf_center"], (f64(c["trbf_center"]) - a) / d, rtol=1e-6)
    assert np.allclose(o["trbf_scale"], f64(c["trbf_scale"]) - math.log(d), atol=1e-6)
    for i in range(9):
        assert np.allclose(o[f"motion_{i}"], f64(c[f"motion_{i}"]) * d ** (i // 3 + 1), rtol=1e-6)
    for i in range(4):
        assert np.allclose(o[f"omega_{i}"], f64(c[f"omega_{i}"]) * d, rtol=1e-6)
    for name in ("x", "y", "z", "rot_0", "scale_1", "opacity", "f_dc_2"):
        assert np.array_equal(o[name], c[name])
    assert report.count_in == report.count_out == 40


def hand_scene(centres, scales) -> Scene:
    """Splats that differ only in time: trbf centre and linear trbf scale."""
    n = len(centres)
    cols = {name: np.zeros(n, np.float32) for name in COLUMNS}
    cols["rot_0"][:] = 1
    cols["trbf_center"][:] = centres
    with np.errstate(divide="ignore"):
        cols["trbf_scale"][:] = np.log(np.asarray(scales, dtype=np.float64))
    return Scene(cols)


def test_trim_keeps_exactly_what_is_visible_in_the_interval():
    r = viewer.VISIBLE_RADIUS
    # Visible intervals: centre +- r * scale.
    centres = [0.1, 0.4, 0.7, 0.05, 0.9, 0.5, math.nan, 0.5, 0.5, 2.0]
    scales = [0.05 / r, 0.01, 0.05 / r, 0.2 / r, 0.3 / r, math.inf, 0.1, math.nan, 0.0, 1e-3]
    # [0.05, 0.15] out; [0.39, 0.41] in; [0.65, 0.75] out; [-0.15, 0.25] in (reaches 0.2); [0.6, 1.2] in
    # (reaches 0.6 exactly, to rounding: use a margin below); inf: always in; NaN centre out; NaN scale out;
    # zero scale at 0.5: visible only at t = 0.5, which is inside; centre 2 with a tiny scale: out.
    scales[4] = 0.31 / r
    scene = hand_scene(centres, scales)
    out, report = trim(scene, 0.2, 0.6)
    kept_centres = (np.asarray(centres)[[1, 3, 4, 5, 8]] - 0.2) / 0.4
    assert np.allclose(out.columns["trbf_center"], kept_centres)
    assert report.count_out == 5 and report.removed == 5
    assert report.counts["nan_time"] == 2
    assert "removed 5 of 10 splats not visible in [0.2, 0.6] (2 of them with a NaN trbf centre or scale)" \
        in report.notes[0]
    assert out.columns["trbf_scale"][3] == np.inf  # visible at every time stays so


@pytest.mark.parametrize("t0, t1", [(0.5, 0.2), (0.3, 0.3), (-0.1, 0.5), (0.2, 1.5), (math.nan, 0.5),
                                    (0.0, math.inf)])
def test_bad_trim_interval_is_a_usage_error(t0, t1):
    with pytest.raises(UsageError, match="--trim"):
        trim(moving_scene(5), t0, t1)


@pytest.mark.parametrize("origin, duration", [(0, 0), (math.nan, 1), (0, math.inf), (math.inf, 1)])
def test_bad_time_map_is_a_usage_error(origin, duration):
    with pytest.raises(UsageError):
        remap_time(moving_scene(5), origin, duration)
    with pytest.raises(UsageError):
        place_in(moving_scene(5), 0.5, 0.5)


def test_values_that_outgrow_float32_are_counted_not_warned():
    scene = moving_scene(10)
    scene.columns["motion_6"][3] = 1e30  # times d^3 = 1e30 -> beyond float32
    scene.columns["x"][4] = np.nan
    out, report = remap_time(scene, 0.0, 1e10)
    assert out.columns["motion_6"][3] == np.inf
    assert report.counts["overflow"] >= 1
    assert any("grew beyond float32" in n for n in report.notes)


def test_convert_trim_on_the_command_line(tmp_path, renderer):
    scene = moving_scene(seed=4)
    src = tmp_path / "in.ply"
    io.write(scene, src)
    out = tmp_path / "out.ply"
    result = CliRunner().invoke(main, ["convert", str(src), str(out), "--trim", "0.25,0.75"])
    assert result.exit_code == 0, result.output
    expected, _ = trim(scene, 0.25, 0.75)
    assert f"note: trim: removed {scene.count - expected.count} of {scene.count} splats not visible in " \
           f"[0.25, 0.75]" in result.stderr
    back = io.read(out)
    assert back.count == expected.count
    for t in (0.0, 0.5, 1.0):
        assert_same_image(draw(renderer, scene, 0.25 + 0.5 * t), draw(renderer, back, t))


@pytest.mark.parametrize("origin, duration", [(0.2, 0.4), (-1.0, 3.0), (1.0, -1.0), (0.5, 1e-3)])
def test_every_time_the_viewer_maths_sees_the_remapped_scene(origin, duration):
    """At t' the remapped scene's position, rotation and temporal opacity are the original's at origin + t' d."""
    scene = moving_scene(200, seed=7)
    out, _ = remap_time(scene, origin, duration)
    for t in (0.0, 0.3, 1.0):
        u = origin + t * duration
        assert np.allclose(viewer.position_at(out.columns, t), viewer.position_at(scene.columns, u),
                           rtol=1e-4, atol=1e-4)
        assert np.allclose(viewer.rotation_at(out.columns, t), viewer.rotation_at(scene.columns, u), atol=1e-4)
        assert np.allclose(viewer.temporal_opacity(out.columns, t, cut=False),
                           viewer.temporal_opacity(scene.columns, u, cut=False), atol=1e-5)
