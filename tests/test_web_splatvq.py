"""The player page plays ``.splatvq`` itself: decoded in its workers, into the texture the shader reads.

The page's decoded texture, read back from the GPU, must hold exactly the words
splatconv's decoder gives (``splatvq.decode``), zero padding after them; its frame
must match ``splatconv render`` of the same file at >= 40 dB; bad files show a
plain message. Scenes come from ``tests/real_scenes.py`` (zero rotations, NaN and
huge positions, infinite temporal scales, flat splats: raw records and every escape).
"""

from __future__ import annotations

import base64
import http.server
import threading
import zlib
from functools import partial
from pathlib import Path

import numpy as np
import pytest

import splatconv
from splatconv.errors import FormatError
from splatconv.formats import splatvq
from splatconv.formats import splatvq_codec as codec
from splatconv.web.page import SceneRef, build_page
from splatconv.publish import publish
from splatconv.server import ViewServer

from .real_scenes import real_scene
from .test_web import W, H, assert_matches, rendered
from .web_support import capture, launched, open_page, serving, wait_settled


@pytest.fixture(scope="module")
def browser():
    with launched() as b:
        yield b


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


def page_words(page) -> np.ndarray:
    """The page's texture as the GPU holds it: ``(rows * 1024, 16) uint32``."""
    text = page.evaluate("window.splatconvPlayer.textureWords(0)")
    return np.frombuffer(base64.b64decode(text), "<u4").reshape(-1, 16)


def assert_same_words(page, path):
    words = page_words(page)
    expected = splatvq.decode(path)
    assert len(words) == -(-len(expected) // 1024) * 1024
    assert np.array_equal(words[:len(expected)], expected), np.argwhere(words[:len(expected)] != expected)[:5]
    assert not words[len(expected):].any()


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
    report = publish([large], site / "clip.html", external=True)
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
    with open(large, "rb") as f:
        head = splatvq.PREAMBLE.unpack(f.read(splatvq.PREAMBLE.size))
    json_length = head[-2]
    table_at = splatvq.PREAMBLE.size + json_length
    (coded0, raw0, stored0), _ = splatvq.BLOCK_ENTRY.iter_unpack(data[table_at:table_at + 2 * splatvq.BLOCK_ENTRY.size])
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


def _parts(data: bytes):
    json_length, blocks = splatvq.PREAMBLE.unpack_from(data)[-2:]
    table_at = splatvq.PREAMBLE.size + json_length
    return table_at, blocks


def _with_entry(data: bytes, i: int, coded=None, raw=None, stored=None) -> bytes:
    table_at, _ = _parts(data)
    at = table_at + i * splatvq.BLOCK_ENTRY.size
    c, r, s = splatvq.BLOCK_ENTRY.unpack_from(data, at)
    entry = splatvq.BLOCK_ENTRY.pack(c if coded is None else coded, r if raw is None else raw,
                                     s if stored is None else stored)
    return data[:at] + entry + data[at + splatvq.BLOCK_ENTRY.size:]


def _corrupt_deflate(data: bytes) -> bytes:
    table_at, blocks = _parts(data)
    start = table_at + blocks * splatvq.BLOCK_ENTRY.size
    # A stored block type of 3 (reserved): no inflater accepts it.
    return data[:start] + bytes([0x07]) + data[start + 1:]


def _wrong_size_block(data: bytes) -> bytes:
    """A valid deflate stream, one byte shorter than its table declares."""
    table_at, blocks = _parts(data)
    start = table_at + blocks * splatvq.BLOCK_ENTRY.size
    coded, raw, stored = splatvq.BLOCK_ENTRY.unpack_from(data, table_at)
    payload = codec.inflate(data[start:start + stored], codec.payload_bytes(coded, raw), "x", ())
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    again = comp.compress(payload[:-1]) + comp.flush()
    data = _with_entry(data, 0, stored=len(again))
    return data[:start] + again + data[start + stored:]


def _bad_position_step(data: bytes) -> bytes:
    """The first two splats' x steps at their largest: the second's code passes 2**32 - 1."""
    table_at, blocks = _parts(data)
    start = table_at + blocks * splatvq.BLOCK_ENTRY.size
    coded, raw, stored = splatvq.BLOCK_ENTRY.unpack_from(data, table_at)
    payload = bytearray(codec.inflate(data[start:start + stored], codec.payload_bytes(coded, raw), "x", ()))
    at = -(-coded // codec.CHUNK) * codec.CHUNK_BYTES
    for plane in range(4):
        payload[at + plane * coded:at + plane * coded + 2] = b"\xff\xff"
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    again = comp.compress(bytes(payload)) + comp.flush()
    data = _with_entry(data, 0, stored=len(again))
    return data[:start] + again + data[start + stored:]


BAD = [
    ("truncated in its last block", lambda d: d[:-100], "the file is truncated: it ends inside block 1 of 1"),
    ("truncated in its header", lambda d: d[:30], "the file is truncated: it ends inside its header"),
    ("a block of no splats", lambda d: _with_entry(d, 0, coded=0, raw=0), "its block table is damaged"),
    ("a count that is not the blocks' sum", lambda d: _with_entry(d, 0, coded=1), "its header is damaged"),
    ("a block that claims too much", lambda d: _with_entry(d, 0, stored=10), "more than deflate can give"),
    ("bytes after the last block", lambda d: d + b"\0" * 7, "bytes after its last block"),
    ("corrupt deflate data", _corrupt_deflate, "block 1 of 1 is corrupt"),
    ("a block shorter than declared", _wrong_size_block, "block 1 of 1 is damaged: it decodes to"),
    ("another version", lambda d: d[:4] + b"\x09" + d[5:], "version 9; this page reads version 2"),
    ("a setting out of range", lambda d: d[:7] + b"\x00" + d[8:], "setting rotation_bits is 0"),
    ("a position step past the code range", _bad_position_step,
     "block 1 of 1 is damaged (a position code past 2^32 - 1)"),
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
    """`view` and `--external` pass a .splatvq on as it is, after checking its header and block table."""
    bad = tmp_path / "bad.splatvq"
    bad.write_bytes(_with_entry(small.read_bytes(), 0, coded=0, raw=0))
    with pytest.raises(FormatError, match="holds 0 splats"):
        publish([bad], tmp_path / "page.html", external=external)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.splatvq"]
    with pytest.raises(FormatError, match="holds 0 splats"):
        ViewServer([bad])
