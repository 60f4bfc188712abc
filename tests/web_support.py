"""Headless Chromium for the player tests: Debian's ``chromium`` driven by playwright.

In CI (``CI`` set) a missing browser or playwright is a failure; elsewhere the
tests skip with a line saying how to install them.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import threading
from contextlib import contextmanager

import numpy as np
import pytest

from splatconv.server import ViewServer

#: WebGL2 on SwiftShader (ANGLE's Vulkan CPU driver), nothing fetched from the network.
CHROMIUM_ARGS = (
    "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run", "--disable-default-apps", "--disable-extensions",
)
INSTALL_HINT = ("browser tests need Chromium and playwright: `apt-get install chromium` "
                "and `pip install -e '.[test]'` (or set SPLATCONV_CHROMIUM to a Chromium binary)")
#: How long a test waits for an event in the page (a frame drawn, a wrap, a zoom): generous, so that a
#: loaded machine is only slower, never failed; a test never waits for a fixed stretch of time instead.
EVENT_DEADLINE_MS = 120_000
SETTLED = """() => {
  const p = window.splatconvPlayer;
  if (!p) return false;
  const s = p.status();
  return !!(s.error || s.settled);
}"""


def chromium_path() -> str | None:
    path = os.environ.get("SPLATCONV_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    return path if path and os.path.exists(path) else None


def require_browser():
    """(playwright sync API module, chromium path), or skip / fail as the environment says."""
    try:
        from playwright import sync_api
    except ImportError:
        sync_api = None
    path = chromium_path()
    if sync_api is None or path is None:
        if os.environ.get("CI"):
            pytest.fail("CI: " + INSTALL_HINT)
        pytest.skip(INSTALL_HINT)
    return sync_api, path


@contextmanager
def launched():
    """A headless Chromium (tests share one: the `browser` fixture in conftest.py)."""
    sync_api, path = require_browser()
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=path, args=list(CHROMIUM_ARGS), headless=True)
        try:
            yield browser
        finally:
            browser.close()


def open_page(browser, url: str, width: int = 640, height: int = 360, settle: bool = True):
    """A new page at ``url`` (viewport ``width`` x ``height``, device pixel ratio 1)."""
    page = browser.new_page(viewport={"width": width, "height": height}, device_scale_factor=1)
    page.set_default_timeout(EVENT_DEADLINE_MS)  # loading, clicks and waits alike
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.js_errors = errors
    page.goto(url)
    if settle:
        wait_settled(page)
    return page


def wait_settled(page, timeout_ms: int = EVENT_DEADLINE_MS) -> dict:
    """Wait until the page drew its whole scene sorted for its current view (or failed)."""
    try:
        page.wait_for_function(SETTLED, timeout=timeout_ms)
    except Exception as e:  # playwright's TimeoutError: say where the page stood
        state = page.evaluate("window.splatconvPlayer ? window.splatconvPlayer.status() : null")
        pytest.fail(f"the page did not settle in {timeout_ms / 1000:.0f} s ({type(e).__name__}): {state}; "
                    f"page errors: {page.js_errors}")
    status = page.evaluate("window.splatconvPlayer.status()")
    assert not page.js_errors, page.js_errors
    return status


def capture(page) -> np.ndarray:
    """The page's framebuffer, drawn now: ``(H, W, 4) uint8``, top row first."""
    shot = page.evaluate("window.splatconvPlayer.capture()")
    data = np.frombuffer(base64.b64decode(shot["rgba"]), np.uint8)
    return data.reshape(shot["height"], shot["width"], 4)


def view_hash(matrix, t=None, ui=False) -> str:
    text = "#view=" + json.dumps(list(matrix), separators=(",", ":"))
    if t is not None:
        text += f"&t={t}"
    return text + ("" if ui else "&ui=0")


@contextmanager
def serving(paths, **options):
    """A :class:`splatconv.server.ViewServer` for ``paths``, running in a thread."""
    server = ViewServer(paths, **options)
    thread = threading.Thread(target=server.serve, kwargs={"open_browser": False}, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.stop()
        thread.join(10)
