"""specs/splatv.md against the code: the tables, constants and test vectors it states."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from splatconv import cameras, model, packing
from splatconv.formats import ply, splatv

SPEC = (Path(__file__).resolve().parent.parent / "specs" / "splatv.md").read_text(encoding="utf-8")


def _section(title: str) -> str:
    start = SPEC.index(title)
    end = SPEC.find("\n## ", start + len(title))
    return SPEC[start:end if end >= 0 else len(SPEC)]


def test_word_table_is_the_record_layout():
    rows = re.findall(r"^\| ([\d, ]+) \| ([^|]+) \|", _section("## The texture"), re.M)
    half_words, exp_names = {}, set()
    for words, content in rows:
        pair = re.fullmatch(r"half2\((.+), (.+)\)", content.strip())
        if pair:
            names = []
            for part in pair.groups():
                if part.startswith("exp "):
                    part = part[4:]
                    exp_names.add(part)
                names.append(None if part == "0" else part)
            half_words[int(words)] = tuple(names)
        elif content.startswith("position"):
            assert [int(w) for w in words.split(",")] == list(splatv.POSITION_WORDS)
        elif content.startswith("RGBA8"):
            assert int(words) == splatv.COLOR_WORD
    assert half_words == splatv.HALF_WORDS
    assert exp_names == set(splatv.EXP_ATTRIBUTES)


@pytest.mark.parametrize("text, number, value", [
    ("`0x0000674b` (`MAGIC`)", 0x674B, splatv.MAGIC),
    ("always 4096 (`TEXWIDTH`)", 4096, splatv.TEXWIDTH),
    ("1024 splats per\n  texture row (`SPLATS_PER_ROW`)", 1024, splatv.SPLATS_PER_ROW),
    ("64 bytes (`RECORD_BYTES`)", 64, splatv.RECORD_BYTES),
    ("at most 64 MiB, `MAX_JSON_BYTES`", 64 << 20, splatv.MAX_JSON_BYTES),
    ("at most\n  65536 (`MAX_TEXHEIGHT`", 65536, splatv.MAX_TEXHEIGHT),
    ("−40 and +40\n  (`ALPHA_LOGIT_LIMIT`)", 40.0, splatv.ALPHA_LOGIT_LIMIT),
    ("rgb = 0.5 + 0.28209479177387814 · f_dc (`SH_C0`", 0.28209479177387814, ply.SH_C0),
    ("at\nmost 65,536 (`FRAMING_SAMPLES`", 65536, cameras.FRAMING_SAMPLES),
    ("exp(trbf_scale) = 1024 (`STATIC_TRBF_*`", 1024.0, np.exp(np.float64(model.STATIC_TRBF_SCALE))),
])
def test_constants_are_as_written(text, number, value):
    # The sentence is in the spec, and the number it states is the code's.
    assert text in SPEC
    assert number == pytest.approx(float(value), rel=1e-6)


def test_splatvjs_test_vectors_hold():
    section = SPEC[SPEC.index("Test vectors (float32 input"):]
    section = section[:section.index("\n\n")]
    pairs = re.findall(r"([−\-\w.]+)→`(0x[0-9a-f]{4})`", section)
    assert len(pairs) == 13
    for text, bits in pairs:
        x = np.float32(float(text.replace("−", "-").replace("NaN", "nan")))
        assert packing.float_to_half_splatvjs(np.array([x]))[0] == int(bits, 16), text


def test_garbage_bands_are_where_splatvjs_is_wrong():
    bands = re.search(r"float32 exponents e = (\d+)–(\d+), (\d+)–(\d+) and (\d+)–(\d+)", SPEC).groups()
    stated = set()
    for lo, hi in zip(bands[::2], bands[1::2]):
        stated |= set(range(int(lo), int(hi) + 1))
    wrong = set()
    for e in range(1, 113):
        bits = np.uint32(e << 23) | np.arange(0, 1 << 23, 4099, dtype=np.uint32)
        x = bits.view(np.float32)
        truncated = np.floor(x.astype(np.float64) / 2.0**-24).astype(np.uint16)
        if (packing.float_to_half_splatvjs(x) != truncated).any():
            wrong.add(e)
    assert wrong == stated


def test_lite_property_order_is_as_written():
    block = _section("## `.splatv` → PLY without loss")
    text = block[block.index("```\n") + 4:block.index("\n```", block.index("```\n") + 4)]
    names = []
    for word in text.split():
        if word == "…":
            continue
        names.append(word)
    expanded = []
    for name in names:
        if expanded and re.fullmatch(r"(\w+)_(\d+)", name) and expanded[-1].rsplit("_", 1)[0] == name.rsplit("_", 1)[0]:
            prefix, last = name.rsplit("_", 1)
            first = int(expanded[-1].rsplit("_", 1)[1])
            expanded.extend(f"{prefix}_{i}" for i in range(first + 1, int(last) + 1))
        else:
            expanded.append(name)
    assert tuple(expanded) == ply.LITE_LAYOUT


# --------------------------------------------------------------------------
# specs/json.md: one document for every JSON output. The keys of info, stats,
# verify and diff are checked in tests/test_stats.py and tests/test_verify.py.

JSON_SPEC = (Path(__file__).resolve().parent.parent / "specs" / "json.md").read_text(encoding="utf-8")


def _json_section(heading: str) -> str:
    return JSON_SPEC.split(f"\n## {heading}\n", 1)[1].split("\n## ", 1)[0]


def _commands_with_json() -> list:
    from splatconv.cli import commands

    return sorted(name for name, command in commands().items()
                  if any("--json" in getattr(p, "opts", ()) for p in command.params))


def test_every_json_output_has_a_section_stating_its_schema(tmp_path):
    import json

    from click.testing import CliRunner
    from PIL import Image

    from splatconv import io
    from splatconv.cli import main

    from .ops_helpers import moving_scene

    headings = re.findall(r"^## (.+)$", JSON_SPEC, re.M)
    assert _commands_with_json() == sorted({h.split()[0] for h in headings}), "a section per command with --json"

    scene = moving_scene(200)
    scene.cameras = [cameras.framing_camera(scene.columns["x"], scene.columns["y"], scene.columns["z"])]
    io.write(scene, tmp_path / "a.ply")
    io.write(moving_scene(200, seed=1), tmp_path / "b.ply")
    png = tmp_path / "p.png"
    Image.new("RGB", (4, 4)).save(png)
    a, b = str(tmp_path / "a.ply"), str(tmp_path / "b.ply")
    runs = {"info": ["info", a], "stats": ["stats", a, "--zstd-level", "1"],
            "verify": ["verify", a, a, "--times", "0.5", "--size", "32x18"], "diff": ["diff", str(png), str(png)],
            "merge --segments": ["merge", a, b, str(tmp_path / "m.splatv"), "--segments", "--no-check"]}
    assert sorted(runs) == sorted(headings)
    for heading, args in runs.items():
        r = CliRunner().invoke(main, args + ["--json"])
        assert r.exit_code == 0, (heading, r.output)
        data = json.loads(r.stdout)
        assert list(data)[0] == "schema", heading
        assert f'`"{data["schema"]}"`' in _json_section(heading), heading
        table = re.findall(r"^\| `(\w+)` \|", _json_section(heading), re.M)
        if heading == "merge --segments":
            assert list(data) == table
