"""``convert OUT.splatvq --min-psnr / --max-bytes``: the quality a compressed file proves, and its size."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import formats, io, viewer
from splatconv.cli import main
from splatconv.formats import splatvq
from splatconv.formats import splatvq_codec as codec
from splatconv.model import COLUMNS, Scene
from splatconv.ops import prune
from splatconv.render import camera as cam
from splatconv.render import proof
from splatconv.render.frames import Source
from splatconv.render.preview import Renderer

from .cli_checks import error_line
from .scenes import CAMERA, moving_scene, overlapping_scene


@pytest.fixture(autouse=True)
def small_frames(monkeypatch):
    # The proof's frames at a test's size: the same views, fewer pixels and times.
    monkeypatch.setattr(proof, "PROOF_WIDTH", 160)
    monkeypatch.setattr(proof, "PROOF_TIMES", (0.2, 0.8))


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _shaped(kind: str, n: int = 160, seed: int = 3) -> Scene:
    """Few large overlapping splats, flat ones, needles, or fast spins, in front of the test camera."""
    scene = moving_scene(n, seed)
    c = {k: np.array(scene.columns[k]) for k in COLUMNS}
    rng = np.random.default_rng(seed)
    if kind == "large":
        for k in ("scale_0", "scale_1", "scale_2"):
            c[k][1:] = np.log(rng.uniform(0.6, 1.6, n - 1))
        c["opacity"][1:] = rng.uniform(-1.0, 1.0, n - 1)
    elif kind == "flat":
        c["scale_2"][1:] = np.log(1e-4)
        c["scale_0"][1:] = c["scale_1"][1:] = np.log(rng.uniform(0.3, 0.8, n - 1))
    elif kind == "needle":
        c["scale_1"][1:] = c["scale_2"][1:] = np.log(2e-3)
        c["scale_0"][1:] = np.log(rng.uniform(0.5, 1.5, n - 1))
    elif kind == "spin":
        for j in range(4):
            c[f"omega_{j}"][1:] = rng.normal(0, 6.0, n - 1)
    return Scene(c, cameras=[dict(CAMERA)])


@pytest.mark.parametrize("kind", ["large", "flat", "needle", "spin"])
def test_the_floor_is_met_or_the_run_fails(tmp_path, kind):
    """What convert prints is what the file it wrote draws; a floor no step reaches writes nothing."""
    scene = _shaped(kind)
    src = tmp_path / "s.ply"
    io.write(scene, src)
    out = tmp_path / "o.splatvq"
    r = run("convert", src, out, "--min-psnr", 40)
    if r.exit_code == 1:
        assert error_line(r, 1).startswith(f"Error: {out}: reaches at best ") and not out.exists()
        return
    assert r.exit_code == 0, r.output
    line = next(n for n in r.stderr.splitlines() if n.startswith("note: proved: worst frame "))
    printed = float(line.split("worst frame ")[1].split(" dB")[0])
    again = proof.prove(io.read(src), io.read(out), proof.proof_views(io.read(src)))
    assert printed >= 40 and again.worst == pytest.approx(printed, abs=0.005)
    # verify --proof draws the same frames: its worst is the one convert printed.
    r = run("verify", src, out, "--proof", "--json", "--min-psnr", 40)
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["worst"]["psnr"] == pytest.approx(printed, abs=0.0051)  # printed to 2 places


def test_axis_aligned_flat_splats_draw_nothing_in_the_file_as_in_the_source(tmp_path):
    # A splat whose rotation is one component alone, with no omega and a zero scale, seen from a
    # view on the scene's axes (the test camera's), has an exactly diagonal screen covariance: the
    # viewer's major axis is normalize(vec2(0, 0)) and it draws nothing. The rotation codes cannot
    # hold the three zeros, and the splat a hair off axis is drawn (no step reached the floor).
    # Such splats are kept verbatim: the default floor holds, and the note counts them.
    scene = _shaped("flat")
    c = {k: np.array(v) for k, v in scene.columns.items()}
    aligned = np.arange(1, len(c["x"]), 2)
    for j in range(4):
        c[f"rot_{j}"][aligned] = float(j == 0)
        c[f"omega_{j}"][aligned] = 0.0
    c["scale_2"][aligned] = -40.0  # a zero half: flat across the view
    src = tmp_path / "s.ply"
    io.write(Scene(c, cameras=scene.cameras), src)
    out = tmp_path / "o.splatvq"
    r = run("convert", src, out)
    assert r.exit_code == 0, r.output
    assert f"{len(aligned)} splats kept verbatim (a zero rotation, an axis-aligned flat splat" in r.stderr
    assert float(r.stderr.split("note: proved: worst frame ")[1].split(" dB")[0]) >= 45


def test_a_floor_out_of_reach_is_an_error_unless_best_effort(tmp_path):
    src = tmp_path / "s.ply"
    io.write(_shaped("large"), src)
    out = tmp_path / "o.splatvq"
    r = run("convert", src, out, "--min-psnr", 150)
    assert error_line(r, 1).startswith(f"Error: {out}: reaches at best ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.ply"]
    r = run("convert", src, out, "--min-psnr", 150, "--best-effort")
    assert r.exit_code == 0, r.output
    short = next(n for n in r.stderr.splitlines() if "short of the --min-psnr 150 dB floor" in n)
    printed = float(next(n for n in r.stderr.splitlines() if n.startswith("note: proved: "))
                    .split("worst frame ")[1].split(" dB")[0])
    assert float(short.split("note: ")[1].split(" dB")[0]) == pytest.approx(150 - printed, abs=0.01)
    assert out.exists()


def _proof_weights(scene):
    """What convert weighs each splat by (the proof's views and times): its levels, its candidates' sizes."""
    views, times = proof.proof_plan(scene, proof.proof_views(scene, ~viewer.undrawable(scene.columns)))
    return proof.frame_weights(scene, views, times)


def test_max_bytes_gives_the_finest_step_that_fits(tmp_path):
    src = tmp_path / "s.ply"
    scene = _shaped("large")
    io.write(scene, src)
    sizes = {}
    coarsest = codec.PRECISIONS[0]
    weights = _proof_weights(scene)
    for step in (coarsest, 0, 3):
        io.write(scene, tmp_path / f"{step}.splatvq", precision=step, weights=weights)
        sizes[step] = (tmp_path / f"{step}.splatvq").stat().st_size
    assert sizes[coarsest] < sizes[0] < sizes[3]
    out = tmp_path / "o.splatvq"
    r = run("convert", src, out, "--max-bytes", sizes[0])
    assert r.exit_code == 0, r.output
    assert out.stat().st_size == sizes[0]  # step 1 would not fit: the steps grow
    assert any(n.startswith("note: proved: worst frame ") for n in r.stderr.splitlines())
    r = run("convert", src, tmp_path / "tiny.splatvq", "--max-bytes", sizes[coarsest] - 1)
    assert error_line(r, 1).startswith(f"Error: {tmp_path / 'tiny.splatvq'}: even the coarsest step")
    assert not (tmp_path / "tiny.splatvq").exists()


@pytest.mark.parametrize("args", [("o.splatv", "--min-psnr", "40"), ("o.ply", "--max-bytes", "5M"),
                                  ("o.splatvq", "--max-bytes", "5M", "--best-effort"),
                                  ("o.splatvq", "--max-bytes", "lots"), ("o.splatvq", "--no-proof", "--prune"),
                                  ("o.splatvq", "--max-bytes", "5M", "--prune"), ("o.ply", "--prune"),
                                  ("o.splatvq", "--no-proof", "--min-psnr", "40")])
def test_proof_options_are_refused_where_they_mean_nothing(tmp_path, args):
    src = tmp_path / "s.ply"
    io.write(moving_scene(20), src)
    r = run("convert", src, tmp_path / args[0], *args[1:])
    error_line(r, 2)
    assert not (tmp_path / args[0]).exists()


def test_verify_proof_takes_no_views_of_its_own(tmp_path):
    src = tmp_path / "s.ply"
    io.write(moving_scene(20), src)
    r = run("verify", src, src, "--proof", "--times", "0.5")
    assert error_line(r, 2).startswith("Error: --proof draws the views and times")


def _with_unseen(n: int = 160, unseen: int = 40) -> Scene:
    """:func:`moving_scene` and ``unseen`` more splats that no proof frame shows (behind the camera)."""
    scene = moving_scene(n, 5)
    extra = moving_scene(unseen + 1, 6)
    c = {k: np.concatenate([np.asarray(scene.columns[k]), np.asarray(extra.columns[k])[1:]]) for k in COLUMNS}
    c["z"][n:] = CAMERA["position"][2] - 5.0  # the camera looks along +z from z = -9
    return Scene(c, cameras=[dict(CAMERA)])


def test_prune_leaves_out_splats_and_the_floor_still_holds(tmp_path):
    """The note's count is the source's drawable splats less those written; the file, as read, meets the floor,
    and verify --proof pairs it with the source and draws the same frames."""
    scene = _with_unseen()
    src = tmp_path / "s.ply"
    io.write(scene, src)
    drawable = int((~viewer.undrawable(scene.columns)).sum())
    out = tmp_path / "o.splatvq"
    r = run("convert", src, out, "--min-psnr", 40, "--prune")
    assert r.exit_code == 0, r.output
    line = next(n for n in r.stderr.splitlines() if n.startswith("note: pruned "))
    left_out = int(line.split("pruned ")[1].split(" splat")[0].replace(",", ""))
    assert line.split(" of ")[1].startswith(f"{drawable:,} drawable")
    written = io.read(out)
    kept = int(np.count_nonzero(viewer.undrawable(written.columns)))  # the few the viewer's depth sort needs
    assert left_out >= 30 and written.count == drawable - left_out + kept
    assert r.stdout.startswith(f"wrote {out}: {written.count:,} splats")
    printed = float(next(n for n in r.stderr.splitlines() if n.startswith("note: proved: "))
                    .split("worst frame ")[1].split(" dB")[0])
    again = proof.prove(io.read(src), written, proof.proof_views(io.read(src)))
    assert printed >= 40 and again.worst == pytest.approx(printed, abs=0.005)
    # The header says it is pruned, and info shows it.
    r = run("info", out, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["details"]["pruned"] == left_out
    r = run("verify", src, out, "--proof", "--json", "--min-psnr", 40)
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["worst"]["psnr"] == pytest.approx(printed, abs=0.0051)  # printed to 2 places
    # Without --prune every drawable splat is kept, and the header says nothing of pruning.
    whole = tmp_path / "whole.splatvq"
    r = run("convert", src, whole, "--min-psnr", 40)
    assert r.exit_code == 0, r.output
    held = io.read(whole)
    assert held.count - np.count_nonzero(viewer.undrawable(held.columns)) == drawable and "pruned" not in held.meta
    assert not any(n.startswith("note: pruned ") for n in r.stderr.splitlines())


def _matrices(views):
    return [(v.matrix, cam.projection_matrix(v.fx, v.fy, v.width, v.height), v.width, v.height) for _, v in views]


def test_contributions_a_chunk_at_a_time_are_the_whole_scenes(monkeypatch):
    """A scene of many splats is placed in the frames a chunk at a time (its footprints kept in float32) and
    its occlusion summed a chunk of cell entries at a time: what each splat adds comes out the same."""
    scene = moving_scene(3000, seed=2)
    views = _matrices(proof.proof_views(scene))
    whole = prune.contributions(scene.columns, views, proof.PROOF_TIMES)
    monkeypatch.setattr(prune, "_FRAME_SPLATS", 700)
    monkeypatch.setattr(prune, "_CHUNK_SPLATS", 256)
    chunked = prune.contributions(scene.columns, views, proof.PROOF_TIMES)
    assert np.count_nonzero(whole) > 2000
    assert np.array_equal(chunked > 0, whole > 0)
    assert np.allclose(chunked, whole, rtol=1e-4, atol=1e-6 * whole.max())


def test_splats_no_frame_shows_rank_last():
    """Behind the camera, out of the frame: nothing added, ranked first to go; hidden in time at every t: nothing
    added and not ranked (undrawable); seen only between the times drawn: counted; behind an opaque splat: less
    than the same splat in the open."""
    c = {k: np.zeros(7, np.float32) for k in COLUMNS}
    c["rot_0"][:] = 1.0
    c["opacity"][:] = 8.0
    c["trbf_scale"][:] = np.log(1e4)  # visible at every time
    for k in ("scale_0", "scale_1", "scale_2"):
        c[k][:] = np.log(0.05)
    # 0: in front of the camera; 1: behind it; 2: far out of frame; 3: hidden at every time in [0, 1];
    # 4: behind a large opaque splat (5) straight ahead; 6: only near t = 0.5.
    c["x"][:] = [0.3, 0.3, 400.0, 0.3, 1.3, 1.3, -0.7]
    c["y"][:] = -0.2
    c["z"][:] = [0.0, -12.0, 0.0, 0.0, 2.0, 0.0, 0.0]
    c["trbf_center"][3], c["trbf_scale"][3] = 3.0, np.log(0.01)
    c["trbf_center"][6], c["trbf_scale"][6] = 0.5, np.log(0.01)
    for k in ("scale_0", "scale_1"):
        c[k][5] = np.log(0.6)
    # The proof draws a camera as splaTV's window shows it (focal lengths in its pixels): this one's field of view.
    window = dict(CAMERA, fx=CAMERA["fx"] * 1280 / CAMERA["width"], fy=CAMERA["fy"] * 1280 / CAMERA["width"])
    scene = Scene(c, cameras=[window])
    views = _matrices(proof.proof_views(scene))
    score = prune.contributions(scene.columns, views, (0.1, 0.9))
    assert score[0] > 0 and score[5] > 0 and score[6] > 0  # 6: at its best between the times drawn
    assert score[1] == score[2] == score[3] == 0
    ranked = prune.ranked(scene.columns, score)
    assert 3 not in ranked and set(ranked[:2]) == {1, 2}
    hidden = prune.contributions(scene.columns, views, (0.5,))[4]
    c["opacity"][5] = -40.0
    alone = prune.contributions(Scene(c, cameras=[window]).columns, views, (0.5,))[4]
    assert 0 < hidden < 0.2 * alone


def _awkward() -> Scene:
    """:func:`overlapping_scene` (tied importance keys, spinning zero rotations) with what real scenes hold:
    a NaN position, an infinite temporal scale, a flat splat, and one far out (raw records)."""
    c = {k: np.array(v) for k, v in overlapping_scene(2500, seed=4).columns.items()}
    c["x"][5], c["trbf_scale"][7], c["scale_2"][9], c["y"][11] = np.nan, np.inf, -np.inf, 3e30
    return Scene(c, cameras=[dict(CAMERA)])


@pytest.mark.parametrize("step", [-2, 0, 3])
def test_a_candidate_is_drawn_as_a_conversion_of_it_holds(tmp_path, step):
    """The proof draws a .splatvq from its decoded records, never decoding the scene: the very texture a
    .splatv conversion of what it reads holds, and the same frames, pieces of any size."""
    out = tmp_path / "o.splatvq"
    io.write(_awkward(), out, precision=step)
    fmt = formats.format_for(out)
    pieces = []
    order = fmt.converted_texture(out, pieces.append)
    records = np.concatenate(pieces)
    converted = Source("", io.read(out)).texture()
    assert len(records) == fmt.splat_count(out) and not converted[len(records):].any()
    assert np.array_equal(records[order], converted[:len(records)])
    # Drawn in pieces that cut rows anywhere, the records in file order mapped through `order`.
    view = proof.proof_views(_awkward())[0][1]
    whole = Renderer(view.width, view.height)
    parts = Renderer(view.width, view.height, whole.ctx)
    try:
        whole.load(converted)
        cuts = [0, 700, 1700, 1701, len(records)]
        parts.load_pieces(len(records), lambda put: [put(records[a:b]) for a, b in zip(cuts, cuts[1:])] and order)
        for t in proof.PROOF_TIMES:
            assert np.array_equal(parts.draw(view, t), whole.draw(view, t))
        proof.load_candidate(parts, out)
        assert np.array_equal(parts.draw(view, 0.5), whole.draw(view, 0.5))
    finally:
        parts.release()
        whole.release()


def test_a_proof_prepares_once_what_each_candidate_shares(tmp_path, monkeypatch):
    """The undrawable kinds and the sort's ends are computed once however many candidates are written, and
    the file is the bytes a write of the step it holds gives without them."""
    scene = _awkward()
    src, out, again = tmp_path / "s.ply", tmp_path / "o.splatvq", tmp_path / "again.splatvq"
    io.write(scene, src)
    calls = []
    real = splatvq.sort_ends
    monkeypatch.setattr(splatvq, "sort_ends", lambda *a, **k: calls.append(1) or real(*a, **k))
    r = run("convert", src, out, "--min-psnr", 60, "--best-effort")
    assert r.exit_code == 0, r.output
    tried = int(re.search(r"; (\d+) candidates in ", r.stderr).group(1))
    assert tried > 1 and len(calls) == 1
    setting = io.read(out).meta["setting"]
    step = next(p for p in codec.PRECISIONS if codec.precision_name("default", p) == setting)
    source = io.read(src)
    io.write(source, again, precision=step, weights=_proof_weights(source))
    assert again.read_bytes() == out.read_bytes()


def test_a_notch_coarsens_one_quantizer_of_the_header():
    base = codec.SETTINGS["default"]
    for name in codec.TUNINGS:
        moved = codec.coarser(base, name)
        changed = {f for f in codec.LIMITS if getattr(moved, f) != getattr(base, f)}
        assert changed == {name}
    assert codec.coarser(base, "rotation_bits").rotation_bits == base.rotation_bits - 1
    assert codec.coarser(base, "scale_step").scale_step == 2 * base.scale_step
    assert codec.coarser(base, "alpha_levels").alpha_levels == base.alpha_levels + 1
    low = codec.tuned(base, ["rotation_bits"] * 20)  # held at its limit
    assert low.rotation_bits == codec.SETTING_LIMITS["rotation_bits"][0] and codec.coarser(low, "rotation_bits") is None
    with pytest.raises(ValueError):
        codec.tuned(base, ["chunk_log2"])
    assert codec.tuned_name("default+1", ()) == "default+1"
    assert codec.tuned_name("default+1", ("time_shift",)) == "default+1, tuned"


def test_a_setting_is_tuned_where_the_scene_has_precision_to_spare(tmp_path):
    """The proof coarsens the quantizers the scene does not need, says which, and the file is smaller than
    the same step untuned; the floor still holds, as verify finds."""
    scene = _shaped("large")
    src, out, plain = tmp_path / "s.ply", tmp_path / "o.splatvq", tmp_path / "plain.splatvq"
    io.write(scene, src)
    r = run("convert", src, out, "--min-psnr", 40)
    assert r.exit_code == 0, r.output
    line = next(n for n in r.stderr.splitlines() if n.startswith("note: proved: worst frame "))
    assert ", tuned to the scene (" in line and " notch" in line
    printed = float(line.split("worst frame ")[1].split(" dB")[0])
    setting = io.read(out).meta["setting"]
    assert setting.endswith(", tuned")
    step = next(p for p in codec.PRECISIONS if codec.precision_name("default", p) == setting[:-len(", tuned")])
    io.write(io.read(src), plain, precision=step)
    assert out.stat().st_size < plain.stat().st_size
    r = run("verify", src, out, "--proof", "--json", "--min-psnr", 40)
    assert r.exit_code == 0, r.output
    assert printed >= 40 and json.loads(r.stdout)["worst"]["psnr"] == pytest.approx(printed, abs=0.0051)
    # The header's numbers are the tuned ones: a decoder needs nothing else.
    tuned = splatvq._header(open(out, "rb"), str(out), out.stat().st_size)[0]
    assert tuned != codec.refined(codec.SETTINGS["default"], step)


def test_a_tuning_is_tried_only_where_a_floor_is_proved(tmp_path):
    """--max-bytes alone writes the finest step that fits, untuned; --best-effort short of its floor too."""
    scene = _shaped("large")
    src = tmp_path / "s.ply"
    io.write(scene, src)
    for args in (("--max-bytes", "1M"), ("--min-psnr", 90, "--best-effort")):
        out = tmp_path / "o.splatvq"
        r = run("convert", src, out, "--force", *args)
        assert r.exit_code == 0, r.output
        assert "tuned" not in io.read(out).meta["setting"] and "tuned to the scene" not in r.stderr


def test_a_large_scene_skips_the_half_step_its_neighbours_put_short():
    """Worst frames measured on the bench's 1M-splat scene: the setting 43.08 dB, a step finer 45.98, the
    half step between 43.67. A scene proved from fewer frames does not prove the half step between once
    the mean of its neighbours falls short; a small one proves it."""
    from types import SimpleNamespace

    from splatconv.jobs import prove as job

    class Measured:
        def __init__(self, worst):
            self.worst, self.proofs = worst, {}

        def proof(self, key):
            return self.proofs.setdefault(key, SimpleNamespace(worst=self.worst[key[0]]))

    worst = {0: 43.08, 1: 43.67, 2: 45.98, 3: 47.0, 4: 48.0}
    for large, proved in ((False, {0, 1, 2}), (True, {0, 2})):
        c = Measured(worst)
        assert job._searched(c, list(codec.PRECISIONS), 45.0, large=large) == 2
        assert {key[0] for key in c.proofs} == proved
    # Where the mean of the two reaches the floor, the step between is proved, and taken.
    c = Measured({0: 42.5, 1: 45.5, 2: 48.0, 3: 49.0})
    assert job._searched(c, list(codec.PRECISIONS), 45.0, large=True) == 1
    assert {key[0] for key in c.proofs} == {0, 1, 2}


def test_a_search_whose_jump_reaches_a_step_proved_short_halves_the_gap():
    """Worst frames measured on the suite's generated 900-splat scene at the default setting, floor 40: the
    setting 19.36 dB, the finest step 58.78. Jumping back by the dB to spare lands on the setting, proved
    short: the search halves the gap instead of stepping back one half step a proof."""
    from types import SimpleNamespace

    from splatconv.jobs import prove as job

    class Measured:
        def __init__(self, worst):
            self.worst, self.proofs = worst, {}

        def proof(self, key):
            return self.proofs.setdefault(key, SimpleNamespace(worst=self.worst[key[0]]))

    steps = list(codec.PRECISIONS)
    worst = {0: 19.36, 1: 19.34, 2: 45.86, 3: 46.65, 6: 51.55, 9: 52.85, 10: 56.31, 11: 57.63, 12: 58.78}
    c = Measured(worst)
    assert job._searched(c, steps, 40.0) == 3
    assert [key[0] for key in c.proofs] == [0, steps[-1], 6, 3, 1]


def test_a_proof_with_a_floor_stops_at_the_first_frame_below_it():
    """A candidate that breaks a floor is known to from one frame, drawn in the order asked (the worst frames
    of a like candidate first); one that holds is drawn in full, as a proof without a floor draws it."""
    scene = _shaped("large")
    c = {k: np.array(v) for k, v in scene.columns.items()}
    c["x"][1::2] += 0.05  # every other splat moved: every frame worse, some more than others
    moved = Scene(c, cameras=scene.cameras)
    views, times = proof.proof_plan(scene)
    with proof.Prover(scene, views, times) as prover:
        full = prover.prove(moved)
        values = np.asarray(full.values)
        assert full.complete and full.frames == len(values) == len(views) * len(times)
        assert full.worst == values.min()
        floor = float(np.median(values))  # about half the frames fall below it
        first = np.argsort(-values, kind="stable")  # best first: the failure shows only later
        stopped = prover.prove(moved, floor=floor, first=first)
        at = next(n for n, i in enumerate(first) if values[i] < floor)
        assert not stopped.complete and stopped.frames == at + 1 and stopped.worst < floor
        assert stopped.worst == values[first[at]]
        drawn = np.asarray(stopped.values)
        assert np.array_equal(np.isnan(drawn), ~np.isin(np.arange(len(values)), first[:at + 1]))
        held = prover.prove(moved, floor=full.worst, first=first)
        assert held.complete and held.values == full.values and held.worst == full.worst


def test_the_tuning_limit_counts_the_splats_a_proof_draws(tmp_path, monkeypatch):
    """Real scenes hold many splats the viewer never draws (zero rotations): the tuning's limits count the
    drawable ones, which are what a proof's frames cost."""
    from splatconv.jobs import prove
    scene = _shaped("large")
    drawable = int(np.count_nonzero(~viewer.undrawable(scene.columns)))
    c = {k: np.concatenate([np.array(v), np.zeros(300, np.float32)]) for k, v in scene.columns.items()}
    padded = Scene(c, cameras=scene.cameras)  # 300 more, each of zero rotation
    assert int(np.count_nonzero(~viewer.undrawable(padded.columns))) == drawable > 100
    kept = []  # the notches each tuning may keep
    monkeypatch.setattr(prove, "_tuned", lambda *args: kept.append(args[-1]) or ())
    for most, many, notches in ((drawable, drawable, [prove.TUNE_NOTCHES]),
                                (drawable, drawable - 1, [prove.TUNE_NOTCHES_LARGE]), (drawable - 1, drawable, [])):
        monkeypatch.setattr(prove, "TUNE_MAX_SPLATS", most)
        monkeypatch.setattr(prove, "TUNE_MANY_SPLATS", many)
        kept.clear()
        prove.write_proven(padded, tmp_path / "out.splatvq", quality=None, min_psnr=20.0, force=True)
        assert kept == notches
