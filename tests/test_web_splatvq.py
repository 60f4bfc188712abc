"""The player page plays ``.splatvq`` itself: decoded in its workers, into the texture the shader reads.

The page's decoded texture, read back from the GPU, must hold exactly the words
splatconv's decoder gives (``splatvq.decode``), zero padding after them, once put in
the order the page draws depth ties in (its importance order); its frame
must match ``splatconv render`` of the same file at >= 40 dB; bad files show a
plain message. Scenes come from ``tests/real_scenes.py`` (zero rotations, NaN and
huge positions, infinite temporal scales, flat splats: raw records and every escape).
"""

from __future__ import annotations

import base64
import http.server
import threading
from functools import partial
from pathlib import Path

import numpy as np
import pytest

import splatconv
from splatconv import packing
from splatconv.model import COLUMNS, Scene
from splatconv.errors import FormatError
from splatconv.formats import splatvq
from splatconv.formats import splatvq_codec as codec
from splatconv.web.page import SceneRef, build_page
from splatconv.publish import publish
from splatconv.render.diff import compare
from splatconv.server import ViewServer

from . import splatvq_files as damage
from .real_scenes import real_file, real_scene
from .conftest import splatv_bytes
from .scenes import CAMERA, overlapping_scene
from .test_web import MIN_PSNR, W, H, assert_matches, rendered
from .web_support import capture, open_page, serving, wait_settled


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A real-scene .splatvq in one block."""
    path = tmp_path_factory.mktemp("webvq") / "small.splatvq"
    splatconv.write(real_scene(3000, seed=5)[0], path)
    return path


@pytest.fixture(scope="module")
def large(tmp_path_factory):
    """A real-scene .splatvq of two blocks (more than 65,536 drawable splats), in the 'small' setting."""
    scene = real_scene(120_000, seed=9, zero_share=0.3)[0]
    path = tmp_path_factory.mktemp("webvq") / "large.splatvq"
    with open(path, "wb") as f:
        splatvq.write(scene, f, quality="small")
    with open(path, "rb") as f:
        blocks = splatvq.PREAMBLE.unpack(f.read(splatvq.PREAMBLE.size))[-1]
    assert blocks == 2
    return path


def texture_words(page) -> np.ndarray:
    """The page's texture as the GPU holds it: ``(rows * 1024, 16) uint32`` (a .splatvq's blocks' records in the
    order the blocks store them)."""
    text = page.evaluate("window.splatconvPlayer.textureWords(0)")
    return np.frombuffer(base64.b64decode(text), "<u4").reshape(-1, 16)


def record_order(page) -> np.ndarray | None:
    """Which texture record the page draws k-th among depth ties: ``(rows * 1024,) uint32``, None for the texture's
    own order."""
    text = page.evaluate("window.splatconvPlayer.recordOrder(0)")
    return None if text is None else np.frombuffer(base64.b64decode(text), "<u4")


def page_words(page) -> np.ndarray:
    """The page's records in the order it draws depth ties in: ``(rows * 1024, 16) uint32``."""
    words, order = texture_words(page), record_order(page)
    if order is None:
        return words
    assert np.array_equal(np.sort(order), np.arange(len(words)))  # each texture record once
    return words[order]


