"""The ``.splatvq`` format: decoded texture words, stability, fidelity by pixels, undrawables, hostile input."""

from __future__ import annotations

import collections
import io as pyio
import json
import zlib

import numpy as np
import pytest
from click.testing import CliRunner

from splatconv import io
from splatconv.cli import main
from splatconv.errors import UsageError
from splatconv.formats import splatv, splatvq
from splatconv.model import COLUMNS, Scene
from splatconv.formats import splatvq_codec as codec
from splatconv.jobs.convert import CONVERT_MEMORY_BYTES
from splatconv.viewer import importance, importance_order, sort_ends, undrawable
from tests.ops_helpers import CAMERA, draw, psnr
from tests import splatvq_files as damage
from tests.real_scenes import real_scene
from tests.scenes import moving_scene, overlapping_scene

TIMES = (0.1, 0.3, 0.5, 0.7, 0.9)


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def real():
    return real_scene(1200, seed=3)


def written(tmp_path, scene, name="a.splatvq", quality=None):
    path = tmp_path / name
    if quality is None:
        return path, io.write(scene, path)
    data, report = splatvq.encode(scene, quality=quality)
    path.write_bytes(data)
    return path, report


def sorted_records(records: np.ndarray) -> np.ndarray:
    return records[np.lexsort(records.T[::-1])]


def test_decoding_gives_the_texture_words_the_splatv_writer_packs(tmp_path, real):
    path, _ = written(tmp_path, real[0])
    words = splatvq.decode(path)
    scene = splatvq.read(path)
    packed, _ = splatv.encode(scene, sort="none")
    assert words.dtype == np.dtype("<u4") and words.shape == (scene.count, 16)
    assert np.array_equal(packed[:scene.count], words)


@pytest.mark.parametrize("quality", list(codec.SETTINGS))
def test_a_second_conversion_changes_nothing(tmp_path, real, quality):
    # .splatvq -> .splatv -> .splatvq -> .splatv: the two .splatv hold the same records.
    first, _ = written(tmp_path, real[0], quality=quality)
    assert run("convert", first, tmp_path / "b.splatv").exit_code == 0
    written(tmp_path, io.read(tmp_path / "b.splatv"), "c.splatvq", quality)
    assert run("convert", tmp_path / "c.splatvq", tmp_path / "d.splatv").exit_code == 0
    b = splatv.read_records(tmp_path / "b.splatv")[0]
    d = splatv.read_records(tmp_path / "d.splatv")[0]
    assert np.array_equal(sorted_records(b), sorted_records(d))
    # The first step did change values (it is lossy), so the second had something to move.
    scene = real[0]
    records = splatv.encode(scene, sort="none")[0][:scene.count]
    drawn = records[~undrawable(scene.columns)]
    # b holds the drawable splats and the few undrawable ones the viewer's depth sort needs.
    assert len(drawn) < len(b) < len(drawn) + 16
    source = {r.tobytes() for r in records}
    assert sum(r.tobytes() not in source for r in b) > len(drawn) // 2


def test_same_input_same_bytes(real):
    assert splatvq.encode(real[0])[0] == splatvq.encode(real[0])[0]


def test_undrawable_splats_are_left_out_and_counted(tmp_path, real, renderer):
    scene, rows = real
    path, report = written(tmp_path, scene)
    decoded = splatvq.read(path)
    kept = int(undrawable(decoded.columns).sum())  # those the viewer's depth sort needs
    assert 0 < kept <= 16
    assert splatvq.splat_count(path) == scene.count - len(rows.undrawable) + kept
    note = next(n for n in report.notes if n.startswith("left out"))
    assert note.startswith(f"left out {len(rows.undrawable) - kept:,} undrawable splats (")
    assert note.endswith(f"; kept {kept:,} that the viewer's depth sort needs")


def test_fidelity_by_pixels(tmp_path, real, renderer):
    scene, _ = real
    for quality, floor in (("default", 42.0), ("small", 31.0)):
        path, _ = written(tmp_path, scene, f"{quality}.splatvq", quality)
        decoded = splatvq.read(path)
        values = [psnr(draw(renderer, scene, t, CAMERA), draw(renderer, decoded, t, CAMERA)) for t in TIMES]
        assert min(values) >= floor, (quality, values)


def test_small_is_smaller_and_both_beat_splatv(tmp_path, real):
    sizes = {quality: len(splatvq.encode(real[0], quality=quality)[0]) for quality in codec.SETTINGS}
    assert sizes["small"] < sizes["default"] < 64 * real[0].count / 2


def test_values_the_codes_cannot_hold_are_kept_verbatim(tmp_path, real):
    scene, rows = real
    path, report = written(tmp_path, scene)
    assert any("kept verbatim" in n for n in report.notes)
    words = splatvq.decode(path)
    source = splatv.encode(scene, sort="none")[0]
    setting = codec.SETTINGS[codec.DEFAULT_SETTING]
    for picked in (rows.huge_position, rows.zero_rotation_spinning):
        # Every word as it was, but the scales: on the lattice, as a coded splat's (the key blocks are cut by).
        want = {r.tobytes() for r in codec.on_lattice(source[picked], setting)}
        assert want <= {r.tobytes() for r in words}
        assert not {r.tobytes() for r in source[picked]} <= {r.tobytes() for r in words}


