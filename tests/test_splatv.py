"""The .splatv writers and reader: record layout, lossless inverse, hostile files."""

from __future__ import annotations

import io
import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import splatconv
from splatconv import packing, viewer
from splatconv.formats import splatv
from splatconv.model import COLUMNS, Scene
from tests import reference
from splatconv.formats.base import WriteReport

from .conftest import random_columns, splatv_bytes


def pack(cols, compat=False):
    report = WriteReport()
    return reference.pack_block(cols, compat, report), report


def one_splat(**values):
    cols = {name: np.zeros(1, np.float32) for name in COLUMNS}
    for k, v in values.items():
        cols[k] = np.array([v], np.float32)
    return cols


def test_record_layout_word_by_word():
    cols = one_splat(x=1.5, y=-2.0, z=3.25, rot_0=1, rot_1=0.5, rot_2=-0.5, rot_3=0.25,
                     scale_0=math.log(2), scale_1=0.0, scale_2=math.log(0.5), f_dc_0=1.0, f_dc_1=0.5,
                     f_dc_2=0.0, opacity=0.0, **{f"motion_{i}": i + 1 for i in range(9)},
                     omega_0=0.125, omega_1=-1, omega_2=2, omega_3=4, trbf_center=0.75,
                     trbf_scale=math.log(0.25))
    words, _ = pack(cols)
    w = words[0]
    f32 = lambda v: struct.unpack("<I", struct.pack("<f", v))[0]  # noqa: E731
    h = lambda v: struct.unpack("<H", struct.pack("<e", v))[0]  # noqa: E731
    pair = lambda a, b: h(a) | h(b) << 16  # noqa: E731
    assert list(w[:3]) == [f32(1.5), f32(-2.0), f32(3.25)]
    assert w[3] == pair(1, 0.5) and w[4] == pair(-0.5, 0.25)
    assert w[5] == pair(2, 1) and w[6] == pair(0.5, 0)
    assert w[7] == 255 | 128 << 8 | 0 << 16 | 128 << 24  # 0.5*255=127.5 -> 128 (even); sigmoid(0)=.5
    assert [w[8], w[9], w[10], w[11], w[12]] == [pair(1, 2), pair(3, 4), pair(5, 6), pair(7, 8), pair(9, 0)]
    assert w[13] == pair(0.125, -1) and w[14] == pair(2, 4)
    assert w[15] == pair(0.75, 0.25)


def js_reference_record(c: dict) -> list:
    """splaTV's converter for one splat, value by value (double maths, float32 stores)."""
    from .test_packing import ref_splatvjs

    def f32(v):
        return struct.unpack("<f", struct.pack("<f", v))[0] if math.isfinite(v) or math.isnan(v) else v

    def half(v):
        return ref_splatvjs(f32(v) if not (math.isinf(v) or abs(v) > 3.4e38) else v)

    def pair(a, b):
        return half(a) | half(b) << 16

    def byte(v):
        v = max(0.0, min(255.0, v)) if not math.isnan(v) else 0.0
        return int(v) & 0xFF

    def exp(v):
        try:
            return math.exp(v)
        except OverflowError:
            return math.inf

    g = {k: float(v[0]) for k, v in c.items()}
    words = [struct.unpack("<I", struct.pack("<f", g[k]))[0] for k in ("x", "y", "z")]
    words += [pair(g["rot_0"], g["rot_1"]), pair(g["rot_2"], g["rot_3"]),
              pair(exp(g["scale_0"]), exp(g["scale_1"])), pair(exp(g["scale_2"]), 0)]
    rgba = [byte(g[f"f_dc_{i}"] * 255) for i in range(3)] + [byte(1 / (1 + exp(-g["opacity"])) * 255)]
    words.append(rgba[0] | rgba[1] << 8 | rgba[2] << 16 | rgba[3] << 24)
    m = [g[f"motion_{i}"] for i in range(9)] + [0.0]
    words += [pair(m[i], m[i + 1]) for i in range(0, 10, 2)]
    words += [pair(g["omega_0"], g["omega_1"]), pair(g["omega_2"], g["omega_3"]),
              pair(g["trbf_center"], exp(g["trbf_scale"]))]
    return words