def assert_same_words(page, path):
    words = page_words(page)
    expected = splatvq.decode(path)
    assert len(words) == -(-len(expected) // 1024) * 1024
    assert np.array_equal(words[:len(expected)], expected), np.argwhere(words[:len(expected)] != expected)[:5]
    assert not words[len(expected):].any()


def assert_page_decodes_as_python(browser, tmp_path, path):
    """The page given ``path``'s bytes holds the texture words Python decodes from it."""
    page_path = tmp_path / (path.stem + ".html")
    page_path.write_bytes(build_page([SceneRef(name=path.name, data=path.read_bytes())]))
    page = open_page(browser, page_path.as_uri() + "#t=0.5&ui=0", W, H)
    assert page.evaluate("window.splatconvPlayer.status()")["error"] is None
    assert_same_words(page, path)
    page.close()


@pytest.mark.parametrize("fixture", ["small", "large"])
def test_served_page_decodes_the_words_python_decodes(browser, request, fixture):
    """`view X.splatvq`: the page fetches the .splatvq itself and decodes it word for word."""
    path = request.getfixturevalue(fixture)
    with serving([path]) as server:
        assert "/scene/0.splatvq" in server.routes
        page = open_page(browser, server.url + "#t=0.5&ui=0", W, H)
        status = page.evaluate("window.splatconvPlayer.status()")
        assert status["error"] is None and status["segments"][0]["format"] == "splatvq"
        assert_same_words(page, path)
        page.close()


def test_more_blocks_than_helpers_come_back_in_file_order(browser, large, tmp_path):
    """Five blocks, of two kinds in no regular turn, on the page's helper workers (two on a two-core
    machine), each helper given the next block when it is free: the page holds them in file order,
    word for word."""
    path = tmp_path / "five.splatvq"
    path.write_bytes(damage.rearranged(large.read_bytes(), [0, 1, 1, 0, 1]))
    with serving([path]) as server:
        page = open_page(browser, server.url + "#t=0.5&ui=0", W, H)
        assert page.evaluate("window.splatconvPlayer.status()")["error"] is None
        assert_same_words(page, path)
        page.close()


@pytest.mark.parametrize("time", [0.2, 0.5, 0.9])
def test_splatvq_frame_matches_render(browser, small, time):
    with serving([small]) as server:
        page = open_page(browser, server.url + f"#t={time}&ui=0", W, H)
        frame = capture(page)
        page.close()
    assert_matches(frame, rendered(small, time), f".splatvq page at t={time}")


def test_published_page_is_half_the_splatv_page_or_less(large, tmp_path):
    """`convert X.splatvq page.html` embeds the .splatvq: the page is under half the .splatv page of the same splats."""
    compact, plain = tmp_path / "compact.html", tmp_path / "plain.html"
    splatconv.convert(large, compact)
    splatconv.convert(large, tmp_path / "plain.splatv")
    splatconv.convert(tmp_path / "plain.splatv", plain)
    ratio = compact.stat().st_size / plain.stat().st_size
    print(f".splatvq page {compact.stat().st_size:,} bytes, .splatv page {plain.stat().st_size:,}: {ratio:.2f}")
    assert ratio <= 0.5


def test_published_page_plays_the_embedded_splatvq_from_disk(browser, small, tmp_path):
    page_path = tmp_path / "compact.html"
    splatconv.convert(small, page_path)
    page = open_page(browser, page_path.as_uri() + "#t=0.5&ui=0", W, H)
    assert page.evaluate("window.splatconvPlayer.status()")["segments"][0]["format"] == "splatvq"
    embedded = tmp_path / "embedded.splatvq"
    text = page_path.read_text(encoding="utf-8")
    start = text.index('data-asset="scene-0">') + len('data-asset="scene-0">')
    embedded.write_bytes(base64.b64decode("".join(text[start:text.index("</script>", start)].split())))
    assert_same_words(page, embedded)
    # Encoded again with its own setting, the source's records come back (in another order where importance ties).
    rows = lambda path: np.sort(splatvq.decode(path).view("V64").ravel())  # noqa: E731
    assert np.array_equal(rows(embedded), rows(small))
    frame = capture(page)
    page.close()
    assert_matches(frame, rendered(small, 0.5), "self-contained .splatvq page")


def test_external_page_fetches_the_splatvq(browser, large, tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    report = publish([large], site / "clip.html", external=True, poster=False)
    assert [Path(p).name for p, _ in report.written] == ["clip.html", "clip.splatvq"]
    assert (site / "clip.splatvq").read_bytes() == large.read_bytes()
    handler = partial(_QuietHandler, directory=str(site))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        page = open_page(browser, f"http://127.0.0.1:{httpd.server_address[1]}/clip.html#t=0.5&ui=0", W, H)
        assert_same_words(page, large)
        page.close()
    finally:
        httpd.shutdown()
        httpd.server_close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


def test_the_first_block_is_drawn_before_the_file_has_arrived(browser, large):
    """Streaming: the server sends the first block, then waits; the page draws it meanwhile."""
    data = large.read_bytes()
    table_at, _, _ = damage.layout(data)
    (coded0, raw0, _, stored0), _ = splatvq.BLOCK_ENTRY.iter_unpack(
        data[table_at:table_at + 2 * splatvq.BLOCK_ENTRY.size])
    first_end = table_at + 2 * splatvq.BLOCK_ENTRY.size + stored0
    release = threading.Event()

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802
            if self.path.split("#")[0] == "/":
                body = build_page([SceneRef(name="large.splatvq", url="scene.splatvq")])
                self.send_response(200)
                self.send_header("Content-Type", "text/html")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)
                return
            self.send_response(200)
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data[:first_end])
            self.wfile.flush()
            release.wait(120)
            self.wfile.write(data[first_end:])

        def log_message(self, *args):
            pass

    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        page = open_page(browser, f"http://127.0.0.1:{httpd.server_address[1]}/#t=0.5&ui=0", W, H, settle=False)
        page.wait_for_function(f"() => {{ const d = window.splatconvPlayer.status().drawn; "
                               f"return d && d.count === {coded0 + raw0}; }}", timeout=60000, polling=100)
        status = page.evaluate("window.splatconvPlayer.status()")
        assert not status["loaded"] and status["error"] is None
        release.set()
        status = wait_settled(page)
        assert status["loaded"] and status["drawn"]["count"] == status["segments"][0]["total"]
        assert_same_words(page, large)
        page.close()
    finally:
        release.set()
        httpd.shutdown()
        httpd.server_close()


