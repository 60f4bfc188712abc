"""``--quality``: the ``.splatvq`` setting as an output option of every command that writes a scene, and the
page that embeds a ``.splatvq`` at that setting."""

from __future__ import annotations

import base64
import re

import pytest
from click.testing import CliRunner

from splatconv import io
from splatconv.cli import main
from splatconv.formats import splatvq
from splatconv.jobs._steps import write_output
from splatconv.viewer import sort_ends, undrawable
from tests import splatvq_files as damage
from tests.conftest import ProgressRecorder
from tests.real_scenes import real_scene

QUALITIES = splatvq.QUALITIES


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A PLY with what real scenes hold (undrawable splats, NaN, infinities)."""
    path = tmp_path_factory.mktemp("src") / "real.ply"
    io.write(real_scene(900, seed=5)[0], path)
    return path


def embedded(page) -> bytes:
    """The scene bytes a one-scene page embeds."""
    text = page.read_text(encoding="utf-8")
    return base64.b64decode("".join(re.search(r'data-asset="scene-0">(.*?)</script>', text, re.S).group(1).split()))


@pytest.mark.parametrize("quality", QUALITIES)
def test_convert_writes_the_setting_asked_for(tmp_path, source, quality):
    out = tmp_path / f"{quality}.splatvq"
    r = run("convert", source, out, "--quality", quality, "--no-proof")
    assert r.exit_code == 0, r.output
    assert io.read(out).meta["setting"] == quality
    # The very bytes the library writes with that setting.
    assert out.read_bytes() == splatvq.encode(io.read(source), quality=quality)[0]
    assert f"quantized with the {quality!r} setting" in r.stderr
    # Proved (the default), the header names the precision step the proof chose beside the setting: the
    # setting asked for, or the best one where its file is smaller, as the note says.
    r = run("convert", source, out, "--quality", quality, "--force")
    assert r.exit_code == 0, r.output
    setting = io.read(out).meta["setting"]
    assert setting.startswith(quality) or (setting.startswith(QUALITIES[0])
                                           and f"(smaller than the {quality!r} setting's best, " in r.stderr)


def test_the_settings_give_different_sizes_the_last_the_smallest(tmp_path, source):
    sizes, proved = [], []
    for quality in QUALITIES:
        out = tmp_path / f"{quality}.splatvq"
        assert run("convert", source, out, "--quality", quality, "--no-proof").exit_code == 0
        sizes.append(out.stat().st_size)
        out = tmp_path / f"{quality}-proved.splatvq"
        r = run("convert", source, out, "--quality", quality)
        assert r.exit_code == 0, r.output
        proved.append((out.stat().st_size, r.output))
    assert len(set(sizes)) == len(QUALITIES)
    assert sizes[-1] == min(sizes) < sizes[0]  # QUALITIES: best first
    # Proved, each setting's ladder and tuning go their own ways on a scene; --quality small never
    # writes a larger file than the default setting's best (which it writes where that is smaller).
    assert proved[-1][0] == min(size for size, _ in proved)
    # No --quality: the writer's default, the first the option lists.
    plain = tmp_path / "plain.splatvq"
    assert run("convert", source, plain).exit_code == 0
    assert plain.read_bytes() == (tmp_path / f"{io.QUALITIES[0]}-proved.splatvq").read_bytes()


@pytest.mark.parametrize("suffix", [".splatv", ".ply", ".splat", ".splatv.zst"])
def test_other_outputs_refuse_it_before_reading(tmp_path, suffix):
    """A usage error naming the suffixes that take it, checked before the input is read (a damaged
    input is not even looked at), nothing written."""
    bad = tmp_path / "damaged.ply"
    bad.write_bytes(b"not a ply at all")
    out = tmp_path / f"out{suffix}"
    r = run("convert", bad, out, "--quality", QUALITIES[-1])
    assert r.exit_code == 2
    assert r.stderr == f"Error: {out}: --quality {QUALITIES[-1]} applies to .splatvq, .html output only\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["damaged.ply"]


def test_an_unknown_setting_is_refused_with_the_choices(tmp_path, source):
    out = tmp_path / "x.splatvq"
    r = run("convert", source, out, "--quality", "no-such-setting")
    assert r.exit_code == 2
    assert r.stderr.startswith("Error: Invalid value for '--quality': 'no-such-setting' is not one of ")
    assert all(f"'{q}'" in r.stderr for q in QUALITIES) and r.stderr.count("\n") == 1
    assert not out.exists()
    # The library refuses it too, listing them.
    with pytest.raises(io.UsageError, match=r"unknown quality 'no-such-setting' \(expected one of "
                                            + ", ".join(io.QUALITIES) + r"\)"):
        io.check_write_options(out, quality="no-such-setting")


@pytest.mark.parametrize("quality", QUALITIES)
def test_a_page_with_a_quality_embeds_a_splatvq_of_that_setting(tmp_path, source, quality):
    page, plain = tmp_path / f"{quality}.html", tmp_path / "plain.html"
    r = run("convert", source, page, "--quality", quality)
    assert r.exit_code == 0, r.output
    data = embedded(page)
    assert data[:4] == splatvq.MAGIC
    (tmp_path / "embedded.splatvq").write_bytes(data)
    assert io.read(tmp_path / "embedded.splatvq").meta["setting"] == quality
    assert data == splatvq.encode(io.read(source), quality=quality)[0]
    # Without it, a PLY's page embeds the .splatv texture, more than twice the bytes (the player is the same).
    assert run("convert", source, plain).exit_code == 0
    assert embedded(plain)[:4] != splatvq.MAGIC
    assert len(data) < 0.5 * len(embedded(plain))
    assert page.stat().st_size < plain.stat().st_size


def test_a_page_takes_a_quality_or_compat_not_both(tmp_path, source):
    for mode in io.COMPAT_MODES:
        r = run("convert", source, tmp_path / "x.html", "--quality", QUALITIES[0], "--compat", mode)
        assert r.exit_code == 2
        assert r.stderr == (f"Error: {tmp_path / 'x.html'}: --compat and --quality exclude each other (--compat keeps "
                            "the texture's bytes, --quality embeds the scene quantized)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_splatvq_page_takes_another_setting(tmp_path, source):
    """A .splatvq input's page keeps its setting, unless --quality asks for another."""
    first, last = QUALITIES[0], QUALITIES[-1]
    vq = tmp_path / "in.splatvq"
    assert run("convert", source, vq, "--quality", first, "--no-proof").exit_code == 0
    assert run("convert", vq, tmp_path / "kept.html").exit_code == 0
    assert run("convert", vq, tmp_path / "other.html", "--quality", last).exit_code == 0
    for name, setting in (("kept.html", first), ("other.html", last)):
        (tmp_path / "e.splatvq").write_bytes(embedded(tmp_path / name))
        assert io.read(tmp_path / "e.splatvq").meta["setting"] == setting


