"""specs/splatvq.md against the code: the file layout, the payload tables, the settings, constants and test vector."""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np
import pytest

from splatconv.formats import splatvq
from splatconv.formats import splatvq_codec as codec

SPEC = (Path(__file__).resolve().parent.parent / "specs" / "splatvq.md").read_text(encoding="utf-8")
TYPES = {"uint8": "u1", "int8": "i1", "uint16": "<u2", "uint32": "<u4", "float64": "<f8"}


def _section(title: str) -> str:
    start = SPEC.index(title)
    end = SPEC.find("\n## ", start + len(title))
    return SPEC[start:end if end >= 0 else len(SPEC)]


def _table(text: str) -> tuple[list, list]:
    """The first Markdown table in ``text``: its header cells and its rows' cells."""
    lines = [line.strip() for line in text.splitlines()]
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    table = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        if not all(set(c) <= {"-"} for c in cells):
            table.append(cells)
    return table[0], table[1:]


def test_preamble_table_is_the_struct():
    _, rows = _table(_section("## File layout"))
    fixed = [r for r in rows if r[0].isdigit() and r[1].isdigit()]
    offset = 0
    fmt = "<"
    for start, size, name, content in fixed:
        assert int(start) == offset, name
        if size == "4" and name == "magic":
            fmt += "4s"
        elif size == "4":
            fmt += "I"
        else:
            fmt += "b" if content.startswith("int8") else "B"
        offset += int(size)
    assert fmt == splatvq.PREAMBLE.format
    names = [r[2] for r in fixed]
    assert names[3:3 + len(splatvq.SETTING_ORDER)] == list(splatvq.SETTING_ORDER)
    assert offset == splatvq.PREAMBLE.size
    assert "16 `B`" in SPEC and splatvq.BLOCK_ENTRY.size == 16
    assert "`coded`, `raw`, `payload`, `stored`, four uint32" in SPEC and splatvq.BLOCK_ENTRY.format == "<IIII"
    assert "the bytes `SPVQ` (`MAGIC`)" in SPEC and splatvq.MAGIC == b"SPVQ"
    assert "| 4 | 1 | version | 6 (`VERSION`) |" in SPEC and splatvq.VERSION == 6
    assert "1: raw deflate (`CODER_DEFLATE_RAW`)" in SPEC and codec.CODER_DEFLATE_RAW == 1
    assert "8: 256 splats a chunk (`CHUNK_LOG2`)" in SPEC and codec.CHUNK == 256


def test_chunk_table_is_the_codec_layout():
    text = _section("## The block payload")
    _, table = _table(text[text.index("table | type | per chunk") - 2:])
    assert [(name, TYPES[kind], int(k)) for name, kind, k, _ in table] == list(codec.CHUNK_FIELDS)


def test_field_table_is_the_codec_layout():
    text = _section("## The block payload")
    _, table = _table(text[text.index("field | per splat | coding") - 2:])
    assert [(name, int(k), coding) for name, k, coding, _ in table] == list(codec.SPLAT_FIELDS)
    assert f"in order ({len(codec.WIDTH_COLUMNS)} bytes, `WIDTH_COLUMNS`)" in text
    assert len(codec.WIDTH_COLUMNS) == sum(int(k) for _, k, coding, _ in table if coding != "byte")


