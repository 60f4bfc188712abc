"""`splatconv view`'s server and `convert OUT.html`: no browser needed."""

from __future__ import annotations

import base64
import errno
import http.client
import inspect
import json
import os
import re
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

import splatconv
from splatconv.cli import main
from splatconv.formats.splatv_layout import COUNT_KEY
from splatconv.zstd import plain_input
from splatconv.web.page import SHADERS, SceneRef, build_page
from splatconv.server import _COPY_CHUNK, HOST, IDLE_TIMEOUT, LISTEN_BACKLOG, REQUEST_DEADLINE, ViewServer

from .web_support import serving
from .cli_checks import error_line

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data" / "dancers.ply"
#: Seconds a test waits for a reply or a process's exit: generous, so that a loaded machine is only slower.
DEADLINE_S = 120


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    path = tmp_path_factory.mktemp("srv") / "dancers.splatv"
    splatconv.convert(SAMPLE, path, cameras=str(ROOT / "sample_data" / "cameras.json"))
    return path


def get(port, path, host=None, method="GET"):
    """A request with ``path`` sent exactly as given (no normalising)."""
    conn = http.client.HTTPConnection(HOST, port, timeout=DEADLINE_S)
    conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
    conn.putheader("Host", host or f"{HOST}:{port}")
    conn.endheaders()
    response = conn.getresponse()
    body = response.read()
    conn.close()
    return response.status, body, response


def test_serves_the_page_and_the_scene_only_on_loopback(sample):
    with serving([sample]) as server:
        assert server.httpd.server_address[0] == "127.0.0.1"
        assert server.url == f"http://127.0.0.1:{server.port}/"
        status, page, response = get(server.port, "/")
        assert status == 200 and response.getheader("Content-Type") == "text/html; charset=utf-8"
        assert get(server.port, "/index.html")[1] == page
        status, scene, response = get(server.port, "/scene/0.splatv")
        assert status == 200 and scene == sample.read_bytes()
        assert int(response.getheader("Content-Length")) == len(scene)
        status, body, response = get(server.port, "/scene/0.splatv", method="HEAD")
        assert status == 200 and body == b"" and int(response.getheader("Content-Length")) == len(scene)
        assert get(server.port, "/", host=f"localhost:{server.port}")[0] == 200
    # Not listening on any other address of this machine.
    assert sorted(server.routes) == ["/", "/index.html", "/scene/0.splatv"]


def test_idle_connections_are_closed(sample):
    # Ten partial requests once held ten threads for as long as their clients liked.
    assert ViewServer([sample]).httpd.RequestHandlerClass.timeout == IDLE_TIMEOUT
    with serving([sample], idle_timeout=0.5) as server:
        held = []
        for _ in range(10):
            s = socket.create_connection((HOST, server.port), timeout=60)
            s.sendall(b"GET / HT")  # a request line that never ends
            held.append(s)
        assert get(server.port, "/")[0] == 200  # the server still answers meanwhile
        deadline = time.monotonic() + 60  # generous: the machine may be loaded
        for s in held:
            s.settimeout(max(0.1, deadline - time.monotonic()))
            try:
                assert s.recv(1024) == b""  # closed by the server, nothing sent
            except ConnectionResetError:
                pass
            s.close()
        assert time.monotonic() < deadline


def _closed_by_server(s, timeout):
    """Whether the server closed ``s`` (EOF or a reset) within ``timeout`` seconds of waiting."""
    s.settimeout(timeout)
    try:
        return s.recv(1024) == b""
    except ConnectionError:
        return True
    except TimeoutError:
        return False


