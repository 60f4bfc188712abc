"""The player page in headless Chromium (SwiftShader), against `splatconv render`.

The page runs the same shader sources as the headless renderer; its frame at a
pinned time and view must match the renderer's of the same file, time, view and
size at >= 40 dB PSNR. Interaction tests drive it as a user would.
"""

from __future__ import annotations

import base64
import http.server
import json
import shutil
import threading
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import splatconv
from splatconv.model import Scene
from splatconv.render import camera as cam
from splatconv.render.diff import compare
from splatconv.render.frames import cameras_of, load, render_frames, resolve_view
from splatconv.web.page import SceneRef, build_page
from splatconv.publish import publish

from .conftest import random_columns
from .web_support import EVENT_DEADLINE_MS, capture, open_page, serving, view_hash, wait_settled

ROOT = Path(__file__).resolve().parent.parent
CAMERAS = json.loads((ROOT / "sample_data" / "cameras.json").read_text())
W, H = 640, 360
MIN_PSNR = 40.0
#: docs/player.png: the page as a user sees it (controls shown), paused at this time.
SCREENSHOT_TIME = 0.4


@pytest.fixture
def sample(sample_splatv):
    """The bundled sample as .splatv with its cameras: the session's (conftest.py), made once a run."""
    return sample_splatv


@pytest.fixture(scope="module")
def nonfinite(tmp_path_factory):
    """A scene where some splats hold NaN and infinite values, as trained scenes do."""
    cols = random_columns(3000, seed=7)
    rng = np.random.default_rng(3)
    for name, value in (("x", np.nan), ("z", np.inf), ("scale_0", np.inf), ("scale_1", -np.inf),
                        ("opacity", np.nan), ("motion_0", np.inf), ("motion_4", np.nan), ("rot_2", np.nan),
                        ("omega_1", np.inf), ("trbf_scale", np.inf), ("trbf_center", np.nan),
                        ("f_dc_0", np.nan), ("f_dc_2", np.inf)):
        cols[name][rng.choice(3000, 60, replace=False)] = value
    path = tmp_path_factory.mktemp("web") / "nonfinite.splatv"
    splatconv.write(Scene(columns=cols), path)
    return path


def rendered(path, time, view=None, size=(W, H)) -> np.ndarray:
    """`splatconv render PATH --time T [--view V] --size WxH`, as an array."""
    source = load(path)
    v = resolve_view(cameras_of(source), view=view, size=size)
    return list(render_frames(source.texture(), v, [time]))[0]


def assert_matches(page_frame, reference, what):
    diff = compare(reference, page_frame)
    print(f"{what}: {diff.psnr:.2f} dB PSNR, largest error {diff.max_abs_error}/255")
    assert diff.psnr >= MIN_PSNR, f"{what}: {diff.psnr:.2f} dB < {MIN_PSNR}"
    # Not a blank pair: the frame shows the scene.
    assert reference[..., :3].max() > 64


@pytest.mark.parametrize("camera, time", [(None, 0.5), (1, 0.35), (2, 0.0), (0, 1.0)])
def test_served_frame_matches_render(browser, sample, camera, time):
    view = None if camera is None else cam.view_matrix(CAMERAS[camera])
    with serving([sample]) as server:
        url = server.url + (view_hash(view, time) if view else f"#t={time}&ui=0")
        page = open_page(browser, url, W, H)
        status = page.evaluate("window.splatconvPlayer.status()")
        assert (status["width"], status["height"]) == (W, H)
        assert status["drawn"]["count"] == 5 * 1024  # every record, padding included, as render draws
        frame = capture(page)
        page.close()
    assert_matches(frame, rendered(sample, time, view), f"sample camera {camera} t={time}")


