"""Benchmark long clips: a frame sequence -> 4D fit, and a segment merge.

The issue's targets: a 300-frame sequence of 100,000 splats a frame, and a
6-segment merge of 300,000 splats a segment, each with peak memory below 2 GB.

Inputs are generated on the fly in a temporary folder and deleted afterwards:

* sequence: a synthetic Spacetime Gaussians lite scene of ``--frame-splats``
  splats (cubic motion, rotation, temporal Gaussians: the model the fit
  recovers), of which ``--nonlinear`` (default 1%) instead move on circles,
  which one cubic cannot follow (so the piece-splitting passes run too); each
  frame written as a plain 3DGS PLY (SH degree 0) of what the viewer shows
  at that frame's time;
* segments: ``--segments`` lite PLY files of ``--segment-splats`` splats, half
  of them long-lived (temporal scale above 1, 300 of them infinite), as the
  issue measures real trained segments.

Each command runs as ``splatconv`` in a fresh process through a launcher that
reports its wall seconds and peak RSS. ``merge --segments`` runs once without
the fidelity check (the merge alone), once with it on every 60th frame (5 of
300: the time of a check). The exit status is 0 whatever the figures; it is a
report, not a test.

Run::

    python bench/bench_clips.py [--frames 300] [--frame-splats 100000] [--segments 6]
        [--segment-splats 300000] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time

import numpy as np

import splatconv
from splatconv import io, viewer
from splatconv.model import COLUMNS, Scene, static_columns
from _harness import CLI, machine_line, row, run_fresh, work_folder

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from tests.scenes import clip_recipe, draw_columns  # noqa: E402  (the scene factory the tests use)

#: Peak memory target, bytes.
TARGET_RSS = 2 * 1024 ** 3


def lite_columns(n: int, seed: int, long_share: float = 0.3) -> dict:
    """A plausible lite scene (:func:`tests.scenes.clip_recipe`): (n,) float32 per model column."""
    cols = draw_columns(n, seed, clip_recipe(long_share))
    return {name: cols[name] for name in COLUMNS}


def snapshot(cols: dict, t: float, circles: np.ndarray) -> Scene:
    """The viewer's state at ``t`` as a static scene; rows ``circles`` on circles instead."""
    out = dict(cols)
    p = viewer.position_at(cols, t)
    q = viewer.rotation_at(cols, t, normalize=False)
    a = viewer.opacity(cols) * viewer.temporal_opacity(cols, t)
    ang = 2 * np.pi * 1.5 * t + np.arange(len(circles))
    p[circles, 0] = np.asarray(cols["x"])[circles] + np.cos(ang)
    p[circles, 1] = np.asarray(cols["y"])[circles] + np.sin(ang)
    for i, name in enumerate("xyz"):
        out[name] = p[:, i].astype(np.float32)
    for i in range(4):
        out[f"rot_{i}"] = q[:, i].astype(np.float32)
    with np.errstate(divide="ignore"):
        out["opacity"] = np.maximum(viewer.logit(a), -30).astype(np.float32)
    out.update(static_columns(len(a)))
    return Scene(columns=out)


def make_frames(folder: str, frames: int, n: int, nonlinear: float) -> int:
    os.makedirs(folder)
    cols = lite_columns(n, 1)
    cols["trbf_scale"] = np.maximum(cols["trbf_scale"], np.float32(np.log(0.3)))  # seen in several frames
    circles = np.flatnonzero(np.random.default_rng(2).uniform(size=n) < nonlinear)
    size = 0
    for k, t in enumerate(np.linspace(0, 1, frames)):
        path = os.path.join(folder, f"frame_{k}.ply")
        io.write(snapshot(cols, t, circles), path, layout="3dgs")
        size += os.path.getsize(path)
    return size


def make_segments(folder: str, count: int, n: int) -> list:
    os.makedirs(folder)
    paths = []
    for i in range(count):
        cols = lite_columns(n, 10 + i, long_share=0.5)
        cols["trbf_scale"][:300] = np.inf
        path = os.path.join(folder, f"seg{i}.ply")
        io.write(Scene(columns=cols), path)
        paths.append(path)
    return paths


def launch(args: list) -> tuple:
    """Run ``splatconv args`` in a fresh process (through :func:`_harness.run_fresh`'s launcher);
    (exit status, wall seconds, peak RSS bytes, its stdout then its stderr)."""
    r = run_fresh([CLI, *args])
    return r["code"], r["wall"], round(r["rss_mb"] * 1e6), r["stdout"] + r["stderr"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--frame-splats", type=int, default=100_000)
    ap.add_argument("--nonlinear", type=float, default=0.01, help="share of splats on circles (default 0.01)")
    ap.add_argument("--segments", type=int, default=6)
    ap.add_argument("--segment-splats", type=int, default=300_000)
    ap.add_argument("--keep", help="generate inputs here and keep them")
    a = ap.parse_args(argv)
    print(f"splatconv {splatconv.__version__}, {machine_line()}; shared machine: figures are noisy")
    with work_folder(a.keep, "bench_clips_") as root:
        t = time.perf_counter()
        size = make_frames(os.path.join(root, "frames"), a.frames, a.frame_splats, a.nonlinear)
        print(f"generated {a.frames} frames of {a.frame_splats:,} splats ({size / 1e9:.2f} GB) in "
              f"{time.perf_counter() - t:.0f} s")
        out = os.path.join(root, "clip.splatv")
        status, wall, rss, text = launch(["convert", os.path.join(root, "frames"), out, "-q"])
        print("frame sequence -> 4D (splatconv convert FRAMES/ clip.splatv)")
        print(row("exit status", str(status)))
        print(row("wall seconds", f"{wall:.1f}", f"{a.frames * a.frame_splats / wall / 1e6:.2f} M splat-frames/s"))
        print(row("peak RSS", f"{rss / 2 ** 20:,.0f} MiB", "target < 2048 MiB: " + ("met" if rss < TARGET_RSS else
                                                                                       "MISSED")))
        print("\n".join("    " + x for x in text.splitlines()))
        shutil.rmtree(os.path.join(root, "frames"))

        t = time.perf_counter()
        paths = make_segments(os.path.join(root, "segments"), a.segments, a.segment_splats)
        print(f"\ngenerated {a.segments} segments of {a.segment_splats:,} splats in {time.perf_counter() - t:.0f} s")
        for label, extra in (("merge alone (--no-check)", ["--no-check"]),
                             ("merge + fidelity every 60th frame", ["--check-every", "60", "--force"])):
            status, wall, rss, text = launch(["merge", *paths, os.path.join(root, "merged.splatv"), "--segments",
                                              "-q", *extra])
            print(f"segments end to end: {label}")
            print(row("exit status", str(status)))
            print(row("wall seconds", f"{wall:.1f}"))
            print(row("peak RSS", f"{rss / 2 ** 20:,.0f} MiB", "target < 2048 MiB: " + ("met" if rss < TARGET_RSS
                                                                                           else "MISSED")))
            keep = [x for x in text.splitlines() if not x.startswith(("frame ", " ")) or
                    x.startswith("  segment")]
            print("\n".join("    " + x for x in keep))
    return 0


if __name__ == "__main__":
    sys.exit(main())
