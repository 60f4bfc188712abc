"""merge: several scenes on one timeline, proved by pixels through the float reference renderer."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io, model, viewer
from splatconv.cli import main
from splatconv.model import Scene
from splatconv.ops import apply_transform, make_transform
from splatconv.ops.bake import bake
from splatconv.ops.merge import overlay

from .test_bake import SAMPLE, draw, psnr
from .cli_checks import error_line

TIMES = (0.0, 0.5, 1.0)


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def moved(scene: Scene, dx=0.0, dy=0.0, dz=0.0) -> Scene:
    """The scene translated (test helper: a translation moves rest positions only, motion is relative)."""
    cols = {name: np.array(scene.columns[name]) for name in model.COLUMNS}
    cols["x"] += np.float32(dx)
    cols["y"] += np.float32(dy)
    cols["z"] += np.float32(dz)
    return Scene(columns=cols, cameras=scene.cameras, variant=scene.variant)


def shrunk(scene: Scene, factor: float) -> Scene:
    """The scene scaled about the origin (positions, motion and splat sizes), to fit beside another."""
    cols = {name: np.array(scene.columns[name]) for name in model.COLUMNS}
    for name in model.POSITION + model.MOTION:
        cols[name] *= np.float32(factor)
    for name in model.SCALE:
        cols[name] += np.float32(np.log(factor))
    return Scene(columns=cols, cameras=scene.cameras, variant=scene.variant)


@pytest.fixture(scope="module")
def actor():
    return io.read(SAMPLE)


@pytest.fixture(scope="module")
def background(actor):
    """A static 3DGS scene behind the actor: the sample's first moment, pushed away from the camera."""
    wall, _ = bake(actor, 0.0)
    return moved(wall, dz=2.0)


def test_two_actors_side_by_side_match_their_parts(actor):
    """Actors whose pictures do not overlap: the composed picture is the sum of the two, at every time.

    To one 8-bit step: the draw order comes from the viewer's 16-bit depth sort
    over the scene's depth range, which the other actor widens, so nearly equal
    depths may swap (one pixel's alpha here).
    """
    left, right = moved(shrunk(actor, 0.45), dx=-1.0), moved(shrunk(actor, 0.45), dx=1.0, dy=0.1)
    merged, report = overlay([left, right])
    assert report.parts == [actor.count, actor.count] and merged.count == 2 * actor.count
    for t in TIMES:
        a, b = draw(left, t), draw(right, t)
        assert a[..., 3].any() and b[..., 3].any()
        assert not ((a[..., 3] > 0) & (b[..., 3] > 0)).any()  # disjoint, so the sum is the answer
        both = draw(merged, t)
        off = np.abs(both.astype(int) - (a.astype(int) + b.astype(int))).max(axis=2)
        assert off.max() <= 1 and (off > 0).mean() < 0.001


def test_static_background_stays_at_full_opacity(actor, background):
    """Where the actor never draws, the composed scene shows the background alone, the same at every time."""
    merged, _ = overlay([background, actor])
    alone = draw(background, 0.5)
    assert alone[..., 3].mean() > 20
    actor_drawn = np.zeros(alone.shape[:2], bool)
    for t in TIMES:
        actor_drawn |= draw(actor, t)[..., 3] > 0
    assert (~actor_drawn).mean() > 0.2
    for t in TIMES:
        assert np.array_equal(draw(background, t), alone)
        both = draw(merged, t)
        # Off by one 8-bit step at most (2 pixels here): the viewer's 16-bit depth
        # sort spans the composed scene's depth range, so nearly equal depths may swap.
        assert np.abs(both[~actor_drawn].astype(int) - alone[~actor_drawn].astype(int)).max() <= 1
        # Where the actor is, it is in front: the picture differs from the background alone.
        assert psnr(both, alone) < 40


def test_a_temporal_scale_of_one_would_fade_the_background(background):
    """The check above can fail: a background with exp(trbf_scale) = 1 fades towards the clip's ends."""
    cols = {name: np.array(background.columns[name]) for name in model.COLUMNS}
    cols["trbf_scale"][:] = 0.0
    faded = Scene(columns=cols)
    a, b = draw(faded, 0.0), draw(background, 0.0)
    assert np.abs(a.astype(int) - b.astype(int)).max() > 20