def test_a_block_of_verbatim_splats_only(tmp_path, real):
    """Every splat of the block kept verbatim (an infinite rotation component: no code holds it): no coded
    splat, no empty plane trouble, the records back as they were."""
    columns = real[0].take(np.flatnonzero(~undrawable(real[0].columns))[:5])
    columns["rot_0"][:] = np.inf
    scene = Scene(columns, cameras=real[0].cameras)
    path, report = written(tmp_path, scene)
    assert any("5 splats kept verbatim" in n for n in report.notes), report.notes
    want = sorted_records(codec.on_lattice(splatv.encode(scene, sort="none")[0][:5],
                                           codec.SETTINGS[codec.DEFAULT_SETTING]))
    assert (sorted_records(splatvq.decode(path)) == want).all()


def test_codes_past_the_old_16_bits_are_coded_not_kept_verbatim(tmp_path, real):
    """A fast spin on a short quaternion: omega / |q| * W takes codes past 2**15 (version 2's omega field held
    16 bits, so such splats went verbatim); version 3's columns hold 32 bits: coded, and decoded as written."""
    columns = real[0].take(np.flatnonzero(~undrawable(real[0].columns))[:50])
    near = np.abs(np.stack([columns[a] for a in "xyz"])).max(axis=0) < 1e3  # no NaN or far position (verbatim)
    columns = {name: v[near] for name, v in columns.items()}
    for i in range(4):
        columns[f"rot_{i}"][:] = 1e-3
    columns["omega_0"][:] = 5.0
    scene = Scene(columns, cameras=real[0].cameras)
    path, report = written(tmp_path, scene)
    assert not any("kept verbatim" in n for n in report.notes), report.notes
    decoded = splatvq.read(path).columns
    # omega / |q| is what the viewer's normalize(q + omega * dt) turns by: the same, within the code step.
    got = decoded["omega_0"] / np.sqrt(sum(decoded[f"rot_{i}"].astype(np.float64) ** 2 for i in range(4)))
    assert np.allclose(got, 5.0 / np.sqrt(4e-6), rtol=1e-2)


def test_flat_splats_and_infinite_temporal_scales_keep_their_infinities(tmp_path, real):
    scene, rows = real
    path, _ = written(tmp_path, scene)
    decoded = splatvq.read(path).columns
    assert np.isneginf(decoded["scale_1"]).sum() >= len(rows.flat)
    assert np.isposinf(decoded["trbf_scale"]).sum() == len(rows.infinite_trbf)


# --------------------------------------------------------------------------
# Record order: a decoder gives each block's records in importance order.


def test_the_order_code_sorts_keys_as_importance_order_does():
    """Descending keys, -0 as +0, then negative keys (the largest first), then NaN; ties in their order."""
    key = np.array([1.0, -0.0, np.nan, -2.0, 0.0, np.inf, -0.5, 3.0, 1.0, -np.inf, 2.0 ** -72, 7e16])
    assert np.argsort(codec.order_code(key), kind="stable").tolist() == [5, 11, 7, 0, 8, 10, 1, 4, 6, 3, 9, 2]
    key = np.random.default_rng(1).choice(key, 5000)
    assert np.array_equal(np.argsort(codec.order_code(key), kind="stable"), importance_order(key))


def test_a_block_of_raw_records_decodes_in_importance_order():
    """Raw records may hold what no encoder writes (negative and NaN scales): they are ordered all the same."""
    raw = damage.odd_key_records()
    payload = bytes(len(codec.WIDTH_COLUMNS)) + raw.tobytes()
    setting = codec.SETTINGS[codec.DEFAULT_SETTING]
    assert np.array_equal(codec.decode_payload(payload, 0, len(raw), setting, "x", ()), raw)
    out = codec.decode_block(payload, 0, len(raw), setting, "x", ())
    assert np.array_equal(out, raw[list(damage.ODD_KEYS_ORDER)])


def test_a_small_block_joins_planes_into_fewer_deflate_blocks(tmp_path, real, monkeypatch):
    """A few hundred splats: their planes share Huffman codes where that is smaller; the records are the same."""
    scene = Scene(real[0].take(np.flatnonzero(~undrawable(real[0].columns))[:400]), cameras=real[0].cameras)
    joined, _ = written(tmp_path, scene, "joined.splatvq", "default")
    monkeypatch.setattr(codec, "deflate_groups", lambda parts, level=9: [[part] for part in parts])
    alone, _ = written(tmp_path, scene, "alone.splatvq", "default")
    assert joined.stat().st_size < alone.stat().st_size - 100
    assert np.array_equal(splatvq.decode(joined), splatvq.decode(alone))


