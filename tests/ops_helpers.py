"""Shared by the tests of splatconv.ops: moving test scenes and drawing them with the float reference path."""

from __future__ import annotations

import numpy as np

from splatconv.model import Scene
from splatconv.render import camera as cam
from splatconv.render.diff import compare
from splatconv.render.layout import float_attributes
from splatconv.render.preview import View

from .scenes import CAMERA, FOCAL, H, W, moving_scene  # noqa: F401  (the scenes these tests draw)


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