def test_merge_command_matches_the_parts_drawn_together(actor, background, tmp_path):
    bg, act = tmp_path / "bg.ply", tmp_path / "actor.ply"
    io.write(background, bg)
    io.write(actor, act)
    assert io.read(bg).variant == model.VARIANT_3DGS
    together, _ = overlay([io.read(bg), io.read(act)])
    for suffix, floor in ((".ply", None), (".splatv", 50)):
        out = tmp_path / f"scene{suffix}"
        r = run("merge", bg, act, out)
        assert r.exit_code == 0, r.output
        total = actor.count + background.count
        assert r.stdout == f"wrote {out}: {total:,} splats, {out.stat().st_size:,} bytes\n"
        assert (f"note: merged 2 scenes on one timeline: {background.count:,} + {actor.count:,} = "
                f"{total:,} splats\n") in r.stderr
        back = io.read(out)
        for t in TIMES:
            want, got = draw(together, t), draw(back, t)
            if floor is None:
                assert np.array_equal(want, got)  # the lite PLY holds the floats exactly
            else:
                assert psnr(want, got) >= floor


def test_merged_static_scenes_stay_static(tmp_path, background, actor):
    a, b = tmp_path / "a.splat", tmp_path / "b.ply"
    io.write(background, a)
    io.write(bake(actor, 0.5)[0], b)
    out = tmp_path / "both.ply"
    assert run("merge", a, b, out).exit_code == 0
    back = io.read(out)
    assert back.variant == model.VARIANT_3DGS  # written as 3DGS
    assert run("merge", a, b, tmp_path / "both.splat").exit_code == 0
    # With a moving input a static output is refused, and nothing is written.
    act = tmp_path / "act.ply"
    io.write(actor, act)
    r = run("merge", a, act, tmp_path / "no.splat")
    assert r.exit_code == 1
    assert r.stderr.splitlines()[-1] == (f"Error: {tmp_path / 'no.splat'}: {actor.count:,} of "
                                         f"{actor.count + background.count:,} splats move, turn or fade over time "
                                         "and a .splat file is static; bake one moment with `splatconv bake INPUT "
                                         "OUTPUT --time T`")
    assert not (tmp_path / "no.splat").exists()


def test_cameras_of_the_first_input_that_has_them(actor, sample_splatv):
    no_cams = Scene(columns=actor.columns, cameras=None)
    merged, report = overlay([no_cams, io.read(sample_splatv), io.read(sample_splatv)])
    assert merged.cameras == io.read(sample_splatv).cameras
    assert report.counts["cameras_from"] == 2
    assert "cameras: input 2's 3 kept; those of input 3 dropped" in report.notes
    assert overlay([no_cams, no_cams])[0].cameras is None


def test_merge_keeps_nonfinite_values_as_they_are(actor):
    cols = {name: np.array(actor.columns[name][:10]) for name in model.COLUMNS}
    cols["x"][0] = np.nan
    cols["trbf_scale"][1] = np.inf
    merged, _ = overlay([Scene(columns=cols), actor])
    assert np.isnan(merged.columns["x"][0]) and np.isinf(merged.columns["trbf_scale"][1])
    assert np.array_equal(merged.columns["opacity"][10:], actor.columns["opacity"])
    assert viewer.temporal_opacity(merged.columns, 0.0)[1] == 1.0


def test_per_input_transforms_place_each_input(actor, tmp_path):
    """--scale N:S and --translate N:X,Y,Z move input N only: two actors side by side from one file."""
    src = tmp_path / "actor.ply"
    io.write(actor, src)
    out = tmp_path / "duet.ply"
    r = run("merge", src, src, out, "--scale", "1:0.45", "--translate", "1:-1,0,0", "--translate", "2:1,0.1,0",
            "--scale", "2:0.45")
    assert r.exit_code == 0, r.output
    assert "note: input 1 (" in r.stderr and "note: input 2 (" in r.stderr
    want, _ = overlay([moved(shrunk(actor, 0.45), dx=-1.0), moved(shrunk(actor, 0.45), dx=1.0, dy=0.1)])
    back = io.read(out)
    for t in TIMES:
        assert psnr(draw(want, t), draw(back, t)) >= 50


