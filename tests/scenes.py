"""Random splat scenes for the tests and the benchmarks: one factory, recipes as data.

A scene is drawn by :func:`draw_columns` from a recipe: the columns in the
order they are drawn, each with its distribution. Every random scene the tests
and ``bench/`` use is a recipe here, so the streams stay what they were when
the figures that depend on them (thresholds, golden sizes) were taken: a new
scene is a new recipe, an old recipe is never reordered.

This module lives in ``tests/`` (test and benchmark code, never shipped with
the package) and imports only numpy and :mod:`splatconv.model`, so that the
benchmarks, run as ``python bench/x.py`` from the repository root, import it
as ``tests.scenes`` (as ``bench/bench_fuzz.py`` imports ``tests.fuzzing``).
"""

from __future__ import annotations

import numpy as np

from splatconv.model import COLUMNS, Scene


def normal(mean: float, sd: float):
    return lambda rng, n: rng.normal(mean, sd, n)


def uniform(low: float, high: float):
    return lambda rng, n: rng.uniform(low, high, n)


def log_uniform(low: float, high: float):
    """A log scale whose linear value is uniform in [low, high)."""
    return lambda rng, n: np.log(rng.uniform(low, high, n))


def _recipe(position, trbf_center, trbf_scale, opacity, motion, color, scale, rotation, omega,
            opacity_last: bool = False) -> tuple:
    """The draw order of the lite scenes: position, time, opacity, motion, (colour, scale), (rotation, omega).

    ``motion`` is one distribution or one per motion group (position, velocity,
    acceleration); ``opacity_last``: opacity drawn after everything else.
    """
    motion = motion if isinstance(motion, tuple) else (motion,) * 3
    draws = [("x", position[0]), ("y", position[1]), ("z", position[2]), ("trbf_center", trbf_center),
             ("trbf_scale", trbf_scale)]
    draws += [] if opacity_last else [("opacity", opacity)]
    draws += [(f"motion_{i}", motion[i // 3]) for i in range(9)]
    for i in range(3):
        draws += [(f"f_dc_{i}", color), (f"scale_{i}", scale)]
    for i in range(4):
        draws += [(f"rot_{i}", rotation), (f"omega_{i}", omega)]
    return tuple(draws + ([("opacity", opacity)] if opacity_last else []))


#: Plausible lite attributes around the origin (the tests' ``random_columns``).
LITE = _recipe(position=(normal(0, 2),) * 3, trbf_center=uniform(0, 1), trbf_scale=log_uniform(0.05, 1),
               opacity=normal(0, 2), motion=normal(0, 0.1), color=uniform(0, 1), scale=log_uniform(0.005, 0.1),
               rotation=normal(0, 1), omega=normal(0, 0.1))

#: Splats that move, turn and fade over [0, 1] in front of :data:`CAMERA` (:func:`moving_scene`).
MOVING = _recipe(position=(uniform(-2.5, 2.5), uniform(-1.8, 1.8), uniform(-2, 2)), trbf_center=uniform(-0.1, 1.1),
                 trbf_scale=log_uniform(0.15, 0.8), opacity=uniform(-0.5, 4),
                 motion=(normal(0, 0.8), normal(0, 0.8), normal(0, 1.2)), color=uniform(0.05, 1),
                 scale=log_uniform(0.04, 0.25), rotation=normal(0, 1), omega=normal(0, 1.5))

#: Large, partly transparent splats on one plane facing :data:`CAMERA` (:func:`overlapping_scene`).
OVERLAPPING = _recipe(position=(uniform(-2.0, 2.0), uniform(-1.5, 1.5), uniform(-0.002, 0.002)),
                      trbf_center=uniform(0, 1), trbf_scale=log_uniform(0.6, 3), opacity=uniform(-1.5, 1),
                      motion=normal(0, 0.05), color=uniform(0.05, 1), scale=log_uniform(0.3, 1.0),
                      rotation=normal(0, 1), omega=normal(0, 0.3))

#: The conversion benchmarks' scene (``bench/bench_convert.py``): :data:`LITE`'s values, drawn a group at a time.
CONVERT = tuple(
    [(name, normal(0, 2)) for name in ("x", "y", "z")]
    + [("trbf_center", uniform(0, 1)), ("trbf_scale", log_uniform(0.05, 1))]
    + [(f"motion_{i}", normal(0, 0.1)) for i in range(9)]
    + [(f"f_dc_{i}", uniform(0, 1)) for i in range(3)]
    + [("opacity", normal(0, 2))]
    + [(f"scale_{i}", log_uniform(0.005, 0.1)) for i in range(3)]
    + [(f"rot_{i}", normal(0, 1)) for i in range(4)]
    + [(f"omega_{i}", normal(0, 0.1)) for i in range(4)])


def render_recipe(huge: bool = False) -> tuple:
    """The render benchmarks' scene: in a 4-unit box, visible at t=0.5 (``huge``: splats near the axis cap)."""
    return _recipe(position=(normal(0, 1.2),) * 3, trbf_center=uniform(0, 1), trbf_scale=log_uniform(0.2, 2),
                   opacity=normal(1, 2), motion=normal(0, 0.05), color=uniform(0, 1),
                   scale=log_uniform(1.0, 3.0) if huge else log_uniform(0.003, 0.03), rotation=normal(0, 1),
                   omega=normal(0, 0.1), opacity_last=True)


def _short_or_long(long_share: float):
    """Temporal scales: short (0.05-0.5) or, for ``long_share`` of the splats, long (1.5-20)."""

    def draw(rng, n):
        short = rng.uniform(0.05, 0.5, n)
        return np.log(np.where(rng.uniform(size=n) < long_share, rng.uniform(1.5, 20, n), short))

    return draw


def clip_recipe(long_share: float = 0.3) -> tuple:
    """The long-clip benchmarks' scene: ``long_share`` of the splats visible for long stretches."""
    return _recipe(position=(normal(0, 2),) * 3, trbf_center=uniform(0, 1), trbf_scale=_short_or_long(long_share),
                   opacity=normal(1, 2), motion=(normal(0, 0.2), normal(0, 0.1), normal(0, 0.2 / 3)),
                   color=uniform(0, 1), scale=log_uniform(0.005, 0.1), rotation=normal(0, 1), omega=normal(0, 0.2))


def draw_columns(n: int, seed: int = 0, recipe: tuple = LITE) -> dict:
    """Draw ``n`` splats from ``recipe`` with ``np.random.default_rng(seed)``.

    Returns
    -------
    dict of str to (n,) float32 ndarray
        The recipe's columns, drawn in float64 and rounded once.
    """
    rng = np.random.default_rng(seed)
    return {name: np.asarray(dist(rng, n), dtype=np.float32) for name, dist in recipe}


def random_columns(n: int, seed: int = 0) -> dict:
    """Plausible lite attributes (:data:`LITE`): ``(n,) float32`` per model column."""
    return draw_columns(n, seed, LITE)


def gs_columns(n: int, names, seed: int = 1) -> dict:
    """Standard normal values for the properties ``names`` (a plain 3DGS file's, with f_rest_*)."""
    rng = np.random.default_rng(seed)
    return {name: rng.normal(0, 1, n).astype(np.float32) for name in names}


W, H = 160, 120
FOCAL = 140.0
#: Looks along +z from 9 units in front of the scene's middle.
CAMERA = {"id": 0, "img_name": "test", "width": W, "height": H, "position": [0.3, -0.2, -9.0],
          "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "fx": FOCAL, "fy": FOCAL}


def moving_scene(n: int = 300, seed: int = 0) -> Scene:
    """A scene of ``n`` splats that move, turn and fade in and out over [0, 1], in front of :data:`CAMERA`.

    The motion is large enough (up to about a unit over the clip, several pixels a
    frame step) that a transform or time map that gets any motion term wrong
    shows in the image.
    """
    c = draw_columns(n, seed, MOVING)
    # Splat 0 is an invisible one far behind the rest. The viewer's depth sort drops
    # the farthest splat or not by the rounding of one float (bucket 65,536) and then
    # draws splat 0 twice: with this splat both are invisible, so that quirk cannot
    # tell two equal scenes apart.
    for k in c:
        c[k][0] = 0.0
    c["z"][0], c["opacity"][0], c["trbf_scale"][0], c["rot_0"][0] = 60.0, -40.0, np.log(1e4), 1.0
    return Scene({k: c[k] for k in COLUMNS}, cameras=[dict(CAMERA)])


def overlapping_scene(n: int = 500, seed: int = 0) -> Scene:
    """``n`` large, partly transparent splats overlapping on one plane in front of :data:`CAMERA`: the
    viewer's depth sort puts most of them in a few buckets, so the record order decides how they blend.

    A third of them take their scales from three values and their opacity from two (many
    equal importance keys, the same scales on other axes among them); a few have a zero
    rotation that spins (a ``.splatvq`` keeps them as raw records). Splat 0 is far behind
    the rest and too small to show: the farthest splat the depth sort drops is that one.
    """
    c = draw_columns(n, seed, OVERLAPPING)
    rng = np.random.default_rng(seed + 1)
    tied = np.arange(1, n, 3)
    for i in range(3):
        c[f"scale_{i}"][tied] = np.log(rng.choice([0.4, 0.6, 0.9], len(tied)))
    c["opacity"][tied] = rng.choice([-0.5, 0.5], len(tied))
    spinning = np.arange(2, n, n // 6)
    for i in range(4):
        c[f"rot_{i}"][spinning] = 0.0
    c["omega_0"][spinning] = 1.5
    c["z"][0], c["trbf_scale"][0] = 60.0, np.log(1e4)
    for i in range(3):
        c[f"scale_{i}"][0] = np.log(1e-4)
    return Scene({k: c[k] for k in COLUMNS}, cameras=[dict(CAMERA)])


__all__ = ["CAMERA", "CONVERT", "LITE", "MOVING", "OVERLAPPING", "clip_recipe", "draw_columns", "gs_columns",
           "moving_scene", "overlapping_scene", "random_columns", "render_recipe"]
