"""Filters by pixels: a filtered scene draws exactly as the splats it should keep, drawn alone."""

from __future__ import annotations

import numpy as np

from splatconv.model import COLUMNS, Scene
from splatconv.ops import crop, drop_nonfinite, min_opacity
from tests.ops_helpers import draw, moving_scene, psnr

TIMES = (0.1, 0.5, 0.9)


def joined(keep: Scene, extra: dict) -> tuple:
    """``keep``'s splats with ``extra`` rows spread among them; and where the kept ones are."""
    n, m = keep.count, len(extra["x"])
    rows = np.zeros(n + m, dtype=bool)
    rows[np.linspace(1, n + m - 1, m).astype(int)] = True  # row 0 (the far splat) stays first
    cols = {}
    for name in COLUMNS:
        col = np.empty(n + m, np.float32)
        col[~rows] = keep.columns[name]
        col[rows] = extra[name]
        cols[name] = col
    return Scene(cols, cameras=keep.cameras), ~rows


def visible_extras(m: int, **values) -> dict:
    """``m`` bright, opaque, always-visible splats in front of the test camera, then ``values`` set."""
    rng = np.random.default_rng(11)
    extra = {name: np.zeros(m, np.float32) for name in COLUMNS}
    extra["x"][:] = rng.uniform(-2, 2, m)
    extra["y"][:] = rng.uniform(-1.5, 1.5, m)
    extra["z"][:] = -3.0  # in front of the kept splats
    extra["rot_0"][:] = 1.0
    extra["rot_3"][:] = 0.3
    extra["scale_0"][:] = extra["scale_2"][:] = np.log(0.3)
    extra["scale_1"][:] = np.log(0.2)
    extra["opacity"][:] = 5.0
    extra["f_dc_0"][:] = extra["f_dc_1"][:] = 1.0
    extra["trbf_center"][:] = 0.5
    extra["trbf_scale"][:] = np.log(100.0)
    for name, v in values.items():
        extra[name][:] = v
    return extra


def assert_draws_as(renderer, filtered: Scene, kept: Scene, full: Scene):
    for t in TIMES:
        want = draw(renderer, kept, t)
        assert np.array_equal(draw(renderer, filtered, t), want)
        # The removed splats show when present: the comparison above could fail.
        assert psnr(draw(renderer, full, t), want) < 35


def test_crop_by_pixels(renderer):
    kept = moving_scene(200, seed=7)
    outside = visible_extras(12)
    outside["x"][:] = np.where(outside["x"] < 0, -4.0, 4.0)  # left and right of the box, in view
    scene, _ = joined(kept, outside)
    cropped, report = crop(scene, (-3.2, -2.5, -3.5), (3.2, 2.5, 61))
    assert report.removed == 12
    assert_draws_as(renderer, cropped, kept, scene)


def test_min_opacity_by_pixels(renderer):
    kept = moving_scene(200, seed=8)
    kept.columns["opacity"][:] = np.maximum(kept.columns["opacity"], -1.0)  # sigmoid >= 0.27
    kept.columns["opacity"][0] = 0.0  # the far splat too
    faint = visible_extras(10, opacity=-1.5)  # sigmoid 0.18: faint, but visible in front
    scene, _ = joined(kept, faint)
    filtered, report = min_opacity(scene, 0.25)
    assert report.removed == 10
    assert_draws_as(renderer, filtered, kept, scene)


def test_drop_nonfinite_by_pixels(renderer):
    kept = moving_scene(200, seed=9)
    broken = visible_extras(6)
    broken["f_dc_1"][0] = np.nan  # NaN colour: stored as 0, a dark blot
    broken["f_dc_0"][1] = np.nan
    broken["rot_2"][2] = np.nan
    broken["scale_0"][3] = np.inf  # a huge splat
    broken["omega_1"][4] = np.inf
    broken["motion_3"][5] = np.nan
    scene, _ = joined(kept, broken)
    cleaned, report = drop_nonfinite(scene)
    assert report.removed == 6
    assert_draws_as(renderer, cleaned, kept, scene)