def test_deflate_groups_keep_every_part_in_order_and_large_ones_alone():
    rng = np.random.default_rng(0)
    parts = [rng.integers(0, k, size, dtype=np.uint8).tobytes()
             for size, k in [(30, 3), (20, 3), (4500, 200), (40, 4), (500, 9), (14, 2), (5000, 50), (60, 60)]]
    groups = codec.deflate_groups(parts)
    assert [part for group in groups for part in group] == parts
    assert [parts[2]] in groups and [parts[6]] in groups
    assert all(sum(map(len, group)) <= codec.GROUP_BYTES for group in groups if len(group) > 1)
    assert len(groups) < len(parts)


def test_deflate_groups_find_the_smallest_cut():
    """Every cut of a few small parts into runs, each run deflated as the writer does: none is smaller."""
    import itertools

    # Parts where joining each to the run before it when the two deflate smaller (the cut before) is
    # larger than the best (538 bytes against 530).
    rng = np.random.default_rng(14)
    parts = [rng.integers(0, k, size, dtype=np.uint8).tobytes()
             for size, k in [(68, 200), (264, 3), (44, 40), (145, 200), (141, 40), (81, 5), (38, 40)]]

    def cost(groups):
        return sum(codec._deflated_size(b"".join(group), 9) for group in groups)

    cuts = []
    for ends in itertools.product([False, True], repeat=len(parts) - 1):
        groups, run = [], [parts[0]]
        for part, end in zip(parts[1:], ends):
            if end:
                groups.append(run)
                run = []
            run.append(part)
        cuts.append(groups + [run])
    best = min(cost(groups) for groups in cuts)
    found = codec.deflate_groups(parts)
    assert [part for group in found for part in group] == parts
    assert cost(found) == best < cost([[part] for part in parts]) and best < cost([parts])


@pytest.fixture(scope="module")
def overlapping():
    """Many equal importance keys (among them raw records'), in blocks of 256 splats: a .splatvq's path."""
    scene = overlapping_scene()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(codec, "BLOCK", 256)
        data, report = splatvq.encode(scene)
    return data, report


class _Pipe:
    """A stream that cannot seek (standard output, a compressor): what write falls back to encode for."""

    def __init__(self):
        self.data = bytearray()

    def write(self, b):
        self.data += b
        return len(b)

    def seekable(self):
        return False


def test_a_write_streams_its_blocks_and_writes_what_encode_gives(tmp_path, monkeypatch, overlapping):
    # A seekable stream gets each block as it is encoded (the block table filled in after, where the
    # header left room for it), from wherever the stream stands; any other stream the bytes encode gives.
    monkeypatch.setattr(codec, "BLOCK", 256)
    scene = overlapping_scene()
    seekable = pyio.BytesIO(b"before")
    seekable.seek(0, 2)
    report = splatvq.write(scene, seekable)
    pipe = _Pipe()
    splatvq.write(scene, pipe)
    assert seekable.getvalue() == b"before" + overlapping[0] and bytes(pipe.data) == overlapping[0]
    assert report.notes == overlapping[1].notes and report.count == overlapping[1].count
    appended = tmp_path / "a.splatvq"  # a file opened to append to seeks in vain: encode's bytes
    appended.write_bytes(b"before")
    with open(appended, "ab") as f:
        splatvq.write(scene, f)
    assert appended.read_bytes() == b"before" + overlapping[0]
    _, entries, body_at = damage.layout(overlapping[0])  # the table filled in: each block where it says
    assert len(entries) == 2 and body_at + sum(e[3] for e in entries) == len(overlapping[0])
    assert all(e[0] + e[1] > 0 for e in entries)


def test_records_decode_in_importance_order_block_after_block(tmp_path, overlapping, monkeypatch):
    monkeypatch.setattr(codec, "BLOCK", 256)
    path = tmp_path / "o.splatvq"
    path.write_bytes(overlapping[0])
    assert any("6 splats kept verbatim" in n for n in overlapping[1].notes)
    words, _, info = splatvq.read_records(path)
    assert info["blocks"] == 2
    key = codec.record_key(words)
    assert len(np.unique(key)) < len(key) - 100  # many ties
    # The whole file, block after block, is in importance order (blocks are cut by the same key).
    assert np.array_equal(importance_order(key), np.arange(len(key)))
    # Inside a block, ties keep the payload's order: coded splats (by position), then raw records.
    data = overlapping[0]
    _, entries, at = damage.layout(data)
    start, ties_with_raw = 0, 0
    for coded, raw, _, stored in entries:
        payload = zlib.decompress(data[at:at + stored], -15)
        records = codec.decode_payload(payload, coded, raw, damage.setting(data), "x", ())
        assert np.array_equal(words[start:start + len(records)], records[importance_order(codec.record_key(records))])
        ties_with_raw += np.isin(codec.record_key(records[:coded]), codec.record_key(records[coded:])).sum()
        start, at = start + len(records), at + stored
    assert ties_with_raw > 0


#: Most the .splatv writer's importance key (exp of float32 log scales times the sigmoid of a float32 logit
#: opacity, in doubles, as splaTV's converter computes it) can err, relative to the exact product, twice over
#: for a pair of keys: a float32 ulp of each log (its tables round up: |log| < 32 for every half, so 2**-19)
#: and of the logit (|logit| < 8: 2**-21).
WRITER_KEY_ERROR = 2 * (3 * 2.0 ** -19 + 2.0 ** -21)


