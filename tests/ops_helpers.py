"""Shared by the tests of splatconv.ops: moving test scenes and drawing them with the float reference path."""

from __future__ import annotations

import numpy as np

from splatconv.model import COLUMNS, Scene
from splatconv.render import camera as cam
from splatconv.render.diff import compare
from splatconv.render.layout import float_attributes
from splatconv.render.preview import View

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
    rng = np.random.default_rng(seed)
    c = {
        "x": rng.uniform(-2.5, 2.5, n), "y": rng.uniform(-1.8, 1.8, n), "z": rng.uniform(-2, 2, n),
        "trbf_center": rng.uniform(-0.1, 1.1, n), "trbf_scale": np.log(rng.uniform(0.15, 0.8, n)),
        "opacity": rng.uniform(-0.5, 4, n),
    }
    for i in range(9):
        c[f"motion_{i}"] = rng.normal(0, (0.8, 0.8, 1.2)[i // 3], n)
    for i in range(3):
        c[f"f_dc_{i}"] = rng.uniform(0.05, 1, n)
        c[f"scale_{i}"] = np.log(rng.uniform(0.04, 0.25, n))
    for i in range(4):
        c[f"rot_{i}"] = rng.normal(0, 1, n)
        c[f"omega_{i}"] = rng.normal(0, 1.5, n)
    # Splat 0 is an invisible one far behind the rest. The viewer's depth sort drops
    # the farthest splat or not by the rounding of one float (bucket 65,536) and then
    # draws splat 0 twice: with this splat both are invisible, so that quirk cannot
    # tell two equal scenes apart.
    for k in c:
        c[k][0] = 0.0
    c["z"][0], c["opacity"][0], c["trbf_scale"][0], c["rot_0"][0] = 60.0, -40.0, np.log(1e4), 1.0
    return Scene({k: np.asarray(c[k], dtype=np.float32) for k in COLUMNS}, cameras=[dict(CAMERA)])


def view_of(camera: dict) -> View:
    return View(cam.view_matrix(camera), float(camera["fx"]), float(camera["fy"]), int(camera["width"]),
                int(camera["height"]))


def draw(renderer, scene: Scene, t: float, camera: dict | None = None) -> np.ndarray:
    """``scene`` at time ``t`` from ``camera`` (default its first), float reference path: ``(H, W, 4) uint8``."""
    renderer.load_float(float_attributes(scene))
    return renderer.draw(view_of(camera or scene.cameras[0]), float(t))


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return compare(a, b).psnr


def coverage(img: np.ndarray) -> float:
    """Share of pixels with any alpha: a frame that is nearly empty proves nothing."""
    return float((img[..., 3] > 0).mean())


def assert_same_image(a: np.ndarray, b: np.ndarray, min_psnr: float = 50.0):
    assert coverage(a) > 0.2, "the reference frame is nearly empty"
    p = psnr(a, b)
    assert p >= min_psnr, f"{p:.1f} dB < {min_psnr} dB"
    return p