def test_a_request_dripped_a_byte_at_a_time_is_cut_at_the_deadline(sample):
    # One byte every 0.3 s once kept its connection and thread for as long as the client liked:
    # the idle timeout starts again at each byte.
    assert inspect.signature(ViewServer).parameters["request_deadline"].default == REQUEST_DEADLINE <= 10
    with serving([sample], request_deadline=1.0) as server:
        s = socket.create_connection((HOST, server.port), timeout=60)
        s.sendall(b"GET / HTTP/1.0\r\nX-Drip: ")
        deadline = time.monotonic() + 60  # generous: the machine may be loaded
        closed = False
        while not closed and time.monotonic() < deadline:
            try:
                s.sendall(b"a")  # a header that never ends
            except ConnectionError:
                closed = True
                break
            closed = _closed_by_server(s, 0.3)
        s.close()
        assert closed  # nothing sent back: the connection closed
        assert get(server.port, "/")[0] == 200  # and the server still answers


def test_hundreds_of_connections_wait_in_the_listen_queue(sample):
    """300 clients connecting at once are all queued and answered (the standard library's queue holds 5)."""
    assert LISTEN_BACKLOG >= 1024
    try:  # Linux caps every listen queue at somaxconn (older kernels: 128)
        cap = int(Path("/proc/sys/net/core/somaxconn").read_text())
    except (OSError, ValueError):
        cap = 128
    count = min(300, cap)
    server = ViewServer([sample])  # listening, not accepting yet: every connection waits in the queue
    clients, thread = [], None
    try:
        with selectors.DefaultSelector() as sel:
            for _ in range(count):
                c = socket.socket()
                c.setblocking(False)
                assert c.connect_ex((HOST, server.port)) in (0, errno.EINPROGRESS)
                clients.append(c)
                sel.register(c, selectors.EVENT_WRITE)
            # Each handshake completes only where the queue has room: beyond it the SYN is dropped.
            deadline = time.monotonic() + 60
            connected = 0
            while connected < count and time.monotonic() < deadline:
                for key, _ in sel.select(timeout=1):
                    sel.unregister(key.fileobj)
                    assert key.fileobj.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR) == 0
                    connected += 1
            assert connected == count
            request = f"GET / HTTP/1.0\r\nHost: {HOST}:{server.port}\r\n\r\n".encode()
            replies = {}
            for c in clients:
                c.sendall(request)  # a few dozen bytes: the socket buffer takes them at once
                sel.register(c, selectors.EVENT_READ)
                replies[c] = bytearray()
            thread = threading.Thread(target=server.serve, kwargs={"open_browser": False}, daemon=True)
            thread.start()
            done = 0
            while done < count and time.monotonic() < deadline:
                for key, _ in sel.select(timeout=1):
                    chunk = key.fileobj.recv(1 << 16)
                    replies[key.fileobj] += chunk
                    if not chunk:  # HTTP/1.0: the reply ends where the server closes
                        sel.unregister(key.fileobj)
                        done += 1
        page = server.routes["/"].data
        assert sum(r.startswith(b"HTTP/1.0 200 ") and r.endswith(page) for r in replies.values()) == count
    finally:
        for c in clients:
            c.close()
        server.stop()
        if thread is not None:
            thread.join(10)
        server.close()


@pytest.mark.parametrize("path", [
    "/../../etc/passwd", "/scene/../../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/..%2f..%2fetc%2fpasswd",
    "/%252e%252e/etc/passwd", "//etc/passwd", "/scene/0.splatv/..", "/scene/1.splatv", "/scene/",
    "/scene", "/assets/player.js", "/player.js", "/sort_worker.js", "/favicon.ico", "/index.html/",
    "/./index.html", "/INDEX.HTML", "/%69ndex.html", "/scene\\0.splatv", "/etc/passwd",
    "http://127.0.0.1/etc/passwd", "*", "/" + str(ROOT / "README.md"),
])
def test_every_other_path_is_404(sample, path):
    with serving([sample]) as server:
        status, body, _ = get(server.port, path)
        assert status == 404, path
        assert b"root:" not in body and b"<canvas" not in body