def test_a_splatv_of_the_decoded_scene_holds_the_records_in_the_same_order(tmp_path, overlapping, monkeypatch):
    """`convert X.splatvq Y.splatv --sort none` keeps the decoded order; the default (importance) sort of the
    .splatv writer gives the same order but where its rounded key swaps near-equal keys."""
    monkeypatch.setattr(codec, "BLOCK", 256)
    path = tmp_path / "o.splatvq"
    path.write_bytes(overlapping[0])
    assert run("convert", path, tmp_path / "none.splatv", "--sort", "none").exit_code == 0
    assert run("convert", path, tmp_path / "sorted.splatv").exit_code == 0
    none = splatv.read_records(tmp_path / "none.splatv")[0]
    ordered = splatv.read_records(tmp_path / "sorted.splatv")[0]
    assert np.array_equal(none, splatvq.decode(path))
    assert np.array_equal(sorted_records(none), sorted_records(ordered))
    # The decoded order is importance order by the exact key; the writer's by its rounded key: at every
    # place the two files hold a record of the same exact key, or of one the writer cannot tell from it.
    key, writer = codec.record_key(none), codec.record_key(ordered)
    assert np.array_equal(importance_order(key), np.arange(len(key)))
    assert (np.abs(writer - key) <= key * WRITER_KEY_ERROR).all()
    # Which of those the writer swaps is its rounding's choice: equal keys with their scales on other axes here.
    moved = np.flatnonzero((none != ordered).any(axis=1))
    print(f"the .splatv writer's rounded key moves {len(moved)} of {len(key)} records, "
          f"{np.count_nonzero(writer != key)} of them to a place of another exact key")
    # Its order is the importance order of the decoded scene, sorted by the writer's own key.
    assert np.array_equal(ordered, none[importance_order(importance(splatv.read(tmp_path / "none.splatv").columns))])


# --------------------------------------------------------------------------
# Hostile input: one Error: line, nothing written.


def _good(tmp_path) -> bytes:
    scene, _ = real_scene(300, seed=1)
    return splatvq.encode(scene)[0]


def _bad_scale(tables, fields):
    fields["scale"][5, 2] = 1 << 20


def _without_end(payload: bytes) -> bytes:
    """Raw deflate of ``payload`` that stops without a final block (a sync flush, no end marker)."""
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    return comp.compress(payload) + comp.flush(zlib.Z_SYNC_FLUSH)


def _no_blocks(data: bytes) -> bytes:
    fields = splatvq.PREAMBLE.unpack_from(data)
    table_at, _, _ = damage.layout(data)
    return splatvq.PREAMBLE.pack(*fields[:-1], 0) + data[splatvq.PREAMBLE.size:table_at]