# ---------------------------------------------------------------------------- bad files


def _corrupt_deflate(data: bytes) -> bytes:
    _, _, start = damage.layout(data)
    # A stored block type of 3 (reserved): no inflater accepts it.
    return data[:start] + bytes([0x07]) + data[start + 1:]


def _wrong_size_block(data: bytes) -> bytes:
    """A valid deflate stream, one byte shorter than its table declares."""
    payload = damage.payload(data)
    return damage.with_payload(data, payload[:-1], declared=len(payload))


def _bad_scale(tables, fields):
    fields["scale"][5, 1] = 1 << 20


BAD = [
    ("truncated in its last block", lambda d: d[:-100], "the file is truncated: it ends inside block 1 of 1"),
    ("truncated in its preamble", lambda d: d[:30], "the file is truncated: it ends inside its header"),
    ("truncated in its stored header", lambda d: d[:splatvq.PREAMBLE.size + 10],
     "the file is truncated: it ends inside its header"),
    ("truncated at its block table", lambda d: d[:damage.layout(d)[0]], "the file is truncated: it ends inside its header"),
    ("a block of no splats", lambda d: damage.with_entry(d, 0, coded=0, raw=0), "its block table is damaged"),
    ("a count that is not the blocks' sum", lambda d: damage.with_count(d, 5), "its header is damaged (its count 5 is"),
    ("a block that claims too much", lambda d: damage.with_entry(d, 0, stored=10), "more than deflate can give"),
    ("a payload size outside its bounds", lambda d: damage.with_entry(d, 0, payload=5),
     "its block table is damaged (block 1 claims 5 decoded bytes, but its"),
    ("bytes after the last block", lambda d: d + b"\0" * 7, "bytes after its last block"),
    ("corrupt deflate data", _corrupt_deflate, "block 1 of 1 is corrupt"),
    # Five blocks: decoded in the helper workers, the fourth refused there.
    ("a corrupt block among many", lambda d: damage.rearranged(d, [0] * 5, corrupt=3), "block 4 of 5 is corrupt"),
    ("a block shorter than declared", _wrong_size_block, "block 1 of 1 is damaged: it decodes to"),
    ("a block that inflates to far more than declared",
     lambda d: damage.with_payload(d, damage.payload(d) + bytes(8 << 20), declared=len(damage.payload(d))),
     "block 1 of 1 is damaged: it decodes to more than the"),
    ("another version", lambda d: d[:4] + b"\x09" + d[5:], "version 9; this page reads version 6"),
    ("a corrupt header", lambda d: damage.with_header(d, b"\xff" * 20, 300),
     "its header is corrupt: its compressed data cannot be decoded"),
    ("a header that inflates to more than declared", lambda d: damage.with_header(d, damage.deflate(b" " * 400), 300),
     "its header is damaged: it decodes to more than the 300 bytes"),
    ("a header past what deflate can give", lambda d: damage.with_header(d, b"\0" * 5, 6000),
     "its header is damaged (it claims 6000 bytes of header from 5 stored"),
    ("a header that is not JSON", lambda d: damage.with_header(d, damage.deflate(b"{count"), 6),
     "its header is damaged (not valid JSON)"),
    ("a setting out of range", lambda d: d[:7] + b"\x00" + d[8:], "setting rotation_bits is 0"),
    ("a position step past the code range", lambda d: damage.with_codes(d, damage.bad_position_step),
     "block 1 of 1 is damaged (a position code past 2^32 - 1)"),
    ("a scale code past the half range", lambda d: damage.with_codes(d, _bad_scale),
     "block 1 of 1 is damaged (a scale code decodes past the half range)"),
    ("a rotation code past its bits", lambda d: damage.with_codes(d, damage.bad_rotation),
     f"block 1 of 1 is damaged (a rotation code past {(1 << codec.SETTINGS['default'].rotation_bits) - 1})"),
    ("a width past 4", lambda d: damage.with_width(d, "x_step[0]", 5),
     "block 1 of 1 is damaged (a column of its values is 5 bytes wide; at most 4)"),
    ("a payload that ends before its last record", lambda d: damage.with_width(d, "rotation[0]", codec.MAX_WIDTH),
     "block 1 of 1 is damaged (its data ends before its last splat)"),
    ("a payload with bytes after its last record",
     lambda d: damage.with_payload(d, damage.payload(d) + bytes(64)),
     "block 1 of 1 is damaged (it has 64 bytes after its last splat)"),
]


