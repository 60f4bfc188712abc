"""Bake on what real trained scenes contain (tests.real_scenes): proved by pixels and by independent readings.

Real scenes hold splats with rotation (0, 0, 0, 0) and omega 0 (never drawn),
NaN positions, alpha bytes of 0, splats hidden in time, flat splats and
infinite temporal scales. A bake must write only what the viewer draws at
that time, draw as the 4D scene draws then, come out the same whether or not
the undrawable rows were there, and write nothing a reader decodes otherwise:
no zero or NaN quaternion (a ``.splat`` reader that decodes bytes as
``b / 255 * 2 - 1``, as splat-transform does, turns the bytes 128, 128, 128,
128 of a zero quaternion into a 120-degree rotation).
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, viewer
from splatconv.cli import main
from splatconv.model import COLUMNS, ROTATION, Scene
from splatconv.ops.bake import FLAT_LOG_SCALE, bake
from splatconv.render.layout import float_attributes

from .ops_helpers import CAMERA, coverage, draw, psnr, view_of
from .real_scenes import real_scene, unpadded_splatv

TIMES = (0.0, 0.3, 0.77, 1.0)
#: One .splat record, read here independently of splatconv.formats.splat.
SPLAT_RECORD = np.dtype([("xyz", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4), ("rot", "u1", 4)])


@pytest.fixture(scope="module")
def real():
    return real_scene(600, seed=0)


def without(scene: Scene, rows: np.ndarray) -> Scene:
    keep = np.setdiff1d(np.arange(scene.count), rows)
    return Scene(scene.take(keep), cameras=scene.cameras)


def test_the_scene_has_what_real_scenes_have(real):
    """Else the tests below prove nothing: every kind of undrawable splat, flat splats, a spinning zero rotation."""
    scene, rows = real
    counts = viewer.undrawable_counts(scene.columns)
    assert all(counts[k] > 0 for k in viewer.UNDRAWABLE_KINDS), counts
    assert counts["zero_rotation"] >= 0.35 * scene.count
    assert np.isneginf(scene.columns["scale_1"][rows.flat]).all()
    assert (np.asarray([scene.columns[n][rows.zero_rotation_spinning] for n in ROTATION]) == 0).all()


def test_undrawable_splats_are_drawn_at_no_time(real):
    """The one definition at one time agrees with the one over [0, 1]: an undrawable splat is drawn at no t."""
    scene, rows = real
    undrawable = viewer.undrawable(scene.columns)
    assert np.array_equal(np.flatnonzero(undrawable), rows.undrawable)
    for t in np.linspace(0.0, 1.0, 41):
        assert not viewer.drawn_at(scene.columns, t)[undrawable].any(), t


def _one_splat(rotation) -> Scene:
    """An opaque splat in front of the camera with ``rotation`` and no omega, and moving_scene's far invisible one."""
    cols = {k: np.zeros(2, np.float32) for k in COLUMNS}
    cols["z"][1], cols["opacity"][:], cols["rot_0"][1] = 60.0, (5.0, -40.0), 1.0
    for i in range(3):
        cols[f"scale_{i}"][0], cols[f"f_dc_{i}"][0] = np.log((0.5, 0.2, 0.3)[i]), 1.0
    cols["trbf_center"][:], cols["trbf_scale"][:] = 0.5, 5.0
    for name, v in zip(ROTATION, rotation):
        cols[name][0] = v
    return Scene(cols, cameras=[dict(CAMERA)])


@pytest.mark.parametrize("rotation, drawn", [
    ((1.0, 0.3, 0.0, 0.0), True),
    ((1e-15, 3e-16, 0.0, 0.0), True),
    ((1.1e-19, 0.0, 0.0, 0.0), True),  # squared length 1.21e-38: a normal float32
    ((1.05e-19, 0.0, 0.0, 0.0), False),  # 1.10e-38: subnormal, flushed
    ((1e-19, 3e-20, 0.0, 0.0), False),
    ((0.0, 0.0, 0.0, 0.0), False),
    ((np.nan, 1.0, 0.0, 0.0), False),
])
def test_rotation_with_no_direction_by_pixels(renderer, rotation, drawn):
    """Where the shader's float32 normalisation has a direction, the splat is drawn (llvmpipe flushes subnormals)."""
    scene = _one_splat(rotation)
    assert viewer.drawn_at(scene.columns, 0.5)[0] == drawn
    assert (coverage(draw(renderer, scene, 0.5)) > 0.01) == drawn


