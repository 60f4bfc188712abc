"""``stats`` and ``.splatvq``: a scene's size as ``.splatvq`` at each setting, measured on the encode, and the
true per-attribute error of a ``.splatvq`` against its source."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io
from splatconv.cli import main
from splatconv.formats import splatv, splatvq
from splatconv.formats import splatvq_codec as codec
from splatconv.viewer import sort_ends, undrawable
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
    drawable = int(np.count_nonzero(~undrawable(scene.columns) | sort_ends(scene.columns, scene.cameras)))
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
    opacity, kept as the source .splatv's bytes, exactly 0, and colour too but at `small`, which rounds
    it to multiples of 4 levels (at most 2 off); every quantized group off by a little, but off. The rotation and omega are compared as the viewer turns a splat: the file normalises the rotation
    and chooses its sign, which the stored numbers would count as errors of up to several units."""
    out = tmp_path / f"{quality}.splatvq"
    assert run("convert", files / "real.splatv", out, "--quality", quality, "--no-proof").exit_code == 0
    data = stats_json(files / "real.splatv", out)
    errors = data["attributes"]
    assert errors["opacity"]["max_abs_error"] == errors["opacity"]["rmse"] == 0
    shift = codec.SETTINGS[quality].color_shift
    if shift:
        assert 0 < errors["color"]["max_abs_error"] <= (1 << (shift - 1)) / 255 + 1e-6
    else:
        assert errors["color"]["max_abs_error"] == errors["color"]["rmse"] == 0
    for group in QUANTIZED:
        assert errors[group]["max_abs_error"] > 0, group
    assert errors["position"]["max_abs_error"] <= position_bound(out, quality)
    # Smallest-three components of a unit quaternion: a kept one is off by at most half a code step,
    # sqrt(1/2) / M; the dropped one, made from the other three, by at most about twice that.
    bits = splatvq.codec.SETTINGS[quality].rotation_bits
    assert errors["rotation"]["max_abs_error"] < 2 * np.sqrt(0.5) / ((1 << bits) - 1)
    # Half a lattice step of the largest splat the file holds (its scales, in viewer units, are linear).
    scene = io.read(files / "real.splatv")
    held = ~undrawable(scene.columns) | sort_ends(scene.columns, scene.cameras)
    largest = max(float(np.exp(scene.columns[f"scale_{i}"][held].max())) for i in range(3))
    step = splatvq.codec.SETTINGS[quality].scale_step
    assert errors["scale"]["max_abs_error"] <= largest * (2 ** (step / 2048) - 1)
    # omega * W is what is quantized (W the splat's time window), so a short-lived splat's omega takes a
    # coarse step: the bound is loose, but far below the 8 the stored numbers compared as they are gave.
    assert errors["omega"]["max_abs_error"] < 0.5
    # Half a lattice step of the longest-lived splat's temporal scale, or of the temporal centre.
    setting = splatvq.codec.SETTINGS[quality]
    trbf = np.exp(scene.columns["trbf_scale"][held].astype(np.float64))
    longest = float(trbf[np.isfinite(trbf)].max())
    assert errors["trbf"]["max_abs_error"] <= max(longest * (2 ** (setting.trbf_scale_step / 2048) - 1),
                                                  2.0 ** -(setting.time_shift + 1))
    # So are the acceleration and jerk, the more so at the small setting (2 and 4 times the velocity's step),
    # and a splat of boost level 0 takes a position step four times version 4's, its motion step with it.
    assert errors["motion"]["max_abs_error"] < 8.0
    # Against the PLY (float colours), colour and opacity are off by the byte's rounding only (and the
    # colour by the setting's rounding of the byte).
    errors = stats_json(files / "real.ply", out)["attributes"]
    assert 0 < errors["opacity"]["max_abs_error"] <= 0.5 / 255 + 1e-6
    assert 0 < errors["color"]["max_abs_error"] <= (0.5 + (1 << shift >> 1)) / 255 + 1e-6
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


# --------------------------------------------------------------------------
# Pairing by content, and a summary that says which file it describes


def position_bound(path, quality: str) -> float:
    """The largest position move the setting allows any splat of the file: 2^(k - 1), k = s + position_shift + c
    (specs/splatvq.md), from the file's decoded scales and alpha bytes; independent of any pairing."""
    from splatconv.packing import float_to_half

    cols = io.read(path).columns
    setting = splatvq.codec.SETTINGS[quality]
    halves = np.stack([float_to_half(np.exp(cols[f"scale_{i}"].astype(np.float64)).astype(np.float32))
                       for i in range(3)], axis=1).astype(np.int64)
    s = np.clip((np.sort(halves, axis=1)[:, 1] >> 10) - 15, -15, 16)
    alpha = np.rint(255 / (1 + np.exp(-cols["opacity"].astype(np.float64))))
    c = np.minimum(setting.alpha_levels, 7 - np.floor(np.log2(np.maximum(alpha, 1)))).astype(np.int64)
    return float(np.max(2.0 ** (s + setting.position_shift + c - 1)))


@pytest.fixture(scope="module")
def shuffled(files, real):
    """The real-like scene's .splatv with its splats in another order (written as they come), and the .splatvq
    converted from the unshuffled file."""
    scene = io.read(files / "real.splatv")
    order = np.random.default_rng(11).permutation(scene.count)
    moved = type(scene)(columns=scene.take(order), cameras=scene.cameras)
    io.write(moved, files / "shuffled.splatv", sort="none")
    assert run("convert", files / "real.splatv", files / "real.splatvq").exit_code == 0
    return files / "shuffled.splatv", files / "real.splatvq"