def test_nonfinite_scene_matches_render(browser, nonfinite):
    with serving([nonfinite]) as server:
        for time in (0.25, 0.6):
            page = open_page(browser, server.url + f"#t={time}&ui=0", W, H)
            frame = capture(page)
            page.close()
            assert_matches(frame, rendered(nonfinite, time), f"non-finite scene t={time}")


def test_self_contained_html_from_disk_matches_render(browser, sample, tmp_path):
    out = tmp_path / "dancers.html"
    report = publish([sample], out)
    assert report.written == [(str(out), out.stat().st_size)]
    view = cam.view_matrix(CAMERAS[1])
    page = open_page(browser, out.as_uri() + view_hash(view, 0.7), W, H)
    frame = capture(page)
    page.close()
    assert_matches(frame, rendered(sample, 0.7, view), "self-contained .html from file://")


def test_external_html_from_a_static_host(browser, sample, tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    report = publish([sample], site / "my scene.html", external=True)
    assert [Path(p).name for p, _ in report.written] == ["my scene.html", "my scene.splatv", "my scene.poster.jpg"]
    assert (site / "my scene.splatv").read_bytes() == sample.read_bytes()
    handler = partial(_QuietHandler, directory=str(site))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        url = f"http://127.0.0.1:{httpd.server_address[1]}/my%20scene.html#t=0.5&ui=0"
        frame = capture(open_page(browser, url, W, H))
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert_matches(frame, rendered(sample, 0.5), "--external page from a static host")


def test_an_external_page_whose_scene_is_missing_names_the_file_it_fetches(browser, tmp_path):
    # Converted from a PLY, the page fetches "page.splatv": that is what a message must name.
    cols = random_columns(50, 2)
    src = tmp_path / "source.ply"
    splatconv.write(Scene(columns=cols), src)
    site = tmp_path / "site"
    site.mkdir()
    publish([src], site / "page.html", external=True)
    (site / "page.splatv").unlink()
    handler = partial(_QuietHandler, directory=str(site))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        page = open_page(browser, f"http://127.0.0.1:{httpd.server_address[1]}/page.html", W, H)
        text = page.locator("#message").text_content()
        page.close()
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert text.startswith("Cannot show page.splatv: the server answered 404"), text


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@pytest.mark.parametrize("durations, times", [(None, (0.25, 0.75)), ("50,150", (0.125, 0.625))])
def test_segments_play_as_one_clip(browser, sample, nonfinite, durations, times):
    """Two segments: equal shares (or 1:3): each clip time shows one segment at its local 0.5."""
    with serving([sample, nonfinite], durations=durations) as server:
        for clip_time, path in zip(times, (sample, nonfinite)):
            page = open_page(browser, server.url + f"#t={clip_time}&ui=0", W, H)
            status = page.evaluate("window.splatconvPlayer.status()")
            assert status["drawn"]["segment"] == (0 if path is sample else 1)
            assert status["drawn"]["time"] == pytest.approx(0.5)
            # Every segment loads, the other one in the background: waited for, not sampled.
            page.wait_for_function("() => window.splatconvPlayer.status().segments.every(s => s.done)",
                                   timeout=EVENT_DEADLINE_MS)
            frame = capture(page)
            page.close()
            # Both are drawn with segment 0's camera (the clip's), as render --view does.
            view = cam.view_matrix(CAMERAS[0])
            assert_matches(frame, rendered(path, 0.5, view), f"segment at clip time {clip_time}")


def test_segment_boundary_has_the_next_segment_ready(browser, sample, nonfinite):
    """Playing across the boundary switches to a segment that is already sorted."""
    with serving([sample, nonfinite]) as server:
        page = open_page(browser, server.url + "#t=0.49&ui=0", W, H)
        page.evaluate("() => { document.getElementById('speed').value = '0.25';"
                      " document.getElementById('speed').dispatchEvent(new Event('change'));"
                      " document.getElementById('play').click(); }")
        page.wait_for_function("() => window.splatconvPlayer.status().drawn.segment === 1", timeout=EVENT_DEADLINE_MS)
        status = page.evaluate("window.splatconvPlayer.status()")
        assert status["drawn"]["clipTime"] >= 0.5 and status["drawn"]["time"] < 0.2
        # The first frame of segment 1 already drew all of it (its sort was done ahead).
        assert status["drawn"]["count"] == status["segments"][1]["total"]
        page.close()


class _StallingHandler(http.server.BaseHTTPRequestHandler):
    """Serves the page, then the scene's first ``head`` bytes, and the rest only once ``release`` is set."""

    page = scene = b""
    head = 0
    release = None

    def do_GET(self):  # noqa: N802
        data = self.page if self.path == "/" else self.scene if self.path == "/scene.splatv" else None
        if data is None:
            self.send_error(404)
            return
        self.send_response(200)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        if data is self.scene:
            self.wfile.write(data[: self.head])
            self.wfile.flush()
            self.release.wait()  # until the test has seen the partial frame (it always sets it, in finally)
            data = data[self.head:]
        self.wfile.write(data)

    def log_message(self, *args):
        pass


def test_draws_what_arrived_while_the_file_streams_in(browser, sample):
    """Records are drawn as they arrive, the most important first; the panel shows the load progress."""
    scene = sample.read_bytes()
    texture_at = 8 + int.from_bytes(scene[4:8], "little")
    handler = type("Handler", (_StallingHandler,), {
        "page": build_page([SceneRef(name="dancers.splatv", url="scene.splatv")]), "scene": scene,
        "head": texture_at + 2 * 1024 * 64, "release": threading.Event()})  # two of five texture rows
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        page = open_page(browser, f"http://127.0.0.1:{httpd.server_address[1]}/#t=0.5", W, H, settle=False)
        page.wait_for_function("() => window.splatconvPlayer.status().drawn?.count === 2048", timeout=EVENT_DEADLINE_MS)
        status = page.evaluate("window.splatconvPlayer.status()")
        assert not status["loaded"] and status["segments"][0]["received"] == 2 * 1024 * 64
        assert page.locator("#progress").is_visible()
        assert page.locator("#progress").evaluate("(e) => e.value") == pytest.approx(0.4)
        partial = capture(page)
        assert partial[..., :3].max() > 64  # the first records already show the scene
        handler.release.set()
        status = wait_settled(page)
        assert status["loaded"] and status["drawn"]["count"] == 5 * 1024
        assert page.locator("#progress").is_hidden()
        page.close()
    finally:
        handler.release.set()
        httpd.shutdown()
        httpd.server_close()


def test_drag_changes_view_and_hash_reproduces_frame_after_reload(browser, sample):
    with serving([sample]) as server:
        page = open_page(browser, server.url + "#t=0.3", W, H)
        before = page.evaluate("window.splatconvPlayer.status()")
        first = capture(page)
        page.mouse.move(320, 180)
        page.mouse.down()
        page.mouse.move(380, 200, steps=5)
        page.mouse.up()
        page.wait_for_function("() => location.hash.startsWith('#view=')")
        after = wait_settled(page)
        assert after["view"] != before["view"]
        moved = capture(page)
        assert compare(first, moved).psnr < 30  # the picture really changed
        # Right-drag pans, the wheel zooms: each moves the camera too.
        page.mouse.move(320, 180)
        page.mouse.down(button="right")
        page.mouse.move(300, 170, steps=3)
        page.mouse.up(button="right")
        panned = page.evaluate("window.splatconvPlayer.status().view")
        assert panned != after["view"]
        # One wheel event, handled before evaluate returns (page.mouse.wheel's arrive asynchronously, on a
        # loaded machine after the test has read the view: seen as a reload that did not match).
        page.evaluate("""() => document.querySelector('canvas').dispatchEvent(new WheelEvent('wheel',
            {deltaY: 200, clientX: 320, clientY: 180, bubbles: true, cancelable: true}))""")
        assert page.evaluate("window.splatconvPlayer.status().view") != panned
        later = wait_settled(page)
        assert later["view"] != after["view"]
        frame = capture(page)
        # The page writes its hash 150 ms after the last move: wait for the one of this view, not a sample.
        page.wait_for_function("""() => decodeURIComponent(location.hash).startsWith(
            '#view=' + JSON.stringify(window.splatconvPlayer.status().view))""")
        url = page.url
        assert "&t=0.3" in url  # paused time is part of the shareable hash
        page.close()
        again = open_page(browser, url, W, H)
        assert again.evaluate("window.splatconvPlayer.status()")["view"] == later["view"]
        assert np.array_equal(capture(again), frame)
        again.close()


def test_touch_orbits_and_pinch_zooms(browser, sample):
    """One finger orbits; two fingers spreading apart move the camera towards the scene."""
    with serving([sample]) as server:
        context = browser.new_context(viewport={"width": W, "height": H}, device_scale_factor=1, has_touch=True)
        context.set_default_timeout(EVENT_DEADLINE_MS)
        page = context.new_page()
        page.js_errors = []
        page.goto(server.url + "#t=0.5")
        start = wait_settled(page)["view"]
        cdp = context.new_cdp_session(page)

        def touch(kind, points):
            cdp.send("Input.dispatchTouchEvent", {
                "type": kind, "touchPoints": [{"x": x, "y": y, "id": i} for i, (x, y) in enumerate(points)]})

        touch("touchStart", [(300, 180)])
        for k in range(1, 6):
            touch("touchMove", [(300 + 10 * k, 180)])
        touch("touchEnd", [])
        orbited = page.evaluate("window.splatconvPlayer.status().view")
        assert orbited != start
        touch("touchStart", [(300, 180), (340, 180)])
        for k in range(1, 6):
            touch("touchMove", [(300 - 10 * k, 180), (340 + 10 * k, 180)])
        touch("touchEnd", [])
        pinched = wait_settled(page)["view"]
        # The camera moved forward along its axis: the scene is nearer (camera-space z shrinks).
        assert pinched[14] < orbited[14] - 1
        context.close()


def test_keys_move_the_camera_and_toggle_play(browser, sample):
    with serving([sample]) as server:
        page = open_page(browser, server.url + "#t=0.5", W, H)
        start = page.evaluate("window.splatconvPlayer.status()")
        page.keyboard.press("ArrowLeft")
        page.keyboard.press("w")
        assert page.evaluate("window.splatconvPlayer.status()")["view"] != start["view"]
        page.keyboard.press(" ")
        assert page.evaluate("window.splatconvPlayer.status()")["playing"] is True
        page.close()


def test_slider_sets_the_time_and_pauses(browser, sample):
    with serving([sample]) as server:
        page = open_page(browser, server.url, W, H, settle=False)
        page.wait_for_function("() => window.splatconvPlayer.status().loaded")
        assert page.evaluate("window.splatconvPlayer.status()")["playing"] is True
        page.locator("#time").fill("0.8")
        status = wait_settled(page)
        assert status["playing"] is False
        assert status["time"] == pytest.approx(0.8)
        assert status["drawn"]["time"] == pytest.approx(0.8)
        frame = capture(page)
        view = page.evaluate("window.splatconvPlayer.status()")["view"]
        page.close()
    assert_matches(frame, rendered(sample, 0.8, view), "after moving the slider to 0.8")


@pytest.mark.parametrize("mode", ["loop", "pingpong"])
def test_loop_and_ping_pong_at_the_end(browser, sample, mode):
    """Played past the end at 4x, the clip wraps to 0 (loop) or turns back (ping-pong)."""
    with serving([sample]) as server:
        page = open_page(browser, server.url + "#t=0.8", 480, 270)
        page.select_option("#mode", mode)
        page.select_option("#speed", "4")
        # Sampled once a frame from before the click until the event (the wrap, or the turn and a run
        # back), however long the machine takes to get there; the deadline only ends a page that never
        # does. (Sampling that starts after the click can start past the event on a slow machine.)
        page.evaluate("""([mode, deadline]) => { window.sampled = new Promise((resolve) => {
            const seen = [], start = performance.now();
            const done = () => {
              if (mode === 'loop') return seen.some((t, i) => i > 0 && t - seen[i - 1] < -0.5);
              const peak = Math.max(...seen);
              return peak > 0.75 && seen[seen.length - 1] < peak - 0.1;
            };
            const poll = () => {
              seen.push(window.splatconvPlayer.status().time);
              if (done() || performance.now() - start > deadline) resolve(seen); else requestAnimationFrame(poll);
            };
            requestAnimationFrame(poll);
        }); }""", [mode, EVENT_DEADLINE_MS])
        page.click("#play")
        times = page.evaluate("window.sampled")
        page.close()
    # A frame advances the clip by at most 0.25 s x 4 / 4 s = 0.25 (the page caps a frame's step).
    # Frames come as the machine allows (a loaded one samples coarsely): judge the shape, not the samples.
    steps = np.diff(times)
    assert steps[0] >= 0, times
    if mode == "loop":
        jump = int(np.argmin(steps))
        assert steps[jump] < -0.5 and times[jump] > 0.75, times  # from near the end back to the start
        assert (steps[:jump] >= 0).all(), times
    else:
        peak = int(np.argmax(times))
        assert np.abs(steps).max() <= 0.25 + 1e-9 and times[peak] > 0.75, times  # it runs on towards the end
        assert (steps[:peak] >= 0).all() and (steps[peak:] <= 0).all(), times  # then turns and runs back
        assert times[-1] < times[peak] - 0.1, times


def test_choosing_a_camera_moves_to_it(browser, sample):
    with serving([sample]) as server:
        page = open_page(browser, server.url + "#t=0.5", W, H)
        options = page.locator("#camera option").all_text_contents()
        assert len(options) == len(CAMERAS)
        page.select_option("#camera", "2")
        status = wait_settled(page)
        assert status["view"] == cam.view_matrix(CAMERAS[2])
        page.close()


def test_bare_splatv_hash_form(browser, sample):
    view = cam.view_matrix(CAMERAS[2])
    with serving([sample]) as server:
        page = open_page(browser, server.url + "#" + json.dumps(view).replace(" ", ""), W, H, settle=False)
        page.wait_for_function("() => window.splatconvPlayer.status().loaded")
        assert page.evaluate("window.splatconvPlayer.status()")["view"] == view
        page.close()


@pytest.mark.parametrize("fragment, time, playing", [
    ("#%E0%A4%A", None, True),  # a broken %-escape, as a hand-edited link may hold
    ("#view=%E0%A4%A&t=0.3", 0.3, False),
    ("#t=%ZZ&ui=0", None, True),
    ("#t=&view=[1,2", None, True),
    ("#view=[1e999,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]&t=nan", None, True),
    ("#t=%30.25", 0.25, False),
])
def test_a_broken_hash_is_ignored_not_fatal(browser, sample, fragment, time, playing):
    """What the hash cannot say is ignored; the scene still plays (never a blank page)."""
    with serving([sample]) as server:
        page = open_page(browser, server.url + fragment, W, H)  # fails on any script error
        status = page.evaluate("window.splatconvPlayer.status()")
        assert status["error"] is None and status["loaded"] and status["drawn"]["count"] == 5 * 1024
        assert status["playing"] is playing
        if time is not None:
            assert status["time"] == time
        # Not from the hash: camera 0, as without one.
        assert status["view"] == cam.view_matrix(CAMERAS[0])
        page.close()


@pytest.mark.parametrize("data, message", [
    (b"not a scene at all", "not a .splatv or .splatvq file"),
    (b"ply\nformat binary_little_endian 1.0\n", "this is a PLY file"),
    (b"\x4b\x67\x00\x00\x05\x00\x00\x00[{]}x", "header is damaged"),
    (b"\x4b\x67\x00\x00\x02\x00\x00\x00[]", "holds no splats"),
    (b"\x4b\x67\x00\x00", "ends inside its header"),
])
def test_bad_file_shows_a_message(browser, tmp_path, data, message):
    page_path = tmp_path / "bad.html"
    page_path.write_bytes(build_page([SceneRef(name="bad.splatv", data=data)]))
    page = open_page(browser, page_path.as_uri(), W, H)
    box = page.locator("#message")
    assert box.is_visible()
    text = box.text_content()
    assert text.startswith("Cannot show bad.splatv: ")
    assert message in text
    page.close()


@pytest.mark.parametrize("width, height", [(375, 667), (1280, 720)])
def test_the_message_uses_the_window_width(browser, tmp_path, width, height):
    """A long message wraps at 32em or the window's width less 32 px, not at half the window."""
    page_path = tmp_path / "bad.html"
    page_path.write_bytes(build_page([SceneRef(name="scene.splatv", data=b"ply\nformat ascii 1.0\n")]))
    page = open_page(browser, page_path.as_uri(), width, height)
    box = page.locator("#message").bounding_box()
    page.close()
    limit = min(32 * 15, width - 32)  # the message's font is 15 px
    assert limit - 1 <= box["width"] <= limit + 1
    assert box["x"] >= 0 and box["y"] >= 0 and box["x"] + box["width"] <= width


def test_missing_external_scene_shows_a_message(browser, tmp_path):
    page_path = tmp_path / "lonely.html"
    page_path.write_bytes(build_page([SceneRef(name="gone.splatv", url="gone.splatv")]))
    page = open_page(browser, page_path.as_uri(), W, H)
    assert "serve the folder with a web server" in page.locator("#message").text_content()
    page.close()


def test_drop_a_file(browser, sample, tmp_path):
    page_path = tmp_path / "empty.html"
    page_path.write_bytes(build_page([]))
    page = open_page(browser, page_path.as_uri() + "#t=0.5&ui=0", W, H, settle=False)
    assert "Drop a .splatv or .splatvq file" in page.locator("#message").text_content()
    data = base64.b64encode(sample.read_bytes()).decode("ascii")
    page.evaluate("""(text) => {
        const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
        const dt = new DataTransfer();
        dt.items.add(new File([bytes], 'dropped.splatv'));
        window.dispatchEvent(new DragEvent('drop', {dataTransfer: dt, cancelable: true}));
    }""", data)
    wait_settled(page)
    assert page.locator("#message").is_hidden()
    frame = capture(page)
    page.close()
    assert_matches(frame, rendered(sample, 0.5), "dropped file")


def test_ui_shows_count_frame_time_and_hides_with_ui_0(browser, sample):
    with serving([sample]) as server:
        page = open_page(browser, server.url + "#t=0.5", W, H)
        # The frame time shows once the page has timed a frame.
        page.wait_for_function("() => document.querySelector('#stats').textContent.includes('ms/frame')",
                               timeout=EVENT_DEADLINE_MS)
        stats = page.locator("#stats").text_content()
        assert "5,000 splats" in stats and "ms/frame" in stats
        assert page.locator("#bar").is_visible()
        page.close()
        page = open_page(browser, server.url + "#t=0.5&ui=0", W, H)
        assert page.locator("#bar").is_hidden() and page.locator("#panel").is_hidden()
        page.close()


@pytest.mark.parametrize("width, height", [(375, 667), (640, 360), (1280, 720)])
def test_controls_fit_the_window_without_overlapping(browser, sample, width, height):
    """On a phone-sized window too, every control is on screen and none covers another."""
    with serving([sample]) as server:
        page = open_page(browser, server.url + "#t=0.5", width, height)
        boxes = page.evaluate("""() => [...document.querySelectorAll(
            '#bar > button, #bar > input, #bar > span, #bar > select, #bar > label:not([hidden]), #panel')]
            .map((e) => { const r = e.getBoundingClientRect(); return [e.id || e.textContent.trim().slice(0, 8),
                                                                    r.left, r.top, r.right, r.bottom]; })""")
        page.close()
    assert len(boxes) == 9
    for name, left, top, right, bottom in boxes:
        assert 0 <= left < right <= width and 0 <= top < bottom <= height, (name, left, top, right, bottom)
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            apart = a[3] <= b[1] or b[3] <= a[1] or a[4] <= b[2] or b[4] <= a[2]
            assert apart, (a, b)


def test_readme_screenshot_is_the_page(browser, sample, tmp_path):
    """docs/player.png is this page as the test browser shows it (controls included).

    Set SPLATCONV_UPDATE_DOCS=1 to rewrite it.
    """
    import os

    with serving([sample]) as server:
        page = open_page(browser, server.url + f"#t={SCREENSHOT_TIME}", 960, 540)
        page.evaluate("document.getElementById('stats').style.visibility = 'hidden'")  # timings vary
        shot = tmp_path / "player.png"
        page.screenshot(path=str(shot))
        page.close()
    target = ROOT / "docs" / "player.png"
    if os.environ.get("SPLATCONV_UPDATE_DOCS"):
        shutil.copyfile(shot, target)
    fresh = np.asarray(Image.open(shot).convert("RGB"))
    stored = np.asarray(Image.open(target).convert("RGB"))
    assert compare(fresh, stored).psnr >= 30
    assert "docs/player.png" in (ROOT / "README.md").read_text()


def _panel_after_load(browser, path):
    """(stats text, note text, note colour, status of the segment) once ``path`` has loaded in the page."""
    with serving([path]) as server:
        page = open_page(browser, server.url + "#t=0.5", W, H)
        page.wait_for_function("() => window.splatconvPlayer.status().loaded", timeout=60000)
        page.wait_for_function("() => /splats( |$)/.test(document.getElementById('stats').textContent) && "
                               "!/so far/.test(document.getElementById('stats').textContent)", timeout=60000)
        stats = page.locator("#stats").text_content()
        note = page.locator("#note").text_content()
        segment = page.evaluate("() => window.splatconvPlayer.status().segments[0]")
        page.close()
    return stats, note, segment


def test_a_file_that_stops_after_its_last_record_shows_its_splats_and_no_warning(browser, tmp_path):
    # Real .splatv files carry no count and stop after their last record: the panel says the true
    # number of splats (as the reader counts them), not the texture's slots, and warns of nothing.
    from .real_scenes import real_scene, unpadded_splatv

    scene, _ = real_scene(1500, 6)
    path = tmp_path / "real.splatv"
    unpadded_splatv(scene, path)
    stats, note, segment = _panel_after_load(browser, path)
    assert splatconv.read(path).count == 1500
    assert "1,500 splats" in stats and "slots" not in stats
    assert note == "" and segment["note"] is None and segment["count"] == 1500


def test_a_file_cut_inside_a_record_is_noted(browser, tmp_path):
    from .real_scenes import real_scene, unpadded_splatv

    scene, _ = real_scene(1500, 6)
    path = tmp_path / "cut.splatv"
    unpadded_splatv(scene, path)
    path.write_bytes(path.read_bytes()[:-10])
    stats, note, segment = _panel_after_load(browser, path)
    assert "1,500 splats" in stats  # the cut record is still a splat, as the reader counts it
    assert splatconv.read(path).count == 1500
    assert note == ("cut.splatv: the file ends inside splat 1499 (after 54 of its 64 bytes): truncated? its missing "
                    "bytes read as zeros")
