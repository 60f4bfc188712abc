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

With ``--splatvq`` the scene is written as ``.splatvq`` (the default setting) and
the page decodes it in its workers. It prints the decode time of the whole file
held in memory, in the page's decode workers with nothing drawn (target: 1M
splats within 1 s), and for each load the time from the first byte to the last
block decoded while the page draws, after the last byte, and the blocks' summed
inflate and decode time in the helper workers. On a shared machine the wall
times stretch with the load: it also prints the CPU time the browser used for
each decode (from ``/proc``), which stretches much less. With ``--baseline REV``
it also times the decoder (``splatvq_decode.js``) of git revision REV on the
same page, decodes of the two alternating, and prints both medians side by side.

Run::

    python bench/bench_web.py [--splats N] [--loads K] [--mbps 100] [--size WxH]
                              [--splatvq [--decode-only] [--baseline REV]]

Needs Debian's ``chromium`` (or SPLATCONV_CHROMIUM) and the ``playwright`` package.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import statistics
import subprocess
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


def _browser_cpu_seconds() -> float | None:
    """CPU seconds (user + system) used so far by this process's descendants (the browser), from /proc.

    On a machine shared with other work, wall times stretch with the load; the CPU
    time the browser spends on a task does much less. None where /proc is missing.
    """
    if not os.path.isdir("/proc/self"):
        return None
    parents, times = {}, {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parents[int(entry)] = int(fields[1])
        times[int(entry)] = int(fields[11]) + int(fields[12])
    me, total = os.getpid(), 0
    for pid in times:
        p = pid
        while p in parents and p != me and p > 1:
            p = parents[p]
        if p == me and pid != me:
            total += times[pid]
    return total / os.sysconf("SC_CLK_TCK")


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
    seg = s["segments"][0]
    if seg["format"] == "splatvq":
        print(f"    decode: {seg['loadedAt'] - seg['firstByteAt']:.0f} ms from the first byte to the last block "
              f"decoded ({seg['loadedAt'] - seg['lastByteAt']:.0f} ms after the last byte; blocks' inflate and "
              f"decode {seg['decodeMs']:.0f} ms summed over the helper workers)")
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
    ap.add_argument("--splatvq", action="store_true", help="write and play the scene as .splatvq")
    ap.add_argument("--decode-only", action="store_true", help="with --splatvq: the decode figures alone")
    ap.add_argument("--baseline", metavar="REV",
                    help="with --splatvq: also time git revision REV's decoder, alternating with this one's")
    args = ap.parse_args()
    size = cam.parse_size(args.size)
    decoders = [("this", None)]
    if args.baseline:
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        source = subprocess.run(["git", "show", f"{args.baseline}:splatconv/web/assets/splatvq_decode.js"], cwd=root,
                                capture_output=True, text=True)
        if source.returncode:
            raise SystemExit(f"--baseline {args.baseline}: {source.stderr.strip()}")
        decoders.append((args.baseline, source.stdout))
    path = os.environ.get("SPLATCONV_CHROMIUM") or shutil.which("chromium")
    if not path:
        raise SystemExit("needs Chromium: apt-get install chromium (or set SPLATCONV_CHROMIUM)")
    from playwright.sync_api import sync_playwright

    with work_folder(prefix="bench-web-") as folder:
        suffix = ".splatvq" if args.splatvq else ".splatv"
        scene_path = os.path.join(folder, "bench" + suffix)
        t0 = time.perf_counter()
        splatconv.write(make_scene(args.splats), scene_path)
        mb = os.path.getsize(scene_path) / 1e6
        print(f"scene: {args.splats:,} splats, {mb:.1f} MB {suffix}, written in {time.perf_counter() - t0:.1f} s; "
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
            if args.splatvq:
                decodes = {label: [] for label, _ in decoders}
                for k in range(args.sorts):
                    for label, source in decoders:
                        cpu0 = _browser_cpu_seconds()
                        r = page.evaluate("([url, source]) => window.splatconvPlayer.benchDecode(url, source)",
                                          [server.url + "scene/0.splatvq", source])
                        cpu1 = _browser_cpu_seconds()
                        if r["error"]:
                            raise SystemExit(f"decode failed ({label} decoder): {r['error']}")
                        decodes[label].append(r["ms"])
                        cpu = "" if cpu0 is None else f"; the browser's CPU time, fetch included: {cpu1 - cpu0:.2f} s"
                        print(f"decode {k} ({label} decoder): {r['splats']:,} splats in {r['ms']:.0f} ms (blocks' work "
                              f"{r['blockMs']:.0f} ms summed over the helper workers, of which inflate "
                              f"{r['inflateMs']:.0f} ms{cpu})")
                med = statistics.median(decodes["this"])
                print(f"decode, median of {len(decodes['this'])}: {med:.0f} ms (target <= 1000 ms: "
                      f"{'met' if med <= 1000 else 'NOT MET'})")
                if args.baseline:
                    base = statistics.median(decodes[args.baseline])
                    print(f"decode medians, alternating: this decoder {med:.0f} ms, {args.baseline}'s {base:.0f} ms "
                          f"({base / med:.2f}x)")
            page.close()
            med = statistics.median(sorts)
            print(f"worker sort, median of {len(sorts)}: {med:.1f} ms (target <= 150 ms: "
                  f"{'met' if med <= 150 else 'NOT MET'})")
            if args.decode_only:
                browser.close()
                server.stop()
                return

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