@pytest.mark.parametrize("what, damage, message", BAD, ids=[b[0] for b in BAD])
def test_bad_splatvq_shows_a_message(browser, small, tmp_path, what, damage, message):
    data = damage(small.read_bytes())
    # splatconv refuses every one of these too.
    bad = tmp_path / "bad.splatvq"
    bad.write_bytes(data)
    with pytest.raises(FormatError):
        splatvq.read_records(bad)
    page_path = tmp_path / "bad.html"
    page_path.write_bytes(build_page([SceneRef(name="bad.splatvq", data=data)]))
    page = open_page(browser, page_path.as_uri(), W, H)
    box = page.locator("#message")
    assert box.is_visible()
    text = box.text_content()
    page.close()
    assert text.startswith("Cannot show bad.splatvq: "), text
    assert message in text, text


#: The precision step of the file the rare paths are written into: fine enough that a temporal scale's
#: codes can pass 255 (at the default step, its lattice holds fewer codes than that).
EVERY_PATH_PRECISION = 2


def _every_path(tables, fields):
    """Valid codes (the default setting's) that take the codings' rare paths: escapes in every saturating
    column, up to 4 bytes wide (codes past 2**32 in motion and omega), plain columns 4 bytes
    wide, every window exponent and rotation index (the boost levels as written). Each splat keeps its step exponent and its position codes stay in range:
    only a scale's largest axis grows, and only the last x step of a chunk."""
    rng = np.random.default_rng(3)
    n = len(fields["x_step"])
    some = rng.random(n) < 0.05
    chunk = np.arange(n) // codec.CHUNK
    for name in ("motion", "omega"):
        fields[name][some] = rng.integers(0, 2 ** 32, (int(some.sum()), fields[name].shape[1]))
        fields[name][np.flatnonzero(some)[:2]] = codec.VALUE_MAX + codec.SATURATED - np.arange(2)[:, None]
    fields["trbf_center"][some, 0] = rng.integers(0, 2 ** 32, int(some.sum()))
    fields["yz"][some, 1] = rng.integers(0, 2 ** 32, int(some.sum()))
    fields["window_index"][some, 0] = (fields["window_index"][some, 0] & 0xC0) | rng.integers(0, 64, int(some.sum()))
    last = np.unique(np.r_[np.arange(codec.CHUNK - 1, n, codec.CHUNK), n - 1])
    fields["x_step"][last, 0] += rng.integers(0, 2 ** 30, len(last))
    # Chunk bases of 0, the codes raised to match (every scale decodes as before): with a coarse
    # scale step a chunk's codes span fewer than 255 lattice points from its base.
    for key, name in (("scale_base", "scale"), ("trbf_scale_base", "trbf_scale")):
        lattice = fields[name] >= codec.SCALE_FIRST
        fields[name] += np.where(lattice, tables[key][chunk].astype(np.int64), 0)
        tables[key] = np.zeros_like(tables[key])
    setting = codec.refined(codec.SETTINGS[codec.DEFAULT_SETTING], EVERY_PATH_PRECISION)
    # The highest code of each axis that stays in the half range, from its chunk's base.
    top = packing.HALF_INF_BITS // setting.scale_step - tables["scale_base"][chunk].astype(np.int64) + codec.SCALE_FIRST
    widest = np.argmax(fields["scale"], axis=1)
    pick = (fields["scale"].min(axis=1) >= codec.SCALE_FIRST) & (top[np.arange(n), widest] >= codec.SATURATED)
    fields["scale"][pick, widest[pick]] = np.maximum(fields["scale"][pick, widest[pick]], top[pick, widest[pick]])
    top = (packing.HALF_INF_BITS // setting.trbf_scale_step - tables["trbf_scale_base"][chunk, 0].astype(np.int64)
           + codec.SCALE_FIRST)
    fields["trbf_scale"][some, 0] = top[some]