def test_bake_writes_only_what_the_viewer_draws_then(real):
    scene, rows = real
    for t in TIMES:
        baked, report = bake(scene, t)
        drawn = viewer.drawn_at(scene.columns, t)
        assert baked.count == np.count_nonzero(drawn) < scene.count - len(rows.undrawable)
        assert not drawn[rows.undrawable].any()
        assert drawn[rows.infinite_trbf].all()  # visible at every time
        assert np.array_equal(drawn[rows.flat], viewer.visible(scene.columns, t)[rows.flat])  # flat: drawn when visible
        left_out = {k: report.counts[k] for k in viewer.UNDRAWABLE_KINDS}
        assert sum(left_out.values()) == scene.count - baked.count
        assert left_out["zero_rotation"] >= len(rows.zero_rotation)
        note = next(n for n in report.notes if n.startswith("left out "))
        assert note.startswith(f"left out {scene.count - baked.count:,} splats the viewer does not draw at t={t:g} "
                               f"(zero rotation {left_out['zero_rotation']:,}, ")
        q = np.stack([baked.columns[n] for n in ROTATION], axis=1).astype(np.float64)
        assert np.isfinite(q).all() and np.allclose((q * q).sum(axis=1), 1.0, atol=1e-6)


def _drawn_in_order(renderer, scene: Scene, t: float, baked: Scene, kept: np.ndarray):
    """The 4D scene at ``t`` and the baked scene, both drawn in the baked scene's draw order."""
    view = view_of(CAMERA)
    renderer.load_float(float_attributes(baked))
    got = renderer.draw(view, 0.5)
    order = np.zeros(scene.count, dtype=np.int32)  # padding draws row 0, moving_scene's invisible far splat
    order[:baked.count] = kept[renderer.last_order]
    renderer.load_float(float_attributes(scene))
    return renderer.draw(view, t, order=order), got


def test_baked_real_scene_draws_as_the_4d_scene(renderer, real):
    """Float reference path, at several times, the baked scene drawn at other times (it is static).

    The viewer sorts a 4D scene by its rest positions and the baked scene by the
    positions at t, so each in its own order they blend overlaps differently
    (measured 43.8-47.4 dB); in the same order they differ by at most one level
    in a few pixels (measured 91-96 dB).
    """
    scene, rows = real
    assert scene.columns["opacity"][0] < -30  # row 0 is invisible: padding the order with it draws nothing
    for t in TIMES:
        want = draw(renderer, scene, t)
        assert coverage(want) > 0.3
        baked, _ = bake(scene, t)
        for shown in (0.0, 0.5, 1.0):
            assert psnr(want, draw(renderer, baked, shown)) >= 40, (t, shown)
        same_order, got = _drawn_in_order(renderer, scene, t, baked, np.flatnonzero(viewer.drawn_at(scene.columns, t)))
        assert np.abs(same_order.astype(int) - got.astype(int)).max() <= 1, t
        assert psnr(same_order, got) >= 80, t


@pytest.mark.parametrize("suffix", [".ply", ".splat", ".splatv"])
def test_baked_real_scene_identical_with_or_without_undrawable_rows(renderer, real, tmp_path, suffix):
    """The same rows, the same bytes, the same pixels, whether or not the scene held splats the viewer never draws."""
    scene, rows = real
    clean = without(scene, rows.undrawable)
    assert not viewer.undrawable(clean.columns).any()
    for t in (0.0, 0.77):
        full, full_report = bake(scene, t)
        lean, lean_report = bake(clean, t)
        assert full.count == lean.count
        for name in COLUMNS:
            assert np.array_equal(full.columns[name], lean.columns[name], equal_nan=True), name
        a, b = tmp_path / f"full{t}{suffix}", tmp_path / f"lean{t}{suffix}"
        io.write(full, a)
        io.write(lean, b)
        assert a.read_bytes() == b.read_bytes()
        for shown in (0.0, 1.0):
            assert np.array_equal(draw(renderer, io.read(a), shown, CAMERA), draw(renderer, io.read(b), shown, CAMERA))
        assert full_report.counts["zero_rotation"] > lean_report.counts["zero_rotation"]