def hostile_columns(n=400, seed=3):
    cols = random_columns(n, seed)
    rng = np.random.default_rng(seed)
    specials = np.array([0, -0.0, 1e-15, 3e-15, 2e-14, 5e-8, 6e-5, 1e-40, 40000, 65504, 70000, -1e6,
                         np.inf, -np.inf, np.nan, 1.00146484375, 0.1], np.float32)
    for name in COLUMNS:
        if name in ("x", "y", "z"):
            continue
        hit = rng.random(n) < 0.2
        cols[name][hit] = rng.choice(specials, hit.sum())
    cols["f_dc_0"][:10] = [-1, 2, np.nan, 0.5, 1.0, 0.999, 1e-9, -0.0, 254.6 / 255, 0.5 / 255]
    cols["scale_1"][:4] = [20.0, -20.0, 11.5, 10.4]  # exp() overflows the half range, or underflows
    return cols


def test_compat_writer_matches_per_splat_reference_of_the_js():
    cols = hostile_columns()
    words, _ = pack(cols, compat=True)
    for i in range(len(words)):
        one = {k: v[i:i + 1] for k, v in cols.items()}
        assert list(words[i]) == js_reference_record(one), f"splat {i}"


def test_compat_sort_is_stable_descending_on_float32_key(tmp_path):
    cols = random_columns(50, 7)
    cols["scale_0"][10:20] = 0.0
    cols["scale_1"][10:20] = 0.0
    cols["scale_2"][10:20] = 0.0
    cols["opacity"][10:20] = 100.0  # ten equal keys: their input order must be kept
    scene = Scene(columns=cols)
    buf = io.BytesIO()
    splatv.write(scene, buf, compat="splatv-js")
    out = splatv_records(buf.getvalue())
    key = viewer.importance(cols).astype(np.float32)
    expected = sorted(range(50), key=lambda i: -key[i])  # Python's sort is stable
    assert np.array_equal(out[:50, 0], packing.f32_bits(cols["x"][expected]))


def _is_snan(bits: np.ndarray) -> np.ndarray:
    return ((bits & 0x7F800000) == 0x7F800000) & (bits & 0x7FFFFF != 0) & (bits & 0x400000 == 0)


def splatv_records(data: bytes) -> np.ndarray:
    n_json = struct.unpack("<I", data[4:8])[0]
    return np.frombuffer(data[8 + n_json:], "<u4").reshape(-1, 16)


def write_bytes(scene, **kw) -> bytes:
    buf = io.BytesIO()
    splatv.write(scene, buf, **kw)
    return buf.getvalue()


def test_header_texture_size_and_padding():
    scene = Scene(columns=random_columns(1500))
    data = write_bytes(scene)
    magic, n_json = struct.unpack("<II", data[:8])
    import json
    header = json.loads(data[8:8 + n_json])
    assert magic == 0x674B
    assert header[0]["texwidth"] == 4096 and header[0]["texheight"] == 2
    assert header[0]["size"] == 4096 * 2 * 16 == len(data) - 8 - n_json
    recs = splatv_records(data)
    assert not recs[1500:].any() and recs[:1500].any(axis=1).all()
    assert len(header[0]["cameras"]) == 1  # never an empty list


def test_importance_sort_largest_first():
    cols = random_columns(3000, 5)
    recs = splatv_records(write_bytes(Scene(columns=cols)))[:3000]
    s = packing.half_to_float(recs[:, 5] & 0xFFFF).astype(np.float64) * packing.half_to_float(
        recs[:, 5] >> 16) * packing.half_to_float(recs[:, 6] & 0xFFFF) * (recs[:, 7] >> 24)
    assert np.all(np.diff(s[::50]) <= 1e-9 + 0.05 * s[:-50:50])  # quantized, so loosely monotone