def test_every_coding_path_decodes_to_the_words_python_decodes(browser, tmp_path):
    finer = tmp_path / "finer.splatvq"
    splatconv.write(real_scene(3000, seed=5)[0], finer, precision=EVERY_PATH_PRECISION)
    data = damage.with_codes(finer.read_bytes(), _every_path)
    path = tmp_path / "every.splatvq"
    path.write_bytes(data)
    _, fields, _ = codec.unpack_payload(damage.payload(data), *damage.layout(data)[1][0][:2], "x", ())
    saturating = [name for name, _, coding in codec.SPLAT_FIELDS if coding == codec.SATURATING]
    assert all((fields[name] > codec.SATURATED).any() for name in saturating)
    assert fields["motion"].max() > codec.VALUE_MAX and fields["yz"].max() > 1 << 24
    assert_page_decodes_as_python(browser, tmp_path, path)


@pytest.mark.parametrize("rotation_bits, boost_step", [(10, 4), (6, 0)])
def test_boost_steps_at_their_limits_decode_to_the_words_python_decodes(browser, tmp_path, monkeypatch,
                                                                       rotation_bits, boost_step):
    """A boost step of 4 (a level-3 splat's rotation at the 16-bit cap) and of 0 (every level alike: levels
    the encoder never writes there, set by hand)."""
    monkeypatch.setitem(codec.SETTINGS, "default", codec.replace(codec.SETTINGS["default"],
                                                                 rotation_bits=rotation_bits, boost_step=boost_step))
    path = tmp_path / "boosted.splatvq"
    scene = real_scene(3000, seed=6)[0]
    weights = 2.0 ** np.random.default_rng(6).uniform(-4, 18, scene.count)  # levels 0 to 3
    splatconv.write(scene, path, weights=weights)
    if not boost_step:
        rng = np.random.default_rng(7)

        def levels_by_hand(tables, fields):
            fields["window_index"][:, 0] |= (rng.integers(0, 4, len(fields["window_index"])) << 6).astype(np.uint8)

        path.write_bytes(damage.with_codes(path.read_bytes(), levels_by_hand))
    _, fields, _ = codec.unpack_payload(damage.payload(path.read_bytes()),
                                        *damage.layout(path.read_bytes())[1][0][:2], "x", ())
    levels = np.bincount(fields["window_index"][:, 0] >> 6, minlength=4)
    assert (levels > 0).all(), levels  # every level taken
    if boost_step:
        assert fields["rotation"].max() >= 1 << 15  # a level-3 splat's 16 bits in use
    assert_page_decodes_as_python(browser, tmp_path, path)