def _decode_antimatter15(rot: np.ndarray) -> np.ndarray:
    """(b - 128) / 128, then normalised: antimatter15's and splaTV's reading."""
    q = (rot.astype(np.float64) - 128.0) / 128.0
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _decode_splat_transform(rot: np.ndarray) -> np.ndarray:
    """b / 255 * 2 - 1, then normalised (identity when zero): splat-transform's reading."""
    q = rot.astype(np.float64) / 255.0 * 2.0 - 1.0
    length = np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(length > 0, q / np.where(length > 0, length, 1.0), [1.0, 0.0, 0.0, 0.0])


def _angle_degrees(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle of the rotation from unit quaternion ``a`` to ``b``, row by row, in degrees."""
    return np.degrees(2.0 * np.arccos(np.clip(np.abs((a * b).sum(axis=1)), 0.0, 1.0)))


def test_baked_splat_rotations_read_alike_by_both_decodings(renderer, real, tmp_path):
    """Read the .splat's bytes with numpy; both decodings give the same rotation to within a degree, and draw alike.

    A unit quaternion has a component of size at least 0.5, 64 byte steps from
    128, so no record holds the zero quaternion's 128, 128, 128, 128; the two
    decodings then differ by an offset of 1/255 a component, under a degree.
    Near-zero rotations: one whose squared length is a normal float32 is
    normalised and written as the shader draws it (bytes checked); one whose
    squared length is subnormal is drawn by no GPU that flushes subnormals
    (llvmpipe draws nothing), and is left out.
    """
    scene, rows = real
    cols = {k: v.copy() for k, v in scene.columns.items()}
    tiny, subnormal = rows.huge_position[0], rows.huge_position[1]
    cols["x"][[tiny, subnormal]] = 0.0
    for name, v in zip(ROTATION, (1e-15, 3e-16, 0.0, 0.0)):
        cols[name][tiny] = v
    for name, v in zip(ROTATION, (1e-19, 3e-20, 0.0, 0.0)):
        cols[name][subnormal] = v
    for name in ("omega_0", "omega_1", "omega_2", "omega_3"):
        cols[name][[tiny, subnormal]] = 0.0
    scene = Scene(cols, cameras=scene.cameras)
    t = 0.3
    drawn = viewer.drawn_at(scene.columns, t)
    assert drawn[tiny] and not drawn[subnormal]
    baked, _ = bake(scene, t)
    out = tmp_path / "moment.splat"
    io.write(baked, out, sort="none")
    records = np.frombuffer(out.read_bytes(), dtype=SPLAT_RECORD)
    assert len(records) == baked.count
    rot = records["rot"]
    assert not (rot == 128).all(axis=1).any()
    raw = (rot.astype(np.float64) - 128.0) / 128.0
    assert (np.abs(raw).max(axis=1) >= 63 / 128).all()  # far from degenerate, either way it is read
    a, b = _decode_antimatter15(rot), _decode_splat_transform(rot)
    assert np.isfinite(a).all() and np.isfinite(b).all()
    assert _angle_degrees(a, b).max() < 1.0  # measured 0.90 degrees
    # What the zero quaternion's bytes were to splat-transform: a 120-degree rotation, not "no rotation".
    zero = np.full((1, 4), 128, dtype=np.uint8)
    assert _angle_degrees(_decode_splat_transform(zero), np.array([[1.0, 0, 0, 0]]))[0] == pytest.approx(120.0)
    # The near-zero rotation: the shader's float32 normalisation of (1e-15, 3e-16, 0, 0), as bytes.
    q32 = np.array([1e-15, 3e-16, 0.0, 0.0], dtype=np.float32)
    unit = q32 / np.sqrt(np.dot(q32, q32))
    row = int(np.searchsorted(np.flatnonzero(drawn), tiny))
    assert list(rot[row]) == list(np.rint(unit.astype(np.float64) * 128 + 128).clip(0, 255).astype(int))
    # The spinning zero rotations (rot 0, omega not) at t: omega * dt, normalised, to within a byte step.
    spinning = rows.zero_rotation_spinning[drawn[rows.zero_rotation_spinning]]
    assert len(spinning)
    dt = t - scene.columns["trbf_center"][spinning].astype(np.float64)
    omega = np.stack([scene.columns[f"omega_{i}"][spinning] for i in range(4)], axis=1) * dt[:, None]
    want = (omega / np.linalg.norm(omega, axis=1, keepdims=True) * 128 + 128).clip(0, 255)
    got = rot[np.searchsorted(np.flatnonzero(drawn), spinning)]
    assert np.abs(got - want).max() <= 0.5 + 1e-6
    # Drawn: the file as splatconv (and antimatter15) reads it, and with splat-transform's rotations.
    ours = io.read(out)
    theirs = {k: v.copy() for k, v in ours.columns.items()}
    for i, name in enumerate(ROTATION):
        theirs[name][:] = b[:, i]
    theirs = Scene(theirs, cameras=ours.cameras)
    for shown in (0.0, 1.0):
        mine = draw(renderer, ours, shown, CAMERA)
        assert coverage(mine) > 0.3
        assert psnr(mine, draw(renderer, theirs, shown, CAMERA)) >= 50  # measured 55.9-57.5 dB


def _read_ply_vertices(path) -> np.ndarray:
    """A binary little-endian 3DGS PLY's vertex table, read from its header with numpy alone."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[1] == "format binary_little_endian 1.0"
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    types = {"float": "<f4", "double": "<f8", "uchar": "u1", "int": "<i4", "uint": "<u4"}
    fields = [(line.split()[2], types[line.split()[1]]) for line in header if line.startswith("property ")]
    return np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=end)