BAD = [
    ("too short", lambda d: d[:10], "10 bytes is too short for a .splatvq file (31-byte preamble)"),
    ("magic", lambda d: b"XXXX" + d[4:], "not a .splatvq file: magic b'XXXX', expected b'SPVQ'"),
    ("version", lambda d: d[:4] + b"\x09" + d[5:], "version 9 is not one this reader knows (6)"),
    ("version 5", lambda d: d[:4] + b"\x05" + d[5:], "version 5 is not one this reader knows (6)"),
    ("coder", lambda d: d[:5] + b"\x02" + d[6:], "coder 2 is not one this reader knows (1: raw deflate)"),
    ("setting", lambda d: d[:7] + b"\x00" + d[8:], "setting 'rotation_bits' is 0, outside [2, 16]"),
    ("truncated", lambda d: d[:-5], "block 0: declares {stored} bytes but the file ends {short} bytes after its "
     "start: file truncated?"),
    ("extra bytes", lambda d: d + b"\0", "the blocks end at byte {size} but the file has {size1}"),
    ("count lies", lambda d: damage.with_count(d, 5), "header 'count' is 5 but the blocks hold {count} splats"),
    ("header corrupt", lambda d: damage.with_header(d, b"\xff" * 20, 300),
     "header JSON: compressed data is corrupt (Error -3 while decompressing data: invalid block type)"),
    ("header decodes to more", lambda d: damage.with_header(d, damage.deflate(b" " * 400), 300),
     "header JSON: decodes to more than the 300 bytes declared"),
    ("header past the JSON read", lambda d: damage.with_header(d, damage.deflate(b" " * 400), (64 << 20) + 1),
     "header declares 67108865 bytes of JSON, more than the 67108864 read"),
    ("stored header past the JSON read", lambda d: d[:19] + ((64 << 20) + 1).to_bytes(4, "little") + d[23:],
     "header declares 67108865 bytes of JSON, more than the 67108864 read"),
    ("header inflating past 0 declared", lambda d: damage.with_header(d, damage.deflate(bytes(1 << 20)), 0),
     "header JSON: decodes to more than the 0 bytes declared"),
    ("header ratio", lambda d: damage.with_header(d, b"\0" * 5, 6000),
     "header declares 6000 bytes of JSON from 5 stored, more than deflate can give"),
    ("header not JSON", lambda d: damage.with_header(d, damage.deflate(b"{count"), 6),
     "header JSON: Expecting property name enclosed in double quotes (line 1, column 2)"),
    ("table lies: more splats", lambda d: damage.with_entry(d, coded=70000), "block 0: holds {big} splats; a block "
     "holds 1 to 65536"),
    ("table lies: decoded size", lambda d: damage.with_entry(d, payload=damage.layout(d)[1][0][2] + 10),
     "block 0: decodes to {payload} bytes, not the {payload10} declared"),
    ("table lies: size out of bounds", lambda d: damage.with_entry(d, payload=5), "block 0: declares 5 decoded bytes; "
     "{coded} coded and {raw} verbatim splats take {fewest} to {most}"),
    ("decodes to more", lambda d: damage.with_entry(d, stored=len(x := damage.deflate(damage.payload(d) + bytes(64))),
                                                    body=x),
     "block 0: decodes to more than the {payload} bytes declared"),
    ("ratio", lambda d: damage.with_entry(d, coded=65000, raw=0, payload=codec.payload_bounds(65000, 0)[0],
                                          stored=5, body=b"\0" * 5),
     "block 0: declares {ratio} decoded bytes from 5 stored, more than deflate can give"),
    ("corrupt stream", lambda d: damage.with_entry(d, body=b"\xff" * len(d[damage.layout(d)[2]:])),
     "block 0: compressed data "
     "is corrupt (Error -3 while decompressing data: invalid block type)"),
    ("position step", lambda d: damage.with_codes(d, damage.bad_position_step),
     "block 0: a position code is past 2**32 - 1"),
    ("rotation code", lambda d: damage.with_codes(d, damage.bad_rotation), f"block 0: a rotation code is past {(1 << codec.SETTINGS['default'].rotation_bits) - 1}"),
    ("scale code", lambda d: damage.with_codes(d, _bad_scale), "block 0: a scale code decodes past the half range"),
    ("width", lambda d: damage.with_width(d, "x_step[0]", 5), "block 0: a column width of 5 bytes (at most 4)"),
    ("payload ends early", lambda d: damage.with_width(d, "rotation[0]", codec.MAX_WIDTH),
     "block 0: its payload ends before its last record"),
    ("payload cut", lambda d: damage.with_payload(d, damage.payload(d)[:-1]), "block 0: its payload ends before its "
     "last record"),
    ("no end marker", lambda d: damage.with_entry(d, stored=len(x := _without_end(damage.payload(d))), body=x),
     "block 0: its compressed data stops after the {payload} bytes declared without its end marker"),
    ("data after the end marker", lambda d: damage.with_entry(d, stored=len(x := damage.deflate(damage.payload(d))
                                                                            + b"\1"), body=x),
     "block 0: 1 byte after the end of its compressed data"),
    ("no blocks", lambda d: damage.with_count(_no_blocks(d), 0), "its block table lists no blocks; a .splatvq "
     "file holds at least one splat"),
    ("payload has more", lambda d: damage.with_payload(d, damage.payload(d) + b"\0" * 64),
     "block 0: its payload has 64 bytes after its last record"),
]


@pytest.mark.parametrize("name, mutate, message", BAD, ids=[b[0] for b in BAD])
def test_bad_input_gives_one_error_line_and_writes_nothing(tmp_path, name, mutate, message):
    good = _good(tmp_path)
    coded, raw, payload, stored = damage.layout(good)[1][0]
    bad = mutate(good)
    path = tmp_path / "bad.splatvq"
    path.write_bytes(bad)
    fewest, most = codec.payload_bounds(coded, raw)
    message = message.format(stored=stored, short=stored - 5, size=len(good), size1=len(good) + 1,
                             count=coded + raw, big=70000 + raw, payload=payload, payload10=payload + 10,
                             coded=coded, raw=raw, fewest=fewest, most=most,
                             ratio=codec.payload_bounds(65000, 0)[0])
    r = run("convert", path, tmp_path / "out.splatv")
    assert (r.exit_code, r.stderr) == (1, f"Error: {path}: {message}\n"), r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.splatvq"]


def _three_blocks():
    """A file of three blocks: a small real scene's block, repeated (the table and count made to agree)."""
    one = splatvq.encode(real_scene(300, seed=1)[0])[0]
    table_at, entries, body_at = damage.layout(one)
    fields = splatvq.PREAMBLE.unpack_from(one)
    head = splatvq.PREAMBLE.pack(*fields[:-1], 3) + one[splatvq.PREAMBLE.size:table_at]
    data = head + splatvq.BLOCK_ENTRY.pack(*entries[0]) * 3 + one[body_at:] * 3
    return damage.with_count(data, 3 * (entries[0][0] + entries[0][1])), entries[0][3]


@pytest.mark.parametrize("damaged", [(2,), (1, 2), (2, 0), (0, 1, 2)], ids=str)
def test_the_first_damaged_block_is_named(tmp_path, damaged):
    """Blocks are decoded two at a time: whichever finishes first, the error names the first damaged block."""
    data, stored = _three_blocks()
    body_at = damage.layout(data)[2]
    assert splatvq.splat_count(_write(tmp_path, data)) is not None
    for i in damaged:
        at = body_at + i * stored
        data = data[:at] + b"\xff" * stored + data[at + stored:]
    r = run("convert", _write(tmp_path, data), tmp_path / "out.splatv")
    assert r.exit_code == 1 and f"bad.splatvq: block {min(damaged)}: compressed data is corrupt" in r.stderr, r.stderr
    undamaged, _ = _three_blocks()
    assert run("convert", _write(tmp_path, undamaged), tmp_path / "out.splatv").exit_code == 0