def test_raw_records_of_every_kind_of_key_come_in_the_order_python_gives(browser, small, tmp_path):
    """Negative, -0, NaN and equal importance keys (a raw record may hold any scale half): the same order."""
    path = tmp_path / "odd.splatvq"
    path.write_bytes(damage.with_raw_only(small.read_bytes(), damage.odd_key_records()))
    assert np.array_equal(splatvq.decode(path), damage.odd_key_records()[list(damage.ODD_KEYS_ORDER)])
    assert_page_decodes_as_python(browser, tmp_path, path)


def test_drop_a_splatvq_file(browser, small, tmp_path):
    page_path = tmp_path / "empty.html"
    page_path.write_bytes(build_page([]))
    page = open_page(browser, page_path.as_uri() + "#t=0.5&ui=0", W, H, settle=False)
    assert "Drop a .splatv or .splatvq file" in page.locator("#message").text_content()
    data = base64.b64encode(small.read_bytes()).decode("ascii")
    page.evaluate("""(text) => {
        const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
        const dt = new DataTransfer();
        dt.items.add(new File([bytes], 'dropped.splatvq'));
        window.dispatchEvent(new DragEvent('drop', {dataTransfer: dt, cancelable: true}));
    }""", data)
    wait_settled(page)
    assert page.locator("#message").is_hidden()
    assert_same_words(page, small)
    page.close()


def test_view_server_serves_the_splatvq_as_it_is(small):
    server = ViewServer([small])
    try:
        resource = server.routes["/scene/0.splatvq"]
        assert resource.path == str(small.resolve()) and resource.data is None
    finally:
        server.close()


@pytest.mark.parametrize("external", [False, True])
def test_a_damaged_splatvq_is_refused_not_published(small, tmp_path, external):
    """`view` and `--external` pass a .splatvq on as it is, after decoding it whole as every command reads it."""
    bad = tmp_path / "bad.splatvq"
    bad.write_bytes(damage.with_entry(small.read_bytes(), 0, coded=0, raw=0))
    with pytest.raises(FormatError, match="holds 0 splats"):
        publish([bad], tmp_path / "page.html", external=external)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.splatvq"]
    with pytest.raises(FormatError, match="holds 0 splats"):
        ViewServer([bad])


# ---------------------------------------------------------------------------- record order

#: Times the pictures of a scene are compared at.
ORDER_TIMES = (0.2, 0.5, 0.8)


def _frames(browser, path, times=ORDER_TIMES) -> list:
    """The page's frames of ``path`` at each of ``times`` (one page load, the time set by its hash)."""
    frames = []
    with serving([path]) as server:
        page = open_page(browser, server.url + f"#t={times[0]}&ui=0", W, H)
        for t in times:
            page.evaluate("(t) => { location.hash = `#t=${t}&ui=0`; }", t)
            page.wait_for_function("(t) => { const s = window.splatconvPlayer.status(); "
                                   "return s.time === t && (s.settled || s.error); }", arg=t)
            frames.append(capture(page))
        if path.suffix == ".splatvq":
            assert_same_words(page, path)
        page.close()
    return frames


@pytest.fixture(scope="module", params=["overlapping", "coffeeshort2"])
def ordered(request, tmp_path_factory):
    """(X.splatvq, a .splatv of its decoded scene in the .splatv writer's importance order)."""
    folder = tmp_path_factory.mktemp("order")
    if request.param == "overlapping":
        source = overlapping_scene()
    else:
        path = real_file("coffeeshort2.splatv")
        source = splatconv.read(path)
    vq = folder / f"{request.param}.splatvq"
    splatconv.write(source, vq)
    plain = folder / f"{request.param}.splatv"
    splatconv.convert(vq, plain)
    return vq, plain