def test_a_splatvq_kept_at_its_setting_is_not_called_quantized(tmp_path, source):
    """Written again at its own setting for a page, a .splatvq input is quantized by nothing: no note says it
    was. Converted to a .splatvq again, it is proved as any input is (its boost levels are chosen anew)."""
    first, last = QUALITIES[0], QUALITIES[-1]
    vq = tmp_path / "in.splatvq"
    assert run("convert", source, vq, "--quality", first, "--no-proof").exit_code == 0
    r = run("convert", vq, tmp_path / "same.html", "--quality", first)
    assert r.exit_code == 0, r.output
    assert "quantized" not in r.stderr and f"kept the source's {first!r} setting" in r.stderr
    r = run("convert", vq, tmp_path / "again.splatvq")
    assert r.exit_code == 0, r.output
    assert "note: proved: worst frame " in r.stderr
    # Asked nothing, the page plays the file's own bytes, as publish and view give it: nothing is encoded.
    r = run("convert", vq, tmp_path / "kept.html")
    assert r.exit_code == 0 and "quantized" not in r.stderr and "setting" not in r.stderr
    assert embedded(tmp_path / "kept.html") == vq.read_bytes()
    # Another setting does quantize it, and says so.
    r = run("convert", vq, tmp_path / "other.html", "--quality", last)
    assert r.exit_code == 0 and f"quantized with the {last!r} setting" in r.stderr