def test_a_shuffled_source_gives_the_same_errors_and_positions_within_the_quantization(files, shuffled):
    """Rows are paired by content (colour word, then nearest position), never by the source's file order:
    the source in any order gives the same errors, the positions within what the setting allows, and the
    infinite temporal scales both sides hold are not counted."""
    source, quantized = shuffled
    plain = stats_json(files / "real.splatv", quantized)
    mixed = stats_json(source, quantized)
    assert plain["pairing"] == mixed["pairing"] == {"paired": plain["described"]["count"], "unpaired": 0}
    for group, errors in plain["attributes"].items():
        for key, value in errors.items():
            assert mixed["attributes"][group][key] == pytest.approx(value, rel=1e-9, abs=1e-15), (group, key)
    assert 0 < mixed["attributes"]["position"]["max_abs_error"] <= position_bound(quantized, "default")
    assert mixed["attributes"]["trbf"]["nonfinite"] == 0
    assert io.read(source).columns["trbf_scale"].max() == np.inf  # the scene holds some


def test_a_splat_no_colour_pairs_with_is_counted_unpaired_never_as_an_error(tmp_path, files):
    """A CONVERTED splat whose colour word SOURCE does not hold is left out of the errors and counted (the
    records in another order, so no writer's order pairs them)."""
    from .conftest import splatv_bytes

    records, _ = splatv.encode(io.read(files / "real.splatv"))
    n = io.read(files / "real.splatv").count
    records = records[:n].copy()
    words = records[:, 7]
    row = int(np.flatnonzero(words >> 24 > 0)[0])
    unused = next(w for w in range(1 << 24, 1 << 25) if w not in set(words.tolist()))
    records[row, 7] = np.uint32(unused | int(words[row]) & 0xFF000000)
    records = records[np.random.default_rng(5).permutation(n)]
    (tmp_path / "other.splatv").write_bytes(splatv_bytes(records, pad=False))
    data = stats_json(files / "real.splatv", tmp_path / "other.splatv")
    assert data["pairing"] == {"paired": n - 1, "unpaired": 1}
    assert data["attributes"]["color"]["max_abs_error"] == 0
    assert data["attributes"]["position"]["max_abs_error"] == 0
    text = run("stats", files / "real.splatv", tmp_path / "other.splatv", "--zstd-level", "1").stdout
    assert "pairing: 1 of CONVERTED's" in " ".join(text.split())


def test_each_summary_line_names_the_file_it_describes(files, shuffled, real):
    """SOURCE holds NaN positions and undrawable splats, the .splatvq only the few its depth sort needs: each
    line says whose it is."""
    _, quantized = shuffled
    source = files / "real.splatv"
    scene = io.read(source)
    kept = int(np.count_nonzero(undrawable(io.read(quantized).columns)))
    drawable = int(np.count_nonzero(~undrawable(scene.columns)))
    nan = int(np.count_nonzero((~np.isfinite(np.stack([scene.columns[c] for c in "xyz"]))).any(axis=0)))
    assert nan > 0 and drawable < scene.count
    data = stats_json(source, quantized)
    assert data["count"] == scene.count
    assert data["described"] == {"role": "converted", "path": str(quantized), "count": drawable + kept,
                                 "omega": "per unit quaternion"}
    assert 0 < sum(data["undrawable"].values()) == kept < 16
    assert (data["viewer"]["role"], data["viewer"]["path"], data["viewer"]["nan_positions"]) == ("source", str(source), nan)
    text = run("stats", source, quantized, "--zstd-level", "1").stdout
    lines = []
    for line in text.split("\n\n")[-1].splitlines():  # wrapped lines go on indented
        if line.startswith("  "):
            lines[-1] += " " + line.strip()
        else:
            lines.append(line)
    assert lines[0].startswith(f"count: SOURCE {source}: {scene.count:,} splats; CONVERTED ")
    assert lines[1].startswith(f"undrawable (CONVERTED): {kept:,} ")
    assert [line.split(":")[0] for line in lines[2:]] == ["bounds (CONVERTED)", "time (CONVERTED)",
                                                          "viewer (SOURCE)"]
    assert f"NaN positions {nan:,}" in " ".join(text.split())
    assert "motion and rotation speed of CONVERTED's drawable splats (per unit time; omega per unit quaternion):" in text


def test_the_speed_table_is_over_the_drawable_splats(tmp_path):
    """A scene 95% undrawable (zero rotations, omega 0): the medians are those of the splats the viewer draws."""
    scene, _ = real_scene(800, seed=9, zero_share=0.95)
    unpadded_splatv(scene, tmp_path / "mostly.splatv")
    cols = io.read(tmp_path / "mostly.splatv").columns
    keep = ~undrawable(cols)
    assert keep.mean() < 0.1
    data = stats_json(tmp_path / "mostly.splatv")
    omega = np.sqrt(sum(cols[f"omega_{i}"].astype(np.float64) ** 2 for i in range(4)))[keep]
    velocity = np.sqrt(sum(cols[f"motion_{i}"].astype(np.float64) ** 2 for i in range(3)))[keep]
    assert data["motion"]["omega"]["p50"] == pytest.approx(np.median(omega[np.isfinite(omega)]), rel=1e-12)
    assert data["motion"]["omega"]["p50"] > 0
    assert data["motion"]["velocity"]["p50"] == pytest.approx(np.median(velocity[np.isfinite(velocity)]), rel=1e-12)
    assert data["described"]["omega"] == "as stored"