def test_rotate_applies_to_its_input_only(actor, tmp_path):
    src = tmp_path / "actor.ply"
    io.write(actor, src)
    out = tmp_path / "turned.ply"
    assert run("merge", src, src, out, "--rotate", "2:y:90,x:30").exit_code == 0
    turned, _ = apply_transform(io.read(src), make_transform(rotate="y:90,x:30"))
    want, _ = overlay([io.read(src), turned])
    back = io.read(out)
    for name in model.COLUMNS:
        assert np.array_equal(back.columns[name], want.columns[name], equal_nan=True), name
    assert back.cameras == want.cameras


@pytest.mark.parametrize("args, code, message", [
    (["only.ply"], 2, "merge needs at least two INPUT files and an OUTPUT"),
    (["a.ply", "out.ply"], 2, "merge needs at least two INPUT files and an OUTPUT"),
    (["a.ply", "b.ply", "out.ply", "--translate", "3:1,0,0"], 2, "--translate 3:...: there are 2 inputs (1..2)"),
    (["a.ply", "b.ply", "out.ply", "--scale", "1:2", "--scale", "1:3"], 2, "--scale given twice for input 1"),
    (["a.ply", "b.ply", "out.ply", "--translate", "1,0,0"], 2,
     "Invalid value for '--translate': '1,0,0': expected N:X,Y,Z, N the input's number (1 for the first)."
     " See 'main merge --help'."),
    (["a.ply", "b.ply", "out.ply", "--scale", "0:2"], 2,
     "Invalid value for '--scale': '0:2': expected N:S, N the input's number (1 for the first)."
     " See 'main merge --help'."),
    (["a.ply", "b.ply", "out.ply", "--scale", "1:-2"], 2,
     "Invalid value for '--scale': -2.0 is not in the range x>0. See 'main merge --help'."),
])
def test_merge_usage_errors(tmp_path, args, code, message, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = run("merge", *args)
    assert r.exit_code == code and r.stderr.splitlines()[-1] == f"Error: {message}"


def test_merge_bad_inputs_give_one_error_line(tmp_path, sample_splatv):
    bad = tmp_path / "bad.splat"
    bad.write_bytes(b"\0" * 40)
    out = tmp_path / "out.splatv"
    r = run("merge", sample_splatv, bad, out)
    assert r.exit_code == 1
    assert r.stderr == (f"Error: {bad}: size 40 bytes is not a whole number of 32-byte records: 8 bytes after "
                        "record 1; file truncated?\n")
    assert not out.exists()
    # Onto an input: refused even with --force.
    r = run("merge", sample_splatv, bad, sample_splatv, "--force")
    assert error_line(r, 1).startswith(f"Error: {sample_splatv}: is the input file")
    # An existing output needs --force.
    out.write_bytes(b"x")
    r = run("merge", sample_splatv, sample_splatv, out)
    assert error_line(r, 1).startswith(f"Error: {out}: already exists")
    assert out.read_bytes() == b"x"


def test_merge_drop_nonfinite_applies_to_every_input(tmp_path, actor):
    cols = {name: np.array(actor.columns[name][:50]) for name in model.COLUMNS}
    cols["rot_1"][:4] = np.inf
    a = tmp_path / "a.ply"
    io.write(Scene(columns=cols), a)
    out = tmp_path / "out.ply"
    r = run("merge", a, a, out, "--drop-nonfinite")
    assert r.exit_code == 0, r.output
    assert r.stderr.count("note: input ") >= 2 and "drop-nonfinite" in r.stderr
    assert io.read(out).count == 2 * 46


def test_merge_has_no_mode_option(tmp_path):
    # --mode had one choice and was never read: it is gone from the command and its help.
    help_text = run("merge", "--help").stdout
    assert "--mode" not in help_text and "overlay:" not in help_text
    r = run("merge", tmp_path / "a.ply", tmp_path / "b.ply", tmp_path / "c.ply", "--mode", "overlay")
    assert r.exit_code == 2 and "No such option '--mode'" in r.stderr