@pytest.mark.parametrize("args", [("convert", "{src}", "{out}.splatvq"), ("convert", "{src}", "{out}.html", "--quality",
                                                                           QUALITIES[-1]),
                                  ("merge", "{src}", "{src}", "{out}.splatvq")])
def test_a_splatvq_output_counts_the_undrawable_splats_it_leaves_out_and_advises_nothing(tmp_path, source, args):
    """The writer leaves undrawable splats out itself: no note advises --drop-undrawable, its own counts them."""
    left_out = int(undrawable(io.read(source).columns).sum()) * args.count("{src}")
    assert left_out >= 0.1 * 900 * args.count("{src}")  # enough for the reading note to be due
    r = run(*(a.format(src=source, out=tmp_path / "out") for a in args))
    assert r.exit_code == 0, r.output
    assert "--drop-undrawable" not in r.stderr
    counted = re.findall(r"left out ([\d,]+) undrawable splats.*?(?:; kept ([\d,]+) that the viewer's depth sort "
                         r"needs)?$", r.stderr, re.M)
    assert len(counted) == 1
    assert int(counted[0][0].replace(",", "")) + int(counted[0][1].replace(",", "") or 0) == left_out
    # A .splatv output keeps them, and the note on reading still says how to remove them.
    r = run("convert", source, tmp_path / "kept.splatv")
    assert r.exit_code == 0 and "--drop-undrawable" in r.stderr




@pytest.mark.parametrize("name, quality", [("x.splatvq", None), ("x.splatvq", QUALITIES[-1]), ("x.html", QUALITIES[0]),
                                           ("x.splatv", None), ("x.ply", None), ("x.html", None)])
def test_the_writing_bar_counts_the_splats_written(tmp_path, source, name, quality):
    """A .splatvq leaves undrawable splats out: its bar's total and count are the splats it writes."""
    scene = io.read(source)
    rec = ProgressRecorder()
    report = write_output(scene, tmp_path / name, quality=quality, progress=rec)  # a page, or io.write
    writing = [s for s in rec.stages if s[0] == "writing"]
    assert [s[1:] for s in writing] == [[report.count, "splat", report.count]]
    drawn = int((~undrawable(scene.columns) | sort_ends(scene.columns, scene.cameras)).sum())
    assert report.count == (drawn if quality or name.endswith(".splatvq") else scene.count)


def test_bake_merge_and_frames_take_it(tmp_path, source):
    quality = QUALITIES[-1]
    baked = tmp_path / "moment.splatvq"
    r = run("bake", source, baked, "--time", "0.5", "--quality", quality)
    assert r.exit_code == 0, r.output
    assert io.read(baked).meta["setting"] == quality
    merged = tmp_path / "merged.splatvq"
    r = run("merge", source, source, merged, "--translate", "2:1,0,0", "--quality", quality)
    assert r.exit_code == 0, r.output
    assert io.read(merged).meta["setting"] == quality
    frames = tmp_path / "frames"
    r = run("bake", source, frames, "--frames", "2", "--frame-suffix", ".splatvq", "--quality", quality)
    assert r.exit_code == 0, r.output
    assert {io.read(p).meta["setting"] for p in frames.iterdir()} == {quality}
    clip = tmp_path / "clip.splatvq"
    r = run("convert", baked, baked, clip, "--same-splats", "yes", "--quality", quality)
    assert r.exit_code == 0, r.output
    assert io.read(clip).meta["setting"] == quality


@pytest.mark.parametrize("args", [["bake", "{bad}", "{out}", "--time", "0.5"],
                                  ["bake", "{bad}", "{dir}", "--frames", "2"],
                                  ["merge", "{bad}", "{bad}", "{out}"],
                                  ["merge", "{bad}", "{bad}", "{out}", "--segments", "--no-check"],
                                  ["convert", "{bad}", "{bad}", "{out}"]])
