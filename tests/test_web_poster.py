"""The player page's poster (its first frame, drawn headlessly) and its fit option, in headless Chromium.

The scene is a wall that fills one camera's whole view, with a red marker just
inside each corner: what a page shows of the camera's view is read off the markers.
"""

from __future__ import annotations

import http.server
import io
import re
import threading
from functools import partial

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

import splatconv
from splatconv.cli import main
from splatconv.model import COLUMNS, Scene
from splatconv.publish import publish
from splatconv.render.diff import compare
from splatconv.render.frames import load, render_frames, resolve_view

from .cli_checks import error_line
from .conftest import splatv_bytes
from .test_web import assert_matches
from .web_support import capture, open_page

#: The camera: 2:1, looking along +z from 5 units before the wall.
CAMERA = {"id": 0, "img_name": "wall", "width": 320, "height": 160, "position": [0.0, 0.0, -5.0],
          "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "fx": 200.0, "fy": 200.0}
#: A square window: another aspect ratio, narrower than the camera.
WINDOW = (240, 240)
#: The markers' centres, just inside the view's corners (the view spans x in [-4, 4], y in [-2, 2]).
CORNERS = [(sx * 3.7, sy * 1.7) for sx in (-1, 1) for sy in (-1, 1)]
#: Make WebGL 2 unavailable in a page, as a browser without it is: the page never draws.
NO_WEBGL = """(() => {
  const get = HTMLCanvasElement.prototype.getContext;
  HTMLCanvasElement.prototype.getContext = function (type, ...rest) {
    return type === "webgl2" ? null : get.call(this, type, ...rest);
  };
})();"""


def _wall_scene() -> Scene:
    # The wall, 5.5 to 5.6 units away, covers the view (x in [-4.4, 4.4], y in [-2.2, 2.2] there); its
    # depths differ (the viewer's depth sort cannot order splats all at one depth).
    xs, ys = np.meshgrid(np.linspace(-4.6, 4.6, 47), np.linspace(-2.3, 2.3, 24))
    x = np.concatenate([xs.ravel(), [c[0] for c in CORNERS]])
    y = np.concatenate([ys.ravel(), [c[1] for c in CORNERS]])
    n, markers = len(x), len(CORNERS)
    cols = {name: np.zeros(n, np.float32) for name in COLUMNS}
    cols["x"], cols["y"] = x.astype(np.float32), y.astype(np.float32)
    cols["z"][:-markers] = np.linspace(0.5, 0.6, n - markers)  # the markers at 5 units, in front
    cols["opacity"][:] = 6.0
    cols["trbf_center"][:] = 0.5
    cols["trbf_scale"][:] = np.log(20.0)  # visible over the whole clip
    cols["rot_0"][:] = 1.0
    for i in range(3):
        cols[f"scale_{i}"][:] = np.log(0.14)
        cols[f"scale_{i}"][-markers:] = np.log(0.1)
    cols["f_dc_0"][:], cols["f_dc_1"][:], cols["f_dc_2"][:] = 0.25, 0.3, 0.7
    cols["f_dc_0"][-markers:], cols["f_dc_1"][-markers:], cols["f_dc_2"][-markers:] = 1.0, 0.0, 0.0
    return Scene(columns=cols, cameras=[CAMERA])


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    path = tmp_path_factory.mktemp("poster") / "wall.splatv"
    splatconv.write(_wall_scene(), path)
    return path


@pytest.fixture(scope="module")
def pages(wall, tmp_path_factory):
    """The wall published three ways: one file, one file that fits, and a folder (--external)."""
    folder = tmp_path_factory.mktemp("pages")
    publish([wall], folder / "wall.html")
    publish([wall], folder / "fit.html", fit=True)
    (folder / "site").mkdir()
    publish([wall], folder / "site" / "index.html", external=True)
    return folder


def _markers(frame: np.ndarray) -> int:
    """How many of the four window quadrants show a red marker."""
    rgb = frame[..., :3].astype(int)
    red = (rgb[..., 0] > 150) & (rgb[..., 1] < 90) & (rgb[..., 2] < 120)
    h, w = red.shape
    return sum(bool(red[r, c].any()) for r in (slice(0, h // 2), slice(h // 2, h)) for c in (slice(0, w // 2),
                                                                                        slice(w // 2, w)))


def _first_frame(browser, url, fit: bool) -> np.ndarray:
    page = open_page(browser, url + "#t=0&ui=0" + ("&fit=1" if fit else ""), *WINDOW)
    status = page.evaluate("window.splatconvPlayer.status()")
    gone = page.evaluate("document.getElementById('poster') === null")
    frame = capture(page)
    page.close()
    assert status["fit"] is fit and not status["poster"] and gone  # the first frame took the poster's place
    return frame


def _poster_shown(browser, url) -> np.ndarray:
    """What a browser without WebGL 2 shows of the page (controls and message hidden): the poster alone."""
    page = browser.new_page(viewport={"width": WINDOW[0], "height": WINDOW[1]}, device_scale_factor=1)
    page.add_init_script(NO_WEBGL)
    page.goto(url)
    page.wait_for_function("() => !document.getElementById('message').hidden")
    assert page.evaluate("window.splatconvPlayer.status().error").startswith("This browser cannot show the scene")
    page.wait_for_function("() => { const p = document.getElementById('poster'); return p && p.complete "
                           "&& p.naturalWidth > 0; }")
    page.evaluate("document.body.classList.add('noui'); document.getElementById('message').hidden = true")
    shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
    page.close()
    return shot


@pytest.mark.parametrize("name, fit", [("wall.html", False), ("fit.html", True)])
def test_the_poster_shows_the_first_frame_until_webgl_draws_it(browser, pages, name, fit):
    """Without WebGL the page shows its poster where the first frame goes (cropped to the camera's focal
    lengths, or fitted); with WebGL the first frame replaces it."""
    url = (pages / name).as_uri()
    shown = _poster_shown(browser, url)
    frame = _first_frame(browser, url, fit)
    # The poster holds the camera's view only: compare where it lies (the page draws the wall beyond it too).
    scale = min(WINDOW[0] / CAMERA["width"], WINDOW[1] / CAMERA["height"]) if fit else 1.0
    w, h = round(CAMERA["width"] * scale), round(CAMERA["height"] * scale)
    left, top = max(0, (WINDOW[0] - w) // 2), max(0, (WINDOW[1] - h) // 2)
    box = np.s_[top + 2:top + h - 2, left + 2:left + w - 2]  # the blurred border pixel aside
    diff = compare(frame[box][..., :3], shown[box])
    print(f"{name}: poster vs first frame {diff.psnr:.2f} dB")
    assert diff.psnr >= 25  # a JPEG at quality 80 of the same frame, laid out in the same place
    assert _markers(shown) == _markers(frame) == (4 if fit else 0)


def test_fit_shows_the_cameras_whole_view_as_render_fit_draws_it(browser, wall, pages):
    """In a square window, fitting shows all four corners (what render --fit draws at that size, from the
    same file); keeping the camera's focal lengths crops them off the 2:1 view."""
    fitted = _first_frame(browser, (pages / "wall.html").as_uri(), fit=True)
    kept = _first_frame(browser, (pages / "wall.html").as_uri(), fit=False)
    source = load(wall)
    view = resolve_view(source.cameras, size=WINDOW, fit=True)
    reference = list(render_frames(source.texture(), view, [0.0]))[0]
    assert_matches(fitted, reference, "page --fit vs render --fit")
    assert _markers(fitted) == 4 and _markers(kept) == 0
    # The view's left and right edges reach the window's; bands above and below (2:1 in a square).
    middle, top = fitted[WINDOW[1] // 2], fitted[4]
    assert middle[:3, 3].min() > 0 and middle[-3:, 3].min() > 0 and top[:, 3].max() == 0


def _meta(text: str, key: str) -> str | None:
    found = re.search(rf'<meta (?:property|name)="{re.escape(key)}" content="([^"]*)">', text)
    return found.group(1) if found else None


def test_a_published_folder_names_its_poster_file_for_sharers(pages):
    site = pages / "site"
    text = (site / "index.html").read_text()
    image = _meta(text, "og:image")
    assert image == _meta(text, "twitter:image") == "index.poster.jpg"
    with Image.open(site / image) as poster:
        assert poster.format == "JPEG" and poster.size == (320, 160)
        assert [int(_meta(text, f"og:image:{side}")) for side in ("width", "height")] == list(poster.size)
    assert f'<img id="poster" alt="" src="{image}"' in text
    # One file: the poster is embedded; sharers get the title (no data: URI for og:image).
    single = (pages / "wall.html").read_text()
    assert '<img id="poster" alt="" src="data:image/jpeg;base64,' in single
    assert _meta(single, "og:image") is None and _meta(single, "og:title") == "wall"


def test_an_external_pages_poster_loads_from_a_static_host(browser, pages):
    """The page's Content-Security-Policy lets it load its poster file from its own origin."""
    handler = partial(_QuietHandler, directory=str(pages / "site"))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        shown = _poster_shown(browser, f"http://127.0.0.1:{httpd.server_address[1]}/index.html")
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert shown.max() > 64 and _markers(shown) == 0  # the wall, cropped as the first frame will be


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


def test_no_poster_and_a_scene_without_a_camera(tmp_path, wall):
    publish([wall], tmp_path / "bare.html", external=True, poster=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bare.html", "bare.splatv"]
    text = (tmp_path / "bare.html").read_text()
    assert '<img id="poster"' not in text and _meta(text, "og:image") is None
    # A .splatv without cameras (splatconv's writer always stores one): the first view depends on the window.
    bare = tmp_path / "nocamera.splatv"
    bare.write_bytes(splatv_bytes(load(wall).stored, cameras=None))
    report = publish([bare], tmp_path / "nocamera.html")
    assert report.notes == ["no poster: the scene has no camera, so the page's first view depends on the window"]
    assert '<img id="poster"' not in (tmp_path / "nocamera.html").read_text()


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_every_commands_page_takes_fit_and_no_poster(tmp_path, wall):
    """convert, bake and merge write .html outputs alike (jobs/_steps.write_output): a poster unless
    --no-poster, the fit option in the page's configuration with --fit; a scene file takes neither."""
    runs = {"convert.html": ("convert", wall), "bake.html": ("bake", wall, "--time", "0.5"),
            "merge.html": ("merge", wall, wall)}
    for name, (command, *args) in runs.items():
        r = _run(command, *args, tmp_path / name, "--fit")
        assert r.exit_code == 0, r.output
        text = (tmp_path / name).read_text()
        assert '<img id="poster"' in text and '"fit":true' in text and '<body class="fit">' in text, name
        r = _run(command, *args, tmp_path / f"bare-{name}", "--no-poster")
        assert r.exit_code == 0, r.output
        text = (tmp_path / f"bare-{name}").read_text()
        assert '<img id="poster"' not in text and '"fit":true' not in text and "<body>" in text, name
    r = _run("convert", wall, tmp_path / "copy.splatv", "--fit")
    assert error_line(r, 2).startswith(f"Error: {tmp_path / 'copy.splatv'}: --fit and --no-poster apply to .html")
    assert not (tmp_path / "copy.splatv").exists()