@pytest.mark.parametrize("compat", [None, "splatv-js"])
def test_every_half_in_every_slot_survives_splatv_ply_splatv(tmp_path, compat):
    # 65,536 records: record i holds half pattern i in every half slot, byte i%256 in
    # every colour channel. Reading then writing must give every word back.
    h = np.arange(1 << 16, dtype=np.uint32)
    recs = np.zeros((1 << 16, 16), "<u4")
    recs[:, 0:3] = (h.astype(np.uint64) * 2654435761 % (1 << 32)).astype(np.uint32)[:, None]  # arbitrary float32 bits, NaNs included
    for w, (lo, hi) in splatv.HALF_WORDS.items():
        recs[:, w] = h | ((h if hi else 0) << 16)
    recs[:, 7] = (h % 256) * 0x01010101
    if compat:
        # splaTV's converter cannot write |x| >= 32768 or NaN other than as infinity.
        v = packing.HALF_TO_FLOAT[h]
        keep = (np.abs(v) < 32768) & ~np.isnan(v)
        recs = recs[keep]
        recs[:, 0:3] |= np.uint32(0x00400000) * _is_snan(recs[:, 0:3])  # it quiets sNaN positions
    src = tmp_path / "all.splatv"
    src.write_bytes(splatv_bytes(recs, cameras=[]))
    scene = splatconv.read(src)
    assert any("negative values have no logarithm" in n for n in scene.notes)
    splatconv.convert(src, tmp_path / "mid.ply", sort="none")
    splatconv.convert(tmp_path / "mid.ply", tmp_path / "back.splatv", sort="none", compat=compat)
    back = splatv_records((tmp_path / "back.splatv").read_bytes())[: len(recs)]
    # Every half must come back, except negative values and -0 in exp() slots, which
    # have no logarithm (reported above).
    for w in range(16):
        halves = [(0, 0xFFFFFFFF, None)] if w not in splatv.HALF_WORDS else [
            (0, 0xFFFF, splatv.HALF_WORDS[w][0]), (16, 0xFFFF, splatv.HALF_WORDS[w][1])]
        for shift, mask, name in halves:
            want = (recs[:, w] >> shift) & mask
            got = (back[:, w] >> shift) & mask
            keep = np.ones(len(recs), bool)
            if name in splatv.EXP_ATTRIBUTES:
                keep = (want & 0x8000 == 0) | np.isnan(packing.HALF_TO_FLOAT[want])
            assert np.array_equal(got[keep], want[keep]), (w, shift, name)


def test_inverse_tables_are_exhaustively_exact():
    # exp() slots: every non-negative half, both writers (where splaTV's can hold it).
    h = np.arange(0x8000, dtype=np.uint16)
    v = packing.HALF_TO_FLOAT[h]
    logs = splatv.LOG_OF_HALF[h]
    with np.errstate(over="ignore", invalid="ignore"):
        lin = np.exp(logs.astype(np.float64))
    near = packing.float_to_half(lin)
    nan = np.isnan(v)
    near[nan] = packing.float_to_half(logs[nan])
    assert np.array_equal(near, h)
    js = packing.float_to_half_splatvjs(lin.astype(np.float32))
    ok = v < 32768
    assert np.array_equal(js[ok], h[ok])
    # Colour and alpha bytes, both writers.
    c = np.arange(256)
    assert np.array_equal(reference.unorm8_nearest(splatv.COLOR_OF_BYTE.astype(np.float64) * 255)[0], c)
    assert np.array_equal(reference.unorm8_truncate(splatv.COLOR_OF_BYTE.astype(np.float64) * 255)[0], c)
    a = viewer.sigmoid(splatv.LOGIT_OF_BYTE) * 255.0
    assert np.array_equal(reference.unorm8_nearest(a)[0], c)
    assert np.array_equal(reference.unorm8_truncate(a)[0], c)
    assert np.isfinite(splatv.LOGIT_OF_BYTE).all()
    # The inverse is the natural one up to float32 rounding.
    assert np.allclose(splatv.COLOR_OF_BYTE, c / 255, rtol=1e-6, atol=0)