def test_every_writing_command_refuses_it_for_other_outputs_before_reading(tmp_path, args):
    bad = tmp_path / "damaged.ply"
    bad.write_bytes(b"not a ply at all")
    names = {"bad": bad, "out": tmp_path / "out.ply", "dir": tmp_path / "frames"}
    r = run(*[a.format(**names) for a in args], "--quality", QUALITIES[0])
    assert r.exit_code == 2, r.output
    takes = ".splatvq" if "{dir}" in args else ".splatvq, .html"  # a frame is a scene file, never a page
    assert r.stderr.startswith("Error: ") and r.stderr.endswith(
        f"--quality {QUALITIES[0]} applies to {takes} output only\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["damaged.ply"]


def test_pages_of_several_scenes_and_external_pages_take_it(tmp_path, source):
    """convert's player pages through publish: each segment embedded as .splatvq at the setting, or
    written beside the page as OUT.splatvq; a .splatvq input is then not played where it is."""
    quality = QUALITIES[-1]
    page = tmp_path / "clip.html"
    r = run("convert", source, source, page, "--quality", quality)
    assert r.exit_code == 0, r.output
    text = page.read_text(encoding="utf-8")
    for i in range(2):
        data = base64.b64decode("".join(re.search(rf'data-asset="scene-{i}">(.*?)</script>', text, re.S)
                                        .group(1).split()))
        assert data == splatvq.encode(io.read(source), quality=quality)[0]
    site = tmp_path / "site"
    site.mkdir()
    r = run("convert", source, site / "scene.html", "--external", "--quality", quality)
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in site.iterdir()) == ["scene.html", "scene.poster.jpg", "scene.splatvq"]
    assert io.read(site / "scene.splatvq").meta["setting"] == quality
    size = (site / "scene.splatvq").stat().st_size
    assert r.stdout.splitlines()[1] == f"wrote {site / 'scene.splatvq'}: {size:,} bytes"
    # A .splatvq input where the page would fetch it is another setting's bytes: not played where it is,
    # and never written onto.
    before = (site / "scene.splatvq").read_bytes()
    r = run("convert", site / "scene.splatvq", site / "scene.html", "--external", "--force", "--quality",
            QUALITIES[0])
    assert r.exit_code == 1
    assert r.stderr == f"Error: {site / 'scene.splatvq'}: is the input file; refusing to write onto it\n"
    assert (site / "scene.splatvq").read_bytes() == before


# --------------------------------------------------------------------------
# A damaged .splatvq is never published: every page path that plays its bytes as they are decodes it whole first.

DAMAGED = {
    "rotation code": lambda d: damage.with_codes(d, damage.bad_rotation),
    "position step": lambda d: damage.with_codes(d, damage.bad_position_step),
    "width": lambda d: damage.with_width(d, "x_step[0]", 5),
    "corrupt stream": lambda d: damage.with_entry(d, body=b"\xff" * len(d[damage.layout(d)[2]:])),
    "payload cut": lambda d: damage.with_payload(d, damage.payload(d)[:-1]),
    "payload has more": lambda d: damage.with_payload(d, damage.payload(d) + bytes(64)),
}
PAGES = {
    "external": lambda bad, good, site: [bad, site / "page.html", "--external"],
    "several inputs": lambda bad, good, site: [bad, good, site / "page.html"],
    "several inputs, external": lambda bad, good, site: [good, bad, site / "page.html", "--external"],
    "played where it is": lambda bad, good, site: [bad, site / "bad.html", "--external"],
}


@pytest.fixture(scope="module")
def good_splatvq(tmp_path_factory):
    path = tmp_path_factory.mktemp("vq") / "good.splatvq"
    path.write_bytes(splatvq.encode(real_scene(300, seed=1)[0])[0])
    return path


@pytest.mark.parametrize("page", PAGES)
@pytest.mark.parametrize("kind", DAMAGED)
def test_a_damaged_splatvq_is_refused_by_every_page_path(tmp_path, good_splatvq, kind, page):
    """The same Error: line as converting it to .splatv, and no file written: no page, no .splatvq beside it."""
    site = tmp_path / "site"
    site.mkdir()
    bad = site / "bad.splatvq"
    bad.write_bytes(DAMAGED[kind](good_splatvq.read_bytes()))
    expected = run("convert", bad, tmp_path / "x.splatv")
    assert expected.exit_code == 1 and expected.stderr.startswith(f"Error: {bad}: block 0: "), expected.stderr
    r = run("convert", *PAGES[page](bad, good_splatvq, site))
    assert (r.exit_code, r.stderr) == (1, expected.stderr), r.output
    assert sorted(p.name for p in site.iterdir()) == ["bad.splatvq"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]