def _write(tmp_path, data):
    path = tmp_path / "bad.splatvq"
    path.write_bytes(data)
    return path


def test_a_small_file_declaring_a_large_scene_is_held_to_the_decompression_ceiling(tmp_path):
    """Blocks of zeros deflate some thousand to one: a 100 KB file can declare millions of splats. A read is
    held to the decompression ceiling (--max-decompressed) from the block table, before a block is decoded."""
    payload = bytes(codec.payload_bounds(codec.BLOCK, 0)[0])  # a valid payload: every code 0
    stored = damage.deflate(payload)
    cameras = damage.header_json(splatvq.encode(real_scene(300, seed=1)[0])[0])["cameras"]
    meta = json.dumps({"count": 8 * codec.BLOCK, "cameras": cameras}).encode()
    packed = splatvq.header_deflated(meta)
    values = [getattr(codec.SETTINGS["default"], f) for f in splatvq.SETTING_ORDER]
    data = (splatvq.PREAMBLE.pack(splatvq.MAGIC, splatvq.VERSION, codec.CODER_DEFLATE_RAW, *values, codec.CHUNK_LOG2,
                                  len(packed), len(meta), 8) + packed
            + splatvq.BLOCK_ENTRY.pack(codec.BLOCK, 0, len(payload), len(stored)) * 8 + stored * 8)
    path = _write(tmp_path, data)
    assert len(data) < 40_000 and splatvq.splat_count(path) == 8 * codec.BLOCK
    out = tmp_path / "out.ply"
    r = CliRunner().invoke(main, ["--max-decompressed", "32M", "convert", str(path), str(out)])
    each = CONVERT_MEMORY_BYTES
    assert r.exit_code == 1 and r.stderr == (
        f"Error: {path}: holds 524,288 splats: up to {524_288 * each:,} bytes in memory ({each} a splat), more than "
        "the 32 MiB a decompressed scene may take (raise it with --max-decompressed or SPLATCONV_MAX_DECOMPRESSED)\n")
    assert not out.exists()
    # info holds a block at a time, never the scene: the ceiling on a scene held does not apply.
    r = CliRunner().invoke(main, ["--max-decompressed", "32M", "info", "--json", str(path)])
    assert r.exit_code == 0 and json.loads(r.stdout)["count"] == 524_288


def test_an_unknown_quality_is_a_usage_error(real):
    with pytest.raises(UsageError, match=r"unknown .splatvq setting 'best' \(expected one of default, small\)"):
        splatvq.encode(real[0], quality="best")


def test_verify_and_stats_compare_against_the_sources_drawable_splats(tmp_path, real):
    """The writer leaves undrawable splats out: both commands pair the file with the source's drawable splats
    (once, in compare.pair) and say so, instead of refusing for the difference in count."""
    scene, _rows = real
    source, converted = tmp_path / "rs.ply", tmp_path / "rs.splatvq"
    io.write(scene, source)
    io.write(scene, converted)
    kept = int(np.count_nonzero(~undrawable(scene.columns)))
    extra = int(np.count_nonzero(undrawable(io.read(converted).columns)))  # those the depth sort needs
    assert kept < scene.count and extra > 0
    note = (f"note: {converted} holds the {kept:,} drawable splats of {source}'s {scene.count:,} and {extra:,} "
            f"undrawable ones the viewer's depth sort needs (the {scene.count - kept - extra:,} other ")
    r = CliRunner().invoke(main, ["verify", str(source), str(converted), "--json", "--times", "0.2,0.8",
                                  "--size", "160x120"])
    assert r.exit_code == 0, r.output
    verified = json.loads(r.stdout)
    assert verified["passed"] and verified["count"] == kept + extra
    assert verified["notes"][0].startswith(note[len("note: "):])
    assert verified["notes"][0].endswith("compared against those")
    assert note in r.stderr
    r = CliRunner().invoke(main, ["stats", str(source), str(converted), "--json"])
    assert r.exit_code == 0, r.output
    stats = json.loads(r.stdout)
    assert stats["notes"] == verified["notes"] and note in r.stderr
    # Paired with the right splats: colour and opacity bytes are kept exactly, positions move by under a step.
    assert stats["attributes"]["color"]["max_abs_error"] <= 0.5 / 255 + 1e-6
    assert stats["attributes"]["opacity"]["max_abs_error"] <= 0.5 / 255 + 1e-6
    assert stats["attributes"]["position"]["max_abs_error"] < 0.02


