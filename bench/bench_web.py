"""The player page on a 1M-splat scene in headless Chromium: worker sort and first frame.

Writes a generated scene of N splats (default 1,000,000; the scene of
``bench_render.py``) as ``.splatv``, serves it with ``splatconv view``'s server and
opens the page in headless Chromium (WebGL2 on SwiftShader, the CPU), then prints:

* the depth sort of all N splats in the page's web worker, for several views
  (target: <= 150 ms);
* the time from the first megabyte of the scene arriving to the first frame with
  splats on screen (target: <= 2 s), from fresh page loads, with the network
  unthrottled (a local server) and throttled to ``--mbps``;
* the time until the whole scene is loaded and drawn sorted, and the frame time then.

Run::

    python bench/bench_web.py [--splats N] [--loads K] [--mbps 100] [--size WxH]

Needs Debian's ``chromium`` (or SPLATCONV_CHROMIUM) and the ``playwright`` package.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import statistics
import sys
import threading
import time

from _harness import work_folder
from bench_render import make_scene

import splatconv
from splatconv.render import camera as cam
from splatconv.server import ViewServer

ARGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox",
        "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run")


def views(k: int) -> list:
    out = []
    for i in range(k):
        a = 0.7 * i
        out.append(cam.view_matrix({"rotation": [[math.cos(a), 0, -math.sin(a)], [0, 1, 0],
                                                 [math.sin(a), 0, math.cos(a)]],
                                    "position": [6 * math.sin(a), 0, -6 * math.cos(a)]}))
    return out


def load_once(browser, url, size, mbps):
    """One fresh page load: (first frame after first MB, full sorted frame after first MB, ms/frame)."""
    page = browser.new_page(viewport={"width": size[0], "height": size[1]}, device_scale_factor=1)
    if mbps:
        cdp = page.context.new_cdp_session(page)
        cdp.send("Network.enable")
        cdp.send("Network.emulateNetworkConditions", {
            "offline": False, "latency": 0, "downloadThroughput": mbps * 1e6 / 8, "uploadThroughput": -1})
    page.goto(url)
    page.wait_for_function("() => { const s = window.splatconvPlayer.status(); return s.error || s.settled; }",
                           timeout=600_000, polling=100)
    s = page.evaluate("window.splatconvPlayer.status()")
    if s["error"]:
        raise SystemExit(f"page error: {s['error']}")
    settled_at = page.evaluate("performance.now()")
    page.wait_for_timeout(1500)  # a few frames for the frame-time average
    frame_ms = page.evaluate("parseFloat(document.getElementById('stats').textContent.split('·')"
                             ".find((p) => p.includes('ms/frame')))")
    page.close()
    # The panel shows "– ms/frame" until two frames were drawn in a row (a page that draws
    # the whole scene at once and then rests, paused, measures none): no figure, not NaN.
    frame_ms = None if frame_ms is None or math.isnan(frame_ms) else frame_ms
    return (s["firstFrameAt"] - s["firstMegabyteAt"]) / 1000, (settled_at - s["firstMegabyteAt"]) / 1000, frame_ms


def _ms(value) -> str:
    return "no frame time (drew no two frames in a row)" if value is None else f"{value:.0f} ms/frame"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--splats", type=int, default=1_000_000)
    ap.add_argument("--loads", type=int, default=3, help="fresh page loads per network setting")
    ap.add_argument("--sorts", type=int, default=7, help="worker sorts to time")
    ap.add_argument("--mbps", type=float, default=100.0, help="throttled download speed (Mbit/s)")
    ap.add_argument("--size", default="1280x720")
    args = ap.parse_args()
    size = cam.parse_size(args.size)
    path = os.environ.get("SPLATCONV_CHROMIUM") or shutil.which("chromium")
    if not path:
        raise SystemExit("needs Chromium: apt-get install chromium (or set SPLATCONV_CHROMIUM)")
    from playwright.sync_api import sync_playwright

    with work_folder(prefix="bench-web-") as folder:
        scene_path = os.path.join(folder, "bench.splatv")
        t0 = time.perf_counter()
        splatconv.write(make_scene(args.splats), scene_path)
        mb = os.path.getsize(scene_path) / 1e6
        print(f"scene: {args.splats:,} splats, {mb:.1f} MB .splatv, written in {time.perf_counter() - t0:.1f} s; "
              f"page {size[0]}x{size[1]}")
        server = ViewServer([scene_path])
        threading.Thread(target=server.serve, kwargs={"open_browser": False}, daemon=True).start()
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=path, args=list(ARGS), headless=True)
            print(f"browser: Chromium {browser.version} (headless, SwiftShader), python {sys.version.split()[0]}")

            page = browser.new_page(viewport={"width": size[0], "height": size[1]}, device_scale_factor=1)
            page.goto(server.url + "#t=0.5&ui=0")
            page.wait_for_function("() => window.splatconvPlayer.status().loaded", timeout=600_000)
            sorts = []
            for k, view in enumerate(views(args.sorts)):
                proj = cam.projection_matrix(1000.0, 1000.0, *size)
                r = page.evaluate("([vp]) => window.splatconvPlayer.benchSort(0, vp)", [cam.multiply(proj, view)])
                sorts.append(r["ms"])
                print(f"worker sort {k}: {r['count']:,} records in {r['ms']:.1f} ms")
            page.close()
            med = statistics.median(sorts)
            print(f"worker sort, median of {len(sorts)}: {med:.1f} ms (target <= 150 ms: "
                  f"{'met' if med <= 150 else 'NOT MET'})")

            for label, mbps in (("unthrottled (local server)", 0), (f"throttled to {args.mbps:g} Mbit/s", args.mbps)):
                rows = [load_once(browser, server.url + "#t=0.5&ui=0", size, mbps) for _ in range(args.loads)]
                first, full = (statistics.median(c) for c in list(zip(*rows))[:2])
                measured = [c for _a, _b, c in rows if c is not None]
                frame = statistics.median(measured) if measured else None
                for i, (a, b, c) in enumerate(rows):
                    print(f"  {label} load {i}: first frame {a:.2f} s after the first MB, whole scene sorted "
                          f"and drawn {b:.2f} s after it, then {_ms(c)}")
                print(f"{label}: first frame {first:.2f} s after the first MB (target <= 2 s: "
                      f"{'met' if first <= 2 else 'NOT MET'}), whole scene {full:.2f} s, {_ms(frame)} "
                      f"(medians of {len(rows)}; frame time of the {len(measured)} loads that measured one)")
            browser.close()
        server.stop()


if __name__ == "__main__":
    main()
