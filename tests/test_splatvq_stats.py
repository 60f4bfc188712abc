"""``stats`` and ``.splatvq``: a scene's size as ``.splatvq`` at each setting, measured on the encode, and the
true per-attribute error of a ``.splatvq`` against its source."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io
from splatconv.cli import main
from splatconv.formats import splatvq
from splatconv.viewer import undrawable
from tests.real_scenes import real_scene, unpadded_splatv

QUALITIES = splatvq.QUALITIES
#: The groups a .splatvq quantizes; colour and opacity it keeps as the texture's bytes.
QUANTIZED = ("position", "rotation", "scale", "motion", "omega", "trbf")


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def real():
    return real_scene(1200, seed=7)


@pytest.fixture(scope="module")
def files(tmp_path_factory, real):
    """The real-like scene as a PLY and as a .splatv written the way real files are (unpadded)."""
    folder = tmp_path_factory.mktemp("stats")
    io.write(real[0], folder / "real.ply")
    unpadded_splatv(real[0], folder / "real.splatv")
    return folder


def stats_json(*args):
    r = run("stats", *args, "--json", "--zstd-level", "1")
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)


@pytest.mark.parametrize("name", ["real.ply", "real.splatv"])
def test_stats_of_one_file_gives_its_splatvq_size_at_each_setting(files, real, name):
    """Measured on the writer's own bytes, per drawable splat (the file leaves the others out)."""
    scene = io.read(files / name)
    drawable = int(np.count_nonzero(~undrawable(scene.columns)))
    assert drawable < scene.count
    data = stats_json(files / name)
    assert [q["quality"] for q in data["quantized"]] == list(io.QUALITIES)
    source_bytes = data["files"][0]["bytes"]
    for entry in data["quantized"]:
        written = splatvq.encode(scene, quality=entry["quality"])[0]
        assert entry == {"format": "splatvq", "quality": entry["quality"], "splats": drawable,
                         "bytes": len(written), "bytes_per_splat": round(len(written) / drawable, 3),
                         "ratio": round(len(written) / source_bytes, 6)}
    # The text and the Markdown print the same figures.
    text = run("stats", files / name, "--zstd-level", "1").stdout
    markdown = run("stats", files / name, "--zstd-level", "1", "--markdown").stdout
    assert "splatvq, each setting (encoded in memory; B/splat: per drawable splat, the only ones held):" in text
    for entry in data["quantized"]:
        row = [entry["quality"], f"{entry['splats']:,}", f"{entry['bytes']:,}", f"{entry['bytes_per_splat']:,.2f}",
               f"{entry['ratio']:.3f}"]
        assert any(line.split() == row for line in text.splitlines()), row
        assert "| " + " | ".join(row) + " |" in markdown
    assert all(len(line) <= 100 for line in text.splitlines())


def test_no_sizes_with_two_files_and_an_empty_list_for_a_scene_none_of_whose_splats_is_drawn(tmp_path, files, real):
    assert stats_json(files / "real.ply", files / "real.splatv")["quantized"] is None
    hidden = real[0]
    hidden = type(hidden)(columns={**hidden.columns, "opacity": np.full(hidden.count, -100.0, np.float32)},
                          cameras=hidden.cameras)
    io.write(hidden, tmp_path / "hidden.ply")
    data = stats_json(tmp_path / "hidden.ply")
    assert data["quantized"] == []
    assert any(n.startswith("no .splatvq size: none of the 1,200 splats can be drawn") for n in data["notes"])


@pytest.mark.parametrize("quality", QUALITIES)
def test_stats_of_a_splatvq_against_its_source_gives_the_true_errors(tmp_path, files, quality):
    """Paired with the source's drawable splats (the file leaves the undrawable ones out and reorders):
    colour and opacity, kept as the source .splatv's bytes, exactly 0; every quantized group off by a little,
    but off. The rotation and omega are compared as the viewer turns a splat: the file normalises the rotation
    and chooses its sign, which the stored numbers would count as errors of up to several units."""
    out = tmp_path / f"{quality}.splatvq"
    assert run("convert", files / "real.splatv", out, "--quality", quality).exit_code == 0
    data = stats_json(files / "real.splatv", out)
    errors = data["attributes"]
    for group in ("color", "opacity"):
        assert errors[group]["max_abs_error"] == errors[group]["rmse"] == 0, group
    for group in QUANTIZED:
        assert errors[group]["max_abs_error"] > 0, group
    assert errors["position"]["max_abs_error"] < 0.01
    # Smallest-three components of a unit quaternion: a kept one is off by at most half a code step,
    # sqrt(1/2) / M; the dropped one, made from the other three, by at most about twice that.
    bits = splatvq.codec.SETTINGS[quality].rotation_bits
    assert errors["rotation"]["max_abs_error"] < 2 * np.sqrt(0.5) / ((1 << bits) - 1)
    assert errors["scale"]["max_abs_error"] < 0.01
    # omega * W is what is quantized (W the splat's time window), so a short-lived splat's omega takes a
    # coarse step: the bound is loose, but far below the 8 the stored numbers compared as they are gave.
    assert errors["omega"]["max_abs_error"] < 0.5
    assert errors["trbf"]["max_abs_error"] < 0.05
    assert errors["motion"]["max_abs_error"] < 0.5
    # Against the PLY (float colours), colour and opacity are off by the byte's rounding only.
    errors = stats_json(files / "real.ply", out)["attributes"]
    for group in ("color", "opacity"):
        assert 0 < errors[group]["max_abs_error"] <= 0.5 / 255 + 1e-6, group
    assert errors["rotation"]["max_abs_error"] < 2 * np.sqrt(0.5) / ((1 << bits) - 1)
    assert errors["omega"]["max_abs_error"] < 0.5


def test_the_rotation_of_a_file_that_keeps_it_is_compared_as_stored(tmp_path, files):
    """A .splatv keeps the rotation's own values (halves): its errors stay those of the stored numbers."""
    from splatconv.compare import compare_scenes
    from splatconv.formats import splatv

    scene = io.read(files / "real.ply")
    # Rows whose rotation has a length (a zero one is compared as stored on both counts).
    q = np.stack([scene.columns[f"rot_{i}"] for i in range(4)], axis=1).astype(np.float64)
    turning = np.isfinite(q).all(axis=1) & ((q * q).sum(axis=1) > 0)
    scene = type(scene)(columns=scene.take(np.flatnonzero(turning)))
    scaled = dict(scene.columns)
    for i in range(4):  # q and omega times -3: the same turning, other numbers
        scaled[f"rot_{i}"] = scaled[f"rot_{i}"] * np.float32(-3)
        scaled[f"omega_{i}"] = scaled[f"omega_{i}"] * np.float32(-3)
    other = type(scene)(columns=scaled)
    kept = compare_scenes(scene, other, None, splatv.STORAGE)
    assert kept["rotation"].max_abs_error > 1 and kept["rotation"].unexplained > 0
    as_drawn = compare_scenes(scene, other, None, splatvq.STORAGE)
    assert as_drawn["rotation"].max_abs_error < 1e-6 and as_drawn["omega"].max_abs_error < 1e-5