def test_a_scene_file_gone_while_serving_is_a_404(sample, tmp_path, capfd):
    scene = tmp_path / "gone.splatv"
    scene.write_bytes(sample.read_bytes())
    with serving([scene]) as server:
        assert get(server.port, "/scene/0.splatv")[0] == 200
        scene.unlink()
        for method in ("GET", "HEAD"):
            status, _, response = get(server.port, "/scene/0.splatv", method=method)
            assert (status, response.reason) == (404, "The scene file can no longer be read")
        assert get(server.port, "/")[0] == 200
    assert capfd.readouterr().err == ""  # no traceback from the server's threads


def test_other_hosts_are_refused(sample):
    """A page elsewhere that rebinds its DNS name to 127.0.0.1 cannot read the scene."""
    with serving([sample]) as server:
        for host in ("evil.example", f"evil.example:{server.port}", "127.0.0.1", f"127.0.0.1:{server.port + 1}"):
            assert get(server.port, "/scene/0.splatv", host=host)[0] == 403, host


def test_a_second_view_picks_another_port(sample):
    with serving([sample]) as first, serving([sample]) as second:
        assert first.port != second.port
        assert get(second.port, "/")[0] == 200


def test_a_taken_port_is_a_usage_error(sample):
    with serving([sample]) as server:
        r = run("view", sample, "--port", server.port, "--no-open")
        assert r.exit_code == 2
        assert r.stderr.startswith(f"Error: --port {server.port}: cannot listen on 127.0.0.1:{server.port} (")


def test_bad_inputs_are_one_error_line(tmp_path):
    bad = tmp_path / "bad.splatv"
    bad.write_bytes(b"nope, not a scene")
    r = run("view", bad, "--no-open")
    assert error_line(r, 1).startswith(f"Error: {bad}: not a .splatv file")
    r = run("view", tmp_path / "scene.obj", "--no-open")
    assert r.exit_code == 2 and r.stderr.startswith(f"Error: {tmp_path / 'scene.obj'}: unknown file type")
    r = run("view", tmp_path / "missing.splatv", "--no-open")
    assert r.exit_code == 1 and "missing.splatv" in r.stderr and "Traceback" not in r.output
    assert run("view").exit_code == 2


def test_ply_and_zst_inputs_are_converted_in_memory(sample, tmp_path):
    zst = tmp_path / "dancers.splatv.zst"
    splatconv.convert(sample, zst)
    with serving([SAMPLE, zst]) as server:
        converted = get(server.port, "/scene/0.splatv")[1]
        with plain_input(zst) as plain:
            assert get(server.port, "/scene/1.splatv")[1] == Path(plain).read_bytes()
    # The PLY becomes exactly what convert writes (cameras aside: none in the PLY).
    direct = tmp_path / "direct.splatv"
    splatconv.convert(SAMPLE, direct)
    assert converted == direct.read_bytes()


def _start_view(path, port=0):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "splatconv", "view", str(path), "--no-open",
                             "--port", str(port)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                            text=True)
    line = proc.stdout.readline()
    match = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
    assert match, (line, proc.stderr.read() if proc.poll() is not None else "")
    return proc, int(match.group(1)), line


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_view_process_exits_cleanly_on_signal(sample, sig):
    proc, port, line = _start_view(sample)
    try:
        assert line == f"serving {sample} at http://127.0.0.1:{port}/ (Ctrl-C to stop)\n"
        assert get(port, "/")[0] == 200
        proc.send_signal(sig)
        assert proc.wait(timeout=DEADLINE_S) == 0
        assert proc.stderr.read() == ""
    finally:
        if proc.poll() is None:
            proc.kill()
    with pytest.raises(OSError):
        socket.create_connection((HOST, port), timeout=2)


def test_page_holds_the_render_shaders_and_makes_no_external_request(sample):
    with serving([sample]) as server:
        page = get(server.port, "/")[1].decode()
    for name in SHADERS:
        source = (ROOT / "splatconv" / "render" / "shaders" / name).read_text()
        assert f'data-asset="{name}">{source}</script>' in page
    # No http(s) URL, no protocol-relative URL, no src/href to load anything.
    assert not re.search(r"https?://|\bsrc=|\bhref=|@import|url\(", page)