def test_bake_command_on_a_real_file_writes_no_nan_and_no_zero_quaternion(tmp_path, real):
    """An unpadded .splatv, as real files are; the outputs read back with numpy alone."""
    scene, _rows = real
    src = tmp_path / "real.splatv"
    unpadded_splatv(scene, src)
    read = io.read(src)
    for t in (0.0, 0.5):
        drawn = viewer.drawn_at(read.columns, t)
        ply, splat = tmp_path / f"m{t}.ply", tmp_path / f"m{t}.splat"
        for out in (ply, splat):
            r = CliRunner().invoke(main, ["bake", str(src), str(out), "--time", str(t)])
            assert r.exit_code == 0, r.output
            assert r.stdout.startswith(f"wrote {out}: {np.count_nonzero(drawn):,} splats")
            assert (f"note: left out {np.count_nonzero(~drawn):,} splats the viewer does not draw at t={t:g} "
                    "(zero rotation ") in r.stderr
        v = _read_ply_vertices(ply)
        assert len(v) == np.count_nonzero(drawn)
        for name in v.dtype.names:
            assert np.isfinite(v[name]).all(), name
        q = np.stack([v[n] for n in ROTATION], axis=1).astype(np.float64)
        assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)
        flat = np.isneginf(read.columns["scale_1"][drawn])
        assert flat.any() and (v["scale_1"][flat] == FLAT_LOG_SCALE).all()
        records = np.frombuffer(splat.read_bytes(), dtype=SPLAT_RECORD)
        assert len(records) == len(v)
        assert not (records["rot"] == 128).all(axis=1).any()
        assert np.isfinite(records["xyz"]).all() and np.isfinite(records["scale"]).all()
        assert np.count_nonzero((records["scale"] == 0).any(axis=1)) == np.count_nonzero(flat)
        assert (records["rgba"][:, 3] > 0).all()


def test_bake_frames_of_a_real_file(tmp_path, real):
    """A flipbook of .splat frames with --drop-nonfinite: each frame only what is drawn then, all finite, no zero
    quaternion, and each frame's note says what was left out."""
    scene, _rows = real
    src = tmp_path / "real.splatv"
    unpadded_splatv(scene, src)
    read = io.read(src)
    out = tmp_path / "flip"
    r = CliRunner().invoke(main, ["bake", str(src), str(out), "--frames", "3", "--frame-suffix", ".splat",
                                  "--drop-nonfinite"])
    assert r.exit_code == 0, r.output
    for k, t in enumerate((0.0, 0.5, 1.0)):
        drawn = viewer.drawn_at(read.columns, t)
        records = np.frombuffer((out / f"frame_000{k}.splat").read_bytes(), dtype=SPLAT_RECORD)
        assert len(records) == np.count_nonzero(drawn)  # the huge positions are finite: none dropped
        assert not (records["rot"] == 128).all(axis=1).any()
        assert np.isfinite(records["xyz"]).all() and np.isfinite(records["scale"]).all()
        assert (f"note: frame_000{k}.splat: left out {np.count_nonzero(~drawn):,} splats the viewer does not draw "
                f"at t={t:g} (") in r.stderr
        assert (f"note: frame_000{k}.splat: drop-nonfinite: removed 0 of {np.count_nonzero(drawn):,} splats"
                in r.stderr)
