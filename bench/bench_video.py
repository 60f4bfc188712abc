"""Seconds to render and encode a video: ``render OUT.mp4 --frames 48 --size 640x360 --orbit 90``.

Times the library call behind ``render`` (read, draw each frame, encode it) on
the bundled sample scene and on a generated scene of N splats (default
100,000; written once to a ``.splatv`` in a temporary folder), then the same
frames drawn without encoding, so the encoder's share can be read off.

Run::

    python bench/bench_video.py [--splats N] [--frames K] [--size WxH] [--suffix .mp4|.webm]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import splatconv  # noqa: E402
from bench_render import make_scene  # noqa: E402  (the render benchmark's scene)
from splatconv import io  # noqa: E402
from splatconv.render import camera as cam  # noqa: E402
from splatconv.render import paths  # noqa: E402
from splatconv.render.commands import render_file  # noqa: E402
from splatconv.render.frames import cameras_of, load, render_frames, resolve_view  # noqa: E402


def _time(path, out, frames: int, size: str, orbit: float) -> tuple:
    t = time.perf_counter()
    summary = render_file(path, out, frames=frames, size=size, orbit=orbit, force=True)
    video = time.perf_counter() - t
    t = time.perf_counter()
    source = load(path)
    camera = cameras_of(source)[0]
    views = [resolve_view([c], size=cam.parse_size(size))
             for c in paths.orbit_path(camera, paths.scene_centre(source.scene), orbit, frames)]
    with contextlib.closing(render_frames(source.texture(), views, paths.shares(frames))) as drawn:
        for _frame in drawn:
            pass
    return summary, video, time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--splats", type=int, default=100_000)
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--orbit", type=float, default=90.0)
    ap.add_argument("--suffix", default=".mp4")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        sample = os.path.join(folder, "dancers.splatv")
        splatconv.convert(ROOT / "sample_data/dancers.ply", sample, cameras=ROOT / "sample_data/cameras.json")
        generated = os.path.join(folder, "generated.splatv")
        io.write(make_scene(args.splats), generated)
        for name, path in (("sample (5,000 splats)", sample), (f"generated ({args.splats:,} splats)", generated)):
            summary, video, drawn = _time(path, os.path.join(folder, "out" + args.suffix), args.frames,
                                          args.size, args.orbit)
            print(f"{name}: {video:.2f} s to read, draw and encode ({drawn:.2f} s to read and draw alone); "
                  f"{summary.split(': ', 1)[1]}")


if __name__ == "__main__":
    main()