def test_convert_to_html_embeds_the_splatv(tmp_path):
    out = tmp_path / "dancers.html"
    r = run("convert", SAMPLE, out, "--cameras", ROOT / "sample_data" / "cameras.json")
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith(f"wrote {out}: 5,000 splats")
    ref = tmp_path / "dancers.splatv"
    assert run("convert", SAMPLE, ref, "--cameras", ROOT / "sample_data" / "cameras.json").exit_code == 0
    page = out.read_text()
    embedded = re.search(r'data-asset="scene-0">\n(.*?)\n</script>', page, re.S).group(1)
    assert base64.b64decode(embedded.replace("\n", "")) == ref.read_bytes()
    # Titled and its scene named by the page's file name, as publish titles its pages.
    assert "<title>dancers</title>" in page and '"name":"dancers"' in page
    assert run("convert", SAMPLE, out).exit_code == 1  # exists; --force replaces
    assert run("convert", SAMPLE, out, "--force").exit_code == 0


def _embedded(page: Path) -> list:
    """The scenes a page embeds, in order: their bytes."""
    return [base64.b64decode(block.replace("\n", "")) for block in
            re.findall(r'data-asset="scene-\d+">\n(.*?)\n</script>', page.read_text(), re.S)]


def test_every_page_chooses_its_bytes_one_way(tmp_path):
    """One rule for a page's bytes, whichever command writes it: a file the page plays, given no option
    that changes it, is embedded as its own bytes (as publish and view give it); a scene made or changed
    in memory is packed as that file format would write it."""
    unsorted = tmp_path / "unsorted.splatv"  # records in PLY order: writing it again would sort them
    assert run("convert", SAMPLE, unsorted, "--sort", "none").exit_code == 0
    r = run("convert", unsorted, tmp_path / "one.html")
    assert r.exit_code == 0 and r.stdout.startswith(f"wrote {tmp_path / 'one.html'}: 5,000 splats")
    assert run("convert", unsorted, unsorted, tmp_path / "two.html").exit_code == 0
    assert _embedded(tmp_path / "one.html") == [unsorted.read_bytes()]
    assert _embedded(tmp_path / "two.html") == [unsorted.read_bytes()] * 2
    # Asked to change it, or made by another command: packed as the same write to a .splatv.
    for i, args in enumerate([["convert", unsorted, "{out}", "--sort", "importance"],
                              ["convert", unsorted, "{out}", "--scale", "2"], ["merge", unsorted, unsorted, "{out}"],
                              ["bake", unsorted, "{out}", "--time", "0.5"]]):
        outs = [tmp_path / f"{args[0]}{i}{suffix}" for suffix in (".html", ".splatv")]
        for out in outs:
            r = run(*[out if a == "{out}" else a for a in args])
            assert r.exit_code == 0, r.output
        assert _embedded(outs[0]) == [outs[1].read_bytes()], args


def test_convert_external_and_segments(sample, tmp_path):
    out = tmp_path / "clip.html"
    r = run("convert", sample, SAMPLE, out, "--external")
    assert r.exit_code == 0, r.output
    parts = [tmp_path / "clip.0.splatv", tmp_path / "clip.1.splatv", tmp_path / "clip.poster.jpg"]
    assert r.stdout.splitlines() == [f"wrote {p}: {p.stat().st_size:,} bytes" for p in [out] + parts]
    assert (tmp_path / "clip.0.splatv").read_bytes() == sample.read_bytes()
    page = out.read_text()
    assert '"url":"clip.0.splatv"' in page and '"url":"clip.1.splatv"' in page
    one = tmp_path / "one.html"
    assert run("convert", sample, one, "--external").exit_code == 0
    assert (tmp_path / "one.splatv").read_bytes() == sample.read_bytes()
    assert '"url":"one.splatv"' in one.read_text()