def test_default_writer_output_survives_roundtrip(tmp_path):
    cols = hostile_columns(3000, 11)
    scene = Scene(columns=cols, cameras=[{"id": 0, "img_name": "a", "width": 10, "height": 20,
                                          "position": [1, 2, 3], "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                                          "fy": 5.5, "fx": 6.5}])
    first = tmp_path / "first.splatv"
    splatconv.write(scene, first)
    splatconv.convert(first, tmp_path / "mid.ply")
    splatconv.convert(tmp_path / "mid.ply", tmp_path / "again.splatv", sort="none")
    assert (tmp_path / "again.splatv").read_bytes() == first.read_bytes()  # cameras included


def test_reader_pads_short_texture_and_drops_trailing_zero_records(tmp_path):
    cols = random_columns(1500, 2)
    recs, _ = pack(cols)
    data = splatv_bytes(recs, pad=False)
    p = tmp_path / "short.splatv"
    p.write_bytes(data[:-10])  # not even a whole record at the end
    scene = splatconv.read(p)
    assert scene.count == 1500
    assert scene.notes == ["record 1499 is cut after 54 of its 64 bytes: file truncated? its missing words read "
                           "as zeros"]
    assert scene.meta["declared_bytes"] == 4096 * 2 * 16
    p.write_bytes(data)  # whole records: not cut, and nothing to note (as splaTV's converter writes files)
    assert splatconv.read(p).notes == []
    assert np.array_equal(packing.f32_bits(scene.columns["x"][:1499]), recs[:1499, 0])


def test_reader_keeps_nan_positions_and_infinite_trbf(tmp_path):
    recs = np.zeros((3, 16), "<u4")
    recs[:, 0] = 0x7FC00001  # NaN with a payload
    recs[:, 15] = 0x3C00 | (0x7C00 << 16)  # trbf centre 1, trbf scale +inf
    recs[1, 5] = 0x0001  # subnormal scale
    recs[2, 5] = 0  # zero scales
    p = tmp_path / "odd.splatv"
    p.write_bytes(splatv_bytes(recs))
    scene = splatconv.read(p)
    assert scene.count == 3
    assert packing.f32_bits(scene.columns["x"]).tolist() == [0x7FC00001] * 3
    assert np.isinf(scene.columns["trbf_scale"]).all()
    assert scene.columns["scale_0"][2] == -np.inf
    assert np.exp(np.float64(scene.columns["scale_0"][1])) == pytest.approx(2.0**-24, rel=1e-3)


def test_other_chunks_are_skipped_by_size(tmp_path):
    recs, _ = pack(random_columns(10))
    h = 1
    import json
    chunks = [{"type": "audio", "size": 7},
              {"type": "splat", "size": 4096 * h * 16, "texwidth": 4096, "texheight": h, "cameras": []}]
    text = json.dumps(chunks).encode()
    body = np.zeros((1024, 16), "<u4")
    body[:10] = recs
    p = tmp_path / "multi.splatv"
    p.write_bytes(struct.pack("<II", 0x674B, len(text)) + text + b"1234567" + body.tobytes())
    scene = splatconv.read(p)
    assert scene.count == 10
    assert np.array_equal(packing.f32_bits(scene.columns["y"]), recs[:, 1])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.integers(0, 2**32 - 1), min_size=16, max_size=16), min_size=1, max_size=40),
       st.sampled_from([None, "splatv-js"]))
def test_random_records_roundtrip_through_ply(tmp_path_factory, rows, compat):
    recs = np.array(rows, dtype="<u4")
    recs[:, 6] &= 0xFFFF  # the unused halves are zero in any converter's output
    recs[:, 12] &= 0xFFFF
    recs[:, 0] |= 1  # no all-zero record (it would count as padding at the end)
    if compat:
        recs[:, 0:3] |= np.uint32(0x00400000) * _is_snan(recs[:, 0:3])  # it quiets sNaN positions
    for w, (lo, hi) in splatv.HALF_WORDS.items():
        for shift, name in ((0, lo), (16, hi)):
            h = (recs[:, w] >> shift) & 0xFFFF
            v = packing.HALF_TO_FLOAT[h]
            bad = np.zeros(len(h), bool)
            if name in splatv.EXP_ATTRIBUTES:
                bad |= (h & 0x8000 != 0) & ~np.isnan(v)  # no logarithm
            if compat and name is not None:
                bad |= np.isnan(v) | (np.abs(v) >= 32768)  # splaTV's converter cannot write these
            recs[bad, w] &= np.uint32(~(0xFFFF << shift) & 0xFFFFFFFF)
    d = tmp_path_factory.mktemp("rt")
    (d / "a.splatv").write_bytes(splatv_bytes(recs))
    splatconv.convert(d / "a.splatv", d / "b.ply")
    splatconv.convert(d / "b.ply", d / "c.splatv", sort="none", compat=compat)
    assert np.array_equal(splatv_records((d / "c.splatv").read_bytes())[: len(recs)], recs)