def test_the_page_draws_a_splatvq_as_it_draws_the_splatv_of_its_decoded_scene(browser, ordered):
    """Few large overlapping splats: the depth sort leaves most of them tied, drawn in record order, so a
    .splatvq's records must come in the order the .splatv writer gives them (importance), not in the
    order its blocks store them."""
    vq, plain = ordered
    psnrs = []
    for t, a, b in zip(ORDER_TIMES, _frames(browser, vq), _frames(browser, plain)):
        diff = compare(b, a)
        print(f"{vq.name} against {plain.name} at t={t}: {diff.psnr:.2f} dB, largest error {diff.max_abs_error}")
        psnrs.append(diff.psnr)
    assert min(psnrs) >= MIN_PSNR, psnrs


def _tied_scene(n: int = 24) -> Scene:
    """``n`` large, partly transparent splats of other colours on the plane z = 0, facing :data:`CAMERA`: one
    depth key, so the viewer blends them all in record order. Their importance (scale) grows with x, and a
    block stores them by x: its payload order is the reverse of their importance order. Four more splats,
    tiny, lie at the ends of the depth range, so that the plane's are none of the ends a .splatvq keeps
    verbatim: two far behind (the farthest is dropped by the depth sort, and the viewer draws its first
    record in its place, last) and two near the camera."""
    c = {name: np.zeros(n + 4, np.float32) for name in COLUMNS}
    c["x"][:n] = np.linspace(-3.0, 3.0, n)
    c["y"][:n] = np.linspace(-1.5, 1.5, n)[::-1]
    c["z"][n:] = 40.0, 41.0, -5.0, -5.5
    for i in range(3):
        c[f"scale_{i}"] = np.log(np.r_[np.linspace(0.8, 1.6, n), [0.01] * 4]).astype(np.float32)
        c[f"f_dc_{i}"] = (0.5 + 0.45 * np.sin(np.arange(n + 4) * 2.4 + 2.1 * i)).astype(np.float32)
    c["opacity"][:] = 0.3
    c["rot_0"][:] = 1.0
    c["trbf_scale"][:] = np.log(1e3)
    c["trbf_center"][:] = 0.5
    return Scene(c, cameras=[dict(CAMERA)])


def _frame_of(browser, tmp_path, name: str, data: bytes) -> tuple:
    """(the page's frame of a scene file's bytes, the page)."""
    page_path = tmp_path / f"{name}.html"
    page_path.write_bytes(build_page([SceneRef(name=name, data=data)]))
    page = open_page(browser, page_path.as_uri() + "#t=0.5&ui=0", W, H)
    assert page.evaluate("window.splatconvPlayer.status()")["error"] is None
    return capture(page), page


def test_depth_ties_are_drawn_in_importance_order_not_in_the_order_blocks_store(browser, tmp_path):
    """The page keeps a block's records where the block stores them and draws depth ties in importance order:
    its frame is the very frame of a .splatv holding the decoded records in decode_block's order, and not that
    of a .splatv holding them in the texture's order."""
    vq = tmp_path / "tied.splatvq"
    splatconv.write(_tied_scene(), vq)
    decoded = splatvq.decode(vq)
    n = len(decoded)
    frame, page = _frame_of(browser, tmp_path, "tied.splatvq", vq.read_bytes())
    stored, order = texture_words(page)[:n], record_order(page)[:n]
    page.close()
    assert not np.array_equal(order, np.arange(n))  # the block stores them in another order
    assert np.array_equal(stored[order], decoded)
    same, page = _frame_of(browser, tmp_path, "decoded.splatv", splatv_bytes(decoded, [dict(CAMERA)]))
    page.close()
    other, page = _frame_of(browser, tmp_path, "stored.splatv", splatv_bytes(stored, [dict(CAMERA)]))
    page.close()
    assert compare(same, other).max_abs_error > 30  # record order shows in this scene
    # The same records blended in the same order by the same shader: the same pixels.
    assert np.array_equal(frame, same), compare(same, frame)
