"""Seconds per frame of the headless preview renderer on a 1M-splat scene.

Draws a generated scene of N splats (default 1,000,000) at 1280x720 from a few
viewpoints and times, and prints per-frame seconds split into the viewer-style
depth sort (numpy), the index upload and the draw (including readback) on
whatever OpenGL the machine has (Mesa llvmpipe on a CPU-only machine).

With ``--huge`` every splat is large (linear scales 1 to 3 at about 6 units
from the camera: screen axes near the viewer's 1,024-pixel cap), the case where
fill, not the vertex stage, sets the cost; it prints the bound of
``specs/render.md`` (records x min(W*H, 4 * 1024^2) fragments) and the seconds per
million fragments of that bound, so the minutes a 1M-splat scene of huge splats
takes can be read off. Use fewer splats there (e.g. ``--splats 20000``).

Run::

    python bench/bench_render.py [--splats N] [--frames K] [--size WxH] [--huge]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time

import numpy as np

from splatconv.formats import splatv
from splatconv.model import COLUMNS, Scene
from splatconv.render import camera as cam
from splatconv.render.preview import FrameTimes, Renderer, View

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from tests.scenes import draw_columns, render_recipe  # noqa: E402  (the scene factory the tests use)


#: Largest screen axis of a splat, pixels (splat_main.glsl's min(..., 1024.0)).
AXIS_CAP = 1024


def make_scene(n: int, huge: bool = False) -> Scene:
    """A random but plausible lite scene: N splats in a 4-unit box, all visible at t=0.5 (``huge``: big splats)."""
    cols = draw_columns(n, 0, render_recipe(huge))
    return Scene(columns={name: cols[name] for name in COLUMNS})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--splats", type=int, default=1_000_000)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--huge", action="store_true", help="Splats with screen axes near the 1,024-pixel cap.")
    args = ap.parse_args()
    width, height = cam.parse_size(args.size)

    t0 = time.perf_counter()
    scene = make_scene(args.splats, args.huge)
    records, _ = splatv.encode(scene)
    prep = time.perf_counter() - t0

    r = Renderer(width, height)
    info = r.ctx.info
    print(f"splatconv render benchmark -- {info['GL_RENDERER']}, {info['GL_VERSION']}")
    print(f"machine: {platform.machine()}, python {platform.python_version()}")
    print(f"scene: {args.splats:,} splats ({len(records):,} records with padding), "
          f"packed in {prep:.2f} s; frame {width}x{height}")
    upload = r.load_records(records)
    print(f"texture upload (once per file): {upload:.3f} s")

    rows = []
    for k in range(args.frames):
        angle = 0.4 * k
        camera = {"rotation": [[np.cos(angle), 0, -np.sin(angle)], [0, 1, 0], [np.sin(angle), 0, np.cos(angle)]],
                  "position": [6 * np.sin(angle), 0, -6 * np.cos(angle)]}
        view = View(cam.view_matrix(camera), 1000.0, 1000.0, width, height)
        ft = FrameTimes()
        t = time.perf_counter()
        img = r.draw(view, 0.5, ft)
        total = time.perf_counter() - t
        rows.append((ft.sort, ft.upload, ft.draw, total))
        print(f"frame {k}: sort {ft.sort:.3f} s  upload {ft.upload:.3f} s  draw+readback {ft.draw:.3f} s  "
              f"total {total:.3f} s  (mean pixel {img[..., :3].mean():.1f})")
    med = [statistics.median(c) for c in zip(*rows)]
    print(f"median per frame: sort {med[0]:.3f} s, upload {med[1]:.3f} s, draw {med[2]:.3f} s, "
          f"total {med[3]:.3f} s")
    records = len(records)
    bound = records * min(width * height, 4 * AXIS_CAP**2)
    print(f"fill bound: {records:,} records x min({width}x{height}, 4 x {AXIS_CAP}^2) = {bound / 1e9:.2f} G fragments "
          f"a frame; {med[2] / (bound / 1e6) * 1e3:.3f} ms of draw per million of them"
          + (f" (1M such splats: about {med[2] * 1e6 / records / 60:.0f} min a frame)" if args.huge else ""))
    share = (med[0] + med[1]) / med[3]
    print(f"sort + upload share of the frame: {100 * share:.0f}% "
          f"({'they do not dominate' if share < 0.5 else 'THEY DOMINATE'})")
    r.release()


if __name__ == "__main__":
    main()