def test_compat_quiets_signalling_nan_positions_like_the_browser():
    # V8 reads positions with DataView.getFloat32 into a double, quieting sNaNs; the
    # accurate writer keeps the bits as they are.
    cols = one_splat()
    cols["x"] = np.array([0x7F800001], np.uint32).view(np.float32)
    cols["z"] = np.array([0xFFC00005], np.uint32).view(np.float32)  # already quiet
    assert pack(cols, compat=True)[0][0, 0] == 0x7FC00001
    assert pack(cols, compat=True)[0][0, 2] == 0xFFC00005
    assert pack(cols)[0][0, 0] == 0x7F800001


# --------------------------------------------------------------------------
# The fast writer (blocks packed by threads, integer half conversion, packed-key
# sort, camera percentiles by sorting) against a plain reference of the format.


def reference_texture(cols: dict, compat: bool, sort: bool) -> np.ndarray:
    """Records the straightforward way: per column, exact converters, stable argsort."""
    with np.errstate(all="ignore"):
        def halves(name):
            v = cols[name]
            if name in splatv.EXP_ATTRIBUTES:
                lin = np.exp(v.astype(np.float64)).astype(np.float32)
                if compat:
                    lin[np.isnan(v)] = v[np.isnan(v)]
                    return packing.float_to_half_exact(lin, splatvjs=True)[0]
                out = packing.float_to_half_exact(lin)[0]
                out[np.isnan(v)] = packing.float_to_half_exact(v[np.isnan(v)])[0]
                return out
            return packing.float_to_half_exact(v, splatvjs=compat)[0]

        n = len(cols["x"])
        recs = np.zeros((n, 16), np.uint32)
        for w, name in splatv.POSITION_WORDS.items():
            bits = packing.f32_bits(cols[name]).copy()
            if compat:
                bits[np.isnan(cols[name])] |= np.uint32(0x00400000)
            recs[:, w] = bits
        for w, (lo, hi) in splatv.HALF_WORDS.items():
            recs[:, w] = reference.pack_half2(halves(lo), halves(hi) if hi else np.zeros(n, np.uint16))
        unorm = reference.unorm8_truncate if compat else reference.unorm8_nearest
        rgba = [unorm(cols[f"f_dc_{i}"].astype(np.float64) * 255.0)[0] for i in range(3)]
        rgba.append(unorm(viewer.sigmoid(cols["opacity"]) * 255.0)[0])
        recs[:, 7] = reference.pack_rgba8(*rgba)
        if sort:
            key = viewer.importance(cols)
            recs = recs[np.argsort(-(key.astype(np.float32) if compat else key), kind="stable")]
    return recs