def test_payload_bounds_sentence():
    sentence = re.search(r"(\d+) · ceil\(coded / (\d+)\) \+ (\d+) \+ (\d+) · raw, plus (\d+) · coded at\s+the "
                         r"fewest and (\d+) · coded at the most", SPEC)
    chunk_bytes, chunk, widths, raw_bytes, fewest, most = map(int, sentence.groups())
    assert (chunk_bytes, chunk, widths, raw_bytes, fewest, most) == (
        codec.CHUNK_BYTES, codec.CHUNK, len(codec.WIDTH_COLUMNS), codec.RAW_BYTES, codec.SPLAT_BYTES_MIN,
        codec.SPLAT_BYTES_MAX)
    for coded, raw in ((0, 1), (1, 0), (300, 7), (65536, 0)):
        chunks = -(-coded // chunk)
        assert codec.payload_bounds(coded, raw) == (chunks * chunk_bytes + widths + raw * raw_bytes + fewest * coded,
                                                    chunks * chunk_bytes + widths + raw * raw_bytes + most * coded)


def test_classed_planes_are_as_written():
    text = " ".join(_section("## The block payload").split())
    assert "how many of 8, 32, 128, 512 (`CLASS_LIMITS`) it reaches" in text
    assert codec.CLASS_LIMITS == (8, 32, 128, 512)
    assert codec.value_class(np.array([[0], [7], [8], [31], [32], [511], [512], [2 ** 32 - 1]])).tolist() == [
        0, 0, 1, 1, 2, 3, 4, 4]
    assert "The plane of motion_1 is stored in the order of the splats sorted by the class of their motion_0 code" in text
    assert "motion_2 by the class of the larger of motion_0 and motion_1" in text
    assert "motion_3..8 and omega_0..3 by the class of the largest of motion_0..2 (`CLASSED_BY`)" in text
    assert codec.CLASSED_BY == {("motion", 1): (0,), ("motion", 2): (0, 1),
                                **{("motion", j): (0, 1, 2) for j in range(3, 9)},
                                **{("omega", j): (0, 1, 2) for j in range(4)}}


def test_settings_table_is_the_code():
    header, rows = _table(_section("### Settings"))
    stated = {r[0]: dict(zip(header[1:], map(int, r[1:]))) for r in rows}
    assert set(stated) == set(codec.SETTINGS)
    for name, values in stated.items():
        assert codec.Setting(**values) == codec.SETTINGS[name]


@pytest.mark.parametrize("text, value", [
    ("1 to 65536 in all (`BLOCK`)", codec.BLOCK == 65536),
    ("level · 64 + (e + 13) · 4 + which quaternion component is dropped (0–3: rot_0..rot_3) (`WINDOW_BIAS`)",
     codec.WINDOW_BIAS == 13 and codec.BOOST_MAX == 3),
    ("e = ((window_index >> 2) AND 15) − 13, from −13 to 2:", (codec.WINDOW_MIN, codec.WINDOW_MAX) == (-13, 2)),
    ("level (window_index >> 6, 0 to 3: `BOOST_MAX`)", codec.BOOST_MAX == 3),
    ("2^min(16, `rotation_bits` + b) − 1", codec.ROTATION_BITS_MAX == 16),
    ("the level is round(0.2 · log2 w), 0 to 3", codec.LEVELS_PER_OCTAVE["frames"] == 0.2),
    ("at 0.5\n  levels an octave", codec.LEVELS_PER_OCTAVE["size"] == 0.5),
    ("each at most 4\n(`MAX_WIDTH`)", codec.MAX_WIDTH == 4),
    ("min(v, 255) of each splat\n  (`SATURATED`)", codec.SATURATED == 255),
    ("at least −13 (`WINDOW_MIN`)", codec.WINDOW_MIN == -13),
    ("code 0 is +0", codec.SCALE_ZERO == 0),
    ("code 1 is +inf\n  (`SCALE_INF`)", codec.SCALE_INF == 1),
    ("c ≥ 2 (`SCALE_FIRST`)", codec.SCALE_FIRST == 2),
    ("4096 interquartile extents", codec.OUTLIER_EXTENTS == 4096),
    ("1032 decoded bytes a stored byte", codec.MAX_RATIO == 1032),
    ("s = clamp((h >> 10) − 15, −15, 16)", True),
    ("h = max(l, m − 1024 · `flat_octaves`)", True),
    ("c = min(`alpha_levels`, 7 − floor(log2(max(a, 1))))", True),
])
def test_constants_are_as_written(text, value):
    assert text in SPEC
    assert value


def test_size_exponent_is_as_written():
    h = np.array([[0, 0x3C00, 0x7C00], [0x4400, 0x4000, 0x3C00], [0x7C00, 0x7C00, 0x7C00], [1, 0x3C00, 0x3C00],
                  [0, 1, 0x3C00]], dtype=np.uint16)
    # The middle of the three bit patterns where flat_octaves is 0 (version 3's rule).
    assert codec.size_exponent(h, 0).tolist() == [0, 1, 16, 0, -15]
    # The least, at most flat_octaves octaves below the middle.
    assert codec.size_exponent(h, 2).tolist() == [-2, 0, 16, -2, -15]
    assert codec.size_exponent(np.array([[0x3000, 0x3C00, 0x3C00]], np.uint16), 15).tolist() == [-3]


def test_alpha_coarsening_is_as_written():
    alpha = np.arange(256)
    expected = [min(3, 7 - int(np.floor(np.log2(max(a, 1))))) for a in alpha]
    assert codec.alpha_coarsening(alpha, 3).tolist() == expected
    assert codec.alpha_coarsening(np.array([0, 1, 127, 128, 255]), 7).tolist() == [7, 7, 1, 0, 0]


def test_the_test_vector_decodes_as_written():
    section = _section("## Test vector")
    blocks = re.findall(r"```\n(.*?)```", section, re.S)
    payload = bytes.fromhex("".join(blocks[0].split()))
    words = [int(w, 16) for w in blocks[1].split()]
    prose = " ".join(section[:section.index("```")].split())
    stated = dict(re.findall(r"(\w+) (−?\d+)[,.]", prose[prose.index("setting"):]))
    setting = codec.Setting(**{name: int(stated[name].replace("−", "-")) for name in splatvq.SETTING_ORDER})
    assert f"The payload ({len(payload)} bytes, hex" in section
    fewest, most = codec.payload_bounds(2, 0)
    assert fewest <= len(payload) <= most
    out = codec.decode_block(payload, 2, 0, setting, "<spec>", ())
    assert out.reshape(-1).tolist() == words
    # The numbers the prose gives are in the payload and the words.
    assert struct.unpack_from("<3d", payload) == (1.0, 2.0, -0.5)
    # In importance order: splat 1 first (splat 0 has a scale of 0); the payload holds splat 0 first.
    key = [1.6875 * 1.9375 * 1.875 * 40, 0.0]
    assert codec.record_key(out).tolist() == key
    assert "its key is 1.6875 · 1.9375 · 1.875 · 40" in section
    assert out[:, 0].view(np.float32).tolist() == [11.125, 4.90625]
    assert codec.x_steps(np.array([1000, 81]), np.array([-8, -3])).tolist() == [1000, 50]
    tables, fields, raw = codec.unpack_payload(payload, 2, 0, "<spec>", ())
    assert fields["x_step"][:, 0].tolist() == [1000, 50] and fields["window_index"][:, 0].tolist() == [112, 54]
    assert fields["motion"][:, :2].tolist() == [[10, 9], [0, 0]] and len(raw) == 0
    # The vector is what the encoder's own packing gives for these codes.
    assert b"".join(codec.payload_parts(tables, fields, raw)) == payload


def test_precision_steps_are_as_written():
    text = " ".join(SPEC.split())
    first, last = codec.PRECISIONS[0], codec.PRECISIONS[-1]
    assert f"a `precision` step from −{-first} to {last} (`PRECISIONS`, `refined`), in half steps" in text
    assert codec.PRECISIONS == tuple(range(first, last + 1))
    base = codec.SETTINGS["default"]
    angular = ("rotation_bits", "omega_shift", "scale_step")
    geometric = ("position_shift", "motion_shift", "time_shift", "trbf_scale_step")
    relations = ("flat_octaves", "acceleration_shift")

    def moved(step):
        s = codec.refined(base, step)
        return {f for f in angular + geometric + relations + ("jerk_shift", "alpha_levels")
                if getattr(s, f) != getattr(base, f)}

    assert moved(1) == set(angular) and moved(2) == set(angular + geometric)
    assert moved(-1) == set(relations) and moved(-2) == set(relations + geometric)
    assert moved(-3) == set(relations + geometric + angular)
    finer = codec.refined(base, 2)
    assert (finer.position_shift, finer.motion_shift) == (base.position_shift - 1, base.motion_shift - 1)
    assert (finer.rotation_bits, finer.time_shift, finer.omega_shift) == (
        base.rotation_bits + 1, base.time_shift + 1, base.omega_shift + 1)
    assert (finer.scale_step, finer.trbf_scale_step) == (round(base.scale_step / 2), round(base.trbf_scale_step / 2))
    coarser = codec.refined(base, -1)
    assert (coarser.flat_octaves, coarser.acceleration_shift) == (base.flat_octaves - 1, base.acceleration_shift + 1)
    assert codec.precision_name("default", 2) == "default+1" and codec.precision_name("small", -1) == "small-0.5"
    for step in codec.PRECISIONS:  # held to the header's limits
        s = codec.refined(base, step)
        assert all(low <= getattr(s, f) <= high for f, (low, high) in codec.SETTING_LIMITS.items())