def test_convert_external_plays_a_splatv_input_where_it_is(sample, tmp_path):
    """`convert scene.splatv scene.html --external`: the input is the file the page fetches, left as it is."""
    scene = tmp_path / "scene.splatv"
    scene.write_bytes(sample.read_bytes())
    before = scene.stat()
    r = run("convert", scene, tmp_path / "scene.html", "--external", "--no-poster")
    assert r.exit_code == 0, r.output
    assert r.stdout == f"wrote {tmp_path / 'scene.html'}: {(tmp_path / 'scene.html').stat().st_size:,} bytes\n"
    assert r.stderr == f"note: {scene}: the page plays this input where it is\n"
    assert scene.stat().st_mtime_ns == before.st_mtime_ns and scene.read_bytes() == sample.read_bytes()
    assert '"url":"scene.splatv"' in (tmp_path / "scene.html").read_text()
    # Segments named as the page would name them; a PLY among them is still written.
    for i in (0, 2):
        (tmp_path / f"clip.{i}.splatv").write_bytes(sample.read_bytes())
    r = run("convert", tmp_path / "clip.0.splatv", SAMPLE, tmp_path / "clip.2.splatv", tmp_path / "clip.html",
            "--external")
    assert r.exit_code == 0, r.output
    assert [line.split(":")[0] for line in r.stdout.splitlines()] == [
        f"wrote {tmp_path / 'clip.html'}", f"wrote {tmp_path / 'clip.1.splatv'}",
        f"wrote {tmp_path / 'clip.poster.jpg'}"]
    # A damaged .splatv input is refused, not published.
    (tmp_path / "bad.splatv").write_bytes(b"nope, not a scene")
    r = run("convert", tmp_path / "bad.splatv", tmp_path / "bad.html", "--external")
    assert r.exit_code == 1 and r.stderr.startswith(f"Error: {tmp_path / 'bad.splatv'}: not a .splatv file")
    assert not (tmp_path / "bad.html").exists()


def test_convert_html_refusals(sample, tmp_path):
    # Several INPUTs to a scene file are a frame sequence (docs/long-clips.md), not a page.
    r = run("convert", sample, tmp_path / "one.splatv", "--external")
    assert error_line(r, 2).startswith(f"Error: {tmp_path / 'one.splatv'}: a player page must be written to an "
                                       ".html file")
    (tmp_path / "taken.splatv").write_bytes(b"keep")
    r = run("convert", sample, tmp_path / "taken.html", "--external")
    assert r.exit_code == 1 and "taken.splatv: already exists" in r.stderr
    assert not (tmp_path / "taken.html").exists() and (tmp_path / "taken.splatv").read_bytes() == b"keep"
    r = run("convert", tmp_path / "x.html", tmp_path / "x.splatv")
    # A page is written, never read: not a file type any command reads.
    assert error_line(r, 2).startswith(f"Error: {tmp_path / 'x.html'}: unknown file type (expected one of .compressed.ply, .glb,")
    r = run("convert", sample, sample, tmp_path / "c.html", "--sort", "none")
    assert r.exit_code == 2 and not (tmp_path / "c.html").exists()
    # Segments are not frames, and are read as they are: options that would change them were once ignored.
    for more in (["--frame-times", "0,1"], ["--same-splats", "yes"], ["--max-error", "0.1"], ["--color", "rgb"]):
        r = run("convert", sample, sample, tmp_path / "c.html", *more)
        assert error_line(r, 2).startswith("Error: --external and several inputs take no other options"), more
        assert not (tmp_path / "c.html").exists()


@pytest.mark.parametrize("durations, message", [
    ("1", "--durations gives 1 value for 2 segments"),
    ("1,x", "--durations: expected comma-separated numbers, got '1,x'"),
    ("1,0", "--durations: every duration must be a positive finite number"),
    ("1,nan", "--durations: every duration must be a positive finite number"),
    # Once accepted: the page's total was infinite, every segment's share 0.
    ("1e308,1e308", "--durations: they add up to more than the largest double (1.8e+308), the page's arithmetic: "
                    "give smaller numbers"),
    ("1e-300,1e300", "--durations: segment 0's share of the timeline (1e-300 of 1e+300) rounds to nothing"),
])
def test_bad_durations_are_usage_errors(sample, tmp_path, durations, message):
    for args in (("view", sample, sample, "--no-open"), ("convert", sample, sample, tmp_path / "c.html")):
        r = run(*args, "--durations", durations)
        assert error_line(r, 2).startswith(f"Error: {message}")
    assert not (tmp_path / "c.html").exists()