def fast_path_columns(n: int, seed: int) -> dict:
    """Hostile columns plus ties in importance, NaN keys and exact zeros."""
    cols = hostile_columns(n, seed)
    cols["scale_0"][::97] = -3.0
    cols["scale_1"][::97] = -2.0
    cols["scale_2"][::97] = -1.0
    cols["opacity"][::97] = 0.5
    cols["opacity"][5::211] = np.nan
    cols["motion_3"][::3] = 0.0
    # Keys that differ only in their last few bits (sigmoid(20 + k ulp) in double),
    # shuffled: the float64 key's bits that the row number displaces decide their order.
    rng = np.random.default_rng(seed)
    near = slice(300, 340)
    for name in ("scale_0", "scale_1", "scale_2"):
        cols[name][near] = -2.0
    ulps = np.nextafter(np.float32(20), np.float32(30)) - np.float32(20)
    cols["opacity"][near] = np.float32(20) + ulps * (rng.permutation(40) // 2).astype(np.float32)
    cols["x"][::401] = np.array([0x7F800001], np.uint32).view(np.float32)[0]
    return cols


@pytest.mark.parametrize("compat", [None, "splatv-js"])
@pytest.mark.parametrize("sort", ["importance", "none"])
@pytest.mark.parametrize("from_ply", [False, True])
def test_threaded_block_writer_matches_reference(tmp_path, monkeypatch, compat, sort, from_ply):
    # Small blocks so that a few thousand splats make many blocks on several threads;
    # from a PLY, the columns are fields of one memory-mapped row buffer (in a
    # shuffled order with extra properties), which the writer copies by runs.
    from .conftest import write_ply

    from splatconv.formats import splatv_engine as engine

    monkeypatch.setattr(engine, "BLOCK", 256)
    monkeypatch.setattr(engine, "KEY_BLOCK", 700)
    monkeypatch.setattr(engine, "HALF_ROWS", 100)
    monkeypatch.setattr(engine, "WORKERS", 3)
    cols = fast_path_columns(5000 + 37, 21)
    if from_ply:
        order = list(COLUMNS[10:]) + ["nx"] + list(COLUMNS[:10])
        cols["nx"] = np.zeros(len(cols["x"]), np.float32)
        scene = splatconv.read(write_ply(tmp_path / "s.ply", cols, order=order, extra_props=("extra",)))
        assert engine.RowSource(scene.columns).rows_whole
    else:
        scene = Scene(columns=cols)
        assert not engine.RowSource(scene.columns).rows_whole
    data = write_bytes(scene, compat=compat, sort=sort)
    want = reference_texture(cols, compat == "splatv-js", sort == "importance")
    assert np.array_equal(splatv_records(data)[: len(want)], want)
    records, report = splatv.encode(scene, compat=compat, sort=sort)
    assert np.array_equal(records[: len(want)], want) and not records[len(want):].any()
    # The same records a block at a time (a block's memory reused once given), with the same counts.
    blocks = []
    given = splatv.pieces(scene, lambda block: blocks.append(block.copy()), compat=compat, sort=sort)
    assert [len(b) for b in blocks] == [256] * (len(want) // 256) + [len(want) % 256]
    assert np.array_equal(np.concatenate(blocks), want)
    assert (given.half, given.notes, given.texheight) == (report.half, report.notes, report.texheight)
    # Counts as the reference converters give them, attribute by attribute, in slot order.
    assert list(report.half) == [name for pair in splatv.HALF_WORDS.values() for name in pair if name]
    for name, c in report.half.items():
        with np.errstate(all="ignore"):
            v = cols[name]
            if name in splatv.EXP_ATTRIBUTES:
                v = np.exp(v.astype(np.float64)).astype(np.float32)
        _, overflow, underflow, nonfinite = packing.float_to_half_exact(v, splatvjs=compat is not None)
        assert (c.overflow, c.underflow, c.nonfinite) == (overflow.sum(), underflow.sum(), nonfinite.sum()), name


def test_importance_order_is_the_stable_descending_argsort():
    rng = np.random.default_rng(4)
    for n in (0, 1, 2, 7, 1000, 5000):
        for dtype in (np.float64, np.float32):
            key = rng.choice([0.0, -0.0, 1.0, 2.5, np.inf, -np.inf, np.nan, -1.0], n).astype(dtype)
            key[: n // 2] = rng.normal(0, 1, n // 2)
            with np.errstate(invalid="ignore"):
                want = np.argsort(-key, kind="stable")
            assert np.array_equal(viewer.importance_order(key), want), (n, dtype)
    # float64 keys that differ only in the bits the row number displaces: the
    # order must still follow the full key.
    key = 1.0 + rng.integers(0, 64, 1 << 14) * np.finfo(np.float64).eps
    key[::5] = key[1::5]
    assert np.array_equal(viewer.importance_order(key), np.argsort(-key, kind="stable"))


def test_framing_box_is_numpys_percentile():
    from splatconv import cameras

    rng = np.random.default_rng(8)
    for n in (1, 2, 3, 50, 51, 1001):
        for scale in (1.0, 1e30):
            pts = (rng.normal(0, 1, (3, n)) * scale).astype(np.float32)
            pts[0, ::7] = np.nan
            pts[2, 3::11] = np.inf
            finite = np.isfinite(pts).all(axis=0)
            want = (np.percentile(pts[:, finite].T.astype(np.float64), [2, 98], axis=0) if finite.any()
                    else np.zeros((2, 3)))
            lo, hi = cameras.framing_box(*pts)
            assert np.array_equal(lo, want[0]) and np.array_equal(hi, want[1]), n
            assert cameras.framing_camera(*pts) == cameras.camera_for_box(lo, hi)


def test_framing_box_of_a_large_scene_looks_at_evenly_strided_points():
    from splatconv import cameras

    n = 3 * cameras.FRAMING_SAMPLES + 5  # step 4: 49,153 points taken
    pts = np.random.default_rng(9).normal(0, 1, (3, n)).astype(np.float32)
    pts[:, 1::4] = 1000.0  # never taken: must not move the box
    lo, hi = cameras.framing_box(*pts)
    want = np.percentile(pts[:, ::4].T.astype(np.float64), [2, 98], axis=0)
    assert np.array_equal(lo, want[0]) and np.array_equal(hi, want[1])
    assert hi.max() < 5


@pytest.mark.parametrize("sort", [None, "importance"])
def test_ply_writer_writes_row_tables_whole_with_the_same_bytes(tmp_path, sort):
    # A scene read from .splatv (or a lite PLY with zero normals) is one table in
    # the written row layout; the PLY writer writes it whole. Same bytes as from
    # separate columns; nonzero normals in a source PLY still come out as zeros.
    from splatconv.formats import ply

    from .conftest import lite_columns_with_normals, write_ply

    cols = fast_path_columns(3000, 5)
    src = tmp_path / "a.splatv"
    splatconv.write(Scene(columns=cols), src, sort="none")
    decoded = splatconv.read(src)
    assert ply._lite_rows_of(decoded) is not None
    copies = Scene(columns={k: np.array(v) for k, v in decoded.columns.items()}, cameras=decoded.cameras)
    assert ply._lite_rows_of(copies) is None
    whole, by_column = io.BytesIO(), io.BytesIO()
    ply.write(decoded, whole, sort=sort)
    ply.write(copies, by_column, sort=sort)
    assert whole.getvalue() == by_column.getvalue()

    full = lite_columns_with_normals(random_columns(500, 6))
    full["ny"] = np.full(500, 0.5, np.float32)
    scene = splatconv.read(write_ply(tmp_path / "n.ply", full))
    assert ply._lite_rows_of(scene) is None
    out = io.BytesIO()
    ply.write(scene, out, sort=sort)
    body = np.frombuffer(out.getvalue()[-500 * 128:], ply.LITE_DTYPE)
    assert not body["ny"].any() and np.array_equal(body["x"] if sort is None else np.sort(body["x"]),
                                                   full["x"] if sort is None else np.sort(full["x"]))


def test_a_logarithm_that_reads_back_as_itself_is_not_reported_lossy(tmp_path):
    """exp(log 65504) rounds past the half range, yet the record reads back the same: no note."""
    import io as _io

    from splatconv.model import COLUMNS, Scene

    n = 4
    cols = {c: np.zeros(n, np.float32) for c in COLUMNS}
    cols["rot_0"][:] = 1
    cols["scale_0"][:] = splatv.LOG_OF_HALF[0x7BFF]  # what a .splatv holding 65504 reads as
    cols["trbf_scale"][:] = splatv.LOG_OF_HALF[0x7BFF]
    cols["scale_1"][0] = np.float32(20.0)  # exp(20) is truly past the range
    report = splatv.write(Scene(columns=cols, cameras=[]), _io.BytesIO())
    lossy = [note for note in report.notes if "half-float range" in note]
    assert lossy == ["scale_1: 1 value past the half-float range saturated to +-65504"]