def test_pairing_finds_each_quantized_splat_and_refuses_any_other_count(tmp_path, real):
    """compare.pair: the source's drawable splats, each paired with its own quantized copy (colour and opacity
    bytes equal, position within two hundredths); a file that lost other splats is still refused."""
    from splatconv.compare import _byte_key, pair
    from splatconv.errors import UnsupportedError
    from splatconv.model import COLUMNS, Scene

    scene, _rows = real
    path, _report = written(tmp_path, scene)
    converted = io.read(path)
    order, notes = pair(scene, converted, storage=splatv.FORMAT.storage(converted))
    keep = np.flatnonzero(~undrawable(scene.columns) | sort_ends(scene.columns, scene.cameras))
    assert sorted(order.tolist()) == keep.tolist() and len(notes) == 1
    assert (_byte_key(scene.take(order)) == _byte_key(converted.columns)).all()
    moved = np.stack([np.abs(scene.columns[c][order] - converted.columns[c]) for c in "xyz"])
    assert moved.max() < 0.02
    # The same count: no note, as before.
    drawable = Scene(columns=scene.take(keep), cameras=scene.cameras)
    same, notes = pair(drawable, converted, storage=splatv.FORMAT.storage(converted))
    assert np.array_equal(keep[same], order) and notes == []
    # One splat fewer than the drawable ones: refused as before.
    short = Scene(columns={k: np.asarray(v)[1:] for k, v in converted.columns.items()})
    refused = f"SOURCE has {scene.count:,} splats but CONVERTED has {len(keep) - 1:,}"
    assert len(keep) - 1 != np.count_nonzero(~undrawable(scene.columns))
    with pytest.raises(UnsupportedError, match=refused):
        pair(scene, short, storage=splatv.FORMAT.storage(converted))


EDITS = [
    ["--drop-undrawable"], ["--drop-nonfinite"], ["--trim", "0.2,0.7"], ["--crop", "-1,-1,-1,1,1,1"],
    ["--min-opacity", "0.3"], ["--max-splats", "100"], ["--translate", "1,2,3"], ["--rotate", "y:30,x:-10"],
    ["--scale", "2"], ["--trim", "0.1,0.6", "--crop", "-2,-2,-2,2,2,2", "--scale", "0.5", "--max-splats", "300"],
]


@pytest.fixture(scope="module")
def pair(tmp_path_factory, real):
    """A .splatvq and the .splatv of what it decodes to (the same texture words)."""
    folder = tmp_path_factory.mktemp("vqedit")
    vq = folder / "scene.splatvq"
    assert run("convert", real_scene_ply(folder, real), vq).exit_code == 0
    decoded = folder / "decoded.splatv"
    assert run("convert", vq, decoded, "--sort", "none").exit_code == 0
    assert (splatv.read_records(decoded)[0] == splatvq.decode(vq)).all()
    return vq, decoded


def real_scene_ply(folder, real):
    path = folder / "real.ply"
    io.write(real[0], path)
    return path


@pytest.mark.parametrize("edit", EDITS, ids=[" ".join(e) for e in EDITS])
def test_every_edit_on_a_splatvq_input_is_the_edit_of_what_it_decodes_to(tmp_path, pair, edit):
    """Each edit reads a .splatvq as the scene its texture words hold: the same output, byte for byte, as the
    same edit of a .splatv holding those words (whose edits are proved by pixels in test_edit*.py)."""
    vq, decoded = pair
    a, b = tmp_path / "from_vq.splatv", tmp_path / "from_splatv.splatv"
    ra, rb = run("convert", vq, a, *edit), run("convert", decoded, b, *edit)
    assert ra.exit_code == rb.exit_code == 0, (ra.output, rb.output)
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("args", [["--time", "0.35"], ["--frames", "3"]], ids=["time", "frames"])
def test_bake_and_merge_on_a_splatvq_input(tmp_path, pair, args):
    vq, decoded = pair
    if "--time" in args:
        outs = [tmp_path / "vq.ply", tmp_path / "v.ply"]
    else:
        outs = [tmp_path / "vq", tmp_path / "v"]
    ra, rb = run("bake", vq, outs[0], *args), run("bake", decoded, outs[1], *args)
    assert ra.exit_code == rb.exit_code == 0, (ra.output, rb.output)
    if "--time" in args:
        assert outs[0].read_bytes() == outs[1].read_bytes()
    else:
        names = sorted(p.name for p in outs[0].iterdir())
        assert len(names) == 3 and names == sorted(p.name for p in outs[1].iterdir())
        assert all((outs[0] / n).read_bytes() == (outs[1] / n).read_bytes() for n in names)
    ma, mb = tmp_path / "m_vq.splatv", tmp_path / "m_v.splatv"
    assert run("merge", vq, decoded, ma).exit_code == 0
    assert run("merge", decoded, decoded, mb).exit_code == 0
    assert ma.read_bytes() == mb.read_bytes()