def test_durations_reach_the_page(sample, tmp_path):
    out = tmp_path / "c.html"
    assert run("convert", sample, sample, out, "--durations", "50,150").exit_code == 0
    config = re.search(r'data-asset="config">(.*?)</script>', out.read_text()).group(1)
    assert [s["duration"] for s in json.loads(config)["scenes"]] == [50.0, 150.0]


def test_specs_player_md_states_what_the_code_does(sample):
    spec = (ROOT / "specs" / "player.md").read_text()
    player = (ROOT / "splatconv" / "web" / "assets" / "player.js").read_text()
    seconds = re.search(r"SECONDS_PER_SEGMENT = (\d+);", player).group(1)
    assert f"The clip plays for {seconds} s per\nsegment at 1× speed" in spec
    with serving([sample, sample]) as server:
        routes = sorted(server.routes)
    assert routes == ["/", "/index.html", "/scene/0.splatv", "/scene/1.splatv"]
    assert "`GET` and `HEAD` for exactly `/`,\n`/index.html` and `/scene/I.splatv`" in spec
    flat = " ".join(spec.split())
    assert f"up to {LISTEN_BACKLOG} connections" in flat
    assert f"request line and headers whole within {REQUEST_DEADLINE:g} s" in flat
    assert f"within {IDLE_TIMEOUT:g} s is dropped" in flat and _COPY_CHUNK == 1 << 20
    for name in SHADERS:
        assert name in spec
    # The page reads the splat count under the writer's key.
    assert f"const count = seg.header.{COUNT_KEY};" in player


def test_without_a_display_view_does_not_start_a_text_browser(sample):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "BROWSER")}
    proc = subprocess.Popen([sys.executable, "-m", "splatconv", "view", str(sample)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=dict(env, PYTHONUNBUFFERED="1"), text=True)
    try:
        assert proc.stdout.readline().startswith(f"serving {sample} at http://127.0.0.1:")
        assert proc.stderr.readline() == "note: no display to open a browser on: open the address above in a browser\n"
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=DEADLINE_S) == 0
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_hostile_file_name_cannot_break_out_of_the_page():
    name = 'x</script><script>alert(1)</script><!--"&.splatv'
    page = build_page([SceneRef(name=name, url="scene/0.splatv")], title=name).decode()
    config = re.search(r'data-asset="config">(.*?)</script>', page).group(1)
    assert json.loads(config)["scenes"][0]["name"] == name
    assert "<script>alert(1)" not in page
    # Every script element closes where the builder closed it.
    assert page.count("<script") == page.count("</script>")


def test_readme_player_commands(sample, tmp_path, monkeypatch):
    """docs/player.md's first two commands (its first block), as written, in a folder holding dancers.splatv."""
    section = (ROOT / "docs" / "player.md").read_text()
    view_line, convert_line = re.search(r"```\n(.*?)```", section, re.S).group(1).strip().splitlines()
    (tmp_path / "dancers.splatv").write_bytes(sample.read_bytes())
    monkeypatch.chdir(tmp_path)
    words = convert_line.split()
    assert words[0] == "splatconv"
    r = run(*words[1:])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "dancers.html").stat().st_size > sample.stat().st_size
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.Popen([sys.executable, "-m", *view_line.split()], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, env=dict(env, PYTHONUNBUFFERED="1"), text=True)
    try:
        port = int(re.search(r"127\.0\.0\.1:(\d+)/", proc.stdout.readline()).group(1))
        assert get(port, "/scene/0.splatv")[1] == sample.read_bytes()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=DEADLINE_S) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
