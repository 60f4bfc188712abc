"""One comparison for ``stats`` and ``verify``: the same figures, rows paired with the right splats.

Built on :mod:`tests.real_scenes` scenes (zero rotations, NaN positions and motion, huge
positions, infinite temporal scales, flat splats, alpha 0, unpadded ``.splatv`` files).
"""

from __future__ import annotations

import json
import shutil
import struct

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import read
from splatconv.formats import splatv
from splatconv.cli import main
from splatconv.compare import align, compare_scenes
from splatconv.model import GROUPS

from .conftest import lite_columns_with_normals, random_columns, write_ply
from .real_scenes import real_scene, unpadded_splatv

ERRORS = ("max_abs_error", "max_rel_error", "rmse")
#: verify's quickest frame: the attribute check is the point here.
ONE_FRAME = ("--times", "0.5", "--cameras", "0", "--size", "32x18")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def stats_attributes(a, b) -> dict:
    result = run("stats", a, b, "--json", "--zstd-level", "1")
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)["attributes"]


def verify_attributes(a, b) -> dict:
    result = run("verify", a, b, *ONE_FRAME, "--json")
    assert result.exit_code in (0, 1), result.output
    return json.loads(result.stdout)["attributes"]


@pytest.fixture(scope="module")
def real_files(tmp_path_factory):
    """A real-like unpadded .splatv, a byte copy, its PLY, and the PLY converted again."""
    folder = tmp_path_factory.mktemp("real")
    scene, _ = real_scene(1500, 4)
    original = folder / "scene.splatv"
    unpadded_splatv(scene, original)
    copy = folder / "copy.splatv"
    shutil.copyfile(original, copy)
    back = folder / "back.ply"
    assert run("convert", original, back).exit_code == 0
    again = folder / "again.splatv"
    assert run("convert", back, again).exit_code == 0
    return original, copy, back, again


@pytest.mark.parametrize("pair", [("original", "copy"), ("original", "back"), ("back", "original"),
                                  ("original", "again"), ("back", "again")])
def test_identical_records_show_zero_in_stats_and_verify(real_files, pair):
    files = dict(zip(("original", "copy", "back", "again"), real_files))
    a, b = (files[p] for p in pair)
    s, v = stats_attributes(a, b), verify_attributes(a, b)
    for group in GROUPS:
        assert [s[group][k] for k in ERRORS] == [0, 0, 0], (pair, group, s[group])
        assert [v[group][k] for k in ERRORS] == [0, 0, 0], (pair, group, v[group])
        assert v[group]["unexplained"] == 0


def test_stats_and_verify_report_the_same_errors(tmp_path):
    # A lossy conversion (a PLY to halves and bytes): both commands give the same figures.
    cols = lite_columns_with_normals(random_columns(400, 3))
    src = write_ply(tmp_path / "s.ply", cols)
    conv = tmp_path / "s.splatv"
    assert run("convert", src, conv).exit_code == 0
    s, v = stats_attributes(src, conv), verify_attributes(src, conv)
    assert any(s[g]["max_abs_error"] > 0 for g in GROUPS)
    for group in GROUPS:
        assert [s[group][k] for k in ERRORS] == [v[group][k] for k in ERRORS], group


def test_relative_errors_of_values_below_the_resolution_are_not_100_percent(tmp_path):
    # An opacity whose alpha rounds to byte 0, and a rotation component below the smallest normal
    # half: relative to the storage's step (1/255; 2^-14), not to the value itself.
    cols = lite_columns_with_normals(random_columns(3, 5))
    cols["opacity"][:] = -20.0          # sigmoid 2e-9: byte 0
    cols["rot_1"][:] = 3e-8             # stored as 2^-24: 0.79 of itself off, 1e-4 of the half's step
    src = write_ply(tmp_path / "tiny.ply", cols)
    conv = tmp_path / "tiny.splatv"
    assert run("convert", src, conv).exit_code == 0
    for attributes in (stats_attributes(src, conv), verify_attributes(src, conv)):
        alpha = 1 / (1 + np.exp(20.0))
        assert attributes["opacity"]["max_rel_error"] == pytest.approx(alpha * 255, rel=1e-3)
        assert attributes["rotation"]["max_rel_error"] < 2.0**-10
        assert attributes["opacity"]["max_abs_error"] == pytest.approx(alpha, rel=1e-3)


# --------------------------------------------------------------------------
# Pairing rows of a damaged file


def _records(path) -> tuple:
    data = path.read_bytes()
    start = 8 + struct.unpack("<I", data[4:8])[0]
    return data, start


def _damage(path, out, splats: int, count: int, seed: int) -> int:
    """``count`` bytes of ``path``'s first ``splats`` records changed at random; returns the records that differ.

    The padding stays zero: a nonzero record there would be one more splat.
    """
    data, start = _records(path)
    raw = bytearray(data)
    rng = np.random.default_rng(seed)
    for offset in rng.choice(np.arange(start, start + 64 * splats), count, replace=False):
        raw[offset] = (raw[offset] + int(rng.integers(1, 256))) % 256
    out.write_bytes(bytes(raw))
    before = np.frombuffer(data[start:], np.uint8).reshape(-1, 64)
    after = np.frombuffer(bytes(raw[start:]), np.uint8).reshape(-1, 64)
    return int(np.count_nonzero((before != after).any(axis=1)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_damaged_file_is_paired_by_the_writers_order(tmp_path, seed):
    scene, _ = real_scene(6000, 10 + seed)
    original = tmp_path / "scene.splatv"
    unpadded_splatv(scene, original)
    ply = tmp_path / "scene.ply"
    assert run("convert", original, ply).exit_code == 0
    faithful = tmp_path / "faithful.splatv"
    assert run("convert", ply, faithful).exit_code == 0
    broken = tmp_path / "broken.splatv"
    differ = _damage(faithful, broken, scene.count, 200, seed)
    assert 0 < differ <= 200
    # The undamaged rows keep the writer's order: align pairs them as it pairs the faithful file.
    source, clean, hurt = read(ply), read(faithful), read(broken)
    writer = align(source, clean, storage=splatv.STORAGE)
    order = align(source, hurt, storage=splatv.STORAGE)
    data, start = _records(faithful)
    same = (np.frombuffer(data[start:], np.uint8).reshape(-1, 64)
            == np.frombuffer(broken.read_bytes()[start:], np.uint8).reshape(-1, 64)).all(axis=1)
    same = same[:scene.count]
    np.testing.assert_array_equal(order[same], writer[same])
    # No count exceeds the values of the records that differ.
    attributes = verify_attributes(ply, broken)
    for group, a in attributes.items():
        assert a["unexplained"] <= differ * len(GROUPS[group]), (group, a["unexplained"], differ)
    errors = compare_scenes(source, hurt, order, splatv.STORAGE)
    assert sum(e.unexplained for e in errors.values()) > 0


def test_another_writers_order_is_still_paired_by_position(tmp_path):
    # Rows in an order no writer here produces: sorting both sides by position pairs them.
    scene, _ = real_scene(800, 7)
    original = tmp_path / "scene.splatv"
    unpadded_splatv(scene, original)
    from splatconv.formats import splatv

    from .conftest import splatv_bytes

    records, _ = splatv.encode(read(original))
    shuffled = tmp_path / "shuffled.splatv"
    records = records[:scene.count][np.random.default_rng(3).permutation(scene.count)]
    shuffled.write_bytes(splatv_bytes(records, pad=False))
    attributes = verify_attributes(original, shuffled)
    for group, a in attributes.items():
        assert a["unexplained"] == 0, group