def _behind_an_unseen_splat(n: int, backdrop: float) -> Scene:
    """Splats in front of the camera, the largest of them opaque, a backdrop ``backdrop`` behind them, and two
    undrawable splats (zero rotation): splat 0 farther than all, splat 1 the largest and most opaque."""
    scene = moving_scene(n, 3)
    c = {k: np.array(scene.columns[k]) for k in COLUMNS}
    rng = np.random.default_rng(3)
    for k in ("scale_0", "scale_1", "scale_2"):
        c[k][2:] = np.log(rng.uniform(0.3, 0.8, n - 2))
    for i in range(4):
        c[f"rot_{i}"][:2] = c[f"omega_{i}"][:2] = 0.0
    c["z"][2] = c["z"][3:].max() + backdrop
    c["z"][0] = c["z"][2] + 40.0
    for k in ("scale_0", "scale_1", "scale_2"):
        c[k][1], c[k][2] = np.log(3.0), np.log(2.5)
    c["opacity"][1:3] = 4.0, 3.0
    for i in range(9):
        c[f"motion_{i}"][2] = 0.0
    c["trbf_scale"][2] = np.log(1e3)
    return Scene(c, cameras=scene.cameras)


def test_the_depth_sort_drops_and_repeats_what_a_splatv_does(tmp_path):
    """The viewer sorts every record, drawable or not: it never draws the farthest when its scaled key reaches
    the top (as the rounding of the keys' range falls) and draws the first record in its place. Here the
    farthest and the first record are undrawable; a file that left them out would drop (or not) and repeat
    other splats: the backdrop, the largest drawable one. From every view of the proof, the decoded file
    drops the records the source drops, at the same positions, and repeats the same first record."""
    from splatconv.render import proof
    from splatconv.render.frames import Source
    from splatconv.render.sort import viewer_order

    def dropped_and_first(scene, vp):
        words = Source("", scene).texture().view(np.uint32).reshape(-1, 16)[:scene.count]
        xyz = words[:, :3].view(np.float32)
        kept = np.zeros(scene.count, bool)
        kept[viewer_order(xyz, vp)] = True
        return sorted(map(tuple, xyz[~kept].tolist())), tuple(xyz[0].tolist())

    for backdrop in (0.5, 1.0, 2.0):
        scene = _behind_an_unseen_splat(120, backdrop)
        assert undrawable(scene.columns)[:2].all() and importance_order(importance(scene.columns))[0] == 1
        path, report = written(tmp_path, scene, f"{backdrop}.splatvq")
        decoded = splatvq.read(path)
        for name, view in proof.proof_views(scene):
            assert dropped_and_first(decoded, view.view_proj()) == dropped_and_first(scene, view.view_proj()), name
        assert "kept 2 undrawable splats: the viewer's depth sort needs them" in report.notes
        assert np.count_nonzero(undrawable(decoded.columns)) == 2


def test_the_small_setting_rounds_colours_and_says_so(tmp_path, monkeypatch):
    """`small` rounds each coded splat's red, green and blue bytes to a multiple of 4 (255 at most), alpha
    kept; the header says so, verify judges colour by the frames, and a second encoding keeps them."""
    from splatconv import compare

    scene = moving_scene(3000, seed=5)
    out, again = tmp_path / "s.splatvq", tmp_path / "again.splatvq"
    io.write(scene, out, quality="small")
    decoded = io.read(out)
    assert decoded.meta.get("color_shift") == 2
    rgb = np.rint(np.clip(np.stack([decoded.columns[f"f_dc_{j}"] for j in range(3)], axis=1), 0, 1) * 255)
    rounded = np.all((rgb % 4 == 0) | (rgb == 255), axis=1)
    with open(out, "rb") as f:  # the splats kept verbatim keep theirs
        raw = sum(b.raw for b in splatvq._header(f, str(out), out.stat().st_size)[2])
    assert np.count_nonzero(~rounded) <= raw < decoded.count // 10
    assert splatvq.storage(decoded)["color"] == "quantized" and "quantized" in compare.UNCHECKED
    src = tmp_path / "s.ply"
    io.write(scene, src)
    r = CliRunner().invoke(main, ["verify", str(src), str(out), "--json", "--size", "160x120", "--times", "0.5"])
    assert json.loads(r.stdout)["attributes"]["color"]["storage"] == "quantized"
    # stats pairs the splats by content: by alpha and position here, the colour words being rounded.
    r = CliRunner().invoke(main, ["stats", str(src), str(out), "--json", "--zstd-level", "1"])
    assert json.loads(r.stdout)["pairing"] == {"paired": decoded.count, "unpaired": 0}
    io.write(decoded, again, quality="small")
    # The rounding is a projection: a second encoding keeps every coded splat. A splat kept verbatim as an
    # end of the source's depth range need not be one of the decoded scene's (its neighbours moved): coded.
    first = collections.Counter(r.tobytes() for r in splatvq.decode(out))
    second = collections.Counter(r.tobytes() for r in splatvq.decode(again))
    assert sum((first - second).values()) <= raw
    default = tmp_path / "d.splatvq"
    io.write(scene, default)
    assert "color_shift" not in io.read(default).meta and splatvq.storage(io.read(default))["color"] == "byte"
    # The rounding is what makes it smaller than the same setting with colours kept.
    kept = tmp_path / "kept.splatvq"
    monkeypatch.setitem(codec.SETTINGS, "small", codec.replace(codec.SETTINGS["small"], color_shift=0))
    io.write(scene, kept, quality="small")
    assert out.stat().st_size < kept.stat().st_size
