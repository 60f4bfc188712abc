"""bake works a block of rows at a time: the blocks' boundaries change nothing it gives."""

from __future__ import annotations

import numpy as np

from splatconv import model
from splatconv.model import Scene
from splatconv.ops import bake as bake_ops

from .scenes import random_columns


def _scene(n: int = 500) -> Scene:
    cols = {name: np.array(c) for name, c in random_columns(n, seed=4).items()}
    cols["rot_0"][::7] = cols["rot_1"][::7] = cols["rot_2"][::7] = cols["rot_3"][::7] = 0.0  # zero rotation
    cols["omega_0"][::7] = cols["omega_1"][::7] = cols["omega_2"][::7] = cols["omega_3"][::7] = 0.0
    cols["x"][3::11] = np.nan
    cols["trbf_center"][5::13] = 9.0  # hidden at t = 0.5
    cols["scale_1"][2::17] = -np.inf  # flat: a finite stand-in
    return Scene(columns=cols)


def test_blocks_of_any_size_bake_the_same_scene(monkeypatch):
    scene = _scene()
    whole, whole_report = bake_ops.bake(scene, 0.5)
    monkeypatch.setattr(bake_ops, "_BLOCK", 37)
    parts, parts_report = bake_ops.bake(scene, 0.5)
    assert 0 < parts.count < scene.count
    assert parts_report.counts == whole_report.counts and parts_report.notes == whole_report.notes
    for name in model.COLUMNS:
        assert np.array_equal(np.asarray(parts.columns[name]), np.asarray(whole.columns[name]), equal_nan=True), name
